// Immediate-mode ray casting (see the header): implicit surfaces and their ray test, bounding
// polyhedra and near caps, object issue orders, ImrRenderer's frame (issue, rasterize with
// ray-cast bound fragments, deferred lighting) and ImrFrameRenderer.
#include "src/raster/imr.h"

#include <nlohmann/json.hpp>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <random>

namespace frontier {

namespace {

constexpr double kPi = 3.14159265358979323846;
// Relative outward margin of bounds and caps over exact enclosure: covers the rounding of
// vertex positions, plane equations and the rasterizer's 1/w.
constexpr double kBoundMargin = 1e-9;

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// x' A x for the quadric's second-order part.
double quadratic_part(const std::array<double, 10>& k, const Vec3& d) {
  return k[0] * d.x * d.x + k[1] * d.y * d.y + k[2] * d.z * d.z + k[3] * d.x * d.y + k[4] * d.y * d.z +
         k[5] * d.x * d.z;
}

// Whether local point p passes every clip plane, with the tolerance intersect_quadric uses.
bool kept_by_planes(const ImplicitSurface& s, const Vec3& p) {
  for (int j = 0; j < s.clip_count; ++j) {
    const Vec4& plane = s.clip[static_cast<size_t>(j)];
    const Vec3 terms = Vec3(plane) * p;
    const double value = terms.x + terms.y + terms.z + plane.w;
    const double scale = std::abs(terms.x) + std::abs(terms.y) + std::abs(terms.z) + std::abs(plane.w);
    if (!(value <= 1e-9 * scale)) return false;
  }
  return true;
}

Vec3 unit_or(const Vec3& v, const Vec3& fallback) {
  const double len = glm::length(v);
  return len > 0.0 ? v / len : fallback;
}

// An orthonormal pair perpendicular to unit vector a.
void perpendicular_basis(const Vec3& a, Vec3& u, Vec3& v) {
  const Vec3 helper = std::abs(a.x) < 0.6 ? Vec3(1, 0, 0) : std::abs(a.y) < 0.6 ? Vec3(0, 1, 0) : Vec3(0, 0, 1);
  u = glm::normalize(glm::cross(a, helper));
  v = glm::cross(a, u);
}

// Orients every face outward (the polyhedron is convex, so its vertex centroid is inside),
// drops zero-area faces and computes the planes.
void finish_polyhedron(BoundingPolyhedron& b) {
  Vec3 centroid(0.0);
  for (const Vec3& v : b.vertices) centroid += v;
  centroid /= static_cast<double>(std::max<size_t>(b.vertices.size(), 1));
  std::vector<std::array<uint32_t, 3>> faces;
  b.planes.clear();
  for (std::array<uint32_t, 3> f : b.faces) {
    const Vec3 &a = b.vertices[f[0]], &c1 = b.vertices[f[1]], &c2 = b.vertices[f[2]];
    Vec3 n = glm::cross(c1 - a, c2 - a);
    const double len = glm::length(n);
    const double size = std::max({glm::length(c1 - a), glm::length(c2 - a), 1e-300});
    if (!(len > 1e-12 * size * size)) continue;  // degenerate (a pointed cone's apex)
    n /= len;
    if (glm::dot(n, (a + c1 + c2) / 3.0 - centroid) < 0.0) {
      std::swap(f[1], f[2]);
      n = -n;
    }
    faces.push_back(f);
    b.planes.push_back(Vec4(n, -glm::dot(n, a)));
  }
  b.faces = std::move(faces);
}

// Sutherland–Hodgman: keeps the part of convex polygon `poly` with dot(n, p) + w <= 0.
void clip_polygon(std::vector<Vec3>& poly, const Vec3& n, double w) {
  std::vector<Vec3> out;
  out.reserve(poly.size() + 1);
  for (size_t i = 0; i < poly.size(); ++i) {
    const Vec3& a = poly[i];
    const Vec3& b = poly[(i + 1) % poly.size()];
    const double da = glm::dot(n, a) + w, db = glm::dot(n, b) + w;
    if (da <= 0.0) out.push_back(a);
    if ((da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0)) out.push_back(a + (da / (da - db)) * (b - a));
  }
  poly = std::move(out);
}

}  // namespace

double ImplicitSurface::value(const Vec3& p) const {
  const auto& k = coeff;
  return p.x * (k[0] * p.x + k[3] * p.y + k[5] * p.z + k[6]) + p.y * (k[1] * p.y + k[4] * p.z + k[7]) +
         p.z * (k[2] * p.z + k[8]) + k[9];
}

Vec3 ImplicitSurface::gradient(const Vec3& p) const {
  const auto& k = coeff;
  return Vec3(2.0 * k[0] * p.x + k[3] * p.y + k[5] * p.z + k[6], 2.0 * k[1] * p.y + k[3] * p.x + k[4] * p.z + k[7],
              2.0 * k[2] * p.z + k[4] * p.y + k[5] * p.x + k[8]);
}

namespace {

// cast_surface in the surface's local frame: o the ray's origin there, d its direction (of any
// length: t is measured in units of d), inv_dir = 1 / d, `box` the bounds grown by the
// tolerance. The normal is computed only when asked for (the per-fragment test needs t alone).
template <bool kWantNormal>
bool cast_local(const ImplicitSurface& s, const Vec3& o, const Vec3& d, const Vec3& inv_dir, const Aabb& box,
                double tmin, double tmax, bool back_sample_culling, SurfaceSample& sample) {
  sample = SurfaceSample{};
  double lo, hi;
  if (!ray_box_interval(o, d, inv_dir, box, lo, hi)) return false;
  lo = std::max(lo, tmin);
  hi = std::min(hi, tmax);
  // A capped solid: the ray's interval inside every clip half-space, and the plane it enters by.
  int entry_plane = -1;
  if (s.capped) {
    for (int j = 0; j < s.clip_count; ++j) {
      const Vec4& plane = s.clip[static_cast<size_t>(j)];
      const double nd = glm::dot(Vec3(plane), d), no = glm::dot(Vec3(plane), o) + plane.w;
      if (nd > 0.0) {
        hi = std::min(hi, -no / nd);
      } else if (nd < 0.0) {
        const double t = -no / nd;
        if (t > lo) {
          lo = t;
          entry_plane = j;
        }
      } else if (no > 0.0) {
        return false;
      }
    }
  }
  if (!(lo <= hi)) return false;

  // Expand about the interval's start so the roots are small numbers (see intersect_quadric).
  const double ts = lo;
  const Vec3 start = o + ts * d;
  const double a = quadratic_part(s.coeff, d);
  const double b = glm::dot(s.gradient(start), d);
  const double c = s.value(start);
  if (entry_plane >= 0 && c <= 0.0) {
    // Entering the clipped solid through a plane while inside the quadric: the cap.
    sample.t = ts;
    sample.normal = Vec3(s.clip[static_cast<size_t>(entry_plane)]);
    sample.cap = true;
    return true;
  }
  double roots[2];
  const int n = interval_quadratic_roots(a, b, c, hi - ts, roots);
  for (int i = 0; i < n; ++i) {
    const double t = ts + roots[i];
    if (!(t >= lo && t <= hi)) continue;
    const Vec3 p = o + t * d;
    if (!s.capped && !kept_by_planes(s, p)) continue;
    const Vec3 grad = s.gradient(p);
    const bool back = glm::dot(grad, d) > 0.0;
    if (back && back_sample_culling) {
      sample.culled = true;
      continue;
    }
    sample.t = t;
    if constexpr (kWantNormal) sample.normal = unit_or(grad, -d);
    sample.back = back;
    sample.culled = false;
    return true;
  }
  return false;
}

// The local box a ray is tested inside: the bounds grown by the cast tolerance.
Aabb cast_box(const ImplicitSurface& s) {
  const double tolerance = 1e-9 * s.scale();
  return Aabb(s.bounds.lo - Vec3(tolerance), s.bounds.hi + Vec3(tolerance));
}

// r² when `s` is a whole sphere about its local origin (no clip planes) inside `box`, so that
// the box cannot cut it and the direct ray-sphere test finds the same samples; else 0.
double whole_sphere_radius2(const ImplicitSurface& s, const Aabb& box) {
  const auto& k = s.coeff;
  if (s.clip_count != 0 || k[0] != 1.0 || k[1] != 1.0 || k[2] != 1.0 || !(k[9] < 0.0)) return 0.0;
  for (int j = 3; j < 9; ++j) {
    if (k[static_cast<size_t>(j)] != 0.0) return 0.0;
  }
  const double r = std::sqrt(-k[9]);
  for (int axis = 0; axis < 3; ++axis) {
    if (!(box.lo[axis] <= -r && box.hi[axis] >= r)) return 0.0;
  }
  return -k[9];
}

}  // namespace

bool cast_surface(const ImplicitSurface& s, const Ray& ray, double tmin, double tmax, bool back_sample_culling,
                  SurfaceSample& sample) {
  return cast_local<true>(s, ray.origin - s.origin, ray.dir, ray.inv_dir, cast_box(s), tmin, tmax,
                          back_sample_culling, sample);
}

bool implicit_surface_of(const Scene& scene, uint32_t i, ImplicitSurface& s) {
  s = ImplicitSurface{};
  s.prim = i;
  const PrimRef& ref = scene.prims[i];
  switch (ref.kind) {
    case PrimKind::Sphere: {
      const Sphere& sphere = scene.spheres[ref.index];
      if (!(sphere.radius > 0.0)) return false;
      s.origin = sphere.center;
      s.coeff = {1, 1, 1, 0, 0, 0, 0, 0, 0, -sphere.radius * sphere.radius};
      s.bounds = Aabb(Vec3(-sphere.radius), Vec3(sphere.radius));
      return true;
    }
    case PrimKind::Cone: {
      // Heights s = a·q along the unit axis a from the base, radius r(s) = r0 + k s:
      // |q|² - (a·q)² - (r0 + k a·q)² = 0, i.e. q'(I - (1 + k²) a a')q - 2 r0 k a·q - r0² = 0.
      const Cone& cone = scene.cones[ref.index];
      const Vec3 along = cone.apex - cone.base;
      const double length = glm::length(along);
      if (!(length > 0.0) || !(std::max(cone.base_radius, cone.apex_radius) > 0.0)) return false;
      const Vec3 ax = along / length;
      const double r0 = cone.base_radius, k = (cone.apex_radius - cone.base_radius) / length;
      const double m = 1.0 + k * k;
      s.origin = cone.base;
      s.coeff = {1.0 - m * ax.x * ax.x,
                 1.0 - m * ax.y * ax.y,
                 1.0 - m * ax.z * ax.z,
                 -2.0 * m * ax.x * ax.y,
                 -2.0 * m * ax.y * ax.z,
                 -2.0 * m * ax.x * ax.z,
                 -2.0 * r0 * k * ax.x,
                 -2.0 * r0 * k * ax.y,
                 -2.0 * r0 * k * ax.z,
                 -r0 * r0};
      s.clip[0] = Vec4(-ax, 0.0);      // s >= 0
      s.clip[1] = Vec4(ax, -length);   // s <= length
      s.clip_count = 2;
      const Aabb world = bounds_of(cone);
      s.bounds = Aabb(world.lo - s.origin, world.hi - s.origin);
      return true;
    }
    case PrimKind::Quadric: {
      // Re-expressed about the centre o of its bounds: p = q + o.
      const Quadric& quadric = scene.quadrics[ref.index];
      const auto& k = quadric.coeff;
      const Vec3 o = quadric.bounds.center();
      s.origin = o;
      s.coeff = k;
      s.coeff[6] = 2.0 * k[0] * o.x + k[3] * o.y + k[5] * o.z + k[6];
      s.coeff[7] = 2.0 * k[1] * o.y + k[3] * o.x + k[4] * o.z + k[7];
      s.coeff[8] = 2.0 * k[2] * o.z + k[4] * o.y + k[5] * o.x + k[8];
      ImplicitSurface world;
      world.coeff = k;
      s.coeff[9] = world.value(o);
      for (int j = 0; j < quadric.clip_count; ++j) {
        const Vec4& plane = quadric.clip[static_cast<size_t>(j)];
        s.clip[static_cast<size_t>(j)] = Vec4(Vec3(plane), plane.w + glm::dot(Vec3(plane), o));
      }
      s.clip_count = quadric.clip_count;
      s.bounds = Aabb(quadric.bounds.lo - o, quadric.bounds.hi - o);
      return true;
    }
    default:
      return false;
  }
}

std::array<double, 2> texture_coordinates(const ImplicitSurface& s, const Vec3& p) {
  const Vec3 q = p - s.origin;
  return {glm::dot(Vec3(s.texgen[0]), q) + s.texgen[0].w, glm::dot(Vec3(s.texgen[1]), q) + s.texgen[1].w};
}

bool BoundingPolyhedron::contains(const Vec3& p, double tolerance) const {
  for (const Vec4& plane : planes) {
    if (glm::dot(Vec3(plane), p) + plane.w > tolerance) return false;
  }
  return true;
}

BoundingPolyhedron bounding_polyhedron(const Scene& scene, uint32_t i, int slices, int stacks) {
  slices = std::max(slices, 3);
  stacks = std::max(stacks, 2);
  BoundingPolyhedron b;
  const PrimRef& ref = scene.prims[i];
  if (ref.kind == PrimKind::Sphere) {
    // gluSphere's layout on the unit sphere, then scaled so the nearest face plane sits at r.
    const double r = scene.spheres[ref.index].radius;
    b.vertices.push_back(Vec3(0, 0, 1));
    for (int k = 1; k < stacks; ++k) {
      const double theta = kPi * k / stacks;
      for (int j = 0; j < slices; ++j) {
        const double phi = 2.0 * kPi * j / slices;
        b.vertices.push_back(Vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)));
      }
    }
    b.vertices.push_back(Vec3(0, 0, -1));
    const uint32_t south = static_cast<uint32_t>(b.vertices.size() - 1);
    auto ring = [&](int k, int j) { return static_cast<uint32_t>(1 + (k - 1) * slices + (j % slices)); };
    for (int j = 0; j < slices; ++j) {
      b.faces.push_back({0, ring(1, j), ring(1, j + 1)});
      b.faces.push_back({south, ring(stacks - 1, j + 1), ring(stacks - 1, j)});
      for (int k = 1; k + 1 < stacks; ++k) {
        b.faces.push_back({ring(k, j), ring(k + 1, j), ring(k + 1, j + 1)});
        b.faces.push_back({ring(k, j), ring(k + 1, j + 1), ring(k, j + 1)});
      }
    }
    finish_polyhedron(b);
    double nearest = kInfinity;
    for (const Vec4& plane : b.planes) nearest = std::min(nearest, -plane.w);
    const double scale = r / nearest * (1.0 + kBoundMargin);
    for (Vec3& v : b.vertices) v *= scale;
    for (Vec4& plane : b.planes) plane.w *= scale;
  } else if (ref.kind == PrimKind::Cone) {
    // A frustum whose side faces touch the cone from outside: at every height the polygon's
    // inscribed radius is the cone's radius (both are linear in the height).
    const Cone& cone = scene.cones[ref.index];
    const Vec3 along = cone.apex - cone.base;
    const double length = glm::length(along);
    const Vec3 ax = along / length;
    Vec3 u, v;
    perpendicular_basis(ax, u, v);
    const double grow = (1.0 + kBoundMargin) / std::cos(kPi / slices);
    const double r0 = cone.base_radius * grow, r1 = cone.apex_radius * grow;
    const double pad = kBoundMargin * std::max({length, cone.base_radius, cone.apex_radius});
    for (int end = 0; end < 2; ++end) {
      const double radius = end == 0 ? r0 : r1;
      const Vec3 centre = end == 0 ? -pad * ax : (length + pad) * ax;
      for (int j = 0; j < slices; ++j) {
        const double phi = 2.0 * kPi * j / slices;
        b.vertices.push_back(centre + radius * (std::cos(phi) * u + std::sin(phi) * v));
      }
    }
    // Sides as two triangles each, the end polygons as fans (a pointed end's fan is degenerate
    // and dropped).
    const uint32_t n = static_cast<uint32_t>(slices), apex_first = n;
    for (uint32_t j = 0; j < n; ++j) {
      const uint32_t j1 = (j + 1) % n;
      b.faces.push_back({j, j1, apex_first + j1});
      b.faces.push_back({j, apex_first + j1, apex_first + j});
      if (j >= 1 && j + 1 < n) {
        b.faces.push_back({0, j1, j});
        b.faces.push_back({apex_first, apex_first + j, apex_first + j1});
      }
    }
    finish_polyhedron(b);
  } else {
    // A quadric: the box of its bounds.
    ImplicitSurface s;
    implicit_surface_of(scene, i, s);
    const double pad = kBoundMargin * s.scale();
    const Aabb box(s.bounds.lo - Vec3(pad), s.bounds.hi + Vec3(pad));
    for (int k = 0; k < 8; ++k) {
      b.vertices.push_back(Vec3(k & 1 ? box.hi.x : box.lo.x, k & 2 ? box.hi.y : box.lo.y, k & 4 ? box.hi.z : box.lo.z));
    }
    const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& q : quads) {
      b.faces.push_back({q[0], q[1], q[2]});
      b.faces.push_back({q[0], q[2], q[3]});
    }
    finish_polyhedron(b);
  }
  return b;
}

std::array<Triangle, 12> box_triangles(const Aabb& box) {
  Vec3 c[8];
  for (int k = 0; k < 8; ++k) c[k] = Vec3(k & 1 ? box.hi.x : box.lo.x, k & 2 ? box.hi.y : box.lo.y, k & 4 ? box.hi.z : box.lo.z);
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  std::array<Triangle, 12> out;
  for (size_t q = 0; q < 6; ++q) {
    const int* v = quads[q];
    out[2 * q] = Triangle{c[v[0]], c[v[1]], c[v[2]]};
    out[2 * q + 1] = Triangle{c[v[0]], c[v[2]], c[v[3]]};
  }
  return out;
}

std::vector<Vec3> near_cap(const BoundingPolyhedron& bound, const Vec3& origin, const View& view, double near) {
  Vec3 centre(0.0);
  for (const Vec3& v : bound.vertices) centre += v;
  centre /= static_cast<double>(std::max<size_t>(bound.vertices.size(), 1));
  double radius = 0.0;
  for (const Vec3& v : bound.vertices) radius = std::max(radius, glm::length(v - centre));
  // A square on the near plane (local coordinates) covering the bound's cross-section.
  const Vec3 eye = view.eye - origin;
  const Vec3 on_plane = centre - (glm::dot(centre - eye, view.forward) - near) * view.forward;
  const double half = 2.0 * radius;
  std::vector<Vec3> poly = {on_plane - half * view.right - half * view.up, on_plane - half * view.right + half * view.up,
                            on_plane + half * view.right + half * view.up, on_plane + half * view.right - half * view.up};
  for (const Vec4& plane : bound.planes) {
    clip_polygon(poly, Vec3(plane), plane.w);
    if (poly.size() < 3) return {};
  }
  // Facing the eye: the normal points back along the view axis.
  if (glm::dot(glm::cross(poly[1] - poly[0], poly[2] - poly[0]), view.forward) > 0.0) std::reverse(poly.begin(), poly.end());
  for (Vec3& v : poly) v += origin;
  return poly;
}

IssueOrder parse_issue_order(const std::string& name, bool& ok) {
  ok = true;
  if (name == "input") return IssueOrder::kInput;
  if (name == "random" || name == "unordered") return IssueOrder::kRandom;
  if (name == "front-to-back") return IssueOrder::kFrontToBack;
  if (name == "nearest-first") return IssueOrder::kNearestFirst;
  ok = false;
  return IssueOrder::kInput;
}

const char* issue_order_name(IssueOrder order) {
  switch (order) {
    case IssueOrder::kRandom:
      return "random";
    case IssueOrder::kFrontToBack:
      return "front-to-back";
    case IssueOrder::kNearestFirst:
      return "nearest-first";
    default:
      return "input";
  }
}

nlohmann::json ImrCounters::to_json() const {
  return {{"objects", objects},
          {"polygons", polygons},
          {"triangles_issued", triangles_issued},
          {"bound_back_faces", bound_back_faces},
          {"near_caps", near_caps},
          {"pixels_covered", pixels_covered},
          {"ray_object_tests", ray_object_tests},
          {"ray_object_hits", ray_object_hits},
          {"surface_writes", surface_writes},
          {"back_samples_culled", back_samples_culled},
          {"immediate_lighting", immediate_lighting},
          {"lit_pixels", lit_pixels},
          {"shading_ops", shading_ops},
          {"texture_fetches", texture_fetches},
          {"nodes_visited", nodes_visited},
          {"order_ms", order_ms},
          {"raster_ms", raster_ms},
          {"shade_ms", shade_ms},
          {"ms", ms}};
}

// The per-fragment ray cast. It works along the pixel's unnormalised direction D =
// view.direction(x, y), whose component along the view axis is 1: the sample eye + w D is at
// view depth w, so the ray parameter is w itself, the near plane is w >= near and the result is
// 1/w, with no normalisation and no square root but the sphere's. local() gathers what every
// fragment of a surface shares (the eye in its local frame, its tolerance box, and for a whole
// sphere the direct test's constants).
SurfaceCaster::Local SurfaceCaster::local(const ImplicitSurface& s) const {
  Local f;
  f.eye = view_.eye - s.origin;
  f.box = cast_box(s);
  f.radius2 = whole_sphere_radius2(s, f.box);
  f.eye_c = glm::dot(f.eye, f.eye) - f.radius2;
  return f;
}

void SurfaceCaster::begin_frame(const View& view, double near, bool back_sample_culling) {
  view_ = view;
  near_ = near;
  back_sample_culling_ = back_sample_culling;
  for (size_t i = 0; i < surfaces_.size(); ++i) frame_[i] = local(surfaces_[i]);
}

void SurfaceCaster::set(uint32_t id, const ImplicitSurface& surface) {
  if (slot_.size() <= id) slot_.resize(size_t(id) + 1, -1);
  if (slot_[id] < 0) {
    slot_[id] = static_cast<int32_t>(surfaces_.size());
    surfaces_.push_back(surface);
    frame_.push_back(local(surface));
    return;
  }
  const auto slot = static_cast<size_t>(slot_[id]);
  surfaces_[slot] = surface;
  frame_[slot] = local(surface);
}

void SurfaceCaster::clear() {
  slot_.clear();
  surfaces_.clear();
  frame_.clear();
}

const ImplicitSurface* SurfaceCaster::surface(uint32_t id) const {
  return id < slot_.size() && slot_[id] >= 0 ? &surfaces_[static_cast<size_t>(slot_[id])] : nullptr;
}

namespace {

// A whole sphere's samples eye + w D, w >= near: a w² + 2 h w + c = 0 with a = D·D,
// h = eye·D, c = |eye|² - r², solved as intersect_sphere does, the quarter discriminant
// h² - a c = a r² - |eye × D|² taken from the centre's offset from the ray's line (Lagrange's
// identity; no cancellation between two large squares at grazing angles). Sets 1/w.
SurfaceHit cast_sphere(const Vec3& eye, double radius2, double eye_c, const Vec3& direction, double near, bool culling,
                       double& inv_w) {
  const double a = glm::dot(direction, direction);
  const double h = glm::dot(eye, direction);
  const Vec3 offset = glm::cross(eye, direction);
  const double disc = a * radius2 - glm::dot(offset, offset);
  if (!(disc >= 0.0)) return SurfaceHit::Miss;
  // The roots are c / q and q / a with q = -(h + sign(h) sqrt(disc)) (no cancellation); for
  // q > 0 the first is the nearer. Each sample's 1/w is the other ratio inverted (q / c,
  // a / q), so it need not wait for the root's division.
  const double q = -(h + std::copysign(std::sqrt(disc), h));
  if (q == 0.0) return SurfaceHit::Miss;  // a double root at w = 0, before the near plane
  const double via_c = eye_c / q, via_a = q / a;
  const bool c_first = q > 0.0;
  bool culled = false;
  for (int k = 0; k < 2; ++k) {
    const bool use_c = c_first == (k == 0);
    const double root = use_c ? via_c : via_a;
    if (!(root >= near)) continue;
    // Leaving the solid (the gradient 2p faces along the ray): a back sample.
    if (culling && h + root * a > 0.0) {
      culled = true;
      continue;
    }
    inv_w = use_c ? q / eye_c : a / q;
    return SurfaceHit::Hit;
  }
  return culled ? SurfaceHit::BackCulled : SurfaceHit::Miss;
}

}  // namespace

SurfaceHit SurfaceCaster::cast(uint32_t id, int x, int y, double& inv_w) const {
  const auto slot = static_cast<size_t>(slot_[id]);
  const Local& f = frame_[slot];
  const Vec3 direction = view_.direction(x, y);
  if (f.radius2 > 0.0) return cast_sphere(f.eye, f.radius2, f.eye_c, direction, near_, back_sample_culling_, inv_w);
  SurfaceSample sample;
  if (!cast_local<false>(surfaces_[slot], f.eye, direction, 1.0 / direction, f.box, near_, kInfinity,
                         back_sample_culling_, sample)) {
    return sample.culled ? SurfaceHit::BackCulled : SurfaceHit::Miss;
  }
  inv_w = 1.0 / sample.t;
  return SurfaceHit::Hit;
}

CurvedBound curved_bound(const Scene& scene, uint32_t i, const ImplicitSurface& surface, int slices, int stacks) {
  CurvedBound b;
  b.polyhedron = bounding_polyhedron(scene, i, slices, stacks);
  b.origin = surface.origin;
  Vec3 centre(0.0);
  for (const Vec3& v : b.polyhedron.vertices) centre += v;
  centre /= static_cast<double>(std::max<size_t>(b.polyhedron.vertices.size(), 1));
  for (const Vec3& v : b.polyhedron.vertices) b.radius = std::max(b.radius, glm::length(v - centre));
  b.centre = centre + surface.origin;
  return b;
}

double surface_near(const View& view, const Aabb& scene_bounds) {
  return view.near > 0.0 ? view.near : 1e-7 * std::max(scene_bounds.magnitude(), 1e-300);
}

void issue_curved(Rasterizer& raster, const CurvedBound& bound, const View& view, double near, uint32_t id,
                  BoundIssueCounters& counters) {
  const BoundingPolyhedron& b = bound.polyhedron;
  // Back faces of the (closed, convex) bound are culled here, so the rasterizer's own culling
  // option stays the polygons' (open polygons are seen from both sides, as by ray casting).
  const Vec3 eye = view.eye - bound.origin;
  for (size_t k = 0; k < b.faces.size(); ++k) {
    const auto& f = b.faces[k];
    ++counters.triangles;
    if (glm::dot(Vec3(b.planes[k]), eye) + b.planes[k].w <= 0.0) {
      ++counters.back_faces;
      continue;
    }
    raster.submit_bound(
        Triangle{b.vertices[f[0]] + bound.origin, b.vertices[f[1]] + bound.origin, b.vertices[f[2]] + bound.origin}, id);
  }
  // §3.2: where the near plane cuts the bound, its front faces are clipped away; a cap on the
  // (slightly farther, so the rasterizer keeps it) near plane still casts those rays.
  const double distance = glm::dot(bound.centre - view.eye, view.forward);
  const double cap_plane = near * (1.0 + 1e-7);
  if (std::abs(distance - cap_plane) <= bound.radius) {
    const std::vector<Vec3> cap = near_cap(b, bound.origin, view, cap_plane);
    if (!cap.empty()) {
      ++counters.near_caps;
      for (size_t k = 1; k + 1 < cap.size(); ++k) raster.submit_bound(Triangle{cap[0], cap[k], cap[k + 1]}, id);
      counters.triangles += cap.size() - 2;
    }
  }
}

Vec3 surface_normal(const ImplicitSurface& s, const Vec3& p, const Vec3& fallback) {
  const Vec3 q = p - s.origin;
  Vec3 normal = unit_or(s.gradient(q), fallback);
  if (s.capped) {
    // On a clip plane (within rounding): the cap's normal.
    for (int j = 0; j < s.clip_count; ++j) {
      const Vec4& plane = s.clip[static_cast<size_t>(j)];
      if (std::abs(glm::dot(Vec3(plane), q) + plane.w) <= 1e-9 * s.scale() &&
          std::abs(s.value(q)) > 1e-9 * glm::length(s.gradient(q)) * s.scale()) {
        normal = Vec3(plane);
      }
    }
  }
  return normal;
}

ImrRenderer::ImrRenderer(const Scene& scene, const ImrOptions& options)
    : scene_(scene),
      options_(options),
      tree_(KdTree::build(scene)),
      arena_(options.threads > 0 ? options.threads : tbb::info::default_concurrency()) {
  if (options_.stacks <= 0) options_.stacks = std::max(2, options_.slices / 2);
  shader_ = std::make_unique<Shader>(scene_, tree_);
  bound_index_.assign(scene.size(), -1);
  for (uint32_t i = 0; i < scene.size(); ++i) {
    ImplicitSurface s;
    if (!implicit_surface_of(scene, i, s)) continue;
    bound_index_[i] = static_cast<int32_t>(bounds_.size());
    bounds_.push_back(curved_bound(scene, i, s, options_.slices, options_.stacks));
    bound_triangles_ += bounds_.back().polyhedron.triangles();
    caster_.set(i, s);
  }
}

ImrRenderer::~ImrRenderer() = default;

namespace {

// A lower bound of the distance from `eye` to primitive i: exact for spheres (their boxes'
// corners stick out by up to 0.73 radius, which reorders overlapping spheres badly), the
// distance to the bounds otherwise.
double nearest_distance(const Scene& scene, uint32_t i, const Vec3& eye) {
  const PrimRef& ref = scene.prims[i];
  if (ref.kind == PrimKind::Sphere) {
    const Sphere& s = scene.spheres[ref.index];
    return std::max(glm::length(s.center - eye) - s.radius, 0.0);
  }
  const Aabb b = scene.prim_bounds(i);
  return glm::length(glm::clamp(eye, b.lo, b.hi) - eye);
}

}  // namespace

std::vector<uint32_t> issue_order(const Scene& scene, const KdTree& tree, const Vec3& eye, IssueOrder kind,
                                  uint64_t seed, uint64_t* nodes_visited) {
  std::vector<uint32_t> order;
  order.reserve(scene.size());
  std::vector<std::pair<double, uint32_t>> nearest;
  if (kind == IssueOrder::kNearestFirst) {
    for (uint32_t i = 0; i < scene.size(); ++i) nearest.emplace_back(nearest_distance(scene, i, eye), i);
    std::sort(nearest.begin(), nearest.end());
    for (const auto& [distance, i] : nearest) order.push_back(i);
    return order;
  }
  if (kind != IssueOrder::kFrontToBack) {
    order.resize(scene.size());
    std::iota(order.begin(), order.end(), 0u);
    if (kind == IssueOrder::kRandom) std::shuffle(order.begin(), order.end(), std::mt19937_64(seed));
    return order;
  }
  std::vector<uint8_t> issued(scene.size(), 0);
  std::vector<uint32_t> stack = {0};
  const auto& nodes = tree.nodes();
  uint64_t visited = 0;
  while (!stack.empty() && !nodes.empty()) {
    const uint32_t index = stack.back();
    const KdTree::Node& node = nodes[index];
    stack.pop_back();
    ++visited;
    if (node.is_leaf()) {
      // The cell's new primitives nearest first (by the distance from the eye to their
      // bounds): a cell can hold many overlapping objects, in any input order.
      const KdTree::Cell& cell = tree.cell(static_cast<int32_t>(node.child));
      const size_t first_new = order.size();
      for (uint32_t r = cell.first; r < cell.first + cell.count; ++r) {
        const uint32_t prim = tree.ref(r);
        if (!issued[prim]) {
          issued[prim] = 1;
          order.push_back(prim);
        }
      }
      nearest.clear();
      for (size_t k = first_new; k < order.size(); ++k) {
        nearest.emplace_back(nearest_distance(scene, order[k], eye), order[k]);
      }
      std::sort(nearest.begin(), nearest.end());
      for (size_t k = first_new; k < order.size(); ++k) order[k] = nearest[k - first_new].second;
      continue;
    }
    const bool eye_below = eye[static_cast<int>(node.axis_or_leaf)] < node.split;
    const uint32_t lower = index + 1, upper = node.child;
    stack.push_back(eye_below ? upper : lower);
    stack.push_back(eye_below ? lower : upper);
  }
  for (uint32_t i = 0; i < scene.size(); ++i) {
    if (!issued[i]) order.push_back(i);
  }
  if (nodes_visited != nullptr) *nodes_visited += visited;
  return order;
}

void ImrRenderer::issue(uint32_t prim, const View& view, double near, ImrCounters& counters) {
  const PrimRef& ref = scene_.prims[prim];
  if (ref.kind == PrimKind::Triangle) {
    raster_->submit(scene_.triangles[ref.index], prim);
    ++counters.polygons;
    ++counters.triangles_issued;
    return;
  }
  if (ref.kind == PrimKind::Box) {
    for (const Triangle& t : box_triangles(scene_.boxes[ref.index].bounds)) raster_->submit(t, prim);
    counters.polygons += 12;
    counters.triangles_issued += 12;
    return;
  }
  const int32_t bi = bound_index_[prim];
  if (bi < 0) return;  // a degenerate sphere or cone: nothing to see
  ++counters.objects;
  BoundIssueCounters issued;
  issue_curved(*raster_, bounds_[static_cast<size_t>(bi)], view, near, prim, issued);
  counters.triangles_issued += issued.triangles;
  counters.bound_back_faces += issued.back_faces;
  counters.near_caps += issued.near_caps;
}

ImrCounters ImrRenderer::render(const View& view) {
  const auto start = std::chrono::steady_clock::now();
  ImrCounters counters;
  const double near = surface_near(view, scene_.bounds());
  RasterOptions raster_options;
  raster_options.threads = options_.threads;
  raster_options.cull_back_faces = options_.cull_back_faces;
  raster_options.near_floor = near;
  if (!raster_ || !raster_->matches(view, raster_options)) raster_ = std::make_unique<Rasterizer>(view, raster_options);
  raster_->clear();
  raster_->reset_counters();
  raster_->set_surface_program(&caster_);
  caster_.begin_frame(view, near, options_.back_sample_culling);

  auto t = std::chrono::steady_clock::now();
  const std::vector<uint32_t> order = issue_order(scene_, tree_, view.eye, options_.order, options_.seed, &counters.nodes_visited);
  counters.order_ms = ms_since(t);
  t = std::chrono::steady_clock::now();
  for (uint32_t prim : order) issue(prim, view, near, counters);
  raster_->flush();
  counters.raster_ms = ms_since(t);
  const RasterCounters& rc = raster_->counters();
  counters.pixels_covered = rc.fragments;
  counters.ray_object_tests = rc.surface_rays;
  counters.ray_object_hits = rc.surface_hits;
  counters.surface_writes = rc.surface_writes;
  counters.back_samples_culled = rc.back_samples_culled;
  counters.immediate_lighting = rc.depth_passes;  // every fragment written, lit as it is written

  t = std::chrono::steady_clock::now();
  shade(view, counters);
  counters.shade_ms = ms_since(t);
  counters.ms = ms_since(start);
  return counters;
}

// One visible sample's colour: the shader's, except on surfaces the scene format cannot describe
// (caps on a clip plane take the plane's normal; textured surfaces a checkerboard).
Rgb ImrRenderer::shade_sample(uint32_t prim, const Ray& ray, double depth, Counters& shading,
                              uint64_t& fetches) const {
  const ImplicitSurface* s = surface_of_prim(prim);
  if (s == nullptr || (!s->capped && !s->textured)) return shader_->shade(prim, ray, depth, options_.shadows, shading);
  const Vec3 p = ray.at(depth);
  const Vec3 normal = surface_normal(*s, p, -ray.dir);
  Rgb c = shader_->shade_surface(scene_.prims[prim].material, normal, ray, depth, shading);
  if (s->textured) {
    const auto uv = texture_coordinates(*s, p);
    ++fetches;
    const bool odd = (static_cast<int64_t>(std::floor(uv[0])) + static_cast<int64_t>(std::floor(uv[1]))) & 1;
    if (odd) c = Rgb{c.r * 0.5f, c.g * 0.5f, c.b * 0.5f};
  }
  return c;
}

// Deferred lighting of the visible samples, with the surfaces' analytic normals.
void ImrRenderer::shade(const View& view, ImrCounters& counters) {
  const std::vector<uint32_t>& ids = raster_->ids();
  const Rasterizer& raster = *raster_;  // flushed by ids()
  std::vector<Rgb> colors(view.pixels(), shader_->background());
  struct Local {
    Counters shading;
    uint64_t lit = 0, fetches = 0;
  };
  tbb::enumerable_thread_specific<Local> local;
  for_each_covered_pixel(arena_, view, ids, local, [&](Local& l, int x, int y, size_t i) {
    ++l.lit;
    colors[i] = shade_sample(ids[i], view.ray(x, y), raster.depth_at(x, y), l.shading, l.fetches);
  });
  for (const Local& l : local) {
    counters.lit_pixels += l.lit;
    counters.texture_fetches += l.fetches;
    counters.shading_ops += l.shading.shading_ops;
  }
  raster_->set_colors(std::move(colors));
}

void add_issue_stats(nlohmann::json& stats, const char* method, IssueOrder order, const View& view,
                     size_t primitives) {
  stats["method"] = method;
  stats["order"] = issue_order_name(order);
  stats["width"] = view.width;
  stats["height"] = view.height;
  stats["primitives"] = primitives;
}

Result<Frame> ImrFrameRenderer::render(const View& view) {
  const ImrCounters counters = imr_.render(view);
  Frame frame;
  frame.colors = imr_.rasterizer().colors();
  frame.ids = source_ids(scene_, imr_.rasterizer().ids());
  frame.ms = counters.ms;
  frame.stats = counters.to_json();
  frame.stats["bound_triangles"] = imr_.bound_triangles();
  add_issue_stats(frame.stats, "imr", imr_.options().order, view, scene_.size());
  return frame;
}

}  // namespace frontier
