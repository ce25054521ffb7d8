// Primitive ray tests, bounds and normals, checked as properties against simple references:
// closed meshes never leak (random rays, and rays aimed exactly at shared vertices and
// edges), hit points lie on the surface, grazing rays agree with a long-double reference,
// results do not depend on where the model sits, and axis-parallel rays never make NaN.
#include "src/core/primitives.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <utility>
#include <vector>

namespace frontier {
namespace {

constexpr double kPi = 3.14159265358979323846;

double relative_error(double value, double reference) {
  return std::abs(value - reference) / std::max(std::abs(reference), 1e-300);
}

Vec3 random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  for (;;) {
    const Vec3 v(normal(rng), normal(rng), normal(rng));
    const double len = glm::length(v);
    if (len > 1e-6) return v / len;
  }
}

Vec3 random_in_ball(std::mt19937_64& rng, double radius) {
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (;;) {
    const Vec3 v(uniform(rng), uniform(rng), uniform(rng));
    if (glm::dot(v, v) <= 1.0) return radius * v;
  }
}

// Any unit vector perpendicular to unit n.
Vec3 perpendicular(const Vec3& n) {
  const Vec3 other = std::abs(n.x) < 0.6 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
  return glm::normalize(glm::cross(n, other));
}

// An indexed mesh, so that shared vertices are bit-identical in every triangle using them.
struct Mesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<int, 3>> faces;

  Triangle triangle(size_t f) const {
    return {vertices[faces[f][0]], vertices[faces[f][1]], vertices[faces[f][2]]};
  }
};

// Unit icosphere: 20 * 4^levels triangles.
Mesh make_icosphere(int levels) {
  Mesh m;
  const double g = (1.0 + std::sqrt(5.0)) / 2.0;
  for (const Vec3& v : {Vec3(-1, g, 0), Vec3(1, g, 0), Vec3(-1, -g, 0), Vec3(1, -g, 0),
                        Vec3(0, -1, g), Vec3(0, 1, g), Vec3(0, -1, -g), Vec3(0, 1, -g),
                        Vec3(g, 0, -1), Vec3(g, 0, 1), Vec3(-g, 0, -1), Vec3(-g, 0, 1)}) {
    m.vertices.push_back(glm::normalize(v));
  }
  m.faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
             {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
             {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
             {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> midpoints;
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = midpoints.find(key);
      if (it != midpoints.end()) return it->second;
      m.vertices.push_back(glm::normalize(m.vertices[a] + m.vertices[b]));
      const int index = static_cast<int>(m.vertices.size()) - 1;
      midpoints.emplace(key, index);
      return index;
    };
    std::vector<std::array<int, 3>> finer;
    for (const auto& f : m.faces) {
      const int a = midpoint(f[0], f[1]);
      const int b = midpoint(f[1], f[2]);
      const int c = midpoint(f[2], f[0]);
      finer.push_back({f[0], a, c});
      finer.push_back({f[1], b, a});
      finer.push_back({f[2], c, b});
      finer.push_back({a, b, c});
    }
    m.faces = std::move(finer);
  }
  return m;
}

// Brute-force nearest hit over a mesh, with a conservative bounding-sphere cull per triangle.
class MeshCaster {
 public:
  explicit MeshCaster(const Mesh& mesh) : mesh_(mesh) {
    for (size_t f = 0; f < mesh.faces.size(); ++f) {
      const Triangle tri = mesh.triangle(f);
      const Vec3 centre = (tri.v0 + tri.v1 + tri.v2) / 3.0;
      const double r2 = std::max({glm::dot(tri.v0 - centre, tri.v0 - centre),
                                  glm::dot(tri.v1 - centre, tri.v1 - centre),
                                  glm::dot(tri.v2 - centre, tri.v2 - centre)});
      centres_.push_back(centre);
      cull_radius2_.push_back(r2 * 1.01 + 1e-12);
    }
  }

  // Nearest hit t in [0, inf), or a negative value on a miss.
  double nearest(const Ray& ray) const {
    double best = kInfinity;
    for (size_t f = 0; f < centres_.size(); ++f) {
      const Vec3 w = centres_[f] - ray.origin;
      const double along = glm::dot(w, ray.dir);
      if (glm::dot(w, w) - along * along > cull_radius2_[f]) continue;
      double t;
      if (intersect_triangle(mesh_.triangle(f), ray, 0.0, best, t)) best = t;
    }
    return best == kInfinity ? -1.0 : best;
  }

 private:
  const Mesh& mesh_;
  std::vector<Vec3> centres_;
  std::vector<double> cull_radius2_;
};

bool hits_any(const Mesh& mesh, const Ray& ray) {
  double t;
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    if (intersect_triangle(mesh.triangle(f), ray, 0.0, kInfinity, t)) return true;
  }
  return false;
}

// ---------------------------------------------------------------------------------------
// Triangles

TEST(TriangleWatertight, ClosedIcosphereNeverLeaks) {
  const Mesh sphere = make_icosphere(4);
  ASSERT_EQ(sphere.faces.size(), 5120u);
  const MeshCaster caster(sphere);
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  int leaks = 0;
  int wrong_distance = 0;
  constexpr int kRays = 100000;
  for (int i = 0; i < kRays; ++i) {
    Vec3 origin, target;
    bool on_surface = true;
    switch (i % 3) {
      case 0:  // random outside point towards a random point well inside
        origin = 3.0 * random_unit(rng);
        target = random_in_ball(rng, 0.5);
        on_surface = false;
        break;
      case 1: {  // exactly at a shared vertex
        target = sphere.vertices[rng() % sphere.vertices.size()];
        origin = target + 3.0 * glm::normalize(target + 0.7 * random_unit(rng));
        break;
      }
      default: {  // at a point of a shared edge (rounded onto it)
        const auto& f = sphere.faces[rng() % sphere.faces.size()];
        const int e = static_cast<int>(rng() % 3);
        const Vec3& a = sphere.vertices[f[e]];
        const Vec3& b = sphere.vertices[f[(e + 1) % 3]];
        const double s = (i % 2) ? 0.5 : uniform(rng);
        target = a + s * (b - a);
        origin = target + 3.0 * glm::normalize(target + 0.7 * random_unit(rng));
        break;
      }
    }
    const Ray ray(origin, target - origin);
    const double t = caster.nearest(ray);
    if (t < 0.0) {
      ++leaks;
    } else if (on_surface && relative_error(t, glm::length(target - origin)) > 1e-9) {
      ++wrong_distance;  // entering a convex mesh at the target: the first hit is the target
    }
  }
  EXPECT_EQ(leaks, 0);
  EXPECT_EQ(wrong_distance, 0);
}

// A regular grid of triangles (alternating diagonals, so vertex valences differ), optionally
// rotated out of the z = 0 plane. Returns the mesh and the interior vertices/edge midpoints.
struct GridCase {
  Mesh mesh;
  std::vector<Vec3> targets;
  Vec3 normal;
};

GridCase make_grid(bool tilted) {
  constexpr int kCells = 12;
  constexpr double kStep = 0.1;  // not a power of two: vertex coordinates are rounded
  GridCase g;
  Vec3 ex(1, 0, 0), ey(0, 1, 0);
  if (tilted) {
    ex = glm::normalize(Vec3(1, 0.3, 0.2));
    ey = glm::normalize(glm::cross(Vec3(0.1, 0.2, 1.0), ex));
  }
  g.normal = glm::normalize(glm::cross(ex, ey));
  auto index = [](int i, int j) { return i * (kCells + 1) + j; };
  for (int i = 0; i <= kCells; ++i) {
    for (int j = 0; j <= kCells; ++j) {
      g.mesh.vertices.push_back(Vec3(0.3, -0.2, 0.7) + (i * kStep - 0.6) * ex +
                                (j * kStep - 0.6) * ey);
    }
  }
  for (int i = 0; i < kCells; ++i) {
    for (int j = 0; j < kCells; ++j) {
      const int a = index(i, j), b = index(i + 1, j), c = index(i + 1, j + 1),
                d = index(i, j + 1);
      if ((i + j) % 2 == 0) {
        g.mesh.faces.push_back({a, b, c});
        g.mesh.faces.push_back({a, c, d});
      } else {
        g.mesh.faces.push_back({a, b, d});
        g.mesh.faces.push_back({b, c, d});
      }
    }
  }
  for (int i = 1; i < kCells; ++i) {
    for (int j = 1; j < kCells; ++j) g.targets.push_back(g.mesh.vertices[index(i, j)]);
  }
  for (const auto& f : g.mesh.faces) {
    for (int e = 0; e < 3; ++e) {
      const Vec3 mid = 0.5 * (g.mesh.vertices[f[e]] + g.mesh.vertices[f[(e + 1) % 3]]);
      // Skip the outer border, where a ray may legitimately pass just outside the grid.
      const Vec3 local = mid - Vec3(0.3, -0.2, 0.7);
      if (std::abs(glm::dot(local, ex)) < 0.55 && std::abs(glm::dot(local, ey)) < 0.55) {
        g.targets.push_back(mid);
      }
    }
  }
  return g;
}

TEST(TriangleWatertight, RaysThroughSharedVerticesAndEdgesOfAGridHit) {
  std::mt19937_64 rng(7);
  for (const bool tilted : {false, true}) {
    const GridCase g = make_grid(tilted);
    std::vector<Vec3> directions = {g.normal, -g.normal};
    if (!tilted) {
      // Axis-parallel and with zero components: the sheared coordinates are exact.
      directions.insert(directions.end(), {Vec3(1, 0, -1), Vec3(0, -1, 1), Vec3(-3, 0, 1),
                                           Vec3(0, 2, -1), Vec3(1, 1, -1)});
    }
    for (int k = 0; k < 6; ++k) {
      Vec3 d = random_unit(rng);
      if (std::abs(glm::dot(d, g.normal)) < 0.3) d = glm::normalize(d + g.normal);
      directions.push_back(d);
    }
    int misses = 0;
    int total = 0;
    for (const Vec3& target : g.targets) {
      for (const Vec3& dir : directions) {
        const Ray ray(target - 2.0 * glm::normalize(dir), dir);
        ++total;
        if (!hits_any(g.mesh, ray)) ++misses;
      }
    }
    EXPECT_GT(total, 1000);
    EXPECT_EQ(misses, 0) << "tilted=" << tilted;
  }
}

TEST(TriangleIntersect, HitsFrontAndBackAtTheRightDistance) {
  const Triangle tri{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  double t = -1.0;
  ASSERT_TRUE(intersect_triangle(tri, Ray(Vec3(0.25, 0.25, 2), Vec3(0, 0, -1)), 0, kInfinity, t));
  EXPECT_DOUBLE_EQ(t, 2.0);
  // Back face (no culling).
  ASSERT_TRUE(intersect_triangle(tri, Ray(Vec3(0.25, 0.25, -3), Vec3(0, 0, 1)), 0, kInfinity, t));
  EXPECT_DOUBLE_EQ(t, 3.0);
  // Oblique.
  const Vec3 origin(-1, 2, 4), target(0.2, 0.3, 0.0);
  ASSERT_TRUE(intersect_triangle(tri, Ray(origin, target - origin), 0, kInfinity, t));
  EXPECT_LT(relative_error(t, glm::length(target - origin)), 1e-14);
  // Outside the triangle, behind the origin, beyond tmax, before tmin.
  EXPECT_FALSE(intersect_triangle(tri, Ray(Vec3(0.6, 0.6, 1), Vec3(0, 0, -1)), 0, kInfinity, t));
  EXPECT_FALSE(intersect_triangle(tri, Ray(Vec3(0.2, 0.2, 1), Vec3(0, 0, 1)), 0, kInfinity, t));
  EXPECT_FALSE(intersect_triangle(tri, Ray(Vec3(0.2, 0.2, 1), Vec3(0, 0, -1)), 0, 0.99, t));
  EXPECT_FALSE(intersect_triangle(tri, Ray(Vec3(0.2, 0.2, 1), Vec3(0, 0, -1)), 1.01, 5, t));
  ASSERT_TRUE(intersect_triangle(tri, Ray(Vec3(0.2, 0.2, 1), Vec3(0, 0, -1)), 1.0, 1.0, t));
  EXPECT_EQ(t, 1.0);
}

TEST(TriangleIntersect, DegenerateTrianglesNeverHit) {
  const std::vector<Triangle> degenerate = {
      {Vec3(0, 0, 0), Vec3(0, 0, 0), Vec3(1, 1, 0)},   // repeated vertex
      {Vec3(0, 0, 0), Vec3(1, 1, 1), Vec3(2, 2, 2)},   // collinear
      {Vec3(1, 2, 3), Vec3(1, 2, 3), Vec3(1, 2, 3)},   // a point
  };
  std::mt19937_64 rng(3);
  double t;
  for (const Triangle& tri : degenerate) {
    for (int i = 0; i < 200; ++i) {
      const Vec3 target = tri.v0 + 0.5 * (tri.v2 - tri.v0);
      const Vec3 origin = target + 4.0 * random_unit(rng);
      EXPECT_FALSE(intersect_triangle(tri, Ray(origin, target - origin), -10, 10, t));
    }
    EXPECT_FALSE(intersect_triangle(tri, Ray(tri.v0 + Vec3(0, 0, 1), Vec3(0, 0, -1)), -10, 10, t));
  }
}

TEST(TriangleIntersect, AxisParallelRaysGiveFiniteHits) {
  const Triangle tri{Vec3(-1, -1, 5), Vec3(2, -1, 5), Vec3(-1, 2, 5)};
  const Triangle wall{Vec3(3, -1, -1), Vec3(3, 2, -1), Vec3(3, -1, 2)};
  double t = 0.0;
  ASSERT_TRUE(intersect_triangle(tri, Ray(Vec3(0, 0, 0), Vec3(0, 0, 1)), 0, kInfinity, t));
  EXPECT_EQ(t, 5.0);
  ASSERT_TRUE(intersect_triangle(tri, Ray(Vec3(0, 0, 9), Vec3(0, 0, -1)), 0, kInfinity, t));
  EXPECT_EQ(t, 4.0);
  ASSERT_TRUE(intersect_triangle(wall, Ray(Vec3(0, 0, 0), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_EQ(t, 3.0);
  // Rays parallel to the triangle's plane (edge-on) miss without NaN.
  EXPECT_FALSE(intersect_triangle(tri, Ray(Vec3(-5, 0, 5), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_FALSE(intersect_triangle(tri, Ray(Vec3(0, -5, 5), Vec3(0, 1, 0)), 0, kInfinity, t));
  // Ray along an axis through the exact edge x = -1 of `tri`: closed edges count.
  ASSERT_TRUE(intersect_triangle(tri, Ray(Vec3(-1, 0, 0), Vec3(0, 0, 1)), 0, kInfinity, t));
  EXPECT_EQ(t, 5.0);
  // Through a vertex exactly.
  ASSERT_TRUE(intersect_triangle(tri, Ray(Vec3(2, -1, 7), Vec3(0, 0, -1)), 0, kInfinity, t));
  EXPECT_EQ(t, 2.0);
  // Just outside.
  EXPECT_FALSE(intersect_triangle(tri, Ray(Vec3(-1.000001, 0, 0), Vec3(0, 0, 1)), 0, kInfinity, t));
}

// ---------------------------------------------------------------------------------------
// Spheres

// Long-double reference: first root of |o + t d - c| = r in [tmin, inf), or -1.
long double sphere_reference(const Sphere& s, const Ray& ray, long double tmin = 0.0L) {
  long double oc[3], d[3];
  for (int i = 0; i < 3; ++i) {
    oc[i] = static_cast<long double>(ray.origin[i]) - s.center[i];
    d[i] = ray.dir[i];
  }
  const long double a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  const long double h = (oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2]) / a;
  long double perp2 = 0.0L;
  for (int i = 0; i < 3; ++i) perp2 += (oc[i] - h * d[i]) * (oc[i] - h * d[i]);
  const long double r = s.radius;
  const long double disc = r * r - perp2;
  if (disc < 0.0L) return -1.0L;
  const long double half = std::sqrt(disc * a) / a;
  if (-h - half >= tmin) return -h - half;
  if (-h + half >= tmin) return -h + half;
  return -1.0L;
}

TEST(SphereIntersect, HitPointsLieOnTheSurface) {
  const Sphere s{Vec3(0.3, -1.2, 2.0), 1.7};
  std::mt19937_64 rng(11);
  for (int i = 0; i < 2000; ++i) {
    const Vec3 origin = s.center + 5.0 * random_unit(rng);
    const Vec3 target = s.center + random_in_ball(rng, s.radius);
    const Ray ray(origin, target - origin);
    double t = -1.0;
    ASSERT_TRUE(intersect_sphere(s, ray, 0, kInfinity, t));
    EXPECT_LT(relative_error(glm::length(ray.at(t) - s.center), s.radius), 1e-13);
    EXPECT_LT(relative_error(t, static_cast<double>(sphere_reference(s, ray))), 1e-12);
    // Re-intersecting from just past the hit finds the far side, which is on the surface too.
    double t2 = -1.0;
    ASSERT_TRUE(intersect_sphere(s, ray, t * (1 + 1e-9), kInfinity, t2));
    EXPECT_GT(t2, t);
    EXPECT_LT(relative_error(glm::length(ray.at(t2) - s.center), s.radius), 1e-13);
  }
}

TEST(SphereIntersect, FromInsideReturnsTheFarRoot) {
  const Sphere s{Vec3(1, 2, 3), 2.0};
  double t = -1.0;
  ASSERT_TRUE(intersect_sphere(s, Ray(Vec3(1, 2, 3), Vec3(0, 1, 0)), 0, kInfinity, t));
  EXPECT_DOUBLE_EQ(t, 2.0);
  ASSERT_TRUE(intersect_sphere(s, Ray(Vec3(1, 2, 4), Vec3(0, 0, -1)), 0, kInfinity, t));
  EXPECT_DOUBLE_EQ(t, 3.0);
  // Outside, but tmin past the entry: the exit.
  ASSERT_TRUE(intersect_sphere(s, Ray(Vec3(1, 2, 10), Vec3(0, 0, -1)), 6.0, kInfinity, t));
  EXPECT_DOUBLE_EQ(t, 9.0);
  EXPECT_FALSE(intersect_sphere(s, Ray(Vec3(1, 2, 10), Vec3(0, 0, -1)), 9.5, kInfinity, t));
  EXPECT_FALSE(intersect_sphere(s, Ray(Vec3(1, 2, 10), Vec3(0, 0, 1)), 0, kInfinity, t));
}

TEST(SphereIntersect, GrazingRaysMatchALongDoubleReference) {
  std::mt19937_64 rng(5);
  for (int i = 0; i < 300; ++i) {
    const Sphere s{random_in_ball(rng, 10.0), 0.5 + i * 0.01};
    const Vec3 dir = random_unit(rng);
    const Vec3 side = perpendicular(dir);
    // Distance from the ray's start to its closest approach: far origins are the hard case
    // for the textbook b² - 4ac.
    const double along = (i % 3 == 0) ? 2.0 : (i % 3 == 1) ? 100.0 : 1e4;
    for (const double scale : {1.0 - 1e-9, 1.0 + 1e-9}) {
      const Vec3 origin = s.center - along * s.radius * dir + scale * s.radius * side;
      const Ray ray(origin, dir);
      double t = -1.0;
      const bool hit = intersect_sphere(s, ray, 0, kInfinity, t);
      ASSERT_EQ(hit, scale < 1.0) << "along=" << along;
      if (hit) {
        const long double reference = sphere_reference(s, ray);
        ASSERT_GT(reference, 0.0L);
        EXPECT_LT(relative_error(t, static_cast<double>(reference)), 1e-9);
      }
    }
  }
}

TEST(SphereIntersect, AxisParallelRays) {
  const Sphere s{Vec3(0, 0, 0), 1.0};
  double t = -1.0;
  const Vec3 dirs[] = {Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, -1)};
  for (const Vec3& d : dirs) {
    ASSERT_TRUE(intersect_sphere(s, Ray(-3.0 * d, d), 0, kInfinity, t));
    EXPECT_EQ(t, 2.0);
    ASSERT_TRUE(intersect_sphere(s, Ray(-3.0 * d + 0.6 * perpendicular(d), d), 0, kInfinity, t));
    EXPECT_FALSE(std::isnan(t));
    EXPECT_NEAR(t, 2.2, 1e-15);
    EXPECT_FALSE(intersect_sphere(s, Ray(-3.0 * d + 1.01 * perpendicular(d), d), 0, kInfinity, t));
  }
}

// ---------------------------------------------------------------------------------------
// Boxes

// Frustum casting tests primary rays with terms computed once per frame from the eye
// (sphere_from_origin, cone_from_origin): the split tests must answer bit for bit like the
// whole ones, for grazing, axis-parallel and far-from-origin rays alike.
TEST(EyeTerms, SplitTestsMatchTheWholeOnesBitForBit) {
  std::mt19937_64 rng(404);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  size_t sphere_hits = 0, cone_hits = 0;
  for (int s = 0; s < 4000; ++s) {
    const Vec3 offset = s % 4 == 3 ? Vec3(1e6, -1e6, 1e6) : Vec3(0.0);
    const Sphere sphere{offset + Vec3(u(rng), u(rng), u(rng)), 0.05 + std::abs(u(rng))};
    const Cone cone{offset + Vec3(u(rng), u(rng), u(rng)), 0.3 * std::abs(u(rng)),
                    offset + Vec3(u(rng), u(rng), u(rng)), s % 3 == 0 ? 0.0 : 0.3 * std::abs(u(rng))};
    const Vec3 origin = offset + 3.0 * Vec3(u(rng), u(rng), u(rng));
    const SphereFromOrigin ks = sphere_from_origin(sphere, origin);
    const ConeFromOrigin kc = cone_from_origin(cone, origin);
    for (int r = 0; r < 16; ++r) {
      Vec3 target = r % 2 ? sphere.center + sphere.radius * glm::normalize(Vec3(u(rng), u(rng), u(rng)))  // grazing
                          : cone.base + 0.5 * (cone.apex - cone.base) + 0.2 * Vec3(u(rng), u(rng), u(rng));
      Vec3 d = target - origin;
      if (r % 5 == 4) d = Vec3(0.0, 0.0, d.z < 0 ? -1.0 : 1.0);  // axis-parallel
      const Ray ray(origin, d);
      const double tmin = r % 3 == 0 ? 0.0 : 0.5 * std::abs(u(rng));
      const double tmax = r % 4 == 0 ? kInfinity : 1.0 + 4.0 * std::abs(u(rng));
      double t_whole = -1.0, t_split = -1.0;
      const bool hit_whole = intersect_sphere(sphere, ray, tmin, tmax, t_whole);
      const bool hit_split = intersect_sphere(ks, ray.dir, tmin, tmax, t_split);
      ASSERT_EQ(hit_whole, hit_split) << "sphere " << s << " ray " << r;
      if (hit_whole) {
        ASSERT_EQ(t_whole, t_split) << "sphere " << s << " ray " << r;
        ++sphere_hits;
      }
      t_whole = t_split = -1.0;
      const bool cone_whole = intersect_cone(cone, ray, tmin, tmax, t_whole);
      const bool cone_split = intersect_cone(kc, ray.dir, tmin, tmax, t_split);
      ASSERT_EQ(cone_whole, cone_split) << "cone " << s << " ray " << r;
      if (cone_whole) {
        ASSERT_EQ(t_whole, t_split) << "cone " << s << " ray " << r;
        ++cone_hits;
      }
    }
  }
  EXPECT_GT(sphere_hits, 10000u);
  EXPECT_GT(cone_hits, 5000u);
}

TEST(BoxIntersect, EntryFromOutsideExitFromInside) {
  const Box b{Aabb(Vec3(-1, -2, -3), Vec3(1, 2, 3))};
  double t = -1.0;
  ASSERT_TRUE(intersect_box(b, Ray(Vec3(-5, 0.5, 0.5), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_EQ(t, 4.0);
  ASSERT_TRUE(intersect_box(b, Ray(Vec3(0, 0, 0), Vec3(0, -1, 0)), 0, kInfinity, t));
  EXPECT_EQ(t, 2.0);
  ASSERT_TRUE(intersect_box(b, Ray(Vec3(-5, 0.5, 0.5), Vec3(1, 0, 0)), 4.5, kInfinity, t));
  EXPECT_EQ(t, 6.0);  // tmin past the entry: the exit
  EXPECT_FALSE(intersect_box(b, Ray(Vec3(-5, 0.5, 0.5), Vec3(1, 0, 0)), 0, 3.9, t));
  EXPECT_FALSE(intersect_box(b, Ray(Vec3(-5, 0.5, 0.5), Vec3(-1, 0, 0)), 0, kInfinity, t));
  const Vec3 origin(4, -5, 6), target(0.5, 1.5, -2.5);
  ASSERT_TRUE(intersect_box(b, Ray(origin, target - origin), 0, kInfinity, t));
  EXPECT_FALSE(std::isnan(t));
  const Vec3 p = Ray(origin, target - origin).at(t);
  EXPECT_LT(distance_to_box(p, b.bounds), 1e-12);
  EXPECT_NEAR(std::max({std::abs(p.x) - 1, std::abs(p.y) - 2, std::abs(p.z) - 3}), 0.0, 1e-12);
}

TEST(BoxIntersect, AxisParallelRaysNeverMakeNaN) {
  const Box b{Aabb(Vec3(0, 0, 0), Vec3(1, 1, 1))};
  double t = -1.0;
  // Zero direction components with the origin inside the slab (including on its face).
  for (const double y : {0.0, 0.5, 1.0}) {
    ASSERT_TRUE(intersect_box(b, Ray(Vec3(-2, y, 0.5), Vec3(1, 0, 0)), 0, kInfinity, t));
    EXPECT_EQ(t, 2.0);
    ASSERT_TRUE(intersect_box(b, Ray(Vec3(0.5, y, 3), Vec3(0, -0.0, -1)), 0, kInfinity, t));
    EXPECT_EQ(t, 2.0);
  }
  // Outside a slab: a miss.
  EXPECT_FALSE(intersect_box(b, Ray(Vec3(-2, 1.5, 0.5), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_FALSE(intersect_box(b, Ray(Vec3(-2, 0.5, -0.1), Vec3(1, 0, 0)), 0, kInfinity, t));
  // Diagonal in a coordinate plane.
  ASSERT_TRUE(intersect_box(b, Ray(Vec3(-1, -1, 0.5), Vec3(1, 1, 0)), 0, kInfinity, t));
  EXPECT_NEAR(t, std::sqrt(2.0), 1e-15);
}

// ---------------------------------------------------------------------------------------
// Cones

// Long-double reference for a horizontal ray (perpendicular to the cone's axis): the cone's
// cross-section at the ray's height is a circle.
long double circle_reference(const Vec3& centre, long double radius, const Ray& ray) {
  long double oc[3], d[3];
  for (int i = 0; i < 3; ++i) {
    oc[i] = static_cast<long double>(ray.origin[i]) - centre[i];
    d[i] = ray.dir[i];
  }
  const long double h = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
  long double perp2 = 0.0L;
  for (int i = 0; i < 3; ++i) perp2 += (oc[i] - h * d[i]) * (oc[i] - h * d[i]);
  const long double disc = radius * radius - perp2;
  if (disc < 0.0L) return -1.0L;
  return -h - std::sqrt(disc);
}

// Signed distance-like residual of a point against the cone's surface, and its height.
std::pair<double, double> cone_residual(const Cone& c, const Vec3& p) {
  const Vec3 axis = c.apex - c.base;
  const double len = glm::length(axis);
  const Vec3 u = axis / len;
  const Vec3 v = p - c.base;
  const double h = glm::dot(v, u);
  const double radial = glm::length(v - h * u);
  const double expected = c.base_radius + (c.apex_radius - c.base_radius) * h / len;
  return {radial - expected, h / len};
}

TEST(ConeIntersect, CylinderMatchesTheAnalyticAnswer) {
  const Cone cyl{Vec3(1, 2, 3), 0.5, Vec3(1, 2, 7), 0.5};
  double t = -1.0;
  // Perpendicular to the axis, offset 0.3 from it: t = 5 - sqrt(0.25 - 0.09) = 4.6.
  ASSERT_TRUE(intersect_cone(cyl, Ray(Vec3(-4, 2.3, 5), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_NEAR(t, 4.6, 1e-14);
  // Oblique: from (1, 2-5, 3) towards the axis point at height 2 => hits the wall at y = 1.5.
  const Vec3 origin(1, -3, 3);
  const Ray ray(origin, Vec3(1, 2, 5) - origin);
  ASSERT_TRUE(intersect_cone(cyl, ray, 0, kInfinity, t));
  EXPECT_NEAR(ray.at(t).y, 1.5, 1e-14);
  EXPECT_NEAR(t, 4.5 * std::sqrt(29.0) / 5.0, 1e-13);
  // Above the top and below the base: miss; along the axis: miss (open ends).
  EXPECT_FALSE(intersect_cone(cyl, Ray(Vec3(-4, 2, 7.01), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_FALSE(intersect_cone(cyl, Ray(Vec3(-4, 2, 2.99), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_FALSE(intersect_cone(cyl, Ray(Vec3(1, 2, 0), Vec3(0, 0, 1)), 0, kInfinity, t));
  EXPECT_FALSE(intersect_cone(cyl, Ray(Vec3(1.2, 2.1, 10), Vec3(0, 0, -1)), 0, kInfinity, t));
}

TEST(ConeIntersect, OpenEndShowsTheInsideSurface) {
  const Cone cyl{Vec3(0, 0, -1), 1.0, Vec3(0, 0, 1), 1.0};
  // Enters through the open top; the outside wall at x = -1 is above the top (z > 1), so the
  // first hit is the inside of the wall at x = +1.
  const Ray ray(Vec3(0, 0, 3), Vec3(0.3, 0, -1));
  double t = -1.0;
  ASSERT_TRUE(intersect_cone(cyl, ray, 0, kInfinity, t));
  EXPECT_NEAR(ray.at(t).x, 1.0, 1e-14);
  EXPECT_NEAR(t, std::sqrt(1.09) / 0.3, 1e-13);
  // From inside, both directions hit the wall.
  ASSERT_TRUE(intersect_cone(cyl, Ray(Vec3(0, 0, 0.5), Vec3(0, -1, 0)), 0, kInfinity, t));
  EXPECT_DOUBLE_EQ(t, 1.0);
  // Outside wall hit from the side when its near root is valid.
  ASSERT_TRUE(intersect_cone(cyl, Ray(Vec3(-3, 0, 0.5), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_DOUBLE_EQ(t, 2.0);
}

TEST(ConeIntersect, PointedConeAndHitPointsOnTheSurface) {
  const Cone pointed{Vec3(0, 0, 0), 1.0, Vec3(0, 0, 2), 0.0};
  double t = -1.0;
  // Height 1: radius 0.5.
  ASSERT_TRUE(intersect_cone(pointed, Ray(Vec3(-3, 0, 1), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_NEAR(t, 2.5, 1e-14);
  // The mirrored nappe beyond the apex is not part of the shape.
  EXPECT_FALSE(intersect_cone(pointed, Ray(Vec3(-3, 0, 3), Vec3(1, 0, 0)), 0, kInfinity, t));
  // Straight down the axis from above: meets the apex.
  ASSERT_TRUE(intersect_cone(pointed, Ray(Vec3(0, 0, 5), Vec3(0, 0, -1)), 0, kInfinity, t));
  EXPECT_NEAR(t, 3.0, 1e-12);

  std::mt19937_64 rng(21);
  const std::vector<Cone> cones = {
      pointed,
      {Vec3(1, -2, 0.5), 0.0, Vec3(2, 1, 3), 0.8},     // point at the base
      {Vec3(-1, 1, 1), 1.2, Vec3(0.5, 0.5, -1), 0.4},  // truncated
      {Vec3(0, 0, 0), 0.7, Vec3(3, 0, 0), 0.7},        // cylinder
  };
  for (const Cone& c : cones) {
    int hits = 0;
    for (int i = 0; i < 3000; ++i) {
      const Vec3 mid = 0.5 * (c.base + c.apex);
      const Vec3 origin = mid + 6.0 * random_unit(rng);
      const Ray ray(origin, mid + random_in_ball(rng, 1.0) - origin);
      if (!intersect_cone(c, ray, 0, kInfinity, t)) continue;
      ++hits;
      const auto [residual, height] = cone_residual(c, ray.at(t));
      EXPECT_LT(std::abs(residual), 1e-12);
      EXPECT_GE(height, -1e-12);
      EXPECT_LE(height, 1.0 + 1e-12);
      // And the next hit along the ray (if any) is on the surface too.
      double t2;
      if (intersect_cone(c, ray, t + 1e-9, kInfinity, t2)) {
        EXPECT_GT(t2, t);
        EXPECT_LT(std::abs(cone_residual(c, ray.at(t2)).first), 1e-12);
      }
    }
    EXPECT_GT(hits, 300);
  }
}

TEST(ConeIntersect, GrazingRaysMatchALongDoubleReference) {
  std::mt19937_64 rng(8);
  for (int i = 0; i < 300; ++i) {
    const Vec3 base = random_in_ball(rng, 10.0);
    const Vec3 axis = random_unit(rng);
    const double height = 2.0;
    const Cone c{base, 1.0, base + height * axis, (i % 2) ? 0.3 : 1.0};
    const double h = 0.1 + 1.8 * (i % 7) / 6.0;  // the ray's height along the axis
    const double r = c.base_radius + (c.apex_radius - c.base_radius) * h / height;
    const Vec3 dir = perpendicular(axis);
    const Vec3 side = glm::normalize(glm::cross(axis, dir));
    const double along = (i % 3 == 0) ? 2.0 : (i % 3 == 1) ? 100.0 : 1e4;
    for (const double scale : {1.0 - 1e-9, 1.0 + 1e-9}) {
      const Vec3 centre = base + h * axis;
      const Ray ray(centre - along * r * dir + scale * r * side, dir);
      double t = -1.0;
      const bool hit = intersect_cone(c, ray, 0, kInfinity, t);
      ASSERT_EQ(hit, scale < 1.0) << "i=" << i;
      if (hit) {
        const long double reference = circle_reference(centre, r, ray);
        ASSERT_GT(reference, 0.0L);
        EXPECT_LT(relative_error(t, static_cast<double>(reference)), 1e-9) << "i=" << i;
      }
    }
  }
}

TEST(ConeIntersect, AxisParallelRays) {
  const Cone c{Vec3(0, 0, 0), 1.0, Vec3(0, 0, 4), 0.5};
  double t = -1.0;
  // Along x at height 2 (radius 0.75), along -y at height 0 (radius 1).
  ASSERT_TRUE(intersect_cone(c, Ray(Vec3(-2, 0, 2), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_NEAR(t, 1.25, 1e-14);
  ASSERT_TRUE(intersect_cone(c, Ray(Vec3(0, 3, 0), Vec3(0, -1, 0)), 0, kInfinity, t));
  EXPECT_NEAR(t, 2.0, 1e-14);
  // Parallel to the axis, outside then inside the open cone: inside hits the slanted wall.
  EXPECT_FALSE(intersect_cone(c, Ray(Vec3(1.5, 0, -1), Vec3(0, 0, 1)), 0, kInfinity, t));
  ASSERT_TRUE(intersect_cone(c, Ray(Vec3(0.75, 0, -1), Vec3(0, 0, 1)), 0, kInfinity, t));
  EXPECT_NEAR(t, 3.0, 1e-14);  // radius 0.75 at height 2
  EXPECT_FALSE(std::isnan(t));
  // Axis along x, ray along z with zero x/y components.
  const Cone cx{Vec3(-1, 0, 0), 0.5, Vec3(1, 0, 0), 0.5};
  ASSERT_TRUE(intersect_cone(cx, Ray(Vec3(0.3, 0, -4), Vec3(0, 0, 1)), 0, kInfinity, t));
  EXPECT_NEAR(t, 3.5, 1e-14);
}

// ---------------------------------------------------------------------------------------
// Far from the origin

TEST(PrimitiveFarFromOrigin, TranslatedShapesGiveTheSameDistances) {
  const Vec3 offset(1e6, 1e6, 1e6);
  std::mt19937_64 rng(99);
  const Sphere sphere{Vec3(0.1, 0.2, -0.3), 0.8};
  const Cone cone{Vec3(-0.2, 0.1, -0.5), 0.6, Vec3(0.3, -0.1, 0.6), 0.2};
  const Triangle tri{Vec3(-1, -0.7, 0.1), Vec3(0.9, -0.4, -0.2), Vec3(0.1, 1.0, 0.3)};
  // Moving the scene rounds every coordinate by up to ulp(1e6)/2 ~ 6e-11, which moves a hit
  // by about that much divided by the cosine of the incidence angle: compare where the ray
  // meets the surface at a reasonable angle (the shape's precision, not the input's).
  auto steep = [](const Vec3& normal, const Ray& ray) {
    return std::abs(glm::dot(normal, ray.dir)) > 0.2;
  };
  int sphere_hits = 0, cone_hits = 0, tri_hits = 0;
  for (int i = 0; i < 4000; ++i) {
    const Vec3 origin = 3.0 * random_unit(rng);
    const Vec3 dir = random_in_ball(rng, 0.5) - origin;
    const Ray near_ray(origin, dir);
    const Ray far_ray(origin + offset, dir);
    double t_near, t_far;
    const Sphere far_sphere{sphere.center + offset, sphere.radius};
    if (intersect_sphere(sphere, near_ray, 0, kInfinity, t_near) &&
        steep(normal_of(sphere, near_ray.at(t_near)), near_ray)) {
      ++sphere_hits;
      ASSERT_TRUE(intersect_sphere(far_sphere, far_ray, 0, kInfinity, t_far));
      EXPECT_LT(relative_error(t_far, t_near), 1e-9);
    }
    const Cone far_cone{cone.base + offset, cone.base_radius, cone.apex + offset,
                        cone.apex_radius};
    if (intersect_cone(cone, near_ray, 0, kInfinity, t_near) &&
        steep(normal_of(cone, near_ray.at(t_near)), near_ray)) {
      ++cone_hits;
      ASSERT_TRUE(intersect_cone(far_cone, far_ray, 0, kInfinity, t_far));
      EXPECT_LT(relative_error(t_far, t_near), 1e-9);
    }
    const Triangle far_tri{tri.v0 + offset, tri.v1 + offset, tri.v2 + offset};
    if (intersect_triangle(tri, near_ray, 0, kInfinity, t_near) &&
        steep(normal_of(tri, near_ray.at(t_near)), near_ray)) {
      ++tri_hits;
      ASSERT_TRUE(intersect_triangle(far_tri, far_ray, 0, kInfinity, t_far));
      EXPECT_LT(relative_error(t_far, t_near), 1e-9);
    }
  }
  EXPECT_GT(sphere_hits, 1000);
  EXPECT_GT(cone_hits, 300);
  EXPECT_GT(tri_hits, 300);
}

// ---------------------------------------------------------------------------------------
// solve_quadratic

TEST(QuadraticSolve, CancellationAndSpecialCases) {
  double r0 = 0.0, r1 = 0.0;
  // b huge, c small: the textbook formula loses the small root entirely.
  ASSERT_EQ(solve_quadratic(1.0, 1e8, 1.0, r0, r1), 2);
  EXPECT_LT(relative_error(r1, -1e-8), 1e-12);  // exact: -1e-8 - 1e-24 - ...
  EXPECT_LT(relative_error(r0, -1e8), 1e-12);
  EXPECT_LT(r0, r1);
  // Negative b.
  ASSERT_EQ(solve_quadratic(2.0, -1e9, 3.0, r0, r1), 2);
  EXPECT_LT(relative_error(r0, 3e-9), 1e-12);
  EXPECT_LT(relative_error(r1, 5e8), 1e-12);
  // Linear.
  ASSERT_EQ(solve_quadratic(0.0, 2.0, -3.0, r0, r1), 1);
  EXPECT_EQ(r0, 1.5);
  EXPECT_EQ(r1, 1.5);
  EXPECT_EQ(solve_quadratic(0.0, 0.0, 1.0, r0, r1), 0);
  EXPECT_EQ(solve_quadratic(0.0, 0.0, 0.0, r0, r1), 0);
  // No real roots, one double root.
  EXPECT_EQ(solve_quadratic(1.0, 1.0, 1.0, r0, r1), 0);
  r0 = r1 = 0.0;
  ASSERT_EQ(solve_quadratic(1.0, -6.0, 9.0, r0, r1), 1);
  EXPECT_EQ(r0, 3.0);
  EXPECT_EQ(r1, 3.0);
  // b == 0: symmetric roots, ascending.
  ASSERT_EQ(solve_quadratic(-2.0, 0.0, 8.0, r0, r1), 2);
  EXPECT_EQ(r0, -2.0);
  EXPECT_EQ(r1, 2.0);
  // Negative a orders the roots too.
  ASSERT_EQ(solve_quadratic(-1.0, 3.0, -2.0, r0, r1), 2);
  EXPECT_DOUBLE_EQ(r0, 1.0);
  EXPECT_DOUBLE_EQ(r1, 2.0);
  // Coefficients whose products overflow / underflow double.
  ASSERT_EQ(solve_quadratic(1e200, 3e200, 2e200, r0, r1), 2);
  EXPECT_DOUBLE_EQ(r0, -2.0);
  EXPECT_DOUBLE_EQ(r1, -1.0);
  ASSERT_EQ(solve_quadratic(1e-200, 3e-200, 2e-200, r0, r1), 2);
  EXPECT_DOUBLE_EQ(r0, -2.0);
  EXPECT_DOUBLE_EQ(r1, -1.0);
}

TEST(QuadraticSolve, RandomRootsAreRecovered) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> exponent(-6.0, 6.0);
  for (int i = 0; i < 10000; ++i) {
    const double x0 = std::pow(10.0, exponent(rng)) * ((rng() & 1) ? 1 : -1);
    const double x1 = std::pow(10.0, exponent(rng)) * ((rng() & 1) ? 1 : -1);
    const double a = std::pow(10.0, exponent(rng));
    // a (t - x0)(t - x1): coefficients rounded, so compare with a loose relative bound.
    double r0, r1;
    ASSERT_EQ(solve_quadratic(a, -a * (x0 + x1), a * x0 * x1, r0, r1), 2)
        << x0 << " " << x1;
    const double lo = std::min(x0, x1), hi = std::max(x0, x1);
    if (std::abs(lo - hi) > 1e-6 * std::max(std::abs(lo), std::abs(hi))) {
      EXPECT_LT(relative_error(r0, lo), 1e-9);
      EXPECT_LT(relative_error(r1, hi), 1e-9);
    }
  }
}

// ---------------------------------------------------------------------------------------
// Quadrics

Quadric sphere_quadric(const Sphere& s) {
  Quadric q;
  const Vec3& c = s.center;
  q.coeff = {1, 1, 1, 0, 0, 0, -2 * c.x, -2 * c.y, -2 * c.z,
             glm::dot(c, c) - s.radius * s.radius};
  q.bounds = bounds_of(s);
  return q;
}

double quadric_value(const Quadric& q, const Vec3& p) {
  const auto& k = q.coeff;
  return k[0] * p.x * p.x + k[1] * p.y * p.y + k[2] * p.z * p.z + k[3] * p.x * p.y +
         k[4] * p.y * p.z + k[5] * p.x * p.z + k[6] * p.x + k[7] * p.y + k[8] * p.z + k[9];
}

TEST(QuadricIntersect, SphereQuadricAgreesWithIntersectSphere) {
  const Sphere s{Vec3(0.3, -0.2, 0.5), 1.5};
  const Quadric q = sphere_quadric(s);
  std::mt19937_64 rng(4);
  for (int i = 0; i < 3000; ++i) {
    // Origins near (including inside) and far: from far away the polynomial about the
    // origin is a difference of huge terms, so the quadric must be expanded nearer the hit.
    const double distances[] = {0.5, 4.0, 300.0, 1e6};
    const Vec3 origin = s.center + distances[i % 4] * random_unit(rng);
    const Vec3 target = s.center + random_in_ball(rng, 0.9 * s.radius);
    const Ray ray(origin, target - origin);
    double ts = -1.0, tq = -1.0;
    ASSERT_TRUE(intersect_sphere(s, ray, 0, kInfinity, ts));
    ASSERT_TRUE(intersect_quadric(q, ray, 0, kInfinity, tq));
    EXPECT_LT(relative_error(tq, ts), 1e-12) << "distance " << distances[i % 4];
    EXPECT_LT(std::abs(quadric_value(q, ray.at(tq))), 1e-9);
    // Normals agree as well.
    EXPECT_LT(glm::length(normal_of(q, ray.at(tq)) - normal_of(s, ray.at(ts))), 1e-9);
  }
  double t;
  EXPECT_FALSE(intersect_quadric(q, Ray(Vec3(5, 5, 5), Vec3(1, 0, 0)), 0, kInfinity, t));
}

Quadric clipped_cylinder() {
  Quadric q;
  q.coeff = {1, 1, 0, 0, 0, 0, 0, 0, 0, -1};  // x² + y² = 1
  q.clip[0] = Vec4(0, 0, 1, -1);              // z - 1 <= 0
  q.clip[1] = Vec4(0, 0, -1, -1);             // -z - 1 <= 0
  q.clip_count = 2;
  // Looser than the clip in z, so that the planes (not the bounds) cut the surface.
  q.bounds = Aabb(Vec3(-1, -1, -2), Vec3(1, 1, 2));
  return q;
}

TEST(QuadricIntersect, ClippedCylinderBehavesLikeAnOpenCylinder) {
  const Quadric q = clipped_cylinder();
  const Cone cyl{Vec3(0, 0, -1), 1.0, Vec3(0, 0, 1), 1.0};
  double t = -1.0;
  // Side hit; above and below the clip planes: miss.
  ASSERT_TRUE(intersect_quadric(q, Ray(Vec3(-3, 0, 0.2), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_NEAR(t, 2.0, 1e-14);
  EXPECT_FALSE(intersect_quadric(q, Ray(Vec3(-3, 0, 1.2), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_FALSE(intersect_quadric(q, Ray(Vec3(-3, 0, -1.2), Vec3(1, 0, 0)), 0, kInfinity, t));
  // Through the open top: the clipped outside root is skipped, the inside wall is hit.
  const Ray through_top(Vec3(0, 0, 3), Vec3(0.3, 0, -1));
  ASSERT_TRUE(intersect_quadric(q, through_top, 0, kInfinity, t));
  EXPECT_NEAR(through_top.at(t).x, 1.0, 1e-12);
  // Along the axis: no hit at all.
  EXPECT_FALSE(intersect_quadric(q, Ray(Vec3(0, 0, 5), Vec3(0, 0, -1)), 0, kInfinity, t));
  // Random rays agree with the equivalent open cylinder.
  std::mt19937_64 rng(6);
  int hits = 0;
  for (int i = 0; i < 5000; ++i) {
    const Vec3 origin = 4.0 * random_unit(rng);
    const Ray ray(origin, random_in_ball(rng, 1.5) - origin);
    double tc = -1.0;
    const bool hit_q = intersect_quadric(q, ray, 0, kInfinity, t);
    const bool hit_c = intersect_cone(cyl, ray, 0, kInfinity, tc);
    if (hit_q != hit_c) {
      // Only rays through the rims may differ (the quadric's clip has a tolerance).
      const Vec3 p = ray.at(hit_q ? t : tc);
      EXPECT_NEAR(std::abs(p.z), 1.0, 1e-8);
      continue;
    }
    if (hit_q) {
      ++hits;
      EXPECT_LT(relative_error(t, tc), 1e-9);
    }
  }
  EXPECT_GT(hits, 1000);
}

TEST(QuadricIntersect, HyperboloidAndParaboloid) {
  // One-sheet hyperboloid x² + y² - z² = 1, clipped to |z| <= 2 by its bounds.
  Quadric hyper;
  hyper.coeff = {1, 1, -1, 0, 0, 0, 0, 0, 0, -1};
  hyper.bounds = Aabb(Vec3(-std::sqrt(5.0), -std::sqrt(5.0), -2), Vec3(std::sqrt(5.0),
                                                                       std::sqrt(5.0), 2));
  double t = -1.0;
  for (const double h : {-1.5, 0.0, 0.7, 1.9}) {
    ASSERT_TRUE(intersect_quadric(hyper, Ray(Vec3(-10, 0, h), Vec3(1, 0, 0)), 0, kInfinity, t));
    EXPECT_NEAR(t, 10.0 - std::sqrt(1.0 + h * h), 1e-12);
    // From the waist outwards: the far root.
    ASSERT_TRUE(intersect_quadric(hyper, Ray(Vec3(0, 0, h), Vec3(0, 1, 0)), 0, kInfinity, t));
    EXPECT_NEAR(t, std::sqrt(1.0 + h * h), 1e-12);
  }
  // Outside the bounds in z: discarded.
  EXPECT_FALSE(intersect_quadric(hyper, Ray(Vec3(-10, 0, 2.5), Vec3(1, 0, 0)), 0, kInfinity, t));

  // Paraboloid z = x² + y²  (x² + y² - z = 0), bounded by z <= 4.
  Quadric para;
  para.coeff = {1, 1, 0, 0, 0, 0, 0, 0, -1, 0};
  para.bounds = Aabb(Vec3(-2, -2, 0), Vec3(2, 2, 4));
  // Straight down: the quadratic term vanishes (linear case), one hit at z = 0.25.
  ASSERT_TRUE(intersect_quadric(para, Ray(Vec3(0.5, 0, 5), Vec3(0, 0, -1)), 0, kInfinity, t));
  EXPECT_NEAR(t, 4.75, 1e-14);
  // Horizontal at z = 1: x = -1 first, then x = +1 from inside.
  ASSERT_TRUE(intersect_quadric(para, Ray(Vec3(-3, 0, 1), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_NEAR(t, 2.0, 1e-14);
  ASSERT_TRUE(intersect_quadric(para, Ray(Vec3(0, 0, 1), Vec3(1, 0, 0)), 0, kInfinity, t));
  EXPECT_NEAR(t, 1.0, 1e-14);
  // Above the bounds: miss.
  EXPECT_FALSE(intersect_quadric(para, Ray(Vec3(-3, 0, 4.5), Vec3(1, 0, 0)), 0, kInfinity, t));
  // Random rays: hit points satisfy the equation; normals are unit and along the gradient.
  std::mt19937_64 rng(10);
  int hits = 0;
  for (int i = 0; i < 3000; ++i) {
    const Vec3 origin = Vec3(0, 0, 2) + 6.0 * random_unit(rng);
    const Ray ray(origin, Vec3(0, 0, 2) + random_in_ball(rng, 2.0) - origin);
    for (const Quadric* q : {&hyper, &para}) {
      if (!intersect_quadric(*q, ray, 0, kInfinity, t)) continue;
      ++hits;
      const Vec3 p = ray.at(t);
      EXPECT_LT(std::abs(quadric_value(*q, p)), 1e-11);
      EXPECT_TRUE(distance_to_box(p, q->bounds) < 1e-8);
      const Vec3 n = normal_of(*q, p);
      EXPECT_NEAR(glm::length(n), 1.0, 1e-14);
    }
  }
  EXPECT_GT(hits, 1000);
}

// ---------------------------------------------------------------------------------------
// Normals and bounds

TEST(PrimitiveNormals, UnitAndPerpendicularToTheSurface) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (int i = 0; i < 500; ++i) {
    const Triangle tri{random_in_ball(rng, 3), random_in_ball(rng, 3), random_in_ball(rng, 3)};
    const Vec3 n = normal_of(tri, tri.v0);
    EXPECT_NEAR(glm::length(n), 1.0, 1e-14);
    EXPECT_NEAR(glm::dot(n, glm::normalize(tri.v1 - tri.v0)), 0.0, 1e-12);
    EXPECT_NEAR(glm::dot(n, glm::normalize(tri.v2 - tri.v0)), 0.0, 1e-12);
    EXPECT_GT(glm::dot(n, glm::cross(tri.v1 - tri.v0, tri.v2 - tri.v0)), 0.0);

    const Sphere s{random_in_ball(rng, 5), 0.1 + uniform(rng)};
    const Vec3 radial = random_unit(rng);
    EXPECT_LT(glm::length(normal_of(s, s.center + s.radius * radial) - radial), 1e-14);

    // Cone: at a surface point, perpendicular to the slant and to the circle's tangent,
    // and pointing away from the axis.
    const Cone c{random_in_ball(rng, 5), uniform(rng), random_in_ball(rng, 5), uniform(rng)};
    const Vec3 axis = glm::normalize(c.apex - c.base);
    const Vec3 e1 = perpendicular(axis), e2 = glm::cross(axis, e1);
    const double angle = 2 * kPi * uniform(rng), h = uniform(rng);
    const Vec3 out = std::cos(angle) * e1 + std::sin(angle) * e2;
    const Vec3 p = c.base + h * (c.apex - c.base) +
                   (c.base_radius + h * (c.apex_radius - c.base_radius)) * out;
    const Vec3 slant = (c.apex + c.apex_radius * out) - (c.base + c.base_radius * out);
    const Vec3 cn = normal_of(c, p);
    EXPECT_NEAR(glm::length(cn), 1.0, 1e-14);
    EXPECT_NEAR(glm::dot(cn, glm::normalize(slant)), 0.0, 1e-12);
    EXPECT_NEAR(glm::dot(cn, glm::cross(axis, out)), 0.0, 1e-12);
    EXPECT_GT(glm::dot(cn, out), 0.0);
  }
  // Box: the face the point lies on.
  const Box b{Aabb(Vec3(0, 0, 0), Vec3(1, 2, 3))};
  EXPECT_EQ(normal_of(b, Vec3(0.5, 1, 3)), Vec3(0, 0, 1));
  EXPECT_EQ(normal_of(b, Vec3(0, 1, 1)), Vec3(-1, 0, 0));
  EXPECT_EQ(normal_of(b, Vec3(0.5, 2.0 + 1e-12, 1)), Vec3(0, 1, 0));
  EXPECT_EQ(normal_of(b, Vec3(0.5, 1, 1e-13)), Vec3(0, 0, -1));
}

TEST(PrimitiveBounds, ContainSampledSurfacePointsAndAreTight) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  auto grown = [](const Aabb& b) {
    const double eps = 1e-12 * std::max(1.0, b.magnitude());
    return Aabb(b.lo - Vec3(eps), b.hi + Vec3(eps));
  };
  for (int i = 0; i < 50; ++i) {
    const Triangle tri{random_in_ball(rng, 3), random_in_ball(rng, 3), random_in_ball(rng, 3)};
    const Aabb tb = bounds_of(tri);
    EXPECT_EQ(tb.lo, glm::min(tri.v0, glm::min(tri.v1, tri.v2)));
    EXPECT_EQ(tb.hi, glm::max(tri.v0, glm::max(tri.v1, tri.v2)));

    const Sphere s{random_in_ball(rng, 5), 0.1 + uniform(rng)};
    const Aabb sb = bounds_of(s);
    EXPECT_EQ(sb.lo, s.center - Vec3(s.radius));
    EXPECT_EQ(sb.hi, s.center + Vec3(s.radius));

    // Cone: 1000 surface samples inside, and the samples reach within 1% of every face.
    const Cone c{random_in_ball(rng, 5), uniform(rng), random_in_ball(rng, 5),
                 (i % 5 == 0) ? 0.0 : uniform(rng)};
    const Aabb cb = bounds_of(c);
    const Vec3 axis = glm::normalize(c.apex - c.base);
    const Vec3 e1 = perpendicular(axis), e2 = glm::cross(axis, e1);
    Aabb samples;
    for (int k = 0; k < 1000; ++k) {
      const double angle = 2 * kPi * uniform(rng);
      const double h = (k % 4 == 0) ? 0.0 : (k % 4 == 1) ? 1.0 : uniform(rng);
      const Vec3 p = c.base + h * (c.apex - c.base) +
                     (c.base_radius + h * (c.apex_radius - c.base_radius)) *
                         (std::cos(angle) * e1 + std::sin(angle) * e2);
      EXPECT_TRUE(grown(cb).contains(p)) << i << " " << k;
      samples.extend(p);
    }
    const double slack = 0.01 * std::max({cb.extent().x, cb.extent().y, cb.extent().z});
    for (int a = 0; a < 3; ++a) {
      EXPECT_LT(samples.lo[a] - cb.lo[a], slack);
      EXPECT_LT(cb.hi[a] - samples.hi[a], slack);
    }
  }
  const Box box{Aabb(Vec3(-1, 2, 3), Vec3(4, 5, 6))};
  EXPECT_EQ(bounds_of(box).lo, box.bounds.lo);
  EXPECT_EQ(bounds_of(box).hi, box.bounds.hi);
  const Quadric q = clipped_cylinder();
  EXPECT_EQ(bounds_of(q).lo, q.bounds.lo);
  EXPECT_EQ(bounds_of(q).hi, q.bounds.hi);
}

}  // namespace
}  // namespace frontier
