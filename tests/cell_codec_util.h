// Test helpers for the cell page codecs (tests/test_cell_codec*.cpp): test meshes, exact
// comparison of decoded cells, order-free triangle multisets, and the damage check every
// codec's payloads go through.
#pragma once

#include "src/codec/cell_codec.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <tuple>
#include <vector>

namespace frontier::codec_test {

using Code = Status::Code;

constexpr double kPi = 3.14159265358979323846;

// A UV sphere (rings of `around` vertices, a pole vertex at each end) with 2*around*(rings-1)
// triangles, outward-facing; vertices snapped to `lattice` when given. Per-vertex normals
// (the unit radius) when `normals`. Sources are 1000 + index, materials change every 700.
inline Scene sphere_mesh(const Vec3& center, double radius, int around, int rings, const Lattice* lattice,
                  bool normals = false) {
  std::vector<Vec3> verts;
  verts.push_back(center + Vec3(0, 0, radius));
  for (int j = 1; j < rings; ++j) {
    const double theta = kPi * j / rings;
    for (int i = 0; i < around; ++i) {
      const double phi = 2 * kPi * i / around;
      verts.push_back(center +
                      radius * Vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)));
    }
  }
  verts.push_back(center - Vec3(0, 0, radius));
  const int south = static_cast<int>(verts.size()) - 1;
  auto ring = [&](int j, int i) { return 1 + (j - 1) * around + (i % around); };
  std::vector<std::array<int, 3>> faces;
  for (int i = 0; i < around; ++i) faces.push_back({0, ring(1, i), ring(1, i + 1)});
  for (int j = 1; j < rings - 1; ++j) {
    for (int i = 0; i < around; ++i) {
      faces.push_back({ring(j, i), ring(j + 1, i), ring(j + 1, i + 1)});
      faces.push_back({ring(j, i), ring(j + 1, i + 1), ring(j, i + 1)});
    }
  }
  for (int i = 0; i < around; ++i) faces.push_back({south, ring(rings - 1, i + 1), ring(rings - 1, i)});
  Scene scene;
  for (size_t f = 0; f < faces.size(); ++f) {
    Vec3 v[3];
    std::array<Vec3, 3> n;
    for (int c = 0; c < 3; ++c) {
      v[c] = lattice != nullptr ? lattice->snap(verts[faces[f][c]]) : verts[faces[f][c]];
      n[c] = glm::normalize(verts[faces[f][c]] - center);
    }
    scene.add_triangle({v[0], v[1], v[2]}, static_cast<uint32_t>(1000 + f), static_cast<uint32_t>(f / 700),
                       normals ? &n : nullptr);
  }
  return scene;
}

// One of each non-triangle primitive (two quadrics, one with clip planes), near `at`.
inline void add_other_primitives(Scene& scene, const Vec3& at, uint32_t source) {
  scene.add_sphere({at + Vec3(1.5, 0.25, -0.125), 0.75}, source, 3);
  Box box;
  box.bounds = Aabb(at + Vec3(-1, -2, -3), at + Vec3(0.1, 0.2, 0.3));
  scene.add_box(box, source + 1, 4);
  scene.add_cone({at + Vec3(0, 0, 1), 0.5, at + Vec3(0, 0, 2.5), 0.0}, source + 2, 4);
  Quadric q;
  q.coeff = {1, 1, 1, 0.5, 0.25, 0.125, -2, 3, -4, -1.0 / 3.0};
  q.clip_count = 3;
  q.clip[0] = Vec4(1, 0, 0, -at.x);
  q.clip[1] = Vec4(0, -1, 0, at.y + 0.1);
  q.clip[2] = Vec4(0.6, 0.8, 0, 1e-7);
  q.bounds = Aabb(at - Vec3(2), at + Vec3(2));
  scene.add_quadric(q, source + 3, 5);
  Quadric plain;
  plain.coeff = {0, 0, 0, 0, 0, 0, 0, 0, 1, -at.z};
  plain.bounds = Aabb(at - Vec3(1), at + Vec3(1));
  scene.add_quadric(plain, source + 4, 0);
}

inline bool same_quadric(const Quadric& a, const Quadric& b) {
  if (a.coeff != b.coeff || a.clip_count != b.clip_count || a.bounds.lo != b.bounds.lo || a.bounds.hi != b.bounds.hi) {
    return false;
  }
  for (int k = 0; k < a.clip_count; ++k) {
    if (a.clip[static_cast<size_t>(k)] != b.clip[static_cast<size_t>(k)]) return false;
  }
  return true;
}

inline bool same_prim(const PrimRef& a, const PrimRef& b) {
  return a.kind == b.kind && a.index == b.index && a.source == b.source && a.material == b.material;
}

// Every primitive, array and normal identical (operator== on doubles).
inline void expect_identical(const Scene& a, const Scene& b) {
  ASSERT_EQ(a.prims.size(), b.prims.size());
  for (size_t i = 0; i < a.prims.size(); ++i) EXPECT_TRUE(same_prim(a.prims[i], b.prims[i])) << "prim " << i;
  ASSERT_EQ(a.triangles.size(), b.triangles.size());
  for (size_t i = 0; i < a.triangles.size(); ++i) {
    EXPECT_TRUE(a.triangles[i].v0 == b.triangles[i].v0 && a.triangles[i].v1 == b.triangles[i].v1 &&
                a.triangles[i].v2 == b.triangles[i].v2)
        << "triangle " << i;
  }
  ASSERT_EQ(a.triangle_normals.size(), b.triangle_normals.size());
  for (size_t i = 0; i < a.triangle_normals.size(); ++i) EXPECT_EQ(a.triangle_normals[i], b.triangle_normals[i]);
  ASSERT_EQ(a.spheres.size(), b.spheres.size());
  for (size_t i = 0; i < a.spheres.size(); ++i) {
    EXPECT_TRUE(a.spheres[i].center == b.spheres[i].center && a.spheres[i].radius == b.spheres[i].radius);
  }
  ASSERT_EQ(a.boxes.size(), b.boxes.size());
  for (size_t i = 0; i < a.boxes.size(); ++i) {
    EXPECT_TRUE(a.boxes[i].bounds.lo == b.boxes[i].bounds.lo && a.boxes[i].bounds.hi == b.boxes[i].bounds.hi);
  }
  ASSERT_EQ(a.cones.size(), b.cones.size());
  for (size_t i = 0; i < a.cones.size(); ++i) {
    EXPECT_TRUE(a.cones[i].base == b.cones[i].base && a.cones[i].apex == b.cones[i].apex &&
                a.cones[i].base_radius == b.cones[i].base_radius && a.cones[i].apex_radius == b.cones[i].apex_radius);
  }
  ASSERT_EQ(a.quadrics.size(), b.quadrics.size());
  for (size_t i = 0; i < a.quadrics.size(); ++i) EXPECT_TRUE(same_quadric(a.quadrics[i], b.quadrics[i])) << i;
}

// A triangle's corners rotated to start at the lexicographically smallest: the same key for
// the same oriented triangle whichever corner comes first.
using Corner = std::tuple<double, double, double>;
using TriangleKey = std::array<Corner, 3>;
inline TriangleKey triangle_key(const Triangle& t) {
  const Corner a{t.v0.x, t.v0.y, t.v0.z}, b{t.v1.x, t.v1.y, t.v1.z}, c{t.v2.x, t.v2.y, t.v2.z};
  if (b < a && b <= c) return {b, c, a};
  if (c < a && c < b) return {c, a, b};
  return {a, b, c};
}

// (source, material, oriented triangle) of every triangle primitive.
inline std::multiset<std::tuple<uint32_t, uint32_t, TriangleKey>> triangle_multiset(const Scene& s) {
  std::multiset<std::tuple<uint32_t, uint32_t, TriangleKey>> out;
  for (const PrimRef& p : s.prims) {
    if (p.kind == PrimKind::Triangle) out.insert({p.source, p.material, triangle_key(s.triangles[p.index])});
  }
  return out;
}

// Encodes `s` with a lattice codec (default options otherwise).
inline Result<EncodedCell> encode_on(CellCodec codec, const Scene& s, const Lattice& lattice) {
  CellCodecOptions options;
  options.codec = codec;
  options.lattice = lattice;
  return encode_cell(s, options);
}

// The codecs that store triangles on the lattice.
constexpr CellCodec kLatticeCodecs[] = {CellCodec::Draco, CellCodec::Meshopt};

inline Lattice lattice_for(const Scene& s, int bits, double margin = 0.0) {
  Aabb b = s.bounds();
  b.lo -= Vec3(margin);
  b.hi += Vec3(margin);
  return Lattice::covering(b, bits);
}


// Every truncation fails; flipping one byte at `samples` positions (and a few multi-byte
// scribbles) either fails or decodes to something sane; nothing crashes. Run under
// -DFRONTIER_SANITIZE=ON to catch out-of-bounds reads as well.
inline void check_damage(const std::vector<uint8_t>& payload, CellCodec codec, const Lattice& lattice, size_t samples) {
  Scene out;
  for (size_t n = 0; n < payload.size(); ++n) {
    const std::vector<uint8_t> cut(payload.begin(), payload.begin() + static_cast<std::ptrdiff_t>(n));
    const Status s = decode_cell(cut, codec, lattice, out);
    ASSERT_FALSE(s.is_ok()) << "truncated to " << n << " of " << payload.size() << " bytes";
    EXPECT_EQ(s.code(), Code::Corruption);
    EXPECT_EQ(out.size(), 0u);
  }
  std::mt19937_64 rng(payload.size());
  const Vec3 lattice_hi = lattice.point({(1 << lattice.bits) - 1, (1 << lattice.bits) - 1, (1 << lattice.bits) - 1});
  size_t failed = 0;
  for (size_t i = 0; i < samples; ++i) {
    std::vector<uint8_t> damaged = payload;
    const size_t at = i < payload.size() && samples >= payload.size() ? i : rng() % payload.size();
    damaged[at] ^= static_cast<uint8_t>(1 + rng() % 255);
    if (i % 10 == 0) {  // and now and then a scribbled run
      for (size_t k = at; k < std::min(damaged.size(), at + 1 + rng() % 16); ++k) damaged[k] = static_cast<uint8_t>(rng());
    }
    const Status s = decode_cell(damaged, codec, lattice, out);
    if (!s.is_ok()) {
      ++failed;
      EXPECT_EQ(s.code(), Code::Corruption) << s.to_string();
      continue;
    }
    EXPECT_LE(out.size(), payload.size());
    if (cell_codec_on_lattice(codec)) {
      for (const Triangle& t : out.triangles) {
        for (const Vec3& v : {t.v0, t.v1, t.v2}) {
          EXPECT_TRUE(v.x >= lattice.origin.x && v.y >= lattice.origin.y && v.z >= lattice.origin.z &&
                      v.x <= lattice_hi.x && v.y <= lattice_hi.y && v.z <= lattice_hi.z);
        }
      }
    }
  }
  // Much damage decodes "fine" (a flipped coordinate bit, a different entropy-coded offset):
  // the store's page checksum is what catches that. The structure must notice some.
  EXPECT_GT(failed, 0u);
  std::vector<uint8_t> bad_magic = payload;
  bad_magic[0] ^= 0x10;
  EXPECT_EQ(decode_cell(bad_magic, codec, lattice, out).code(), Code::Corruption);
}

}  // namespace frontier::codec_test
