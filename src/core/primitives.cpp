// Ray tests, bounds and normals of frontier's primitive shapes: the ray caster's inner loop.
//
// Nothing here allocates, branches on type or calls through a pointer. Precision rules:
//  - Triangles use the watertight test of Woop, Benthin & Wald (JCGT 2013). Its guarantee rests
//    on every edge function having the exact sign of the exact product of the (rounded) sheared
//    coordinates, or being zero. Plain `x*y - z*w` has that property only without fused
//    multiply-add contraction, so on FMA targets the edge functions use Kahan's sign-exact
//    difference of products instead, and the shear is written as an explicit fma so each
//    vertex is sheared identically whichever triangle it belongs to. Zero edge functions are
//    recomputed in long double, and zero counts as inside, so a ray can never slip between two
//    triangles that share an edge or a vertex.
//  - Quadratics use the stable root form q = -(b + sign(b) sqrt(disc)). Where the geometry
//    yields a cancellation-free discriminant (sphere, cone) it is computed from vectors rather
//    than as b² - ac, so grazing rays stay accurate.
//  - Shapes are evaluated relative to a point of their own (sphere centre, cone base, the
//    ray's entry into a quadric's bounds) so models far from the origin keep their precision.
#include "src/core/primitives.h"

#include <glm/gtx/norm.hpp>

#include <cmath>
#include <utility>

namespace frontier {
namespace {

#if defined(__FP_FAST_FMA)
constexpr bool kFastFma = true;
#else
constexpr bool kFastFma = false;
#endif

// a*b - c*d. With hardware FMA this is Kahan's algorithm (relative error <= 2 ulp, so the
// sign is exact and the result is zero only when the exact value is); without it, the plain
// expression, whose sign is exact or zero because rounding is monotonic.
inline double difference_of_products(double a, double b, double c, double d) {
  if constexpr (kFastFma) {
    const double cd = c * d;
    const double error = std::fma(-c, d, cd);  // cd - c*d, exactly
    return std::fma(a, b, -cd) + error;
  } else {
    return a * b - c * d;
  }
}

// a - s*b, computed the same way for every vertex (see the file comment).
inline double shear(double a, double s, double b) {
  if constexpr (kFastFma) {
    return std::fma(-s, b, a);
  } else {
    return a - s * b;
  }
}

// The watertight test with the shear axes fixed at compile time (kz: the ray's dominant axis;
// kx, ky: the other two, swapped when the ray points down kz so the winding, and det's sign,
// mean the same for every ray; without culling nothing depends on it yet).
template <int kx, int ky, int kz>
inline bool watertight_triangle(const Triangle& tri, const Ray& ray, double tmin, double tmax,
                                double& t) {
  const Vec3& d = ray.dir;
  const double sz = 1.0 / d[kz];
  const double sx = d[kx] * sz;
  const double sy = d[ky] * sz;

  const Vec3 a = tri.v0 - ray.origin;
  const Vec3 b = tri.v1 - ray.origin;
  const Vec3 c = tri.v2 - ray.origin;
  const double ax = shear(a[kx], sx, a[kz]);
  const double ay = shear(a[ky], sy, a[kz]);
  const double bx = shear(b[kx], sx, b[kz]);
  const double by = shear(b[ky], sy, b[kz]);
  const double cx = shear(c[kx], sx, c[kz]);
  const double cy = shear(c[ky], sy, c[kz]);

  // Edge functions: twice the signed areas of the sub-triangles the ray's 2-D point (the
  // origin) cuts the projected triangle into.
  double u = difference_of_products(cx, by, cy, bx);
  double v = difference_of_products(ax, cy, ay, cx);
  double w = difference_of_products(bx, ay, by, ax);
  // Bitwise, not short-circuit, operators: one well-predicted branch instead of three
  // data-dependent ones.
  if ((u == 0.0) | (v == 0.0) | (w == 0.0)) [[unlikely]] {
    const long double lax = ax, lay = ay, lbx = bx, lby = by, lcx = cx, lcy = cy;
    u = static_cast<double>(lcx * lby - lcy * lbx);
    v = static_cast<double>(lax * lcy - lay * lcx);
    w = static_cast<double>(lbx * lay - lby * lax);
  }
  // Zero counts as inside: that is what closes the cracks.
  if (((u < 0.0) | (v < 0.0) | (w < 0.0)) & ((u > 0.0) | (v > 0.0) | (w > 0.0))) return false;
  const double det = u + v + w;
  if (det == 0.0) return false;  // seen edge-on, or zero area

  // All of u, v, w share det's sign, so t is a convex combination of the vertex depths.
  const double hit = (u * (sz * a[kz]) + v * (sz * b[kz]) + w * (sz * c[kz])) / det;
  if (!(hit >= tmin && hit <= tmax)) return false;
  // A triangle with an exactly zero normal has no shading normal; never report a hit on it.
  if (glm::cross(tri.v1 - tri.v0, tri.v2 - tri.v0) == Vec3(0.0)) return false;
  t = hit;
  return true;
}

// The roots q / a and c / q of a t² + b t + c = 0 (Vieta's formulas, with q of the sign that
// avoids cancellation: no difference of nearly equal numbers), in increasing order; returns 2.
inline int two_roots(double q, double a, double c, double& r0, double& r1) {
  double x0 = q / a;
  double x1 = c / q;
  if (x0 > x1) std::swap(x0, x1);
  r0 = x0;
  r1 = x1;
  return 2;
}

// Roots of a t² + 2 h t + c = 0 given the quarter discriminant disc = h² - a c (which callers
// compute in a cancellation-free way). Same output convention as solve_quadratic.
inline int solve_half_b(double a, double h, double c, double disc, double& r0, double& r1) {
  if (a == 0.0) {
    if (h == 0.0) return 0;
    r0 = r1 = -0.5 * c / h;
    return 1;
  }
  if (!(disc >= 0.0)) return 0;  // also rejects NaN
  if (disc == 0.0) {
    r0 = r1 = -h / a;
    return 1;
  }
  const double q = -(h + std::copysign(std::sqrt(disc), h));  // |q| >= sqrt(disc) > 0
  return two_roots(q, a, c, r0, r1);
}

// Unit axis of a cone and the radius slope k (radius grows by k per unit of height).
struct ConeFrame {
  Vec3 axis;  // unit, base -> apex
  double height;
  double slope;
};

inline ConeFrame cone_frame(const Cone& c) {
  const Vec3 along = c.apex - c.base;
  const double height = glm::length(along);
  return {along / height, height, (c.apex_radius - c.base_radius) / height};
}

// Extent of a disc of radius r with unit normal u, per axis.
inline Vec3 disc_extent(const Vec3& u, double r) {
  return r * glm::sqrt(glm::max(Vec3(0.0), Vec3(1.0) - u * u));
}

}  // namespace

int solve_quadratic(double a, double b, double c, double& r0, double& r1) {
  // Scaling all coefficients by a power of two leaves the roots unchanged and keeps b² and
  // 4ac inside the double range for coefficients of extreme magnitude.
  const double largest = std::max({std::abs(a), std::abs(b), std::abs(c)});
  if (!(largest > 0.0)) return 0;  // 0 = 0 (every t) or NaN input: no isolated roots
  if (largest > 0x1p+500 || largest < 0x1p-500) {
    int exponent = 0;
    std::frexp(largest, &exponent);
    a = std::ldexp(a, -exponent);
    b = std::ldexp(b, -exponent);
    c = std::ldexp(c, -exponent);
  }
  if (a == 0.0) {
    if (b == 0.0) return 0;
    r0 = r1 = -c / b;
    return 1;
  }
  const double disc = difference_of_products(b, b, 4.0 * a, c);
  if (!(disc >= 0.0)) return 0;
  if (disc == 0.0) {
    r0 = r1 = -0.5 * b / a;
    return 1;
  }
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  return two_roots(q, a, c, r0, r1);
}

bool intersect_triangle(const Triangle& tri, const Ray& ray, double tmin, double tmax,
                        double& t) {
  // Shear so that the ray becomes the +z axis through the origin: kz is the dominant
  // direction axis; swapping kx/ky for a negative kz keeps the winding (and so the signs).
  // Dispatching once to compile-time axes keeps the body free of per-access index branches.
  const Vec3& d = ray.dir;
  const double ax = std::abs(d.x), ay = std::abs(d.y), az = std::abs(d.z);
  if (ax > ay && ax > az) {
    return d.x < 0.0 ? watertight_triangle<2, 1, 0>(tri, ray, tmin, tmax, t)
                     : watertight_triangle<1, 2, 0>(tri, ray, tmin, tmax, t);
  }
  if (ay > az) {
    return d.y < 0.0 ? watertight_triangle<0, 2, 1>(tri, ray, tmin, tmax, t)
                     : watertight_triangle<2, 0, 1>(tri, ray, tmin, tmax, t);
  }
  return d.z < 0.0 ? watertight_triangle<1, 0, 2>(tri, ray, tmin, tmax, t)
                   : watertight_triangle<0, 1, 2>(tri, ray, tmin, tmax, t);
}

// The sphere's hit from its roots r0 <= r1: the near one within [tmin, tmax], else the far one
// (the ray starts inside, or the near root lies before tmin).
inline bool nearer_root_within(double r0, double r1, double tmin, double tmax, double& t) {
  if (r0 >= tmin && r0 <= tmax) {
    t = r0;
    return true;
  }
  if (r1 >= tmin && r1 <= tmax) {
    t = r1;
    return true;
  }
  return false;
}

bool intersect_sphere(const Sphere& s, const Ray& ray, double tmin, double tmax, double& t) {
  const Vec3 oc = ray.origin - s.center;
  const Vec3& d = ray.dir;
  const double a = glm::dot(d, d);
  const double h = glm::dot(oc, d);
  // Both roots lie within `reach` of the closest approach t = -h/a (reach = r/sqrt(a) <= r/a
  // for a <= 1): a sphere wholly outside [tmin, tmax] is rejected without a square root.
  const double tc = -h / a, reach = s.radius * (1.0 + 1e-9) / std::min(a, 1.0);
  if (tc - reach > tmax || tc + reach < tmin) return false;
  const double r2 = s.radius * s.radius;
  const double c = glm::dot(oc, oc) - r2;
  // h² - a c = a (r² - |perp|²) with perp the centre's offset from the ray's line: no
  // cancellation between two large squares at grazing angles (Haines et al., RT Gems ch. 7).
  const Vec3 perp = oc - (h / a) * d;
  const double disc = a * (r2 - glm::length2(perp));
  double r0, r1;
  if (solve_half_b(a, h, c, disc, r0, r1) == 0) return false;
  return nearer_root_within(r0, r1, tmin, tmax, t);
}

SphereFromOrigin sphere_from_origin(const Sphere& s, const Vec3& origin) {
  SphereFromOrigin k;
  k.oc = origin - s.center;
  k.reach = s.radius * (1.0 + 1e-9);
  k.r2 = s.radius * s.radius;
  k.c = glm::dot(k.oc, k.oc) - k.r2;
  return k;
}

// intersect_sphere with the origin's terms given (see there for the reasoning).
bool intersect_sphere(const SphereFromOrigin& k, const Vec3& d, double tmin, double tmax, double& t) {
  const double a = glm::dot(d, d);
  const double h = glm::dot(k.oc, d);
  const double tc = -h / a, reach = k.reach / std::min(a, 1.0);
  if (tc - reach > tmax || tc + reach < tmin) return false;
  const Vec3 perp = k.oc - (h / a) * d;
  const double disc = a * (k.r2 - glm::length2(perp));
  double r0, r1;
  if (solve_half_b(a, h, k.c, disc, r0, r1) == 0) return false;
  return nearer_root_within(r0, r1, tmin, tmax, t);
}

bool intersect_box(const Box& b, const Ray& ray, double tmin, double tmax, double& t) {
  double t0, t1;
  if (!ray_box_interval(ray, b.bounds, t0, t1)) return false;
  if (t0 >= tmin && t0 <= tmax) {
    t = t0;
    return true;
  }
  if (t1 >= tmin && t1 <= tmax) {  // origin inside (or entry before tmin): the exit face
    t = t1;
    return true;
  }
  return false;
}

ConeFromOrigin cone_from_origin(const Cone& cone, const Vec3& origin) {
  // Local frame at the base, with heights measured as fractions s of the axis A = apex - base
  // (no normalisation, so no sqrt): a point v is at s = v·A / |A|², its radial part is
  // v - s A, and the (double) cone is |v - s A|² = (r0 + (r1 - r0) s)².
  ConeFromOrigin k;
  k.along = cone.apex - cone.base;
  k.inv_len2 = 1.0 / glm::length2(k.along);
  const Vec3 o = origin - cone.base;
  k.os = glm::dot(o, k.along) * k.inv_len2;
  k.op = o - k.os * k.along;
  k.growth = cone.apex_radius - cone.base_radius;
  k.radius_at_origin = cone.base_radius + k.growth * k.os;
  k.c = glm::length2(k.op) - k.radius_at_origin * k.radius_at_origin;
  return k;
}

bool intersect_cone(const ConeFromOrigin& k, const Vec3& d, double tmin, double tmax, double& t) {
  const double ds = glm::dot(d, k.along) * k.inv_len2;
  const Vec3 dp = d - ds * k.along;
  const double kdh = k.growth * ds;  // radius change per unit of t

  // a t² + 2 h t + c = 0. Expanding h² - a c gives |R dp - k dh op|² - |op × dp|²,
  // which stays accurate for grazing rays where h² and a c nearly cancel.
  const double a = glm::length2(dp) - kdh * kdh;
  const double h = glm::dot(k.op, dp) - kdh * k.radius_at_origin;
  const double disc = glm::length2(k.radius_at_origin * dp - kdh * k.op) - glm::length2(glm::cross(k.op, dp));
  double roots[2];
  const int n = solve_half_b(a, h, k.c, disc, roots[0], roots[1]);
  for (int i = 0; i < n; ++i) {
    const double r = roots[i];
    if (!(r >= tmin && r <= tmax)) continue;
    const double s = k.os + r * ds;
    if (s >= 0.0 && s <= 1.0) {  // both roots are checked: the near one may be clipped
      t = r;
      return true;
    }
  }
  return false;
}

bool intersect_cone(const Cone& cone, const Ray& ray, double tmin, double tmax, double& t) {
  return intersect_cone(cone_from_origin(cone, ray.origin), ray.dir, tmin, tmax, t);
}

int interval_quadratic_roots(double a, double b, double c, double span, double roots[2]) {
  if (std::abs(a) * span <= 1e-12 * std::abs(b)) {
    // The second root lies >= 1e12 spans away: treat the equation as linear.
    if (b == 0.0) return 0;
    roots[0] = -c / b;
    return 1;
  }
  return solve_quadratic(a, b, c, roots[0], roots[1]);
}

bool intersect_quadric(const Quadric& q, const Ray& ray, double tmin, double tmax, double& t) {
  const auto& k = q.coeff;  // A B C D E F G H I J
  // Only the part of the ray inside the (slightly grown) bounds can hit; this is also the
  // early rejection for most rays.
  const double tolerance = 1e-9 * std::max(q.bounds.magnitude(), 1e-300);
  const Aabb grown(q.bounds.lo - Vec3(tolerance), q.bounds.hi + Vec3(tolerance));
  double t0, t1;
  if (!ray_box_interval(ray, grown, t0, t1)) return false;
  t0 = std::max(t0, tmin);
  t1 = std::min(t1, tmax);
  if (!(t0 <= t1)) return false;

  // Expand the polynomial about s, where the ray enters the bounds: there c = Q(s) and the
  // roots are small, instead of the difference of large numbers they are about a far origin.
  const double ts = std::isfinite(t0) ? t0 : 0.0;
  const Vec3 s = ray.at(ts);
  const Vec3& d = ray.dir;
  const Vec3 grad(2.0 * k[0] * s.x + k[3] * s.y + k[5] * s.z + k[6],
                  2.0 * k[1] * s.y + k[3] * s.x + k[4] * s.z + k[7],
                  2.0 * k[2] * s.z + k[4] * s.y + k[5] * s.x + k[8]);
  const double a = k[0] * d.x * d.x + k[1] * d.y * d.y + k[2] * d.z * d.z +
                   k[3] * d.x * d.y + k[4] * d.y * d.z + k[5] * d.x * d.z;
  const double b = glm::dot(grad, d);
  const double c = s.x * (k[0] * s.x + k[3] * s.y + k[5] * s.z + k[6]) +
                   s.y * (k[1] * s.y + k[4] * s.z + k[7]) + s.z * (k[2] * s.z + k[8]) + k[9];

  double roots[2];
  const int n = interval_quadratic_roots(a, b, c, t1 - ts, roots);
  for (int i = 0; i < n; ++i) {
    const double hit = ts + roots[i];
    if (!(hit >= t0 && hit <= t1)) continue;
    const Vec3 p = ray.at(hit);
    bool kept = true;
    for (int j = 0; j < q.clip_count && kept; ++j) {
      const Vec4& plane = q.clip[j];
      const Vec3 terms = Vec3(plane) * p;
      const double value = terms.x + terms.y + terms.z + plane.w;
      const double scale = std::abs(terms.x) + std::abs(terms.y) + std::abs(terms.z) +
                           std::abs(plane.w);
      kept = value <= 1e-9 * scale;
    }
    if (kept) {
      t = hit;
      return true;
    }
  }
  return false;
}

Aabb bounds_of(const Triangle& tri) {
  return Aabb(glm::min(tri.v0, glm::min(tri.v1, tri.v2)),
              glm::max(tri.v0, glm::max(tri.v1, tri.v2)));
}

Aabb bounds_of(const Sphere& s) {
  const Vec3 r(std::abs(s.radius));
  return Aabb(s.center - r, s.center + r);
}

Aabb bounds_of(const Box& b) { return b.bounds; }

double distance_bound(const Sphere& s, const Vec3& p) {
  const double centre = glm::length(p - s.center), r = std::abs(s.radius);
  return std::max(0.0, centre - r - 1e-9 * (centre + r));
}

// Every surface point lies within the larger radius of the axis segment.
double distance_bound(const Cone& c, const Vec3& p) {
  const Vec3 axis = c.apex - c.base;
  const double len2 = glm::dot(axis, axis);
  const double s = len2 > 0.0 ? std::clamp(glm::dot(p - c.base, axis) / len2, 0.0, 1.0) : 0.0;
  const double to_axis = glm::length(p - (c.base + s * axis));
  const double r = std::max(std::abs(c.base_radius), std::abs(c.apex_radius));
  const double scale = glm::length(p - c.base) + std::sqrt(len2) + r;
  return std::max(0.0, to_axis - r - 1e-9 * scale);
}

Aabb bounds_of(const Cone& c) {
  const Vec3 u = cone_frame(c).axis;
  const Vec3 e0 = disc_extent(u, std::abs(c.base_radius));
  const Vec3 e1 = disc_extent(u, std::abs(c.apex_radius));
  Aabb box(c.base - e0, c.base + e0);
  box.extend(Aabb(c.apex - e1, c.apex + e1));
  return box;
}

Aabb bounds_of(const Quadric& q) { return q.bounds; }

Vec3 normal_of(const Triangle& tri, const Vec3& p) {
  const Vec3 n = glm::cross(tri.v1 - tri.v0, tri.v2 - tri.v0);
  const double len = glm::length(n);
  return len > 0.0 ? n / len : Vec3(0.0, 0.0, 1.0);  // degenerate: never hit, any unit vector
}

Vec3 normal_of(const Sphere& s, const Vec3& p) {
  // Normalising (rather than dividing by r) stays unit when p is a rounded hit point.
  const Vec3 n = p - s.center;
  const double len = glm::length(n);
  return len > 0.0 ? n / len : Vec3(0.0, 0.0, 1.0);
}

Vec3 normal_of(const Box& b, const Vec3& p) {
  int best_axis = 0;
  double best_sign = -1.0;
  double best_distance = kInfinity;
  for (int axis = 0; axis < 3; ++axis) {
    const double to_lo = std::abs(p[axis] - b.bounds.lo[axis]);
    const double to_hi = std::abs(p[axis] - b.bounds.hi[axis]);
    if (to_lo < best_distance) {
      best_distance = to_lo;
      best_axis = axis;
      best_sign = -1.0;
    }
    if (to_hi < best_distance) {
      best_distance = to_hi;
      best_axis = axis;
      best_sign = 1.0;
    }
  }
  Vec3 n(0.0);
  n[best_axis] = best_sign;
  return n;
}

Vec3 normal_of(const Cone& c, const Vec3& p) {
  // Gradient of |p_perp|² - (r0 + k h)², divided by 2 r(h): p̂_perp - k axis. It is
  // perpendicular to the slant direction axis + k p̂_perp.
  const ConeFrame f = cone_frame(c);
  const Vec3 v = p - c.base;
  const Vec3 radial = v - glm::dot(v, f.axis) * f.axis;
  const double len = glm::length(radial);
  if (!(len > 0.0)) {
    // On the axis (a pointed apex): the gradient's radial part is undefined; point away
    // from the cone along the axis.
    return f.slope > 0.0 ? -f.axis : f.axis;
  }
  return glm::normalize(radial / len - f.slope * f.axis);
}

Vec3 normal_of(const Quadric& q, const Vec3& p) {
  const auto& k = q.coeff;
  const Vec3 grad(2.0 * k[0] * p.x + k[3] * p.y + k[5] * p.z + k[6],
                  2.0 * k[1] * p.y + k[3] * p.x + k[4] * p.z + k[7],
                  2.0 * k[2] * p.z + k[4] * p.y + k[5] * p.x + k[8]);
  const double len = glm::length(grad);
  return len > 0.0 ? grad / len : Vec3(0.0, 0.0, 1.0);  // singular point (e.g. a cone apex)
}

}  // namespace frontier
