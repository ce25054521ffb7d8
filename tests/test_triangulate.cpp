// triangulate_polygon: properties against simple references. For every polygon the result has
// n-2 triangles, their areas add up to the polygon's (Newell) area, each triangle keeps the
// polygon's winding and lies inside the polygon (its centroid passes a crossing-number test).
#include "src/io/triangulate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace frontier {
namespace {

constexpr double kPi = std::numbers::pi;

Vec3 newell_normal(const std::vector<Vec3>& poly) {
  Vec3 n(0.0);
  for (size_t i = 0; i < poly.size(); ++i) {
    const Vec3& a = poly[i];
    const Vec3& b = poly[(i + 1) % poly.size()];
    n += glm::cross(a - poly[0], b - poly[0]);
  }
  return n;
}

// Crossing-number test after dropping the coordinate the normal is most aligned with.
bool inside_polygon(const std::vector<Vec3>& poly, const Vec3& normal, const Vec3& p) {
  const Vec3 an = glm::abs(normal);
  const int axis = an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2);
  const int u = (axis + 1) % 3, v = (axis + 2) % 3;
  bool in = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Vec3 &a = poly[i], &b = poly[j];
    if ((a[v] > p[v]) != (b[v] > p[v])) {
      const double x = a[u] + (p[v] - a[v]) / (b[v] - a[v]) * (b[u] - a[u]);
      if (p[u] < x) in = !in;
    }
  }
  return in;
}

// Checks every property; `label` names the polygon in failure messages.
void expect_valid_triangulation(const std::vector<Vec3>& poly, const std::string& label) {
  std::vector<std::array<uint32_t, 3>> tris;
  ASSERT_TRUE(triangulate_polygon(poly, tris)) << label;
  ASSERT_EQ(tris.size(), poly.size() - 2) << label;
  const Vec3 normal = newell_normal(poly);
  const double area = 0.5 * glm::length(normal);
  double sum = 0.0;
  std::vector<int> used(poly.size(), 0);
  for (const auto& t : tris) {
    for (uint32_t k : t) {
      ASSERT_LT(k, poly.size()) << label;
      ++used[k];
    }
    const Vec3 &a = poly[t[0]], &b = poly[t[1]], &c = poly[t[2]];
    const Vec3 tn = glm::cross(b - a, c - a);
    const double ta = 0.5 * glm::length(tn);
    sum += ta;
    if (ta > 1e-12 * area) {
      // Same winding as the polygon, and inside it.
      EXPECT_GT(glm::dot(tn, normal), 0.0) << label;
      EXPECT_TRUE(inside_polygon(poly, normal, (a + b + c) / 3.0)) << label;
    }
  }
  EXPECT_NEAR(sum, area, 1e-9 * area) << label;
  for (size_t i = 0; i < poly.size(); ++i) EXPECT_GE(used[i], 1) << label << " vertex " << i;
}

std::vector<Vec3> reversed(std::vector<Vec3> p) {
  std::reverse(p.begin(), p.end());
  return p;
}

// Places 2D points on an arbitrary plane far from the origin.
std::vector<Vec3> embed(const std::vector<glm::dvec2>& pts, const Vec3& offset = Vec3(0.0)) {
  const Vec3 e1 = glm::normalize(Vec3(1.0, 0.3, -0.2));
  const Vec3 e2 = glm::normalize(glm::cross(Vec3(0.1, 0.2, 1.0), e1));
  std::vector<Vec3> out;
  for (const auto& p : pts) out.push_back(offset + p.x * e1 + p.y * e2);
  return out;
}

std::vector<glm::dvec2> star(int points, double outer, double inner) {
  std::vector<glm::dvec2> p;
  for (int i = 0; i < 2 * points; ++i) {
    const double a = kPi * i / points;
    const double r = i % 2 == 0 ? outer : inner;
    p.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  return p;
}

// An SPD-style gear: `teeth` teeth of 4 vertices each (144 vertices for 36 teeth).
std::vector<glm::dvec2> gear(int teeth, double outer, double inner) {
  std::vector<glm::dvec2> p;
  const double step = 2.0 * kPi / teeth;
  for (int i = 0; i < teeth; ++i) {
    const double a = i * step;
    p.emplace_back(inner * std::cos(a), inner * std::sin(a));
    p.emplace_back(outer * std::cos(a + 0.25 * step), outer * std::sin(a + 0.25 * step));
    p.emplace_back(outer * std::cos(a + 0.5 * step), outer * std::sin(a + 0.5 * step));
    p.emplace_back(inner * std::cos(a + 0.75 * step), inner * std::sin(a + 0.75 * step));
  }
  return p;
}

// A comb: a bar along the x axis with `teeth` teeth pointing up; area 3 * teeth - 1.
std::vector<glm::dvec2> comb(int teeth) {
  std::vector<glm::dvec2> p = {{0.0, 0.0}, {2.0 * teeth - 1.0, 0.0}};
  for (int k = teeth - 1; k >= 0; --k) {
    p.emplace_back(2.0 * k + 1.0, 2.0);
    p.emplace_back(2.0 * k, 2.0);
    if (k > 0) {
      p.emplace_back(2.0 * k, 1.0);
      p.emplace_back(2.0 * k - 1.0, 1.0);
    }
  }
  return p;
}

TEST(Triangulate, ConvexPolygonsBothWindings) {
  for (int n = 3; n <= 40; ++n) {
    std::vector<glm::dvec2> p;
    for (int i = 0; i < n; ++i) p.emplace_back(std::cos(2 * kPi * i / n), std::sin(2 * kPi * i / n));
    const auto poly = embed(p);
    expect_valid_triangulation(poly, "convex ccw " + std::to_string(n));
    expect_valid_triangulation(reversed(poly), "convex cw " + std::to_string(n));
  }
}

TEST(Triangulate, StarsBothWindings) {
  for (int points : {3, 5, 12, 50}) {
    const auto poly = embed(star(points, 1.0, 0.3));
    expect_valid_triangulation(poly, "star " + std::to_string(points));
    expect_valid_triangulation(reversed(poly), "star cw " + std::to_string(points));
  }
}

TEST(Triangulate, StarAreaMatchesAnalyticValue) {
  // A 5-point star with outer radius 1, inner r: 10 triangles of area sin(36°) r / 2.
  const double r = 0.4;
  const auto poly = embed(star(5, 1.0, r));
  std::vector<std::array<uint32_t, 3>> tris;
  ASSERT_TRUE(triangulate_polygon(poly, tris));
  double sum = 0.0;
  for (const auto& t : tris) sum += 0.5 * glm::length(glm::cross(poly[t[1]] - poly[t[0]], poly[t[2]] - poly[t[0]]));
  EXPECT_NEAR(sum, 10 * 0.5 * r * std::sin(kPi / 5), 1e-12);
}

TEST(Triangulate, GearsAndCombs) {
  expect_valid_triangulation(embed(gear(36, 1.0, 0.8)), "gear 144");
  expect_valid_triangulation(reversed(embed(gear(36, 1.0, 0.8))), "gear 144 cw");
  expect_valid_triangulation(embed(gear(250, 1.0, 0.9)), "gear 1000");
  const auto c = embed(comb(60));
  expect_valid_triangulation(c, "comb");
  expect_valid_triangulation(reversed(c), "comb cw");
  double area = 0.5 * glm::length(newell_normal(c));
  EXPECT_NEAR(area, 3 * 60 - 1, 1e-9);
}

TEST(Triangulate, CollinearVertices) {
  // A square with every edge split in several pieces, and an L shape with a collinear run.
  std::vector<glm::dvec2> sq;
  for (int i = 0; i < 4; ++i) sq.emplace_back(i, 0);
  for (int i = 0; i < 4; ++i) sq.emplace_back(4, i);
  for (int i = 4; i > 0; --i) sq.emplace_back(i, 4);
  for (int i = 4; i > 0; --i) sq.emplace_back(0, i);
  expect_valid_triangulation(embed(sq), "split square");
  expect_valid_triangulation(reversed(embed(sq)), "split square cw");
  const std::vector<glm::dvec2> ell = {{0, 0}, {1, 0}, {2, 0}, {3, 0}, {3, 1}, {2, 1}, {1, 1}, {1, 2}, {1, 3}, {0, 3}, {0, 2}, {0, 1}};
  expect_valid_triangulation(embed(ell), "L");
  // A triangle with a vertex in the middle of an edge.
  expect_valid_triangulation(embed({{0, 0}, {1, 0}, {2, 0}, {1, 1}}), "split triangle");
}

TEST(Triangulate, FarFromOrigin) {
  const Vec3 offset(1e7, -3e6, 5e6);
  expect_valid_triangulation(embed(star(7, 1.0, 0.5), offset), "star far");
  expect_valid_triangulation(embed(gear(36, 1.0, 0.8), offset), "gear far");
}

TEST(Triangulate, RandomStarShapedPolygons) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<double> radius(0.1, 1.0);
  for (int trial = 0; trial < 300; ++trial) {
    const int n = 4 + static_cast<int>(rng() % 60);
    // Jittered angles: consecutive gaps stay below pi, so the outline is simple.
    std::vector<double> angles(n);
    for (int i = 0; i < n; ++i) angles[i] = 2 * kPi * (i + 0.9 * std::uniform_real_distribution<double>(0.0, 1.0)(rng)) / n;
    std::vector<glm::dvec2> p;
    for (double a : angles) {
      const double r = radius(rng);
      p.emplace_back(r * std::cos(a), r * std::sin(a));
    }
    const auto poly = embed(p, Vec3(trial * 10.0, 0.0, 0.0));
    expect_valid_triangulation(trial % 2 == 0 ? poly : reversed(poly), "random " + std::to_string(trial));
    if (HasFailure()) break;
  }
}

TEST(Triangulate, ZeroAreaPolygonsAreRejected) {
  std::vector<std::array<uint32_t, 3>> tris;
  EXPECT_FALSE(triangulate_polygon({Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(2, 2, 2), Vec3(3, 3, 3)}, tris));
  EXPECT_FALSE(triangulate_polygon({Vec3(1, 2, 3), Vec3(1, 2, 3), Vec3(1, 2, 3)}, tris));
  EXPECT_FALSE(triangulate_polygon({Vec3(0, 0, 0), Vec3(1, 0, 0)}, tris));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(triangulate_polygon({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, nan, 0)}, tris));
  // A bow-tie's two halves cancel in the Newell normal.
  EXPECT_FALSE(triangulate_polygon({Vec3(0, 0, 0), Vec3(1, 1, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, tris));
  EXPECT_TRUE(triangulate_polygon({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, tris));
  EXPECT_EQ(tris.size(), 1u);
}

TEST(Triangulate, SelfTouchingPolygonStillCoversItsArea) {
  // Duplicate vertices where an outline touches itself (a square with a square hole joined
  // by a bridge, as hole-free formats write it).
  const std::vector<glm::dvec2> p = {{0, 0}, {4, 0}, {4, 4}, {0, 4}, {0, 0}, {1, 1}, {1, 3}, {3, 3}, {3, 1}, {1, 1}};
  std::vector<std::array<uint32_t, 3>> tris;
  const auto poly = embed(p);
  ASSERT_TRUE(triangulate_polygon(poly, tris));
  ASSERT_EQ(tris.size(), p.size() - 2);
  double sum = 0.0;
  for (const auto& t : tris) sum += 0.5 * glm::length(glm::cross(poly[t[1]] - poly[t[0]], poly[t[2]] - poly[t[0]]));
  EXPECT_NEAR(sum, 16.0 - 4.0, 1e-9);
}

}  // namespace
}  // namespace frontier
