// The build's spill files (preprocess/spill.h): every primitive comes back bit for bit, on the
// lattice or off it; a torn file is Corruption naming the byte; a terrain's parts take at most
// 16 bytes a triangle on disk; a build that the temporary folder cannot hold fails at once.
#include "preprocess/build.h"
#include "preprocess/spill.h"
#include "preprocess/temp_dir.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <sys/statvfs.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <thread>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_build_spill"); }

// memcmp may not be given a null pointer, which an empty vector's data() can be, even for no bytes.
bool same_bits(const void* a, const void* b, size_t n) { return n == 0 || std::memcmp(a, b, n) == 0; }

// A mix of every kind: triangles of a grid on the lattice (sharing vertices), a few off it, with
// and without float precision, normals on all, and the other kinds' doubles.
Scene mixed_scene(const Lattice& lattice, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-3.0, 7.0);
  Scene s;
  const auto on_lattice = [&](int i, int j) { return lattice.snap(Vec3(0.01 * i, 0.02 * j, u(rng) * 0.1)); };
  uint32_t source = 0;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 40; ++j) {
      const Vec3 a = on_lattice(i, j), b = on_lattice(i + 1, j), c = on_lattice(i, j + 1);
      const std::array<Vec3, 3> n = {Vec3(0, 0, 1), Vec3(0.1f, 0.2f, 0.9f), Vec3(u(rng), u(rng), u(rng))};
      s.add_triangle({a, b, c}, source++, static_cast<uint32_t>(i % 3), &n);
      s.add_triangle({b, c, a}, source += 3, static_cast<uint32_t>(i % 3), &n);  // shared, a skip in ids
    }
  }
  const std::array<Vec3, 3> n = {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
  s.add_triangle({Vec3(u(rng), u(rng), u(rng)), Vec3(1.5f, 2.5f, 0.25f), Vec3(-0.0, 1e300, 3)}, 7, 2, &n);
  s.add_triangle({Vec3(1.5f, 2.5f, 0.25f), Vec3(0.5f), Vec3(u(rng))}, UINT32_MAX - 1, 0, &n);
  s.add_sphere({Vec3(u(rng), u(rng), u(rng)), 0.5}, 3, 1);
  s.add_box({Aabb(Vec3(-1.0), Vec3(u(rng) + 10.0))}, 0, 4000000);
  s.add_cone({Vec3(1, 2, 3), 0.5, Vec3(u(rng), 5, 6), 0.1}, 12, 1);
  Quadric q;
  for (double& c : q.coeff) c = u(rng);
  q.clip_count = 3;
  for (Vec4& c : q.clip) c = Vec4(u(rng), u(rng), u(rng), u(rng));
  q.bounds = Aabb(Vec3(-2.0), Vec3(2.0));
  s.add_quadric(q, 13, 1);
  return s;
}

// Writes `scene` to a spill file and reads it back in batches of `batch`.
Scene round_trip(const Scene& scene, std::optional<Lattice> lattice, const std::string& name, size_t batch,
                 uint64_t* file_bytes = nullptr) {
  const std::string path = (scratch() / name).string();
  SpillWriter out(4096);  // small: many flushes
  EXPECT_TRUE(out.open(path, lattice).is_ok());
  for (uint32_t i = 0; i < scene.size(); ++i) EXPECT_TRUE(out.write(scene, i).is_ok());
  EXPECT_TRUE(out.close().is_ok());
  if (file_bytes != nullptr) *file_bytes = out.bytes();
  SpillReader in;
  EXPECT_TRUE(in.open(path, lattice).is_ok());
  Scene back;
  for (bool end = false; !end;) {
    const Status s = in.read(back, batch, end);
    EXPECT_TRUE(s.is_ok()) << s.to_string();
    if (!s) break;
  }
  return back;
}

void expect_same(const Scene& a, const Scene& b) {
  ASSERT_EQ(a.size(), b.size());
  for (uint32_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a.prims[i].kind, b.prims[i].kind) << i;
    EXPECT_EQ(a.prims[i].source, b.prims[i].source) << i;
    EXPECT_EQ(a.prims[i].material, b.prims[i].material) << i;
  }
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  EXPECT_TRUE(same_bits(a.triangles.data(), b.triangles.data(), a.triangles.size() * sizeof(Triangle)));
  ASSERT_EQ(a.triangle_normals.size(), b.triangle_normals.size());
  EXPECT_TRUE(same_bits(a.triangle_normals.data(), b.triangle_normals.data(),
                        a.triangle_normals.size() * sizeof(a.triangle_normals[0])));
  EXPECT_TRUE(same_bits(a.spheres.data(), b.spheres.data(), a.spheres.size() * sizeof(Sphere)));
  EXPECT_TRUE(same_bits(a.boxes.data(), b.boxes.data(), a.boxes.size() * sizeof(Box)));
  EXPECT_TRUE(same_bits(a.cones.data(), b.cones.data(), a.cones.size() * sizeof(Cone)));
  ASSERT_EQ(a.quadrics.size(), b.quadrics.size());
  for (size_t i = 0; i < a.quadrics.size(); ++i) {
    EXPECT_EQ(a.quadrics[i].coeff, b.quadrics[i].coeff);
    EXPECT_EQ(a.quadrics[i].clip_count, b.quadrics[i].clip_count);
    EXPECT_TRUE(same_bits(&a.quadrics[i].clip, &b.quadrics[i].clip, sizeof(a.quadrics[i].clip)));
  }
}

TEST(BuildStoreSpill, EveryPrimitiveComesBackBitForBit) {
  const Lattice lattice = Lattice::covering(Aabb(Vec3(-3.0), Vec3(7.0)), 16);
  const Scene scene = mixed_scene(lattice, 5);
  expect_same(scene, round_trip(scene, lattice, "lattice.spill", 97));
  expect_same(scene, round_trip(scene, std::nullopt, "exact.spill", 4096));
}

TEST(BuildStoreSpill, AMeshOnTheLatticeTakesAFewBytesATriangle) {
  // A height field of 200 x 200 quads in row order, snapped as the build snaps it.
  const Lattice lattice = Lattice::covering(Aabb(Vec3(0.0), Vec3(1.0)), 16);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> h(0.0, 0.05);
  constexpr int kSide = 200;
  std::vector<Vec3> grid;
  for (int j = 0; j <= kSide; ++j) {
    for (int i = 0; i <= kSide; ++i) grid.push_back(lattice.snap(Vec3(double(i) / kSide, double(j) / kSide, h(rng))));
  }
  Scene mesh;
  for (int j = 0; j < kSide; ++j) {
    for (int i = 0; i < kSide; ++i) {
      const auto at = [&](int x, int y) { return grid[static_cast<size_t>(y * (kSide + 1) + x)]; };
      mesh.add_triangle({at(i, j), at(i + 1, j), at(i + 1, j + 1)}, static_cast<uint32_t>(mesh.size()), 0);
      mesh.add_triangle({at(i, j), at(i + 1, j + 1), at(i, j + 1)}, static_cast<uint32_t>(mesh.size()), 0);
    }
  }
  uint64_t on_lattice = 0, exact = 0;
  expect_same(mesh, round_trip(mesh, lattice, "mesh_lattice.spill", 4096, &on_lattice));
  expect_same(mesh, round_trip(mesh, std::nullopt, "mesh_exact.spill", 4096, &exact));
  const double per_triangle = static_cast<double>(on_lattice) / static_cast<double>(mesh.size());
  std::printf("%.2f bytes a triangle on the lattice, %.2f as doubles\n", per_triangle,
              static_cast<double>(exact) / static_cast<double>(mesh.size()));
  EXPECT_LE(per_triangle, 16.0);
  EXPECT_LT(on_lattice, exact);
}

TEST(BuildStoreSpill, TornFileIsCorruptionNamingTheByte) {
  const Lattice lattice = Lattice::covering(Aabb(Vec3(-3.0), Vec3(7.0)), 16);
  const Scene scene = mixed_scene(lattice, 6);
  const std::string path = (scratch() / "torn.spill").string();
  {
    SpillWriter out;
    ASSERT_TRUE(out.open(path, lattice).is_ok());
    for (uint32_t i = 0; i < scene.size(); ++i) ASSERT_TRUE(out.write(scene, i).is_ok());
    ASSERT_TRUE(out.close().is_ok());
  }
  fs::resize_file(path, fs::file_size(path) - 5);
  SpillReader in;
  ASSERT_TRUE(in.open(path, lattice).is_ok());
  Scene back;
  Status s;
  for (bool end = false; !end && s;) s = in.read(back, 1000, end);
  ASSERT_FALSE(s.is_ok());
  EXPECT_EQ(s.code(), Status::Code::Corruption);
  EXPECT_NE(s.message().find(path + ": byte "), std::string::npos) << s.message();
}

// The ingest spill (a PLY with normals, through the spill file instead of parsed again) and
// the parts give the store the second parse gives: the spill changes nothing but the disk used.
TEST(BuildStoreSpill, SpilledAndReparsedInputsGiveTheSameStore) {
  const fs::path in = scratch() / "normals.ply";
  const auto gen = run_binary(proc::gen_binary(),
                              {"terrain", "--triangles", "20000", "--normals", "-o", in.string(), "--quiet"}, scratch());
  ASSERT_EQ(gen.exit_code, 0) << gen.err;
  std::vector<uint8_t> stores[2];
  for (int spill = 0; spill < 2; ++spill) {
    BuildOptions o;
    o.inputs = {in.string()};
    o.output = (scratch() / ("normals_" + std::to_string(spill) + ".frontier")).string();
    o.quiet = true;
    o.threads = 2;
    o.cell_prims = 64;
    o.part_primitives = 3000;
    o.reparse_binary_ply = spill == 0;
    auto report = build_store(o);
    ASSERT_TRUE(report.is_ok()) << report.status().to_string();
    EXPECT_GT(report->parts, 4u);
    EXPECT_LE(report->spill_peak_bytes, report->spill_bytes);
    std::ifstream f(o.output, std::ios::binary);
    stores[spill].assign(std::istreambuf_iterator<char>(f), {});
  }
  EXPECT_FALSE(stores[0].empty());
  EXPECT_TRUE(stores[0] == stores[1]);
}

TEST(BuildTemporaries, ATerrainsSpillTakesAtMost16BytesATriangle) {
  const uint64_t triangles = 1000000;
  const fs::path in = scratch() / "terrain.ply";
  const auto gen = run_binary(proc::gen_binary(),
                              {"terrain", "--triangles", std::to_string(triangles), "-o", in.string(), "--quiet"},
                              scratch());
  ASSERT_EQ(gen.exit_code, 0) << gen.err;
  const fs::path tmp = scratch() / "spill_tmp", out = scratch() / "spill.frontier";
  fs::create_directories(tmp);
  const auto so = scratch() / "spill_out", se = scratch() / "spill_err";
  const pid_t pid = proc::spawn(FRONTIER_BUILD_PATH,
                                {in.string(), "-o", out.string(), "--memory", "16M", "--tmp-dir", tmp.string()}, so, se);
  const auto running = [pid] {
    siginfo_t info{};
    return ::waitid(P_PID, static_cast<id_t>(pid), &info, WEXITED | WNOHANG | WNOWAIT) == 0 && info.si_pid == 0;
  };
  uint64_t peak = 0;
  while (running()) {
    peak = std::max(peak, bytes_under(tmp.string()));
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const auto r = proc::finish(pid, so, se);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const double per_triangle = static_cast<double>(peak) / static_cast<double>(triangles);
  std::printf("temporary folder peaked at %.1f MB: %.1f bytes a triangle\n%s", static_cast<double>(peak) / 1e6,
              per_triangle, r.err.c_str());
  EXPECT_GT(peak, 0u);
  EXPECT_LE(per_triangle, 16.0);
}

TEST(BuildTemporaries, NotEnoughDiskFailsAtOnceNamingTheSpace) {
  const fs::path tmp = scratch() / "full_tmp";
  fs::create_directories(tmp);
  struct statvfs st {};
  ASSERT_EQ(::statvfs(tmp.c_str(), &st), 0);
  const uint64_t free = static_cast<uint64_t>(st.f_bavail) * st.f_frsize;
  // A sparse model twice the free space: its spill alone would need several times the disk.
  const fs::path in = scratch() / "huge.nff";
  std::ofstream(in) << "s 0 0 0 1\n";
  std::error_code ec;
  fs::resize_file(in, 2 * free + (uint64_t{1} << 30), ec);
  if (ec) GTEST_SKIP() << "no sparse file of " << 2 * free << " bytes here: " << ec.message();
  const fs::path out = scratch() / "huge.frontier";
  const auto start = std::chrono::steady_clock::now();
  const auto r = run_binary(FRONTIER_BUILD_PATH, {in.string(), "-o", out.string(), "--tmp-dir", tmp.string()}, scratch());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  fs::remove(in);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find(tmp.string() + ": not enough free space"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("MB needed"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("MB free"), std::string::npos) << r.err;
  EXPECT_LT(seconds, 30.0) << "it read the input first";
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
  EXPECT_TRUE(fs::is_empty(tmp));
}

}  // namespace
}  // namespace frontier
