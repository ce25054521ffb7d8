// Frustum casting, incidence lists and resolving pixels against them: a cell's references
// with their screen rectangles, distance bounds and direction cones, built once per frame
// (cell_entries, incidence), and the two ways a frustum's open pixels test such a list —
// element by element over their footprints (resolve_in_cell) or pixel by pixel with depth
// early-out (resolve_pixel_major).
//
// Invariants: every list is sorted nearest first by a lower bound on any hit, and an entry's
// rectangle and direction test only ever exclude pixels that cannot hit its element, so a
// pixel's nearest hit is the same as testing every element. A hit counts only before the
// pixel's exit from the cell (plus slack) unless the list holds everything ahead.
#include "src/engine/frustum.h"

#include "src/engine/frustum_internal.h"

#include <algorithm>
#include <cmath>
#include <mutex>
#include <vector>

namespace frontier {

using namespace frustum_detail;

// Frusta up to this many pixels count their open pixels exactly after resolving in a cell.
constexpr size_t kExactOpenCount = 64;
// Small frusta (pixels × elements up to this) resolve pixel by pixel with depth early-out.
constexpr size_t kPixelMajorWork = 4096;

namespace {
// w.open.push_back with the vector's growth path inlined into resolve_in_cell, as it was while
// Pixel was private to one file: called out of line, it cost the inner loop there registers.
[[gnu::flatten]] void append_open(std::vector<Pixel>& open, const Pixel& p) { open.push_back(p); }
}  // namespace

// The incidence entry of reference r whose element lies within `box` (in front of the eye):
// its screen rectangle, a lower bound on its distance and its cone of directions.
FrustumCaster::Incidence FrustumCaster::incidence(uint32_t r, const Aabb& box) const {
  PixelRect rect;
  const bool bounded = view_.project(box, rect.x0, rect.y0, rect.x1, rect.y1);
  if (!bounded) rect = {0, 0, view_.width - 1, view_.height - 1};
  // Nearest first by a lower bound on any hit: the bounds' distance, or for a sphere or cone
  // the surface's own bound when larger (a box corner comes nearer than the surface by up
  // to 0.73 r; in a heap of overlapping spheres that adds dozens of tests per pixel).
  const double distance = std::max(distance_to_box(view_.eye, box), scene_.distance_bound(tree_.ref(r), view_.eye));
  Incidence inc{r, float(distance * (1.0 - 1e-6)), int16_t(rect.x0), int16_t(rect.y0), int16_t(rect.x1),
                int16_t(rect.y1), 0, bounded, false, 0.0f, 0.0f, 0.0f, -2.0f};
  const PrimRef& prim = scene_.prims[tree_.ref(r)];
  if (prim.kind == PrimKind::Sphere) {
    const Sphere& sphere = scene_.spheres[prim.index];
    const Vec3 v = sphere.center - view_.eye;
    const double d = glm::length(v), radius = std::abs(sphere.radius);
    if (d > radius * (1.0 + 1e-6)) {
      // The axis and the cosine are rounded to float: the dot product moves by at most
      // ~1e-7; a margin of 1e-6 (about a pixel's angle at 513² and 45°) keeps the cone
      // conservative.
      const Vec3 axis = v / d;
      const double s = radius / d;
      inc.axis_x = float(axis.x);
      inc.axis_y = float(axis.y);
      inc.axis_z = float(axis.z);
      inc.reach = float(std::sqrt(std::max(0.0, 1.0 - s * s)) - 1e-6);
    }
  } else if (prim.kind == PrimKind::Cone && distance > 0.0) {
    const Cone& cone = scene_.cones[prim.index];
    const Vec3 a = cone.base - view_.eye, b = cone.apex - view_.eye;
    const Vec3 n = glm::cross(a, b);
    const double n_length = glm::length(n);
    const double reach = std::max(std::abs(cone.base_radius), std::abs(cone.apex_radius)) / distance;
    // Skipped when the eye is nearly on the axis line (the plane is then ill-defined). The
    // normal is rounded to float (~1e-7 in the dot product): the margins cover it.
    if (n_length > 1e-3 * glm::length(a) * glm::length(b) && reach < 1.0) {
      inc.wedge = true;
      inc.axis_x = float(n.x / n_length);
      inc.axis_y = float(n.y / n_length);
      inc.axis_z = float(n.z / n_length);
      inc.reach = -float(reach * (1.0 + 1e-6) + 1e-6);
    }
  }
  return inc;
}

// The references of a cell with their screen rectangles and eye distances, sorted nearest
// first, built once per frame by the first thread that needs them (the others wait on a
// striped lock or read the finished list). For bounds in front of the eye, testing the
// rectangle against a frustum's pixel rectangle is the ternary classification against its
// four planes (every pixel column and row is one plane through the eye), done once per frame
// instead of once per frustum. Bounds wholly behind the near plane are left out.
const std::vector<FrustumCaster::Incidence>& FrustumCaster::cell_entries(int32_t cell) const {
  CellCache& cache = cell_cache_[size_t(cell)];
  if (cache.stamp.load(std::memory_order_acquire) == frame_) return cache.entries;
  std::lock_guard<std::mutex> lock(cell_locks_[size_t(cell) % cell_locks_.size()]);
  if (cache.stamp.load(std::memory_order_relaxed) == frame_) return cache.entries;
  cache.entries.clear();
  const KdTree::Cell& c = tree_.cell(cell);
  for (uint32_t r = c.first; r < c.first + c.count; ++r) {
    const Aabb& box = tree_.ref_bounds(r);
    if (in_front(box)) cache.entries.push_back(incidence(r, box));
  }
  std::sort(cache.entries.begin(), cache.entries.end(),
            [](const Incidence& a, const Incidence& b) { return a.distance < b.distance; });
  cache.stamp.store(frame_, std::memory_order_release);
  return cache.entries;
}

// Clips the list's screen rectangles to the frustum into w.rects; returns the area they cover
// (in pixels, overlaps counted once per element).
double FrustumCaster::footprint(const Job& job, const Incidence* list, uint32_t n, Worker& w) const {
  w.rects.resize(n);
  double area = 0.0;
  for (uint32_t j = 0; j < n; ++j) {
    const Incidence& inc = list[j];
    PixelRect r;
    r.x0 = std::max<int>(inc.x0, job.x0);
    r.y0 = std::max<int>(inc.y0, job.y0);
    r.x1 = std::min<int>(inc.x1, job.x1);
    r.y1 = std::min<int>(inc.y1, job.y1);
    w.rects[j] = r;
    if (r.x0 <= r.x1 && r.y0 <= r.y1) area += double(r.x1 - r.x0 + 1) * double(r.y1 - r.y0 + 1);
  }
  return area;
}

// Tests every unresolved pixel of the frustum against the elements of this cell whose screen
// footprint covers it; pixels with a hit inside the cell are confirmed (the nearest such hit is
// the first hit: earlier cells held nothing for this frustum). Work is proportional to the
// footprints, not to the frustum's area. Returns 0 when no pixel of the frustum is left open
// (checked exactly only for small frusta; large ones report themselves as open).
size_t FrustumCaster::resolve_in_cell(const Job& job, const Incidence* list, uint32_t n, bool have_rects,
                                      Worker& w) {
  const size_t npix = size_t(job.x1 - job.x0 + 1) * size_t(job.y1 - job.y0 + 1);
  if (npix * n <= kPixelMajorWork) return resolve_pixel_major(job, list, n, false, w);
  if (!have_rects) footprint(job, list, n, w);
  const size_t W = size_t(view_.width);
  if (++w.stamp == 0) {
    std::fill(w.slot_stamp.begin(), w.slot_stamp.end(), 0u);
    w.stamp = 1;
  }
  w.open.clear();
  constexpr uint32_t kDoneSlot = 0xFFFFFFFFu;
  for (uint32_t j = 0; j < n; ++j) {
    const PixelRect& r = w.rects[j];
    const uint32_t prim = tree_.ref(list[j].ref);
    const double distance = list[j].distance;
    for (int y = r.y0; y <= r.y1; ++y) {
      for (int x = r.x0; x <= r.x1; ++x) {
        const size_t i = size_t(y) * W + size_t(x);
        uint32_t slot;
        if (w.slot_stamp[i] != w.stamp) {
          w.slot_stamp[i] = w.stamp;
          if (buffer_->confirmed(i)) {
            w.slot[i] = kDoneSlot;
            continue;
          }
          Pixel p;
          p.x = x;
          p.y = y;
          p.ray = view_.ray(x, y);
          p.tmin = view_.tmin(p.ray);
          const KdTree::Exit e = tree_.exit(job.cell, p.ray);
          p.tmax = e.t + cell_slack(e.t, slack_scale_);
          slot = static_cast<uint32_t>(w.open.size());
          w.slot[i] = slot;
          append_open(w.open, p);
        } else {
          slot = w.slot[i];
          if (slot == kDoneSlot) continue;
        }
        Pixel& p = w.open[slot];
        if (p.hit.t < distance) continue;  // already hit in front of these bounds
        if (!list[j].reaches(p.ray.dir)) continue;
        offer(prim, p.ray, p.tmin, p.tmax, p.hit, w.counters);
      }
    }
  }
  for (const Pixel& p : w.open) {
    if (p.hit.hit()) confirm(job, p.x, p.y, p.hit.prim, p.hit.t, p.ray, w);
  }
  if (npix > kExactOpenCount) return npix;
  size_t remaining = 0;
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) remaining += buffer_->confirmed(size_t(y) * W + size_t(x)) ? 0 : 1;
  }
  return remaining;
}

// The same for small frusta, pixel by pixel: the list is sorted nearest first, so a pixel stops
// at the first element whose bounds lie beyond its best hit (early termination in depth).
// `to_infinity`: the list holds everything the pixels can still hit (gather_ahead), so hits
// count along the whole ray and a pixel that hits nothing is background.
size_t FrustumCaster::resolve_pixel_major(const Job& job, const Incidence* list, uint32_t n, bool to_infinity,
                                          Worker& w) {
  const size_t W = size_t(view_.width);
  size_t remaining = 0;
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) {
      const size_t i = size_t(y) * W + size_t(x);
      if (buffer_->confirmed(i)) continue;
      Ray ray;
      double tmin = 0.0, tmax = 0.0;
      bool have_ray = false;
      RayHit best;
      for (uint32_t j = 0; j < n; ++j) {
        const Incidence& e = list[j];
        if (e.distance > best.t) break;
        if (x < e.x0 || x > e.x1 || y < e.y0 || y > e.y1) continue;
        if (!have_ray) {
          ray = view_.ray(x, y);
          tmin = view_.tmin(ray);
          if (to_infinity) {
            tmax = kInfinity;
          } else {
            const KdTree::Exit exit = tree_.exit(job.cell, ray);
            tmax = exit.t + cell_slack(exit.t, slack_scale_);
          }
          have_ray = true;
        }
        if (!e.reaches(ray.dir)) continue;
        const uint32_t prim = tree_.ref(e.ref);
        offer(prim, ray, tmin, tmax, best, w.counters);
      }
      if (best.hit()) {
        confirm(job, x, y, best.prim, best.t, ray, w);
      } else if (to_infinity) {
        if (!have_ray) ray = view_.ray(x, y);
        confirm(job, x, y, kNoPrim, kInfinity, ray, w);
      } else {
        ++remaining;
      }
    }
  }
  return remaining;
}

}  // namespace frontier
