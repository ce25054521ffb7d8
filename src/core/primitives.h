// The primitive shapes frontier renders and their ray tests.
//
// Contract shared by every `intersect_*` function: it returns true and writes `t` when the
// ray meets the surface at a parameter t with tmin <= t <= tmax, choosing the smallest such t.
// Ray::dir is unit length. Tests are exact where the math allows and numerically stable
// everywhere: quadratic roots use the stable form (no cancellation at grazing angles),
// axis-parallel rays never produce NaN, and the triangle test is watertight (a ray never slips
// between two triangles that share an edge, Woop/Benthin/Wald 2013).
#pragma once

#include "src/core/geometry.h"

#include <array>
#include <cstdint>

namespace frontier {

struct Triangle {
  Vec3 v0, v1, v2;
};

struct Sphere {
  Vec3 center;
  double radius = 0.0;
};

// An axis-aligned solid box (NFF-style "axial parallelepiped").
struct Box {
  Aabb bounds;
};

// A truncated cone (a cylinder when the radii are equal), open at both ends, as NFF's `c`.
// One radius may be zero (a pointed cone); the axis must have non-zero length.
struct Cone {
  Vec3 base;
  double base_radius = 0.0;
  Vec3 apex;
  double apex_radius = 0.0;
};

// A general quadric  A x² + B y² + C z² + D xy + E yz + F xz + G x + H y + I z + J = 0
// (coefficients in that order), clipped by up to 12 half-spaces: a surface point p is kept
// when dot(plane.xyz, p) + plane.w <= 0 for every clip plane. `bounds` must be finite and
// enclose the kept surface; hits outside it are discarded.
struct Quadric {
  static constexpr int kMaxClipPlanes = 12;
  std::array<double, 10> coeff{};
  std::array<Vec4, kMaxClipPlanes> clip{};
  int clip_count = 0;
  Aabb bounds;
};

bool intersect_triangle(const Triangle& tri, const Ray& ray, double tmin, double tmax, double& t);
bool intersect_sphere(const Sphere& s, const Ray& ray, double tmin, double tmax, double& t);
bool intersect_box(const Box& b, const Ray& ray, double tmin, double tmax, double& t);
bool intersect_cone(const Cone& c, const Ray& ray, double tmin, double tmax, double& t);
// The cone test split in two for many rays from one origin (a frame's primary rays): the terms
// that depend only on the cone and the origin, then the rest per direction. Composed they are
// intersect_cone, operation for operation (bit-identical results).
struct ConeFromOrigin {
  Vec3 along;            // apex - base
  double inv_len2 = 0.0;
  Vec3 op;               // origin - base, without its part along the axis
  double os = 0.0;       // the origin's height as a fraction of the axis
  double growth = 0.0;   // apex radius - base radius
  double radius_at_origin = 0.0;
  double c = 0.0;
};
ConeFromOrigin cone_from_origin(const Cone& c, const Vec3& origin);
bool intersect_cone(const ConeFromOrigin& k, const Vec3& dir, double tmin, double tmax, double& t);
// The same split for spheres: the terms of intersect_sphere that depend only on the sphere and
// the origin, then the rest per direction, in the same operations (bit-identical results).
struct SphereFromOrigin {
  Vec3 oc;              // origin - centre
  double reach = 0.0;   // radius with its margin (intersect_sphere's early rejection)
  double r2 = 0.0;
  double c = 0.0;       // |oc|² - r²
};
SphereFromOrigin sphere_from_origin(const Sphere& s, const Vec3& origin);
bool intersect_sphere(const SphereFromOrigin& k, const Vec3& dir, double tmin, double tmax, double& t);
bool intersect_quadric(const Quadric& q, const Ray& ray, double tmin, double tmax, double& t);

// Tight (or slightly conservative) axis-aligned bounds.
Aabb bounds_of(const Triangle& tri);
Aabb bounds_of(const Sphere& s);
Aabb bounds_of(const Box& b);
Aabb bounds_of(const Cone& c);
Aabb bounds_of(const Quadric& q);

// A lower bound on the distance from p to any point of the surface (0 when p may lie on or
// inside it), slightly conservative against rounding. Together with the distance to the
// bounds it orders and cuts per-pixel tests (a hit at distance t from p needs bound <= t), so
// it must never exceed the true distance.
double distance_bound(const Sphere& s, const Vec3& p);
double distance_bound(const Cone& c, const Vec3& p);

// Unit geometric normal at surface point p (for shading). Callers flip it to face the viewer.
Vec3 normal_of(const Triangle& tri, const Vec3& p);
Vec3 normal_of(const Sphere& s, const Vec3& p);
Vec3 normal_of(const Box& b, const Vec3& p);
Vec3 normal_of(const Cone& c, const Vec3& p);
Vec3 normal_of(const Quadric& q, const Vec3& p);

// Solves a t² + b t + c = 0 in the numerically stable form. Returns the number of real roots
// (0, 1 or 2), written in ascending order. Handles a == 0 (linear) without dividing by zero.
int solve_quadratic(double a, double b, double c, double& r0, double& r1);

// The roots of a t² + b t + c = 0 for a ray interval `span` long (ascending, into roots[0..n)):
// linear when the second root lies >= 1e12 spans away (a quadric seen nearly along a ruling
// line), else solve_quadratic. Returns n (0 when a == b == 0).
int interval_quadratic_roots(double a, double b, double c, double span, double roots[2]);

}  // namespace frontier
