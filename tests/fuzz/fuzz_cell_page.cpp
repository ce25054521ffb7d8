// libFuzzer target for the cell page decoders (src/codec/cell_codec.h): the first input byte picks
// the codec (its value mod 3: raw, Draco, meshopt), the rest is the page payload, decoded against a fixed
// 16-bit lattice. Any crash, leak, sanitizer report, hang or out-of-memory is a finding; a
// Corruption status is the expected outcome for garbage. A scene that decodes must be usable:
// every primitive refers into its array and lattice codecs' vertices lie on the lattice.
//
// With FRONTIER_FUZZ_SEEDS=DIR in the environment, start-up first writes valid pages of every
// codec into DIR (tests/fuzz/run.sh passes the corpus directory), so that mutation starts
// from real Draco and meshoptimizer streams rather than having to discover them.
#include "src/codec/cell_codec.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace {

using frontier::CellCodec;
using frontier::Lattice;
using frontier::Scene;
using frontier::Vec3;

const Lattice& fuzz_lattice() {
  static const Lattice lattice = Lattice::covering(frontier::Aabb(Vec3(-10.0), Vec3(10.0)), 16);
  return lattice;
}

// A bumpy n x n grid on the lattice (two triangles per square), optionally with normals, plus
// one primitive of every other kind.
Scene seed_scene(int n, bool normals, bool others) {
  const Lattice& lattice = fuzz_lattice();
  auto at = [&](int i, int j) {
    return lattice.snap(Vec3(i * 0.5 - 5.0, j * 0.5 - 5.0, std::sin(i * 0.7) * std::cos(j * 0.4)));
  };
  Scene scene;
  uint32_t source = 0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const std::array<Vec3, 3> up = {Vec3(0, 0, 1), Vec3(0, 0.6, 0.8), Vec3(0.6, 0, 0.8)};
      scene.add_triangle({at(i, j), at(i + 1, j), at(i + 1, j + 1)}, source++, static_cast<uint32_t>(i / 3),
                         normals ? &up : nullptr);
      scene.add_triangle({at(i, j), at(i + 1, j + 1), at(i, j + 1)}, source++, static_cast<uint32_t>(i / 3),
                         normals ? &up : nullptr);
    }
  }
  if (others) {
    scene.add_sphere({Vec3(1.0), 0.5}, source++, 1);
    frontier::Box box;
    box.bounds = frontier::Aabb(Vec3(-1.0), Vec3(0.5));
    scene.add_box(box, source++, 2);
    scene.add_cone({Vec3(0.0), 0.5, Vec3(0.0, 0.0, 2.0), 0.25}, source++, 3);
    frontier::Quadric q;
    q.coeff = {1, 1, 1, 0, 0, 0, 0, 0, 0, -1};
    q.clip_count = 1;
    q.clip[0] = frontier::Vec4(0, 0, 1, 0);
    q.bounds = frontier::Aabb(Vec3(-1.0), Vec3(1.0));
    scene.add_quadric(q, source++, 4);
  }
  return scene;
}

void write_seeds(const std::string& dir) {
  int written = 0;
  for (CellCodec codec : {CellCodec::Raw, CellCodec::Draco, CellCodec::Meshopt}) {
    for (int n : {0, 1, 4, 12}) {
      for (bool normals : {false, true}) {
        frontier::CellCodecOptions options;
        options.codec = codec;
        options.lattice = fuzz_lattice();
        auto encoded = frontier::encode_cell(seed_scene(n, normals, n != 4), options);
        if (!encoded.is_ok()) continue;
        const std::string path = dir + "/seed-" + std::to_string(written++);
        FILE* f = std::fopen(path.c_str(), "wb");
        if (f == nullptr) return;
        const auto tag = static_cast<uint8_t>(codec);
        std::fwrite(&tag, 1, 1, f);
        std::fwrite(encoded->payload.data(), 1, encoded->payload.size(), f);
        std::fclose(f);
      }
    }
  }
}

void check_usable(const Scene& scene, CellCodec codec) {
  for (const frontier::PrimRef& p : scene.prims) {
    size_t size = 0;
    switch (p.kind) {
      case frontier::PrimKind::Triangle: size = scene.triangles.size(); break;
      case frontier::PrimKind::Sphere: size = scene.spheres.size(); break;
      case frontier::PrimKind::Box: size = scene.boxes.size(); break;
      case frontier::PrimKind::Cone: size = scene.cones.size(); break;
      case frontier::PrimKind::Quadric: size = scene.quadrics.size(); break;
    }
    if (p.index >= size) __builtin_trap();
  }
  if (!scene.triangle_normals.empty() && scene.triangle_normals.size() != scene.triangles.size()) __builtin_trap();
  for (const frontier::Quadric& q : scene.quadrics) {
    if (q.clip_count < 0 || q.clip_count > frontier::Quadric::kMaxClipPlanes) __builtin_trap();
  }
  if (frontier::cell_codec_on_lattice(codec)) {
    const Lattice& lattice = fuzz_lattice();
    const int64_t last = (int64_t{1} << lattice.bits) - 1;
    const Vec3 hi = lattice.point({last, last, last});
    for (const frontier::Triangle& t : scene.triangles) {
      for (const Vec3& v : {t.v0, t.v1, t.v2}) {
        if (!(v.x >= lattice.origin.x && v.y >= lattice.origin.y && v.z >= lattice.origin.z && v.x <= hi.x &&
              v.y <= hi.y && v.z <= hi.z)) {
          __builtin_trap();
        }
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  if (const char* dir = std::getenv("FRONTIER_FUZZ_SEEDS"); dir != nullptr) write_seeds(dir);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const auto codec = static_cast<CellCodec>(data[0] % 3);
  Scene scene;
  const frontier::Status s = frontier::decode_cell({data + 1, size - 1}, codec, fuzz_lattice(), scene);
  if (s.is_ok()) {
    check_usable(scene, codec);
  } else if (scene.size() != 0) {
    __builtin_trap();  // a failed decode leaves an empty scene
  }
  return 0;
}
