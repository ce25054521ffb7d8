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
#include <cstdint>
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

namespace {

// Calls visit(i, j) for every 0 <= i < nx, 0 <= j < ny in Z order (i from the even bits of a
// counter, j from the odd ones), so that consecutive cells lie close together: 16 of them fill
// a 4 × 4 block. (Packing a leaf's open pixels this way instead of in 4 × 4 blocks made fewer,
// fuller packets but sampled less of the pegged building walk: 0.42-0.60 against 0.57-0.63.)
template <typename Visit>
void for_each_in_z_order(int nx, int ny, const Visit& visit) {
  uint32_t side = 1;
  while (side < uint32_t(std::max(nx, ny))) side *= 2;
  for (uint32_t k = 0; k < side * side; ++k) {
    uint32_t i = 0, j = 0;
    for (uint32_t b = 0; (side >> b) > 1; ++b) {
      i |= ((k >> (2 * b)) & 1u) << b;
      j |= ((k >> (2 * b + 1)) & 1u) << b;
    }
    if (int(i) < nx && int(j) < ny) visit(int(i), int(j));
  }
}

}  // namespace

// The open pixels of a job traced as ray packets of 4x4-pixel blocks (src/engine/packet.h)
// instead of walked one by one (trace_packet), and every pixel of a scene with primitives
// other than triangles walked. In a budgeted frame with previews (set_preview) a leaf frustum
// first traces only its preview (trace_preview) and goes back in the queue, marked, for the
// rest of its pixels in the next level: every leaf of the frame gets its preview before any
// leaf gets the rest, so a frame whose budget ends among the leaves reconstructs its
// unfinished ones from samples a few pixels apart instead of from the anchors 32 pixels apart
// (blurred blocks the size of a run of order_level's where the leaf level was left undone).
void FrustumCaster::resolve_by_packets(const Job& job, Worker& w, bool from_next_cell) {
  // Curved primitives would be tested exactly for every lane, where a lone walk's per-cell
  // lists skip most (their screen rectangles and direction cones: rings.nff's frusta ran at
  // half speed with packets).
  if (!packets_apply()) {
    resolve_by_walking(job, w, from_next_cell);
    return;
  }
  if (!w.packets) w.packets = std::make_unique<PacketTracer>(scene_, tree_);
  w.packets->bind(marks_, gate_, gate_ == nullptr ? packet_layout_.get() : nullptr,
                  gate_ == nullptr && use_accel_ ? accel_.get() : nullptr, &kernel_choice_);
  if (preview_ && budgeted_ && job.refine == 0 && (job.x1 - job.x0 + 1) * (job.y1 - job.y0 + 1) > 2 * kPacketRays) {
    trace_preview(job, w, from_next_cell);
    Job rest = job;
    rest.refine = from_next_cell ? kRefineFromNext : kRefineFromCell;
    w.children.push_back(rest);
    return;
  }
  for (int by = job.y0; by <= job.y1; by += 4) {
    for (int bx = job.x0; bx <= job.x1; bx += 4) {
      int px[kPacketRays], py[kPacketRays];
      int n = 0;
      for (int y = by; y <= std::min(by + 3, int(job.y1)); ++y) {
        for (int x = bx; x <= std::min(bx + 3, int(job.x1)); ++x) {
          px[n] = x;
          py[n] = y;
          ++n;
        }
      }
      trace_packet(job, px, py, n, w, from_next_cell);
    }
  }
}

// A leaf frustum's preview: the points of the quadrant subdivision of its rectangle (the ones
// reconstruct() interpolates from) about kPreviewSpacing pixels apart — each axis halved while
// its parts are longer than one and a half times that — traced as packets of neighbouring
// points from where its other pixels' rays start. About 1/25 of its pixels.
void FrustumCaster::trace_preview(const Job& job, Worker& w, bool from_next_cell) {
  constexpr int kPreviewSpacing = 4;
  const auto points = [](int lo, int hi) {
    std::vector<int> out = {lo};
    const auto halve = [&](const auto& self, int a, int b) -> void {
      if (2 * (b - a) <= 3 * kPreviewSpacing || b - a < 2) return;
      const int mid = (a + b) / 2;
      self(self, a, mid);
      out.push_back(mid);
      self(self, mid, b);
    };
    halve(halve, lo, hi);
    if (hi != lo) out.push_back(hi);
    return out;
  };
  const std::vector<int> xs = points(job.x0, job.x1), ys = points(job.y0, job.y1);
  int px[kPacketRays], py[kPacketRays];
  int n = 0;
  for_each_in_z_order(int(xs.size()), int(ys.size()), [&](int i, int j) {
    px[n] = xs[size_t(i)];
    py[n] = ys[size_t(j)];
    if (++n == kPacketRays) {
      trace_packet(job, px, py, n, w, from_next_cell);
      n = 0;
    }
  });
  if (n > 0) trace_packet(job, px, py, n, w, from_next_cell);
}

// The open pixels among (px[k], py[k]), k < n <= kPacketRays, of a job traced as one ray
// packet. Each ray starts where its walk would: past the job's cell when the frustum has
// resolved that cell for them (`from_next_cell`: nothing there or before it within the slack,
// so no hit is lost by starting at the cell's exit), at the cell's entry otherwise, and from
// the near plane when the job has no cell (outside the root).
// A lane stopped by a missing cell is parked as a lone walk would be; a packet whose rays
// disagree on a direction's sign, or of fewer than kMinPacketRays open pixels, is walked.
// REQUIRES: w.packets made and bound for this frame (resolve_by_packets, once per job).
void FrustumCaster::trace_packet(const Job& job, const int* px, const int* py, int n, Worker& w,
                                 bool from_next_cell) {
  constexpr int kMinPacketRays = 4;
  const size_t W = static_cast<size_t>(view_.width);
  RayPacket packet;
  int lx[kPacketRays], ly[kPacketRays];
  for (int k = 0; k < n; ++k) {
    const int x = px[k], y = py[k];
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
    lx[packet.count] = x;
    ly[packet.count] = y;
    packet.add(ray, tmin);
  }
  if (packet.count == 0) return;
  PacketResult result;
  if (packet.count >= kMinPacketRays && w.packets->trace(packet, result, w.counters)) {
    for (int l = 0; l < packet.count; ++l) {
      if (result.parked & (1u << l)) {
        park_pixel(lx[l], ly[l], w);
      } else {
        confirm(job, lx[l], ly[l], result.hit[l].prim, result.hit[l].t, packet.rays[l], w);
      }
    }
    return;
  }
  for (int l = 0; l < packet.count; ++l) {
    const Ray& ray = packet.rays[l];
    walk_open_pixel(job, lx[l], ly[l], ray, view_.tmin(ray), w, from_next_cell);
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
