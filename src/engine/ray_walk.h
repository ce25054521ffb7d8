// Per-ray visibility: brute force (every ray against every primitive, the reference) and ray
// walking through the k-d tree cells (frustum-casting paper §2.3, the per-ray baseline).
//
// A hit counts in a cell only if its parameter lies in that cell's interval along the ray
// (widened by a relative 1e-9 so that a hit computed a few ulps past a cell boundary is not
// lost; the neighbouring cell references the primitive too). Cells are visited in ray order, so
// the first cell with a hit holds the nearest hit.
#pragma once

#include "src/core/counters.h"
#include "src/engine/cell_gate.h"
#include "src/engine/kdtree.h"
#include "src/core/sample_buffer.h"
#include "src/core/scene.h"

namespace frontier {

struct RayHit {
  uint32_t prim = kNoPrim;
  double t = kInfinity;
  bool hit() const { return prim != kNoPrim; }
};

// Counts one ray-primitive test and keeps its hit at t in `best` when nearer (equal distances:
// the lower primitive index, so every method agrees).
inline void record_test(bool hit, uint32_t prim, double t, RayHit& best, Counters& counters) {
  ++counters.ray_primitive_tests;
  if (!hit) return;
  ++counters.hits;
  if (t < best.t || (t == best.t && prim < best.prim)) best = {prim, t};
}

// Tests primitive `prim` against the ray for tmin <= t <= min(tmax, best.t) and keeps the
// nearer hit in `best`.
inline void offer_primitive(const Scene& scene, uint32_t prim, const Ray& ray, double tmin, double tmax,
                            RayHit& best, Counters& counters) {
  double t = 0.0;
  const bool hit = scene.intersect(prim, ray, tmin, std::min(tmax, best.t), t);
  record_test(hit, prim, t, best, counters);
}

// Nearest hit with t >= tmin among all primitives. Also reports the nearest t of a primitive
// with a different source (for tie detection in tests) through `second_t` when non-null.
RayHit brute_force_hit(const Scene& scene, const Ray& ray, double tmin, Counters& counters,
                       double* second_t = nullptr);

// Tolerance for "a hit at t lies inside a cell interval ending at t_exit".
inline double cell_slack(double t_exit, double scale) { return 1e-9 * std::max(std::abs(t_exit), scale); }

// Walks `ray` from cell `cell` (which the ray is in or on) to its nearest hit with t >= tmin.
// Marks the cells it enters in `marks` when non-null.
RayHit walk_ray(const Scene& scene, const KdTree& tree, const Ray& ray, double tmin, int32_t cell,
                Counters& counters, CellMarks* marks);

// Locates the ray's first cell (the eye's cell, or where it enters the root) and walks.
RayHit cast_ray(const Scene& scene, const KdTree& tree, const Ray& ray, double tmin,
                Counters& counters, CellMarks* marks);

// True if any primitive blocks the segment (tmin, tmax) of the ray (shadow rays).
bool occluded(const Scene& scene, const KdTree& tree, const Ray& ray, double tmin, double tmax,
              Counters& counters);

// A shadow ray in a tree whose cells may be missing (CellGate): blocked when a primitive in
// memory blocks the segment; else missing when the segment crosses a missing cell (each one
// crossed is wanted: the answer depends on it); else clear. The cells it enters are marked in
// `marks` when non-null (they belong to the frame's working set). Without a gate it is
// occluded().
enum class Occlusion : uint8_t { kClear, kBlocked, kMissing };
Occlusion occlusion(const Scene& scene, const KdTree& tree, const Ray& ray, double tmin, double tmax,
                    Counters& counters, CellGate* gate, CellMarks* marks);

// Nearest hit among the references [first, first+count) of a cell with tmin <= t <= tmax.
RayHit nearest_in_refs(const Scene& scene, const KdTree& tree, uint32_t first, uint32_t count,
                       const Ray& ray, double tmin, double tmax, Counters& counters);

}  // namespace frontier
