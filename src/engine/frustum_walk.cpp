// Frustum casting, the pixels no frustum resolves as a whole: those of a leaf frustum that
// cannot advance (or of a small one outside the root) go on as ray packets of 4x4 pixels
// (resolve_by_packets); anchors, pixels a §4 fill's element misses and blocks packets refuse
// each walk their own ray through the cells (§3.2's 2×2 case) while sharing the frame's
// per-cell lists.
//
// Invariants: a walk starts in a cell its ray is in (or, from_next_cell, the cell it arrives
// in from the frustum's cell) and tests each cell's elements along the ray before moving on, so
// its first hit inside a cell is the nearest; it never reads past a missing cell (the pixel is
// parked instead). NextCells only ever suggests a cell that a box test then confirms.
#include "src/engine/frustum.h"

#include "src/engine/frustum_internal.h"

#include <algorithm>
#include <vector>

namespace frontier {

using namespace frustum_detail;

// Walks every open pixel of the job from its cell (from the cell each ray arrives in next,
// with `from_next_cell`; from the root's entry when the job is outside it).
void FrustumCaster::resolve_by_walking(const Job& job, Worker& w, bool from_next_cell) {
  for_each_open_pixel(job, [&](int x, int y, const Ray& ray, double tmin) {
    walk_open_pixel(job, x, y, ray, tmin, w, from_next_cell);
  });
}

// One open pixel of resolve_by_walking.
void FrustumCaster::walk_open_pixel(const Job& job, int x, int y, const Ray& ray, double tmin, Worker& w,
                                    bool from_next_cell) {
  int32_t start = job.cell;
  if (start == KdTree::kNone) {
    start = tree_.locate(ray.at(tmin), ray.dir);
    if (start == KdTree::kNone) {
      double t_enter;
      int face;
      start = tree_.enter_root(ray, tmin, t_enter, face);
    }
  } else if (from_next_cell) {
    start = w.next_cells.arrival(tree_, job.cell, ray, tree_.exit(job.cell, ray));
  }
  bool parked = false;
  const RayHit hit = walk_pixel(x, y, ray, tmin, start, w, parked);
  if (!parked) confirm(job, x, y, hit.prim, hit.t, ray, w);
}

// The open pixels of a job traced as ray packets of 4x4-pixel blocks (src/engine/packet.h)
// instead of walked one by one. Each ray starts where its walk would: past the job's cell when
// the frustum has resolved that cell for them (`from_next_cell`: nothing there or before it
// within the slack, so no hit is lost by starting at the cell's exit), at the cell's entry
// otherwise, and from the near plane outside the root. A lane stopped by a missing cell is
// parked as a lone walk would be; a block whose rays disagree on a direction's sign, or of
// fewer than kMinPacketRays open pixels, is walked, and so is every pixel of a scene with
// primitives other than triangles.
void FrustumCaster::resolve_by_packets(const Job& job, Worker& w, bool from_next_cell) {
  constexpr int kMinPacketRays = 4;
  // Curved primitives would be tested exactly for every lane, where a lone walk's per-cell
  // lists skip most (their screen rectangles and direction cones: rings.nff's frusta ran at
  // half speed with packets).
  if (!packets_apply()) {
    resolve_by_walking(job, w, from_next_cell);
    return;
  }
  if (!w.packets) w.packets = std::make_unique<PacketTracer>(scene_, tree_);
  w.packets->bind(marks_, gate_, gate_ == nullptr ? packet_layout_.get() : nullptr);
  const size_t W = static_cast<size_t>(view_.width);
  for (int by = job.y0; by <= job.y1; by += 4) {
    for (int bx = job.x0; bx <= job.x1; bx += 4) {
      RayPacket packet;
      int px[kPacketRays], py[kPacketRays];
      for (int y = by; y <= std::min(by + 3, int(job.y1)); ++y) {
        for (int x = bx; x <= std::min(bx + 3, int(job.x1)); ++x) {
          if (buffer_->confirmed(static_cast<size_t>(y) * W + static_cast<size_t>(x))) continue;
          const Ray ray = view_.ray(x, y);
          double tmin = view_.tmin(ray);
          if (job.cell != KdTree::kNone) {
            if (from_next_cell) {
              tmin = std::max(tmin, tree_.exit(job.cell, ray).t);
            } else {
              double t0, t1;
              if (ray_box_interval(ray, tree_.cell(job.cell).bounds, t0, t1)) tmin = std::max(tmin, t0);
            }
          }
          px[packet.count] = x;
          py[packet.count] = y;
          packet.add(ray, tmin);
        }
      }
      if (packet.count == 0) continue;
      PacketResult result;
      if (packet.count >= kMinPacketRays && w.packets->trace(packet, result, w.counters)) {
        for (int l = 0; l < packet.count; ++l) {
          if (result.parked & (1u << l)) {
            park_pixel(px[l], py[l], w);
          } else {
            confirm(job, px[l], py[l], result.hit[l].prim, result.hit[l].t, packet.rays[l], w);
          }
        }
        continue;
      }
      for (int l = 0; l < packet.count; ++l) {
        const Ray& ray = packet.rays[l];
        walk_open_pixel(job, px[l], py[l], ray, view_.tmin(ray), w, from_next_cell);
      }
    }
  }
}

// Ray walking for one pixel of a frustum (§3.2's 2×2 case). Unlike a lone ray it shares the
// frame's per-element screen rectangles: an element whose rectangle misses the pixel, or whose
// bounds lie beyond the best hit so far, is never intersected.
RayHit FrustumCaster::walk_pixel(int x, int y, const Ray& ray, double tmin, int32_t cell, Worker& w,
                                 bool& parked) const {
  ++w.counters.rays_walked;
  size_t steps_left = tree_.cells().size() + 16;
  while (cell != KdTree::kNone && steps_left-- > 0) {
    ++w.counters.cell_visits;
    if (marks_->mark(cell)) ++w.counters.cells_touched;
    if (gate_missing(cell)) {
      park_pixel(x, y, w);
      parked = true;
      return {};
    }
    const KdTree::Exit e = tree_.exit(cell, ray);
    const double tmax = e.t + cell_slack(e.t, slack_scale_);
    RayHit best;
    // An empty cell is passed without a list or a first-visit check.
    const KdTree::Cell& c = tree_.cell(cell);
    if (c.count > 0 && first_pixel_visit(cell)) {
      // The first pixel to cross a cell no frustum has listed this frame tests its references
      // directly: listing them (screen rectangles, sorted) pays only when more pixels follow,
      // and through a fine tree seen from afar most cells are crossed by a pixel or two. The
      // nearest hit is the same either way (the list only skips references that cannot win).
      w.counters.primitives_tested += c.count;
      for (uint32_t r = c.first; r < c.first + c.count; ++r) {
        offer(tree_.ref(r), ray, tmin, tmax, best, w.counters);
      }
    } else if (c.count > 0) {
      const std::vector<Incidence>& entries = cell_entries(cell);
      w.counters.primitives_tested += entries.size();
      for (const Incidence& inc : entries) {
        if (inc.distance > std::min(best.t, tmax)) break;  // sorted: the rest lie farther
        if (x < inc.x0 || x > inc.x1 || y < inc.y0 || y > inc.y1 || !inc.reaches(ray.dir)) continue;
        const uint32_t prim = tree_.ref(inc.ref);
        offer(prim, ray, tmin, tmax, best, w.counters);
      }
    }
    if (best.hit()) return best;
    cell = w.next_cells.arrival(tree_, cell, ray, e);
  }
  return {};
}

bool FrustumCaster::first_pixel_visit(int32_t cell) const {
  CellCache& cache = cell_cache_[size_t(cell)];
  if (cache.stamp.load(std::memory_order_acquire) == frame_) return false;  // listed already
  if (cache.seen.load(std::memory_order_relaxed) == frame_) return false;
  return cache.seen.exchange(frame_, std::memory_order_relaxed) != frame_;
}

}  // namespace frontier
