// Basic geometry shared by every layer: vectors (double precision, so that models far from
// the origin keep their detail), axis-aligned boxes and rays.
// Invariant: Ray::dir is unit length, so a ray parameter t is a Euclidean distance; this makes
// the tie tolerance between methods (1e-6 relative) meaningful.
#pragma once

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace frontier {

using Vec3 = glm::dvec3;
using Vec4 = glm::dvec4;

inline constexpr double kInfinity = std::numeric_limits<double>::infinity();

struct Aabb {
  Vec3 lo{kInfinity};
  Vec3 hi{-kInfinity};

  Aabb() = default;
  Aabb(const Vec3& a, const Vec3& b) : lo(glm::min(a, b)), hi(glm::max(a, b)) {}

  bool empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  void extend(const Vec3& p) { lo = glm::min(lo, p); hi = glm::max(hi, p); }
  void extend(const Aabb& b) { lo = glm::min(lo, b.lo); hi = glm::max(hi, b.hi); }
  Vec3 center() const { return 0.5 * (lo + hi); }
  Vec3 extent() const { return hi - lo; }
  double surface_area() const {
    if (empty()) return 0.0;
    const Vec3 e = extent();
    return 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
  }
  // Closed-box tests: touching counts as overlapping.
  bool overlaps(const Aabb& b) const {
    return lo.x <= b.hi.x && b.lo.x <= hi.x && lo.y <= b.hi.y && b.lo.y <= hi.y &&
           lo.z <= b.hi.z && b.lo.z <= hi.z;
  }
  bool contains(const Vec3& p) const {
    return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z;
  }
  Aabb intersection(const Aabb& b) const {
    Aabb r;
    r.lo = glm::max(lo, b.lo);
    r.hi = glm::min(hi, b.hi);
    return r;
  }
  // Largest absolute coordinate: the scale for relative tolerances.
  double magnitude() const {
    return std::max({std::abs(lo.x), std::abs(lo.y), std::abs(lo.z), std::abs(hi.x),
                     std::abs(hi.y), std::abs(hi.z)});
  }
};

struct Ray {
  Vec3 origin{0.0};
  Vec3 dir{0.0, 0.0, 1.0};  // unit length
  Vec3 inv_dir{kInfinity, kInfinity, 1.0};

  Ray() = default;
  Ray(const Vec3& o, const Vec3& d) : origin(o), dir(glm::normalize(d)) { inv_dir = 1.0 / dir; }
  Vec3 at(double t) const { return origin + t * dir; }
};

// Slab test. On a hit returns true with the parametric interval [t0, t1] of the ray inside
// the closed box (t0 may be negative when the origin is inside). Axis-parallel rays are
// handled without NaN: a zero direction component tests the origin against the slab.
// The same for a ray given as origin, direction (of any length: t is in units of it) and its
// component-wise inverse.
inline bool ray_box_interval(const Vec3& origin, const Vec3& dir, const Vec3& inv_dir, const Aabb& box, double& t0,
                             double& t1) {
  t0 = -kInfinity;
  t1 = kInfinity;
  for (int a = 0; a < 3; ++a) {
    if (dir[a] == 0.0) {
      if (origin[a] < box.lo[a] || origin[a] > box.hi[a]) return false;
      continue;
    }
    double ta = (box.lo[a] - origin[a]) * inv_dir[a];
    double tb = (box.hi[a] - origin[a]) * inv_dir[a];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

inline bool ray_box_interval(const Ray& ray, const Aabb& box, double& t0, double& t1) {
  return ray_box_interval(ray.origin, ray.dir, ray.inv_dir, box, t0, t1);
}

// Distance from a point to the closest point of a box (0 when inside).
inline double distance_to_box(const Vec3& p, const Aabb& box) {
  const Vec3 q = glm::clamp(p, box.lo, box.hi);
  return glm::length(q - p);
}

}  // namespace frontier
