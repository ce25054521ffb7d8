// Brute force, ray walking and shadow rays.
#include "src/engine/ray_walk.h"

namespace frontier {

RayHit brute_force_hit(const Scene& scene, const Ray& ray, double tmin, Counters& counters,
                       double* second_t) {
  RayHit best;
  double second = kInfinity;
  for (uint32_t i = 0; i < scene.size(); ++i) {
    double t;
    ++counters.ray_primitive_tests;
    if (!scene.intersect(i, ray, tmin, kInfinity, t)) continue;
    ++counters.hits;
    if (t < best.t) {
      if (best.hit() && scene.prims[best.prim].source != scene.prims[i].source) second = best.t;
      best = {i, t};
    } else if (t < second && scene.prims[best.prim].source != scene.prims[i].source) {
      second = t;
    }
  }
  if (second_t != nullptr) *second_t = second;
  return best;
}

RayHit nearest_in_refs(const Scene& scene, const KdTree& tree, uint32_t first, uint32_t count,
                       const Ray& ray, double tmin, double tmax, Counters& counters) {
  RayHit best;
  for (uint32_t r = first; r < first + count; ++r) {
    const uint32_t prim = tree.ref(r);
    offer_primitive(scene, prim, ray, tmin, tmax, best, counters);
  }
  return best;
}

RayHit walk_ray(const Scene& scene, const KdTree& tree, const Ray& ray, double tmin, int32_t cell,
                Counters& counters, CellMarks* marks) {
  const double scale = glm::length(tree.bounds().extent()) + tree.bounds().magnitude();
  // A ray can cross each cell at most once; the cap only guards against a broken tree.
  size_t steps_left = tree.cells().size() + 16;
  while (cell != KdTree::kNone && steps_left-- > 0) {
    ++counters.cell_visits;
    if (marks != nullptr && marks->mark(cell)) ++counters.cells_touched;
    const KdTree::Cell& c = tree.cell(cell);
    const KdTree::Exit e = tree.exit(cell, ray);
    if (c.count > 0 && e.t + cell_slack(e.t, scale) >= tmin) {
      counters.primitives_tested += c.count;
      const RayHit hit =
          nearest_in_refs(scene, tree, c.first, c.count, ray, tmin, e.t + cell_slack(e.t, scale), counters);
      if (hit.hit()) return hit;
    }
    cell = tree.arrival(cell, ray, e);
  }
  return {};
}

RayHit cast_ray(const Scene& scene, const KdTree& tree, const Ray& ray, double tmin,
                Counters& counters, CellMarks* marks) {
  // Start where the ray's valid part begins: at tmin (inside the root) or at the root entry.
  const Vec3 start = ray.at(tmin);
  int32_t cell = tree.locate(start, ray.dir);
  if (cell == KdTree::kNone) {
    double t_enter;
    int face;
    cell = tree.enter_root(ray, tmin, t_enter, face);
    if (cell == KdTree::kNone) return {};
  }
  return walk_ray(scene, tree, ray, tmin, cell, counters, marks);
}

bool occluded(const Scene& scene, const KdTree& tree, const Ray& ray, double tmin, double tmax,
              Counters& counters) {
  return occlusion(scene, tree, ray, tmin, tmax, counters, nullptr, nullptr) == Occlusion::kBlocked;
}

Occlusion occlusion(const Scene& scene, const KdTree& tree, const Ray& ray, double tmin, double tmax,
                    Counters& counters, CellGate* gate, CellMarks* marks) {
  ++counters.shadow_rays;
  int32_t cell = tree.locate(ray.at(tmin), ray.dir);
  if (cell == KdTree::kNone) {
    double t_enter;
    int face;
    cell = tree.enter_root(ray, tmin, t_enter, face);
  }
  bool missing = false;
  size_t steps_left = tree.cells().size() + 16;
  while (cell != KdTree::kNone && steps_left-- > 0) {
    if (marks != nullptr && marks->mark(cell)) ++counters.cells_touched;
    if (gate != nullptr && gate->missing(cell)) {
      // Undecided here; a primitive farther along may still block the segment.
      gate->want(cell);
      missing = true;
    }
    const KdTree::Cell& c = tree.cell(cell);
    for (uint32_t r = c.first; r < c.first + c.count; ++r) {
      double t;
      ++counters.ray_primitive_tests;
      if (scene.intersect(tree.ref(r), ray, tmin, tmax, t)) {
        ++counters.hits;
        return Occlusion::kBlocked;
      }
    }
    const KdTree::Exit e = tree.exit(cell, ray);
    if (e.t >= tmax) break;
    cell = tree.arrival(cell, ray, e);
  }
  return missing ? Occlusion::kMissing : Occlusion::kClear;
}

}  // namespace frontier
