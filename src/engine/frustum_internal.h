// Private to frustum casting (frustum*.cpp, never included elsewhere): the records the parts
// of FrustumCaster share — a frustum job, a cell's incidence entry, the per-thread Worker with
// its scratch state — and the small helpers every part calls per pixel, kept inline here so
// that splitting the caster across files does not put a call into the inner loops.
//
// Invariants the parts rely on:
// - a Job's pixel rectangle is inclusive and its corner pixels are its four corner rays; live
//   jobs never nest and overlap only on the edges siblings share (claim());
// - an incidence list (a cell's entries, a Job's inherited list, gather_ahead's) is sorted
//   nearest first by `distance`, a lower bound on any hit, so a pixel may stop at the first
//   entry beyond its best hit;
// - a Worker belongs to one thread of the caster's arena at a time; nothing in it is shared.
#pragma once

#include "src/engine/frustum.h"
#include "src/engine/packet.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <vector>

namespace frontier {

namespace frustum_detail {

constexpr uint8_t kLeft = 1, kRight = 2, kBottom = 4, kTop = 8;  // straddle bits per plane
// Job::state: no list collected yet in this cell, nothing left in it, or a list inherited.
constexpr uint8_t kFresh = 0, kEmpty = 1, kList = 2;
constexpr uint8_t kRefineFromNext = 1, kRefineFromCell = 2;
// A fill gives up when more elements than this could come before its element (fill files and
// the look-ahead's plane fill).
constexpr uint32_t kMaxFillOccluders = 6;

struct Pixel {
  int x = 0, y = 0;
  Ray ray;
  double tmin = 0.0, tmax = 0.0;
  RayHit hit;
};

// The cells lone pixel walks arrived in last, by the cell and face they left: the next pixel's
// ray mostly arrives in the same cell, which a box test confirms (KdTree::arrives_in) for
// less than the rope descent costs. Direct-mapped; an entry only ever suggests a cell.
struct NextCells {
  static constexpr size_t kSlots = 256;
  std::array<int64_t, kSlots> key;
  std::array<int32_t, kSlots> cell;
  NextCells() { clear(); }
  void clear() { key.fill(-1); }
  int32_t arrival(const KdTree& tree, int32_t from, const Ray& ray, const KdTree::Exit& e) {
    if (e.face < 0) return KdTree::kNone;
    const int64_t k = int64_t(from) * 6 + e.face;
    const size_t slot = size_t(k) % kSlots;
    if (key[slot] == k && tree.arrives_in(from, ray, e, cell[slot])) return cell[slot];
    const int32_t next = tree.arrival(from, ray, e);
    key[slot] = k;
    cell[slot] = next;
    return next;
  }
};

// An element gather_ahead found: one of its references and the union of its bounds in the
// cells ahead (what its screen rectangle is made from).
struct AheadElement {
  uint32_t prim;
  uint32_t ref;
  Aabb bounds;
};

// A node on gather_ahead's stack: its region and the frustum planes it may still straddle.
struct AheadNode {
  int32_t node;
  uint16_t planes;
  Aabb box;
};

}  // namespace frustum_detail

struct FrustumCaster::Job {
  int32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // inclusive pixel rectangle; corners are its rays
  int32_t cell = KdTree::kNone;            // current cell; kNone = not yet inside the root
  uint32_t inc_begin = 0, inc_count = 0;   // incidence list in arenas_in_[arena]
  uint16_t arena = 0;
  uint8_t state = 0;                       // kFresh, kEmpty or kList
  // A leaf frustum of a budgeted frame whose preview is traced (resolve_by_packets):
  // kRefineFromNext or kRefineFromCell, where its other pixels' rays start; 0 otherwise.
  uint8_t refine = 0;
  bool small(int leaf) const { return x1 - x0 < leaf && y1 - y0 < leaf; }
};

// What a step of FrustumCaster::process did with its frustum.
enum class FrustumCaster::Step : uint8_t {
  Done,   // every pixel is resolved, parked or handed to children
  Moved,  // the frustum moved into another cell (or entered the root): go on there
  Stays,  // the frustum is still open in its cell
};

struct FrustumCaster::Incidence {
  uint32_t ref;            // k-d tree reference (primitive + its bounds clipped to the cell)
  float distance;          // eye to the bounds, rounded down (a lower bound on any hit)
  int16_t x0, y0, x1, y1;  // screen rectangle of the bounds (whole view if unbounded)
  uint8_t straddle;        // planes (kLeft...) the bounds straddle; others: inside
  bool bounded;            // the rectangle holds every pixel that can hit the bounds (View::project)
  bool wedge;              // the direction test below is a cone's wedge
  // Directions from the eye that can reach the element, for spheres and cones:
  // - a sphere's cone of directions (wedge false): a unit ray direction d can hit it only if
  //   d · axis >= reach. Exact, so a sphere's rectangle corners, a quarter of its area, are
  //   never tested;
  // - a cone's wedge around the plane through the eye and its axis (wedge true): every
  //   surface point lies within the largest radius R of that plane, and beyond `distance`, so
  //   d can hit it only if |d · axis| <= R / distance, kept as reach = -R / distance. A thin
  //   tube seen across is a thin strip of directions, where its bounding sphere's cone would
  //   be a disc, and far fewer of its rays are tested against it.
  // reach -2 (no test) passes all. Stored in float with margins far above the rounding (see
  // incidence()).
  float axis_x, axis_y, axis_z, reach;
  bool reaches(const Vec3& d) const {
    const double v = d.x * axis_x + d.y * axis_y + d.z * axis_z;
    // Branch-free: a sphere's test is v >= reach; a wedge's, stored with its reach negated,
    // -|v| >= -R.
    return (wedge ? -std::abs(v) : v) >= reach;
  }
};

// A pixel strictly inside a job's rectangle belongs to that job alone (live jobs are never
// nested and overlap only on the edges they share with siblings), so it is claimed without an
// atomic read-modify-write, which costs much of a frame where one element fills the view.
// Inline: fill_background calls it for every sky pixel.
inline bool FrustumCaster::claim(const Job& job, int x, int y, size_t i) const {
  const bool interior = x > job.x0 && x < job.x1 && y > job.y0 && y < job.y1;
  return interior ? buffer_->claim_exclusive(i) : buffer_->claim(i);
}

struct FrustumCaster::CellCache {
  std::atomic<uint32_t> stamp{0};  // frame whose entries these are
  std::atomic<uint32_t> seen{0};   // frame in which a lone pixel walk tested the cell directly
  std::vector<Incidence> entries;
};

struct FrustumCaster::Worker {
  std::vector<Job> children;                 // next level
  std::vector<Incidence> arena_out;          // incidence lists of those children
  std::vector<Job> remaining;                // jobs skipped because the budget ran out
  std::vector<Job> parked;                   // jobs that reached a missing cell (paging)
  std::vector<uint32_t> reopen;              // pixels claimed whose shadow rays need missing cells
  std::vector<Incidence> scratch;            // a freshly collected list
  std::vector<double> fill_t;                // per-pixel hits of the fill element
  std::vector<uint32_t> occluders;
  std::vector<PixelRect> rects;              // screen footprints of the incidence list
  // resolve_in_cell's sparse per-pixel state: slot_stamp[i] == stamp marks pixel i as seen in
  // this call, slot[i] indexes `open` (a frame-sized map without clearing).
  std::vector<uint32_t> slot_stamp, slot;
  uint32_t stamp = 0;
  std::vector<frustum_detail::Pixel> open;
  frustum_detail::NextCells next_cells;                // lone pixel walks' arrivals
  std::vector<frustum_detail::AheadNode> nodes;        // gather_ahead's descent stack,
  std::vector<frustum_detail::AheadElement> ahead;     // the elements it found
  std::vector<int32_t> ahead_cells;                    // and the cells it read them from
  std::unique_ptr<PacketTracer> packets;              // resolve_by_packets' tracer, made on first use
  Counters counters;
  // counters.samples as last added to a sample budget's shared count (flush_samples): the count
  // is kept a job at a time (one contended atomic per pixel was half of confirm()'s time).
  uint64_t flushed = 0;
  uint16_t index = 0;  // which arenas_in_ slot its arena_out becomes
};

// offer_primitive for a ray from the eye: cones and spheres use this frame's eye terms
// (bit-identical to intersect_cone and intersect_sphere; a cone test costs about a third less).
[[gnu::always_inline]] inline void FrustumCaster::offer(uint32_t prim, const Ray& ray, double tmin, double tmax,
                                                        RayHit& best, Counters& counters) const {
  const PrimRef& p = scene_.prims[prim];
  double t = 0.0;
  bool hit;
  if (p.kind == PrimKind::Cone && p.index < cone_terms_.size()) {
    hit = intersect_cone(cone_terms_[p.index], ray.dir, tmin, std::min(tmax, best.t), t);
  } else if (p.kind == PrimKind::Sphere && p.index < sphere_terms_.size()) {
    hit = intersect_sphere(sphere_terms_[p.index], ray.dir, tmin, std::min(tmax, best.t), t);
  } else {
    offer_primitive(scene_, prim, ray, tmin, tmax, best, counters);
    return;
  }
  record_test(hit, prim, t, best, counters);
}

// Calls visit(x, y, ray, tmin) for every pixel of the job not confirmed yet, row by row, with
// the pixel's ray from the eye and where it starts (the near plane).
template <typename Visit>
inline void FrustumCaster::for_each_open_pixel(const Job& job, const Visit& visit) const {
  const size_t W = static_cast<size_t>(view_.width);
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) {
      if (buffer_->confirmed(static_cast<size_t>(y) * W + static_cast<size_t>(x))) continue;
      const Ray ray = view_.ray(x, y);
      visit(x, y, ray, view_.tmin(ray));
    }
  }
}

}  // namespace frontier
