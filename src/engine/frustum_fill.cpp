// Frustum casting, fills: resolving a whole frustum at once when its corner rays agree about
// what they see. The plane fill (fill_plane) takes every pixel's distance from a triangle's
// plane when the corners hit its interior inside the cell; the §4 fill (corners_and_fill,
// try_fill) tests every pixel against the one element all four corners hit; a frustum that
// sees nothing at all is background (fill_background).
//
// Invariants: a fill either resolves every open pixel of its frustum exactly or writes nothing
// and returns false (or, in try_fill, walks the pixels its element misses). Exactness rests on
// convexity: the frustum's section with a plane is the hull of its corner points, and every
// element that could come nearer than the filled surface (at most kMaxFillOccluders of them)
// is tested per pixel.
#include "src/engine/frustum.h"

#include "src/engine/frustum_internal.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace frontier {

using namespace frustum_detail;

// Frusta of at least this many pixels try the plane fill (fill_plane).
constexpr int kPlaneFillMinPixels = 16;
// Triangles covering the frustum whose corners it tests (a quad's two halves both cover it).
constexpr uint32_t kPlaneFillCandidates = 3;

// Every open pixel of the frustum is background: nothing is left for its rays to hit (they
// miss or leave the root, or look-ahead found nothing ahead).
void FrustumCaster::fill_background(const Job& job, Worker& w) {
  const Rgb bg = shader_.background();
  const size_t W = static_cast<size_t>(view_.width);
  uint64_t n = 0;
  for (int y = job.y0; y <= job.y1; ++y) {
    const size_t row = static_cast<size_t>(y) * W;
    for (int x = job.x0; x <= job.x1; ++x) {
      const size_t i = row + static_cast<size_t>(x);
      if (!claim(job, x, y, i)) continue;
      buffer_->set_background(i, bg);
      ++n;
    }
  }
  w.counters.samples += n;
  w.counters.rays += n;
}

// Corner rays against the impinging elements (a corner hit inside this cell is final), then
// the §4 fill when all four corners see the same element. True if the frustum is resolved.
bool FrustumCaster::corners_and_fill(const Job& job, const Incidence* list, uint32_t n,
                                     const std::array<Ray, 4>& rays, const std::array<double, 4>& tmins,
                                     Worker& w) {
  const int W = view_.width;
  const std::array<std::array<int, 2>, 4> corner = {{{job.x0, job.y0}, {job.x1, job.y0},
                                                     {job.x0, job.y1}, {job.x1, job.y1}}};
  std::array<RayHit, 4> hits;
  for (size_t k = 0; k < 4; ++k) {
    const int x = corner[k][0], y = corner[k][1];
    const size_t i = static_cast<size_t>(y) * static_cast<size_t>(W) + static_cast<size_t>(x);
    const KdTree::Exit e = tree_.exit(job.cell, rays[k]);
    const double tmax = e.t + cell_slack(e.t, slack_scale_);
    RayHit best;
    for (uint32_t j = 0; j < n; ++j) {
      const uint32_t prim = tree_.ref(list[j].ref);
      offer(prim, rays[k], tmins[k], tmax, best, w.counters);
    }
    hits[k] = best;
    if (best.hit() && !buffer_->confirmed(i)) confirm(job, x, y, best.prim, best.t, rays[k], w);
  }
  const bool same = hits[0].hit() && std::all_of(hits.begin(), hits.end(), [&](const RayHit& h) {
                      return h.prim == hits[0].prim;
                    });
  if (!same) return false;
  // Quick rejection before the per-pixel pass: too many elements come nearer than the corners.
  double corner_t = 0.0;
  for (const RayHit& h : hits) corner_t = std::max(corner_t, h.t);
  uint32_t near_elements = 0;
  for (uint32_t j = 0; j < n; ++j) {
    if (tree_.ref(list[j].ref) != hits[0].prim &&
        distance_to_box(view_.eye, tree_.ref_bounds(list[j].ref)) <= corner_t) {
      if (++near_elements > kMaxFillOccluders) return false;
    }
  }
  if (!try_fill(job, list, n, hits[0].prim, w)) return false;
  ++w.counters.frustum_fills;
  return true;
}

// The §4 fill for a triangle that covers the whole frustum inside this cell, without a ray
// per pixel. When the four corner rays hit the triangle's interior at points inside the cell,
// every interior ray does too: the frustum's section with the triangle's plane is the convex
// hull of the corner points, and the triangle and the cell are convex. Each pixel's distance
// then follows from its direction alone (t = n·(v0 - eye) |D| / n·D), and only elements that
// could come nearer than the farthest corner (distance along rays to a plane is convex over
// the section, so the corners bound it) are tested per pixel. Returns false, having written
// nothing, when no triangle qualifies or too many elements could occlude it.
bool FrustumCaster::fill_plane(const Job& job, const Incidence* list, uint32_t n, const std::array<Ray, 4>& rays,
                               const std::array<double, 4>& tmins, const Aabb* cell, Worker& w) {
  Vec3 normal;
  double max_t = 0.0;
  const uint32_t candidate = plane_candidate(job, list, n, rays, tmins, cell, normal, max_t, w);
  if (candidate == n) return false;
  const uint32_t element = tree_.ref(list[candidate].ref);
  w.occluders.clear();
  if (!add_list_occluders(job, list, n, element, normal, max_t, w)) return false;
  fill_from_plane(job, element, normal, w);
  ++w.counters.frustum_fills;
  return true;
}

// The index in `list` of a triangle covering the frustum whose interior the four corner rays
// hit (inside `cell` when given), with its normal and the farthest corner hit; n when none of
// the first kPlaneFillCandidates triangles does, or the frustum is too small to fill.
uint32_t FrustumCaster::plane_candidate(const Job& job, const Incidence* list, uint32_t n,
                                        const std::array<Ray, 4>& rays, const std::array<double, 4>& tmins,
                                        const Aabb* cell, Vec3& normal, double& max_t, Worker& w) const {
  const int nx = job.x1 - job.x0 + 1, ny = job.y1 - job.y0 + 1;
  if (nx * ny < kPlaneFillMinPixels) return n;
  uint32_t tried = 0;
  for (uint32_t j = 0; j < n && tried < kPlaneFillCandidates; ++j) {
    const Incidence& e = list[j];
    if (e.x0 > job.x0 || e.x1 < job.x1 || e.y0 > job.y0 || e.y1 < job.y1) continue;
    const PrimRef& ref = scene_.prims[tree_.ref(e.ref)];
    if (ref.kind != PrimKind::Triangle) continue;
    ++tried;
    if (corners_on_triangle(scene_.triangles[ref.index], rays, tmins, cell, normal, max_t, w)) return j;
  }
  return n;
}

// Adds to w.occluders the elements of `list` that could come before the plane of `element`
// inside the frustum: nearer than the farthest corner hit `max_t` (distance along rays to a
// plane is convex over the section, so the corners bound it), overlapping the frustum, not in
// the plane. False when that makes more than kMaxFillOccluders.
bool FrustumCaster::add_list_occluders(const Job& job, const Incidence* list, uint32_t n, uint32_t element,
                                       const Vec3& normal, double max_t, Worker& w) const {
  for (uint32_t j = 0; j < n; ++j) {
    const Incidence& e = list[j];
    if (double(e.distance) > max_t) break;  // sorted nearest first
    const uint32_t prim = tree_.ref(e.ref);
    if (prim == element || e.x1 < job.x0 || e.x0 > job.x1 || e.y1 < job.y0 || e.y0 > job.y1) continue;
    if (coplanar(prim, element, normal)) continue;
    if (std::find(w.occluders.begin(), w.occluders.end(), prim) != w.occluders.end()) continue;
    w.occluders.push_back(prim);
    if (w.occluders.size() > kMaxFillOccluders) return false;
  }
  return true;
}

// Whether `prim` is a triangle in the plane of triangle `element` (normal `normal`): the other
// half of a quad, a neighbouring floor tile. It cannot come before the plane (a hit on it is at
// the plane's distance, a tie), so a plane fill need not test it per pixel.
bool FrustumCaster::coplanar(uint32_t prim, uint32_t element, const Vec3& normal) const {
  const PrimRef& ref = scene_.prims[prim];
  if (ref.kind != PrimKind::Triangle) return false;
  const Triangle& other = scene_.triangles[ref.index];
  const Vec3& origin = scene_.triangles[scene_.prims[element].index].v0;
  const double n_length = glm::length(normal);
  for (const Vec3& v : {other.v0, other.v1, other.v2}) {
    const Vec3 d = v - origin;
    if (!(std::abs(glm::dot(normal, d)) <= 1e-12 * n_length * (glm::length(d) + glm::length(origin)))) return false;
  }
  return true;
}

// Whether the four corner rays hit `tri` strictly inside (a barycentric margin, so interior
// rays never graze an edge) and, given `cell`, at points inside it. Gives the triangle's
// normal and the farthest corner hit.
bool FrustumCaster::corners_on_triangle(const Triangle& tri, const std::array<Ray, 4>& rays,
                                        const std::array<double, 4>& tmins, const Aabb* cell, Vec3& normal,
                                        double& max_t, Worker& w) const {
  normal = glm::cross(tri.v1 - tri.v0, tri.v2 - tri.v0);
  const double area2 = glm::dot(normal, normal);
  if (!(area2 > 0.0)) return false;
  const double inset = cell ? 1e-12 * (cell->magnitude() + glm::length(cell->extent())) : 0.0;
  max_t = 0.0;
  for (size_t k = 0; k < 4; ++k) {
    double t;
    ++w.counters.ray_primitive_tests;
    if (!intersect_triangle(tri, rays[k], tmins[k], kInfinity, t)) return false;
    ++w.counters.hits;
    const Vec3 p = rays[k].at(t);
    for (int a = 0; a < 3 && cell; ++a) {
      if (!(p[a] >= cell->lo[a] + inset && p[a] <= cell->hi[a] - inset)) return false;
    }
    const double b0 = glm::dot(glm::cross(tri.v1 - tri.v0, p - tri.v0), normal);
    const double b1 = glm::dot(glm::cross(tri.v2 - tri.v1, p - tri.v1), normal);
    const double b2 = glm::dot(glm::cross(tri.v0 - tri.v2, p - tri.v2), normal);
    if (!(b0 > 1e-7 * area2 && b1 > 1e-7 * area2 && b2 > 1e-7 * area2)) return false;
    max_t = std::max(max_t, t);
  }
  return true;
}

// Every open pixel of the frustum takes its distance to triangle `element` (normal `normal`)
// from its direction alone, then tests w.occluders, which must hold every element that could
// come nearer.
void FrustumCaster::fill_from_plane(const Job& job, uint32_t element, const Vec3& normal, Worker& w) {
  const Triangle& tri = scene_.triangles[scene_.prims[element].index];
  const double offset = glm::dot(normal, tri.v0 - view_.eye);
  const bool need_ray = shade_ || !w.occluders.empty();
  const size_t W = size_t(view_.width);
  Ray ray;
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) {
      const size_t i = size_t(y) * W + size_t(x);
      if (buffer_->confirmed(i)) continue;
      const Vec3 d = view_.direction(x, y);
      RayHit best{element, offset * glm::length(d) / glm::dot(normal, d)};
      if (need_ray) {
        ray = Ray(view_.eye, d);
        const double tmin = view_.tmin(ray);
        for (uint32_t prim : w.occluders) offer(prim, ray, tmin, kInfinity, best, w.counters);
      }
      confirm(job, x, y, best.prim, best.t, ray, w);
    }
  }
}

// Resolves every pixel of the frustum against `element` and the few impinging elements whose
// bounds come nearer than its farthest hit; pixels that miss the element within this cell are
// walked individually. Gives up (returns false, nothing written) when too many elements could
// occlude it.
bool FrustumCaster::try_fill(const Job& job, const Incidence* list, uint32_t n, uint32_t element, Worker& w) {
  const size_t nx = static_cast<size_t>(job.x1 - job.x0 + 1), ny = static_cast<size_t>(job.y1 - job.y0 + 1);
  auto fill_index = [&](int x, int y) {
    return static_cast<size_t>(y - job.y0) * nx + static_cast<size_t>(x - job.x0);
  };
  w.fill_t.assign(nx * ny, kInfinity);
  // Cheap pre-check with the corners' distance: the far corner bounds most of the fill.
  double max_t = 0.0;
  for_each_open_pixel(job, [&](int x, int y, const Ray& ray, double tmin) {
    const KdTree::Exit e = tree_.exit(job.cell, ray);
    double t;
    ++w.counters.ray_primitive_tests;
    if (scene_.intersect(element, ray, tmin, e.t + cell_slack(e.t, slack_scale_), t)) {
      ++w.counters.hits;
      w.fill_t[fill_index(x, y)] = t;
      max_t = std::max(max_t, t);
    }
  });
  w.occluders.clear();
  for (uint32_t j = 0; j < n; ++j) {
    const uint32_t prim = tree_.ref(list[j].ref);
    if (prim == element) continue;
    if (distance_to_box(view_.eye, tree_.ref_bounds(list[j].ref)) <= max_t * (1.0 + 1e-9)) {
      w.occluders.push_back(prim);
      if (w.occluders.size() > kMaxFillOccluders) return false;
    }
  }
  for_each_open_pixel(job, [&](int x, int y, const Ray& ray, double tmin) {
    const double te = w.fill_t[fill_index(x, y)];
    if (te == kInfinity) {
      // The element misses this ray inside the cell: walk it like a 2×2 ray.
      bool parked = false;
      const RayHit hit = walk_pixel(x, y, ray, tmin, job.cell, w, parked);
      if (!parked) confirm(job, x, y, hit.prim, hit.t, ray, w);
      return;
    }
    RayHit best{element, te};
    for (uint32_t prim : w.occluders) {
      offer(prim, ray, tmin, kInfinity, best, w.counters);
    }
    confirm(job, x, y, best.prim, best.t, ray, w);
  });
  return true;
}

}  // namespace frontier
