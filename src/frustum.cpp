// Frustum casting: the job queue, frustum advance, incidence lists and the fill test.
#include "src/frustum.h"

#include "src/ray_walk.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>

namespace frontier {

namespace {

constexpr uint8_t kLeft = 1, kRight = 2, kBottom = 4, kTop = 8;  // straddle bits per plane
constexpr uint32_t kMaxFillOccluders = 6;
// Quadrant order of children on the next level: diagonal quadrants first, so that an
// interrupted level leaves samples spread over the screen (interleaved order, §5.2).
constexpr std::array<int, 4> kQuadrantOrder = {0, 3, 1, 2};

}  // namespace

struct FrustumCaster::Job {
  int32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // inclusive pixel rectangle; corners are its rays
  int32_t cell = KdTree::kNone;            // current cell; kNone = not yet inside the root
  uint32_t inc_begin = 0, inc_count = 0;   // incidence list in arenas_in_[arena]
  uint16_t arena = 0;
  uint8_t state = 0;                       // kFresh, kEmpty or kList
  bool small() const { return x1 - x0 <= 1 && y1 - y0 <= 1; }
};

namespace {
constexpr uint8_t kFresh = 0, kEmpty = 1, kList = 2;
}

struct FrustumCaster::Incidence {
  uint32_t ref;      // k-d tree reference (primitive + its bounds clipped to the cell)
  uint8_t straddle;  // planes (kLeft...) the bounds straddle; others: inside
};

struct FrustumCaster::Worker {
  std::array<std::vector<Job>, 4> children;  // next level, by quadrant
  std::vector<Incidence> arena_out;          // incidence lists of those children
  std::vector<Job> remaining;                // jobs skipped because the budget ran out
  std::vector<Incidence> scratch;            // a freshly collected list
  std::vector<double> fill_t;                // per-pixel hits of the fill element
  std::vector<uint32_t> occluders;
  Counters counters;
  uint16_t index = 0;  // which arenas_in_ slot its arena_out becomes
};

struct FrustumCaster::Arena {
  explicit Arena(int threads) : arena(threads) {}
  tbb::task_arena arena;
};

FrustumCaster::FrustumCaster(const Scene& scene, const KdTree& tree, const Shader& shader, int threads)
    : scene_(scene), tree_(tree), shader_(shader) {
  threads_ = threads > 0 ? threads : tbb::info::default_concurrency();
  arena_ = std::make_unique<Arena>(threads_);
  workers_.resize(static_cast<size_t>(threads_) + 1);
  for (size_t k = 0; k < workers_.size(); ++k) {
    workers_[k] = std::make_unique<Worker>();
    workers_[k]->index = static_cast<uint16_t>(k);
  }
  slack_scale_ = glm::length(tree.bounds().extent()) + tree.bounds().magnitude();
}

FrustumCaster::~FrustumCaster() = default;

void FrustumCaster::begin(const View& view, SampleBuffer& buffer, CellMarks& marks, bool shade,
                          bool shadows) {
  shade_ = shade;
  view_ = view;
  buffer_ = &buffer;
  marks_ = &marks;
  shadows_ = shadows;
  buffer.resize(view.width, view.height);
  buffer.begin_frame();
  marks.resize(tree_.cells().size());
  marks.begin_frame();
  samples_done_ = 0;
  // One plane per pixel column and row, through the eye (§3.1: children reuse them).
  column_normal_.resize(static_cast<size_t>(view.width));
  row_normal_.resize(static_cast<size_t>(view.height));
  for (int x = 0; x < view.width; ++x) {
    Vec3 n = glm::cross(view.base + double(x) * view.step_x, view.step_y);
    if (glm::dot(n, view.step_x) < 0.0) n = -n;
    column_normal_[static_cast<size_t>(x)] = n;
  }
  for (int y = 0; y < view.height; ++y) {
    Vec3 n = glm::cross(view.base + double(y) * view.step_y, view.step_x);
    if (glm::dot(n, view.step_y) < 0.0) n = -n;
    row_normal_[static_cast<size_t>(y)] = n;
  }
  for (auto& w : workers_) {
    for (auto& c : w->children) c.clear();
    w->arena_out.clear();
    w->remaining.clear();
  }
  arenas_in_.clear();
  current_.clear();
  Job root;
  root.x0 = 0;
  root.y0 = 0;
  root.x1 = view.width - 1;
  root.y1 = view.height - 1;
  root.cell = tree_.locate(view.eye, view.forward);
  root.state = kFresh;
  current_.push_back(root);
}

bool FrustumCaster::complete() const {
  if (!current_.empty()) return false;
  for (const auto& w : workers_) {
    for (const auto& c : w->children) {
      if (!c.empty()) return false;
    }
  }
  return true;
}

bool FrustumCaster::run(const FrameBudget& budget, Counters& counters) {
  const auto start = std::chrono::steady_clock::now();
  const auto deadline = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                    std::chrono::duration<double, std::milli>(budget.ms));
  auto out_of_budget = [&]() {
    if (budget.samples > 0 && samples_done_.load(std::memory_order_relaxed) >= budget.samples) return true;
    return budget.ms > 0.0 && std::chrono::steady_clock::now() >= deadline;
  };
  for (auto& w : workers_) w->counters = Counters{};
  bool interrupted = false;
  while (!complete() && !interrupted) {
    if (current_.empty()) finish_level();
    std::vector<Job> level;
    level.swap(current_);
    arena_->arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, level.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        const int slot = std::max(0, tbb::this_task_arena::current_thread_index());
        Worker& w = *workers_[static_cast<size_t>(std::min(slot, threads_))];
        for (size_t i = r.begin(); i != r.end(); ++i) {
          if (out_of_budget()) {
            w.remaining.push_back(level[i]);
          } else {
            process(level[i], w);
          }
        }
      });
    });
    for (auto& w : workers_) {
      current_.insert(current_.end(), w->remaining.begin(), w->remaining.end());
      w->remaining.clear();
    }
    interrupted = !current_.empty();
  }
  for (auto& w : workers_) counters += w->counters;
  counters.ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return complete();
}

void FrustumCaster::finish_level() {
  arenas_in_.resize(workers_.size());
  for (size_t k = 0; k < workers_.size(); ++k) {
    arenas_in_[k].swap(workers_[k]->arena_out);
    workers_[k]->arena_out.clear();
  }
  for (int q : kQuadrantOrder) {
    for (auto& w : workers_) {
      auto& c = w->children[static_cast<size_t>(q)];
      current_.insert(current_.end(), c.begin(), c.end());
      c.clear();
    }
  }
}

FrustumCaster::Side FrustumCaster::classify(const Vec3& n, const Aabb& box) const {
  const Vec3 c = box.center() - view_.eye;
  const Vec3 h = 0.5 * box.extent();
  const double s = glm::dot(n, c);
  const double r = std::abs(n.x) * h.x + std::abs(n.y) * h.y + std::abs(n.z) * h.z;
  const double tol = 1e-9 * (std::abs(s) + r) + 1e-300;
  if (s + r < -tol) return Side::Outside;
  if (s - r > tol) return Side::Inside;
  return Side::Straddle;
}

bool FrustumCaster::in_front(const Aabb& box) const {
  const Vec3 c = box.center() - view_.eye;
  const Vec3 h = 0.5 * box.extent();
  const Vec3& f = view_.forward;
  const double far_point = glm::dot(f, c) + std::abs(f.x) * h.x + std::abs(f.y) * h.y + std::abs(f.z) * h.z;
  return far_point >= view_.near - 1e-9 * (std::abs(far_point) + glm::length(c) + 1e-300);
}

void FrustumCaster::confirm(int x, int y, uint32_t prim, double t, const Ray& ray, Worker& w) {
  const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x);
  if (!buffer_->claim(i)) return;
  const Rgb color = prim == kNoPrim ? shader_.background()
                    : shade_        ? shader_.shade(prim, ray, t, shadows_, w.counters)
                                    : Rgb{};
  buffer_->set(i, prim, t, color);
  ++w.counters.samples;
  ++w.counters.rays;
  samples_done_.fetch_add(1, std::memory_order_relaxed);
}

void FrustumCaster::fill_background(const Job& job, Worker& w) {
  const Rgb bg = shader_.background();
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) {
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x);
      if (!buffer_->claim(i)) continue;
      buffer_->set(i, kNoPrim, kInfinity, bg);
      ++w.counters.samples;
      ++w.counters.rays;
      samples_done_.fetch_add(1, std::memory_order_relaxed);
    }
  }
}

void FrustumCaster::resolve_by_walking(const Job& job, Worker& w) {
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) {
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x);
      if (buffer_->confirmed(i)) continue;
      const Ray ray = view_.ray(x, y);
      const double tmin = view_.tmin(ray);
      ++w.counters.rays_walked;
      const RayHit hit = job.cell == KdTree::kNone
                             ? cast_ray(scene_, tree_, ray, tmin, w.counters, marks_)
                             : walk_ray(scene_, tree_, ray, tmin, job.cell, w.counters, marks_);
      confirm(x, y, hit.prim, hit.t, ray, w);
    }
  }
}

// Builds the incidence list of job.cell into w.scratch: references whose clipped bounds are not
// outside any frustum plane. Returns false when the list is empty.
bool FrustumCaster::collect(const Job& job, Worker& w) {
  w.scratch.clear();
  const KdTree::Cell& cell = tree_.cell(job.cell);
  const Vec3& nl = column_normal_[static_cast<size_t>(job.x0)];
  const Vec3& nr = column_normal_[static_cast<size_t>(job.x1)];
  const Vec3& nb = row_normal_[static_cast<size_t>(job.y0)];
  const Vec3& nt = row_normal_[static_cast<size_t>(job.y1)];
  w.counters.primitives_tested += cell.count;
  for (uint32_t r = cell.first; r < cell.first + cell.count; ++r) {
    const Aabb& box = tree_.ref_bounds(r);
    w.counters.plane_tests += 5;
    if (!in_front(box)) continue;
    uint8_t straddle = 0;
    Side s = classify(nl, box);
    if (s == Side::Outside) continue;
    if (s == Side::Straddle) straddle |= kLeft;
    s = classify(-nr, box);
    if (s == Side::Outside) continue;
    if (s == Side::Straddle) straddle |= kRight;
    s = classify(nb, box);
    if (s == Side::Outside) continue;
    if (s == Side::Straddle) straddle |= kBottom;
    s = classify(-nt, box);
    if (s == Side::Outside) continue;
    if (s == Side::Straddle) straddle |= kTop;
    w.scratch.push_back({r, straddle});
  }
  return !w.scratch.empty();
}

void FrustumCaster::process(Job job, Worker& w) {
  const int W = view_.width;
  const std::array<std::array<int, 2>, 4> corner = {{{job.x0, job.y0}, {job.x1, job.y0},
                                                     {job.x0, job.y1}, {job.x1, job.y1}}};
  std::array<Ray, 4> rays;
  std::array<double, 4> tmins;
  for (int k = 0; k < 4; ++k) {
    rays[static_cast<size_t>(k)] = view_.ray(corner[static_cast<size_t>(k)][0], corner[static_cast<size_t>(k)][1]);
    tmins[static_cast<size_t>(k)] = view_.tmin(rays[static_cast<size_t>(k)]);
  }
  while (true) {
    ++w.counters.frusta;
    // §4 special case: the eye is outside the root; find where the corner rays enter it.
    if (job.cell == KdTree::kNone) {
      std::array<int32_t, 4> cells;
      std::array<int, 4> faces;
      for (size_t k = 0; k < 4; ++k) {
        double t_enter;
        cells[k] = tree_.enter_root(rays[k], tmins[k], t_enter, faces[k]);
      }
      const bool agree = cells[0] != KdTree::kNone && faces[0] >= 0 &&
                         std::all_of(cells.begin(), cells.end(), [&](int32_t c) { return c == cells[0]; }) &&
                         std::all_of(faces.begin(), faces.end(), [&](int f) { return f == faces[0]; });
      if (agree) {
        job.cell = cells[0];
        job.state = kFresh;
        continue;
      }
      if (job.small()) {
        resolve_by_walking(job, w);
        return;
      }
      const Aabb& root = tree_.bounds();
      w.counters.plane_tests += 5;
      if (!in_front(root) || classify(column_normal_[static_cast<size_t>(job.x0)], root) == Side::Outside ||
          classify(-column_normal_[static_cast<size_t>(job.x1)], root) == Side::Outside ||
          classify(row_normal_[static_cast<size_t>(job.y0)], root) == Side::Outside ||
          classify(-row_normal_[static_cast<size_t>(job.y1)], root) == Side::Outside) {
        fill_background(job, w);
        return;
      }
      split(job, nullptr, 0, w);
      return;
    }

    if (marks_->mark(job.cell)) ++w.counters.cells_touched;
    ++w.counters.cell_visits;
    const Incidence* list = nullptr;
    uint32_t n = 0;
    if (job.state == kFresh) {
      if (collect(job, w)) {
        list = w.scratch.data();
        n = static_cast<uint32_t>(w.scratch.size());
      }
    } else if (job.state == kList) {
      list = arenas_in_[job.arena].data() + job.inc_begin;
      n = job.inc_count;
    }

    if (n == 0) {
      // Nothing impinges here: advance if all corner rays leave through one face into one cell.
      std::array<KdTree::Exit, 4> exits;
      std::array<int32_t, 4> next;
      for (size_t k = 0; k < 4; ++k) {
        exits[k] = tree_.exit(job.cell, rays[k]);
        next[k] = tree_.arrival(job.cell, rays[k], exits[k]);
      }
      const bool agree = exits[0].face >= 0 &&
                         std::all_of(exits.begin(), exits.end(), [&](const KdTree::Exit& e) { return e.face == exits[0].face; }) &&
                         std::all_of(next.begin(), next.end(), [&](int32_t c) { return c == next[0]; });
      if (agree) {
        if (next[0] == KdTree::kNone) {
          fill_background(job, w);
          return;
        }
        job.cell = next[0];
        job.state = kFresh;
        continue;
      }
      if (job.small()) {
        resolve_by_walking(job, w);
        return;
      }
      split(job, nullptr, 0, w);
      return;
    }

    if (job.small()) {
      resolve_by_walking(job, w);
      return;
    }
    // Corner rays against the impinging elements; a corner hit inside this cell is final.
    std::array<RayHit, 4> hits;
    for (size_t k = 0; k < 4; ++k) {
      const int x = corner[k][0], y = corner[k][1];
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(W) + static_cast<size_t>(x);
      const KdTree::Exit e = tree_.exit(job.cell, rays[k]);
      const double tmax = e.t + cell_slack(e.t, slack_scale_);
      RayHit best;
      for (uint32_t j = 0; j < n; ++j) {
        const uint32_t prim = tree_.ref(list[j].ref);
        double t;
        ++w.counters.ray_primitive_tests;
        if (scene_.intersect(prim, rays[k], tmins[k], std::min(tmax, best.t), t)) {
          ++w.counters.hits;
          if (t < best.t || (t == best.t && prim < best.prim)) best = {prim, t};
        }
      }
      hits[k] = best;
      if (best.hit() && !buffer_->confirmed(i)) confirm(x, y, best.prim, best.t, rays[k], w);
    }
    const bool same = hits[0].hit() && std::all_of(hits.begin(), hits.end(), [&](const RayHit& h) {
                        return h.prim == hits[0].prim;
                      });
    if (same && try_fill(job, list, n, hits[0].prim, w)) {
      ++w.counters.frustum_fills;
      return;
    }
    split(job, list, n, w);
    return;
  }
}

// Resolves every pixel of the frustum against `element` and the few impinging elements whose
// bounds come nearer than its farthest hit; pixels that miss the element within this cell are
// walked individually. Gives up (returns false, nothing written) when too many elements could
// occlude it.
bool FrustumCaster::try_fill(const Job& job, const Incidence* list, uint32_t n, uint32_t element, Worker& w) {
  const int W = view_.width;
  const int nx = job.x1 - job.x0 + 1, ny = job.y1 - job.y0 + 1;
  w.fill_t.assign(static_cast<size_t>(nx) * static_cast<size_t>(ny), kInfinity);
  // Cheap pre-check with the corners' distance: the far corner bounds most of the fill.
  double max_t = 0.0;
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) {
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(W) + static_cast<size_t>(x);
      if (buffer_->confirmed(i)) continue;
      const Ray ray = view_.ray(x, y);
      const double tmin = view_.tmin(ray);
      const KdTree::Exit e = tree_.exit(job.cell, ray);
      double t;
      ++w.counters.ray_primitive_tests;
      if (scene_.intersect(element, ray, tmin, e.t + cell_slack(e.t, slack_scale_), t)) {
        ++w.counters.hits;
        w.fill_t[static_cast<size_t>(y - job.y0) * nx + static_cast<size_t>(x - job.x0)] = t;
        max_t = std::max(max_t, t);
      }
    }
  }
  w.occluders.clear();
  for (uint32_t j = 0; j < n; ++j) {
    const uint32_t prim = tree_.ref(list[j].ref);
    if (prim == element) continue;
    if (distance_to_box(view_.eye, tree_.ref_bounds(list[j].ref)) <= max_t * (1.0 + 1e-9)) {
      w.occluders.push_back(prim);
      if (w.occluders.size() > kMaxFillOccluders) return false;
    }
  }
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) {
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(W) + static_cast<size_t>(x);
      if (buffer_->confirmed(i)) continue;
      const Ray ray = view_.ray(x, y);
      const double tmin = view_.tmin(ray);
      const double te = w.fill_t[static_cast<size_t>(y - job.y0) * nx + static_cast<size_t>(x - job.x0)];
      if (te == kInfinity) {
        // The element misses this ray inside the cell: walk it like a 2×2 ray.
        ++w.counters.rays_walked;
        const RayHit hit = walk_ray(scene_, tree_, ray, tmin, job.cell, w.counters, marks_);
        confirm(x, y, hit.prim, hit.t, ray, w);
        continue;
      }
      RayHit best{element, te};
      for (uint32_t prim : w.occluders) {
        double t;
        ++w.counters.ray_primitive_tests;
        if (scene_.intersect(prim, ray, tmin, best.t, t)) {
          ++w.counters.hits;
          if (t < best.t || (t == best.t && prim < best.prim)) best = {prim, t};
        }
      }
      confirm(x, y, best.prim, best.t, ray, w);
    }
  }
  return true;
}

// Splits the frustum into two or four children in the same cell. With an incidence list, each
// child inherits the elements not rejected by its new planes; straddle bits carry over.
void FrustumCaster::split(const Job& job, const Incidence* list, uint32_t n, Worker& w) {
  const bool split_x = job.x1 - job.x0 >= 2, split_y = job.y1 - job.y0 >= 2;
  const int xm = (job.x0 + job.x1) / 2, ym = (job.y0 + job.y1) / 2;
  struct Rect { int x0, y0, x1, y1, quadrant; };
  std::array<Rect, 4> rects;
  int count = 0;
  if (split_x && split_y) {
    rects[0] = {job.x0, job.y0, xm, ym, 0};
    rects[1] = {xm, job.y0, job.x1, ym, 1};
    rects[2] = {job.x0, ym, xm, job.y1, 2};
    rects[3] = {xm, ym, job.x1, job.y1, 3};
    count = 4;
  } else if (split_x) {
    rects[0] = {job.x0, job.y0, xm, job.y1, 0};
    rects[1] = {xm, job.y0, job.x1, job.y1, 3};
    count = 2;
  } else {
    rects[0] = {job.x0, job.y0, job.x1, ym, 0};
    rects[1] = {job.x0, ym, job.x1, job.y1, 3};
    count = 2;
  }
  const uint16_t arena_index = w.index;
  for (int c = 0; c < count; ++c) {
    const Rect& r = rects[static_cast<size_t>(c)];
    Job child;
    child.x0 = r.x0;
    child.y0 = r.y0;
    child.x1 = r.x1;
    child.y1 = r.y1;
    child.cell = job.cell;
    if (job.cell == KdTree::kNone) {
      child.state = kFresh;
    } else if (n == 0) {
      child.state = kEmpty;
    } else {
      child.arena = arena_index;
      child.inc_begin = static_cast<uint32_t>(w.arena_out.size());
      const bool new_left = r.x0 != job.x0, new_right = r.x1 != job.x1;
      const bool new_bottom = r.y0 != job.y0, new_top = r.y1 != job.y1;
      for (uint32_t j = 0; j < n; ++j) {
        const Incidence& inc = list[j];
        uint8_t s = inc.straddle;
        const bool spans_x = (s & (kLeft | kRight)) == (kLeft | kRight);
        const bool spans_y = (s & (kBottom | kTop)) == (kBottom | kTop);
        const Aabb& box = tree_.ref_bounds(inc.ref);
        bool rejected = false;
        auto test = [&](bool fresh, bool spans, const Vec3& normal, uint8_t bit) {
          if (rejected || !fresh || spans) return;
          ++w.counters.plane_tests;
          const Side side = classify(normal, box);
          if (side == Side::Outside) {
            rejected = true;
          } else if (side == Side::Straddle) {
            s |= bit;
          } else {
            s &= static_cast<uint8_t>(~bit);
          }
        };
        test(new_left, spans_x, column_normal_[static_cast<size_t>(r.x0)], kLeft);
        test(new_right, spans_x, -column_normal_[static_cast<size_t>(r.x1)], kRight);
        test(new_bottom, spans_y, row_normal_[static_cast<size_t>(r.y0)], kBottom);
        test(new_top, spans_y, -row_normal_[static_cast<size_t>(r.y1)], kTop);
        if (!rejected) w.arena_out.push_back({inc.ref, s});
      }
      child.inc_count = static_cast<uint32_t>(w.arena_out.size()) - child.inc_begin;
      child.state = child.inc_count > 0 ? kList : kEmpty;
    }
    w.children[static_cast<size_t>(r.quadrant)].push_back(child);
  }
}

}  // namespace frontier
