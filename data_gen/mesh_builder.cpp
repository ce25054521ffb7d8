// Tessellation of the generator's solids (see header for the invariants).
#include "data_gen/mesh_builder.h"

#include <cassert>
#include <cmath>
#include <numbers>
#include <vector>

namespace frontier::gen {
namespace {

// cos/sin of 2 pi j / n, computed once per thread and n (sincos dominated tessellation).
const std::vector<glm::dvec2>& unit_circle(uint64_t n) {
  thread_local std::vector<std::vector<glm::dvec2>> tables;
  if (tables.size() <= n) tables.resize(n + 1);
  std::vector<glm::dvec2>& t = tables[n];
  if (t.empty()) {
    t.resize(n);
    for (uint64_t j = 0; j < n; ++j) {
      const double theta = 2.0 * std::numbers::pi * static_cast<double>(j) / static_cast<double>(n);
      t[j] = {std::cos(theta), std::sin(theta)};
    }
  }
  return t;
}

}  // namespace

uint32_t MeshBuilder::vertex(const Vec3& p, const Vec3& n, Rgb c) {
  const uint32_t index = static_cast<uint32_t>(out_->positions.size() / 3);
  auto& pos = out_->positions;
  pos.push_back(static_cast<float>(p.x));
  pos.push_back(static_cast<float>(p.y));
  pos.push_back(static_cast<float>(p.z));
  if (layout_.normals) {
    auto& nor = out_->normals;
    nor.push_back(static_cast<float>(n.x));
    nor.push_back(static_cast<float>(n.y));
    nor.push_back(static_cast<float>(n.z));
  }
  if (layout_.colors) {
    auto& col = out_->colors;
    col.push_back(c.r);
    col.push_back(c.g);
    col.push_back(c.b);
  }
  return index;
}

void MeshBuilder::box(const Vec3& lo, const Vec3& hi, Rgb color) {
  assert(lo.x < hi.x && lo.y < hi.y && lo.z < hi.z);
  triangles_ += 12;
  vertices_ += layout_.normals ? 24 : 8;
  if (counting()) return;
  auto corner = [&](int i) {
    return Vec3((i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z);
  };
  // Corner index bits: x=1, y=2, z=4. Each face is listed counter-clockwise from outside.
  static constexpr int kFaces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                       {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  static constexpr double kNormals[6][3] = {{-1, 0, 0}, {1, 0, 0},  {0, -1, 0},
                                            {0, 1, 0},  {0, 0, -1}, {0, 0, 1}};
  if (layout_.normals) {
    for (int f = 0; f < 6; ++f) {
      const Vec3 n(kNormals[f][0], kNormals[f][1], kNormals[f][2]);
      uint32_t v[4];
      for (int k = 0; k < 4; ++k) v[k] = vertex(corner(kFaces[f][k]), n, color);
      quad(v[0], v[1], v[2], v[3]);
    }
    return;
  }
  uint32_t v[8];
  for (int i = 0; i < 8; ++i) v[i] = vertex(corner(i), Vec3(0.0), color);
  for (const auto& f : kFaces) quad(v[f[0]], v[f[1]], v[f[2]], v[f[3]]);
}

void MeshBuilder::cylinder(const Vec3& a, const Vec3& b, double radius, int segments, int rings,
                           Rgb color) {
  tube(a, radius, b, radius, segments, rings, color);
}

void MeshBuilder::frustum(const Vec3& a, double radius_a, const Vec3& b, double radius_b,
                          int segments, Rgb color) {
  tube(a, radius_a, b, radius_b, segments, 1, color);
}

void MeshBuilder::tube(const Vec3& a, double ra, const Vec3& b, double rb, int segments,
                       int rings, Rgb color) {
  assert(segments >= 3 && rings >= 1 && ra > 0.0 && rb > 0.0);
  const uint64_t T = static_cast<uint64_t>(segments), K = static_cast<uint64_t>(rings);
  triangles_ += 2 * T * K + 2 * T;
  vertices_ += T * (K + 1) + (layout_.normals ? 2 * (T + 1) : 2);
  if (counting()) return;

  const Vec3 axis = b - a;
  const Vec3 w = glm::normalize(axis);
  const Vec3 helper = std::abs(w.z) < 0.9 ? Vec3(0, 0, 1) : Vec3(1, 0, 0);
  const Vec3 u = glm::normalize(glm::cross(helper, w));
  const Vec3 v = glm::cross(w, u);  // u x v = w
  // Side normal tilts along the axis when the radii differ.
  const double slope = (ra - rb) / glm::length(axis);

  const std::vector<glm::dvec2>& circle = unit_circle(T);
  const uint32_t first = static_cast<uint32_t>(out_->positions.size() / 3);
  for (uint64_t k = 0; k <= K; ++k) {
    const double s = static_cast<double>(k) / static_cast<double>(K);
    const Vec3 center = a + axis * s;
    const double r = ra + (rb - ra) * s;
    for (uint64_t j = 0; j < T; ++j) {
      const Vec3 radial = circle[j].x * u + circle[j].y * v;
      vertex(center + r * radial, glm::normalize(radial + slope * w), color);
    }
  }
  auto ring = [&](uint64_t k, uint64_t j) { return first + static_cast<uint32_t>(k * T + j % T); };
  for (uint64_t k = 0; k < K; ++k)
    for (uint64_t j = 0; j < T; ++j)
      quad(ring(k, j), ring(k, j + 1), ring(k + 1, j + 1), ring(k + 1, j));

  // Caps: a fan around a centre vertex; with normals the cap gets its own ring of vertices.
  auto cap = [&](const Vec3& center, double r, uint64_t k, const Vec3& n, bool top) {
    const uint32_t c = vertex(center, n, color);
    uint32_t base = ring(k, 0);
    if (layout_.normals) {
      base = static_cast<uint32_t>(out_->positions.size() / 3);
      for (uint64_t j = 0; j < T; ++j) vertex(center + r * (circle[j].x * u + circle[j].y * v), n, color);
    }
    for (uint64_t j = 0; j < T; ++j) {
      const uint32_t p = base + static_cast<uint32_t>(j), q = base + static_cast<uint32_t>((j + 1) % T);
      if (top)
        tri(c, p, q);
      else
        tri(c, q, p);
    }
  };
  cap(a, ra, 0, -w, false);
  cap(b, rb, K, w, true);
}

void MeshBuilder::sphere(const Vec3& center, double radius, int segments, Rgb color) {
  assert(segments >= 3 && radius > 0.0);
  const uint64_t T = static_cast<uint64_t>(segments);
  const uint64_t L = static_cast<uint64_t>(sphere_bands(segments));
  triangles_ += 2 * T * (L - 1);
  vertices_ += 2 + T * (L - 1);
  if (counting()) return;

  const std::vector<glm::dvec2>& circle = unit_circle(T);
  const std::vector<glm::dvec2>& meridian = unit_circle(2 * L);  // angles pi i / L
  const uint32_t north = vertex(center + Vec3(0, 0, radius), Vec3(0, 0, 1), color);
  const uint32_t first = static_cast<uint32_t>(out_->positions.size() / 3);
  for (uint64_t i = 1; i < L; ++i) {
    const double cos_phi = meridian[i].x, sin_phi = meridian[i].y;
    for (uint64_t j = 0; j < T; ++j) {
      const Vec3 n(sin_phi * circle[j].x, sin_phi * circle[j].y, cos_phi);
      vertex(center + radius * n, n, color);
    }
  }
  const uint32_t south = vertex(center - Vec3(0, 0, radius), Vec3(0, 0, -1), color);
  auto ring = [&](uint64_t i, uint64_t j) {
    return first + static_cast<uint32_t>((i - 1) * T + j % T);
  };
  for (uint64_t j = 0; j < T; ++j) tri(north, ring(1, j), ring(1, j + 1));
  for (uint64_t i = 1; i + 1 < L; ++i)
    for (uint64_t j = 0; j < T; ++j) quad(ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1));
  for (uint64_t j = 0; j < T; ++j) tri(south, ring(L - 1, j + 1), ring(L - 1, j));
}

}  // namespace frontier::gen
