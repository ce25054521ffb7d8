// PrimAccel: Embree's BVH over a scene's primitives, with frontier's exact tests.
//
// Embree (Debian libembree-dev) builds and walks a BVH of boxes, SIMD, in single precision; the
// primitives are user geometry, so each box Embree's traversal reaches is tested by frontier's
// own exact test (Scene::intersect: the watertight triangle test in double precision, and the
// curved primitives' tests) on frontier's own double-precision ray. Embree only decides which
// primitives to test, so a hit is the exact one provided no primitive the double ray meets is
// skipped:
//   - Embree works relative to the scene's centre (the boxes and the rays' origins are moved by
//     it in double precision first), so a model far from the origin loses nothing;
//   - every box is widened by a margin (2^-16 of the scene's diagonal): more than the float ray
//     Embree walks can stray from the double one, 2^-24 of the eye's and the point's distance
//     from the centre (times four, for the rounding of Embree's own arithmetic, robust mode); a
//     ray for which that bound exceeds the margin (an eye some 16 scene sizes away) is not
//     traced here (usable() says so) but by the k-d tree;
//   - Embree's interval is the ray's [tmin, tmax] rounded outwards to float, and after each hit
//     its far end is that hit's t rounded up, so every box that may hold a nearer hit (or an
//     equal one of a lower primitive: ties go to the lower primitive, as everywhere) is visited.
// So the hits are those of the k-d tree the accelerator stands beside, nearest first, ties to
// the lower primitive (tests/test_engine.cpp checks every primitive kind against brute force).
//
// Frustum casting and ray packets of an in-memory scene trace their packets' rays through it
// (FrustumCaster, Renderer): Embree's SIMD BVH of boxes tests fewer primitives per ray than the
// k-d tree's leaves of paging-cell size. A paged world's subtrees do not use it: a ray crosses
// many small ones there, and a call into Embree per subtree costs more than the packet kernel's
// descent (tests/bench/REPORT.md section 1, "Frontier's exact test inside Embree's BVH").
#pragma once

#include "src/core/counters.h"
#include "src/core/geometry.h"
#include "src/core/scene.h"
#include "src/engine/ray_walk.h"

#include <atomic>
#include <cstdint>

namespace frontier {

// Which of two exact kernels traces a scene's packets faster, measured as they run: Embree's BVH
// of boxes (PrimAccel) or the k-d tree. Neither wins everywhere: on a terrain's compact
// triangles Embree's BVH tests far fewer of them; on long thin ones (tessellated rings and
// shells, a building's walls) their boxes overlap and the k-d tree, which clips them, wins
// (tests/bench/REPORT.md section 1). The packets alternate until each kernel has traced
// kMeasureRays rays; from then on the faster one (nanoseconds per ray) takes every packet but
// one in kExplore, which keeps measuring the other; every kForgetRays rays the sums are halved,
// so a view that changes the balance changes the choice. Shared by a frame's workers.
class KernelChoice {
 public:
  static constexpr uint64_t kMeasureRays = 4096;
  static constexpr uint64_t kExplore = 64;
  static constexpr uint64_t kForgetRays = uint64_t{1} << 22;
  // Whether the `packet`-th packet of the calling tracer goes through Embree's BVH, and whether
  // it is timed (record()).
  bool use_accel(uint64_t packet, bool& timed) const;
  void record(bool accel, uint64_t ns, uint64_t rays);
  bool prefers_accel() const;

 private:
  struct Sum {
    std::atomic<uint64_t> ns{0}, rays{0};
  };
  Sum accel_, kd_;
};

class PrimAccel {
 public:
  PrimAccel() = default;
  // Over the primitives of `scene` (0 .. size()-1, in order); empty for a scene without any.
  // `scene` is read only while this runs.
  static PrimAccel build(const Scene& scene);
  PrimAccel(PrimAccel&& other) noexcept;
  PrimAccel& operator=(PrimAccel&& other) noexcept;
  ~PrimAccel();
  PrimAccel(const PrimAccel&) = delete;
  PrimAccel& operator=(const PrimAccel&) = delete;

  bool empty() const { return handle_ == nullptr; }
  // Whether a ray from `origin` with direction components up to `dmax` (per axis) can be traced
  // here up to t = tmax (see the header's comment).
  bool usable(const Vec3& origin, double dmax, double tmax) const;

  // One ray: the nearest hit with tmin <= t <= min(tmax, best.t) of the scene it was built over
  // goes into `best` (ties: the lower primitive); counts the exact tests as ray walking does.
  void trace(const Scene& scene, const Ray& ray, double tmin, double tmax, RayHit& best, Counters& counters) const;

 private:
  void* handle_ = nullptr;  // RTCScene
  double margin_ = 0.0;
  Vec3 centre_{0.0};
};

}  // namespace frontier
