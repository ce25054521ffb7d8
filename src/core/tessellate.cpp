// Tessellation of spheres, cones, boxes (and quadrics as boxes); see tessellate.h for the meshes.
// Vertices are computed from (index mod segments), so the seam and the poles are bit-identical
// wherever triangles meet: a ray can never slip through a crack of a closed mesh, given a
// watertight triangle test.
#include "src/core/tessellate.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>

namespace frontier {

namespace {

using Normals = std::array<Vec3, 3>;

// Segments so that the sagitta r (1 - cos(pi / n)) <= max_error.
int segments_for_error(double radius, double max_error, const TessellateOptions& options) {
  const int lo = std::max(3, options.min_segments);
  const int hi = std::max(lo, options.max_segments);
  if (!(radius > max_error)) return lo;
  const double n = std::numbers::pi / std::acos(1.0 - max_error / radius);
  if (!(n < hi)) return hi;
  return std::max(lo, int(std::ceil(n)));
}

// Two unit vectors perpendicular to unit `axis` and to each other, with u x v = axis.
void basis_for(const Vec3& axis, Vec3& u, Vec3& v) {
  const Vec3 helper = std::abs(axis.x) < 0.9 ? Vec3(1, 0, 0) : Vec3(0, 1, 0);
  u = glm::normalize(glm::cross(axis, helper));
  v = glm::cross(axis, u);
}

// Appends triangles (and normals) for one primitive; `normals` may be null.
class Emitter {
 public:
  Emitter(std::vector<Triangle>& out, std::vector<Normals>* normals) : out_(out), normals_(normals) {}

  void add(const Vec3& a, const Vec3& b, const Vec3& c, const Normals& n) {
    out_.push_back({a, b, c});
    if (normals_ != nullptr) normals_->push_back(n);
  }
  void add_flat(const Vec3& a, const Vec3& b, const Vec3& c) {
    const Triangle t{a, b, c};
    const Vec3 n = normal_of(t, a);
    add(a, b, c, {n, n, n});
  }

 private:
  std::vector<Triangle>& out_;
  std::vector<Normals>* normals_;
};

// Faces wound counter-clockwise seen from outside; corner k has x from bit 0, y bit 1, z bit 2.
void emit_box(Emitter& emit, const Aabb& b) {
  Vec3 c[8];
  for (int i = 0; i < 8; ++i) {
    c[i] = Vec3(i & 1 ? b.hi.x : b.lo.x, i & 2 ? b.hi.y : b.lo.y, i & 4 ? b.hi.z : b.lo.z);
  }
  static constexpr int kFaces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                       {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  for (const auto& f : kFaces) {
    emit.add_flat(c[f[0]], c[f[1]], c[f[2]]);
    emit.add_flat(c[f[0]], c[f[2]], c[f[3]]);
  }
}

void emit_sphere(Emitter& emit, const Sphere& s, const TessellateOptions& options) {
  if (!(s.radius > 0.0)) return;
  // Quads of a latitude/longitude mesh bulge along two curves: half the error for each.
  const int lon = options.max_chord_error > 0.0
                      ? segments_for_error(s.radius, 0.5 * options.max_chord_error, options)
                      : tessellation_segments(s.radius, options);
  const int lat = std::max(3, (lon + 1) / 2);  // latitude steps no longer than longitude ones
  // Unit direction of vertex (i, j): j = 0 the south pole, j = lat the north pole.
  auto dir = [&](int i, int j) {
    if (j == 0) return Vec3(0, 0, -1);
    if (j == lat) return Vec3(0, 0, 1);
    const double theta = std::numbers::pi * j / lat - std::numbers::pi / 2;
    const double phi = 2.0 * std::numbers::pi * (i % lon) / lon;
    return Vec3(std::cos(theta) * std::cos(phi), std::cos(theta) * std::sin(phi), std::sin(theta));
  };
  for (int j = 0; j < lat; ++j) {
    for (int i = 0; i < lon; ++i) {
      const Vec3 a = dir(i, j), b = dir(i + 1, j), c = dir(i + 1, j + 1), d = dir(i, j + 1);
      const Vec3 pa = s.center + s.radius * a, pb = s.center + s.radius * b;
      const Vec3 pc = s.center + s.radius * c, pd = s.center + s.radius * d;
      if (j != 0) emit.add(pa, pb, pc, {a, b, c});        // the south cap's a == b
      if (j != lat - 1) emit.add(pa, pc, pd, {a, c, d});  // the north cap's c == d
    }
  }
}

void emit_cone(Emitter& emit, const Cone& cone, const TessellateOptions& options) {
  const Vec3 axis = cone.apex - cone.base;
  const double len = glm::length(axis);
  if (!(len > 0.0) || !(std::max(cone.base_radius, cone.apex_radius) > 0.0)) return;
  const Vec3 w = axis / len;
  Vec3 u, v;
  basis_for(w, u, v);
  const int n = tessellation_segments(std::max(cone.base_radius, cone.apex_radius), options);
  auto radial = [&](double i) {
    const double phi = 2.0 * std::numbers::pi * i / n;
    return std::cos(phi) * u + std::sin(phi) * v;
  };
  // The side's outward normal at angle phi: perpendicular to the slant len w + (ra - rb) radial.
  auto normal = [&](const Vec3& r) {
    return glm::normalize(len * r + (cone.base_radius - cone.apex_radius) * w);
  };
  for (int i = 0; i < n; ++i) {
    const Vec3 r0 = radial(i % n), r1 = radial((i + 1) % n);
    const Vec3 n0 = normal(r0), n1 = normal(r1), mid = normal(radial(i + 0.5));
    const Vec3 b0 = cone.base + cone.base_radius * r0, b1 = cone.base + cone.base_radius * r1;
    const Vec3 a0 = cone.apex + cone.apex_radius * r0, a1 = cone.apex + cone.apex_radius * r1;
    // A pointed end gets one triangle per segment; its tip's normal is the segment's middle one.
    if (cone.base_radius > 0.0) emit.add(b0, b1, a1, {n0, n1, cone.apex_radius > 0.0 ? n1 : mid});
    if (cone.apex_radius > 0.0) emit.add(b0, a1, a0, {cone.base_radius > 0.0 ? n0 : mid, n1, n0});
  }
}

bool zero_area(const Triangle& t) {
  const Vec3 n = glm::cross(t.v1 - t.v0, t.v2 - t.v0);
  return n.x == 0.0 && n.y == 0.0 && n.z == 0.0;
}

}  // namespace

int tessellation_segments(double radius, const TessellateOptions& options) {
  if (options.max_chord_error > 0.0) return segments_for_error(radius, options.max_chord_error, options);
  return std::max(3, options.segments);
}

void tessellate_primitive(std::vector<Triangle>& out, std::vector<Normals>* normals, const Scene& scene,
                          uint32_t i, const TessellateOptions& options) {
  assert(i < scene.size());
  Emitter emit(out, normals);
  const PrimRef& ref = scene.prims[i];
  switch (ref.kind) {
    case PrimKind::Triangle: {
      const Triangle& t = scene.triangles[ref.index];
      if (scene.triangle_normals.empty()) {
        emit.add_flat(t.v0, t.v1, t.v2);
      } else {
        emit.add(t.v0, t.v1, t.v2, scene.triangle_normals[ref.index]);
      }
      break;
    }
    case PrimKind::Sphere: emit_sphere(emit, scene.spheres[ref.index], options); break;
    case PrimKind::Box: emit_box(emit, scene.boxes[ref.index].bounds); break;
    case PrimKind::Cone: emit_cone(emit, scene.cones[ref.index], options); break;
    case PrimKind::Quadric: emit_box(emit, scene.quadrics[ref.index].bounds); break;
  }
}

Scene tessellate(const Scene& scene, const TessellateOptions& options, TessellateStats* stats) {
  Scene out = scene.without_primitives();
  out.degenerate_dropped = scene.degenerate_dropped;
  TessellateStats local;
  // Curved primitives need their vertex normals for smooth shading; a scene of only flat
  // primitives keeps none (as if loaded), unless its triangles already had some.
  bool any_curved = false;
  for (const PrimRef& ref : scene.prims) any_curved |= ref.kind == PrimKind::Sphere || ref.kind == PrimKind::Cone;
  const bool keep_normals = !scene.triangle_normals.empty() || (options.smooth_normals && any_curved);
  std::vector<Triangle> tris;
  std::vector<Normals> normals;
  for (uint32_t i = 0; i < scene.size(); ++i) {
    const PrimRef& ref = scene.prims[i];
    if (ref.kind == PrimKind::Triangle) ++local.triangles_in;
    if (ref.kind == PrimKind::Quadric) ++local.quadrics_as_boxes;
    tris.clear();
    normals.clear();
    tessellate_primitive(tris, &normals, scene, i, options);
    const bool smooth = keep_normals && (options.smooth_normals || ref.kind == PrimKind::Triangle);
    for (size_t k = 0; k < tris.size(); ++k) {
      if (zero_area(tris[k])) {
        ++local.degenerate_dropped;
        continue;
      }
      if (keep_normals && !smooth) {
        const Vec3 n = normal_of(tris[k], tris[k].v0);
        normals[k] = {n, n, n};
      }
      out.add_triangle(tris[k], ref.source, ref.material, keep_normals ? &normals[k] : nullptr);
    }
  }
  local.triangles_out = out.triangles.size();
  out.degenerate_dropped += local.degenerate_dropped;
  if (stats != nullptr) *stats = local;
  return out;
}

}  // namespace frontier
