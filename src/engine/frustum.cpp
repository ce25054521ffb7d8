// Frustum casting, the frame and its job queue: construction, begin() (the frame's shared
// pixel planes, the presplit root), run() over levels of the breadth-first subdivision in
// Z order (order_level), the reconstruction anchors of budgeted frames, parking and resuming
// work at missing cells, and confirm(), which writes a resolved pixel into the frame.
//
// Invariants: a level's jobs run in parallel and only read arenas_in_ (the lists the level
// before wrote); each worker writes its children and their lists to its own arena_out, which
// finish_level() turns into the next level's input. run() may stop between jobs (budget) and
// leaves what it did not run in current_, in the order it had; a pixel is confirmed at most
// once per frame (claim()).
#include "src/engine/frustum.h"

#include "src/engine/frustum_internal.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <limits>

namespace frontier {

using namespace frustum_detail;

// Levels of subdivision done before the queue starts (4^4 = 256 tiles): measured faster than
// one root frustum on 1 and 2 threads (large frusta pay corner tests and fill attempts).
constexpr int kPresplitLevels = 4;
// Quadrant order of the reconstruction anchors: diagonal quadrants first, so that an image
// stopped early has them spread over the screen (interleaved order, §5.2).
constexpr std::array<int, 4> kQuadrantOrder = {0, 3, 1, 2};
// A budgeted frame runs each level in runs of this many jobs in Z order, the runs in
// bit-reversed order (order_level). Whole levels in Z order run fastest and a budgeted frame
// stopped early wants its samples spread; runs of 16 keep most of the speed (runs of 4 lose
// more of it) and still spread.
constexpr size_t kOrderRun = 16;

struct FrustumCaster::Arena {
  explicit Arena(int threads) : arena(threads) {}
  tbb::task_arena arena;
};

FrustumCaster::FrustumCaster(const Scene& scene, const KdTree& tree, const Shader& shader, int threads)
    : scene_(scene), tree_(tree), shader_(shader) {
  threads_ = threads > 0 ? threads : tbb::info::default_concurrency();
  // A job names the worker whose list it reads in 16 bits (Job::arena, Worker::index): one
  // worker more than that would wrap around to another's list and read past its end.
  threads_ = std::min(threads_, int{std::numeric_limits<uint16_t>::max()});
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
  buffer.set_sky(shader_.background());
  marks.resize(tree_.cells().size());
  marks.begin_frame();
  samples_done_ = 0;
  ++frame_;
  grow_cell_cache(tree_.cells().size());
  compute_eye_terms(view);
  if (gate_ == nullptr && packets_apply()) {
    if (use_accel_ && !accel_) accel_ = std::make_unique<PrimAccel>(PrimAccel::build(scene_));
    if (!packet_layout_) packet_layout_ = std::make_unique<PacketLayout>(scene_, tree_);
  }
  reset_workers(view.pixels());
  arenas_in_.clear();
  current_.clear();
  held_.clear();
  if (anchor_width_ != view.width || anchor_height_ != view.height) plan_anchors(view.width, view.height);
  anchors_next_ = 0;
  queue_root();
}

// What this frame computes from the eye once: the eye terms of every cone and sphere (offer())
// and one plane per pixel column and row (§3.1: children reuse them).
void FrustumCaster::compute_eye_terms(const View& view) {
  cone_terms_.clear();
  sphere_terms_.clear();
  if (gate_ == nullptr && scene_.cones.size() <= kMaxEyeTerms && scene_.spheres.size() <= kMaxEyeTerms) {
    cone_terms_.reserve(scene_.cones.size());
    for (const Cone& c : scene_.cones) cone_terms_.push_back(cone_from_origin(c, view.eye));
    sphere_terms_.reserve(scene_.spheres.size());
    for (const Sphere& sphere : scene_.spheres) sphere_terms_.push_back(sphere_from_origin(sphere, view.eye));
  }
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
}

// Clears every worker's per-frame state.
void FrustumCaster::reset_workers(size_t pixels) {
  for (auto& w : workers_) {
    // The stamps run on across frames (a 1 MB clear per worker per frame otherwise); a new
    // image size starts them again.
    if (w->slot_stamp.size() != pixels) {
      w->slot_stamp.assign(pixels, 0u);
      w->slot.resize(pixels);
      w->stamp = 0;
    }
    w->children.clear();
    w->arena_out.clear();
    w->remaining.clear();
    w->parked.clear();
    w->reopen.clear();
    w->next_cells.clear();
  }
}

// Queues the whole view as one root frustum from the eye's cell, already split into the first
// kPresplitLevels levels of the subdivision (splitting is always allowed, and a fresh child
// collects its own elements), so that every worker has jobs from the start instead of
// waiting for one root frustum to fan out.
void FrustumCaster::queue_root() {
  Job root;
  root.x0 = 0;
  root.y0 = 0;
  root.x1 = view_.width - 1;
  root.y1 = view_.height - 1;
  root.cell = tree_.locate(view_.eye, view_.forward);
  root.state = kFresh;
  current_.push_back(root);
  level_ordered_ = false;
  for (int level = 0; level < kPresplitLevels; ++level) {
    std::vector<Job> next;  // run() puts each level in its order
    for (const Job& job : current_) {
      const bool split_x = job.x1 - job.x0 >= 2, split_y = job.y1 - job.y0 >= 2;
      if (!split_x && !split_y) {
        next.push_back(job);
        continue;
      }
      const int xm = split_x ? (job.x0 + job.x1) / 2 : job.x1, ym = split_y ? (job.y0 + job.y1) / 2 : job.y1;
      for (int q = 0; q < 4; ++q) {
        const bool right = (q & 1) != 0, lower = (q & 2) != 0;
        if ((right && !split_x) || (lower && !split_y)) continue;
        Job child = job;
        child.x0 = right ? xm : job.x0;
        child.x1 = right || !split_x ? job.x1 : xm;
        child.y0 = lower ? ym : job.y0;
        child.y1 = lower || !split_y ? job.y1 : ym;
        next.push_back(child);
      }
    }
    current_.swap(next);
  }
}

void FrustumCaster::plan_anchors(int width, int height) {
  anchor_width_ = width;
  anchor_height_ = height;
  anchors_.clear();
  std::vector<uint8_t> seen(size_t(width) * size_t(height), 0);
  auto add = [&](int x, int y) {
    const size_t i = size_t(y) * size_t(width) + size_t(x);
    if (!seen[i]) {
      seen[i] = 1;
      anchors_.push_back(uint32_t(i));
    }
  };
  add(0, 0);
  add(width - 1, 0);
  add(0, height - 1);
  add(width - 1, height - 1);
  struct Rect {
    int x0, y0, x1, y1;
  };
  std::vector<Rect> level = {{0, 0, width - 1, height - 1}};
  while (!level.empty()) {
    std::array<std::vector<Rect>, 4> buckets;  // by quadrant, for the interleaved order
    for (const Rect& r : level) {
      if (r.x1 - r.x0 <= kAnchorSpacing && r.y1 - r.y0 <= kAnchorSpacing) continue;
      // The same midpoints as reconstruct() and the frusta.
      const bool split_x = r.x1 - r.x0 >= 2, split_y = r.y1 - r.y0 >= 2;
      const int xm = split_x ? (r.x0 + r.x1) / 2 : r.x0, ym = split_y ? (r.y0 + r.y1) / 2 : r.y0;
      if (split_x) {
        add(xm, r.y0);
        add(xm, r.y1);
      }
      if (split_y) {
        add(r.x0, ym);
        add(r.x1, ym);
      }
      if (split_x && split_y) add(xm, ym);
      buckets[0].push_back({r.x0, r.y0, xm, ym});
      if (split_x) buckets[1].push_back({xm, r.y0, r.x1, ym});
      if (split_y) buckets[2].push_back({r.x0, ym, xm, r.y1});
      if (split_x && split_y) buckets[3].push_back({xm, ym, r.x1, r.y1});
      if (!split_x) buckets[0].back().x1 = r.x1;
      if (!split_y) buckets[0].back().y1 = r.y1;
    }
    level.clear();
    for (int q : kQuadrantOrder) level.insert(level.end(), buckets[size_t(q)].begin(), buckets[size_t(q)].end());
  }
}

// Walks the anchors not yet walked, coarse to fine, on every worker, until the budget is
// spent. An anchor that reaches a missing cell is parked like any pixel.
template <typename OutOfBudget>
void FrustumCaster::walk_anchors(const OutOfBudget& out_of_budget) {
  const int32_t eye_cell = tree_.locate(view_.eye, view_.forward);  // the tree may have grown
  std::atomic<size_t> next{anchors_next_};
  const size_t end = anchors_.size();
  const size_t W = size_t(view_.width);
  arena_->arena.execute([&] {
    tbb::parallel_for(0, threads_, [&](int) {
      Worker& w = current_worker();
      while (!out_of_budget()) {
        const size_t k = next.fetch_add(1, std::memory_order_relaxed);
        if (k >= end) break;
        Job pixel;
        pixel.x0 = pixel.x1 = int32_t(anchors_[k] % W);
        pixel.y0 = pixel.y1 = int32_t(anchors_[k] / W);
        pixel.cell = eye_cell;
        resolve_by_walking(pixel, w, false);
        flush_samples(w);
      }
    });
  });
  anchors_next_ = std::min(next.load(), end);
}

// The worker record of the calling thread of the caster's arena.
FrustumCaster::Worker& FrustumCaster::current_worker() {
  const int slot = std::max(0, tbb::this_task_arena::current_thread_index());
  return *workers_[static_cast<size_t>(std::min(slot, threads_))];
}

bool FrustumCaster::runnable() const {
  if (!current_.empty()) return true;
  for (const auto& w : workers_) {
    if (!w->children.empty()) return true;
  }
  return false;
}

size_t FrustumCaster::queued() const {
  size_t n = current_.size();
  for (const auto& w : workers_) n += w->children.size();
  return n;
}

size_t FrustumCaster::held() const { return held_.size(); }

bool FrustumCaster::complete() const { return !runnable() && parked() == 0 && held_.empty(); }

size_t FrustumCaster::parked() const {
  size_t n = 0;
  for (const auto& w : workers_) n += w->parked.size();
  return n;
}

// Whether `cell` is not paged in; then the gate is asked for it.
bool FrustumCaster::gate_missing(int32_t cell) const {
  if (gate_ == nullptr || !gate_->missing(cell)) return false;
  gate_->want(cell);
  return true;
}

// Keeps the job until resume_parked() queues it again from the eye.
void FrustumCaster::park(const Job& job, Worker& w) const {
  ++w.counters.parks;
  Job parked = job;
  parked.state = kFresh;
  parked.inc_count = 0;
  w.parked.push_back(parked);
}

// A pixel whose sample must wait for a missing cell: resolved again, alone, from the eye.
void FrustumCaster::park_pixel(int x, int y, Worker& w) const {
  Job job;
  job.x0 = job.x1 = x;
  job.y0 = job.y1 = y;
  park(job, w);
}

// Pixels whose shadow rays crossed missing cells become unsampled again and wait, each alone,
// for those cells (resume_parked() resolves them again from the eye).
void FrustumCaster::reopen_unshaded() {
  const uint32_t W = static_cast<uint32_t>(view_.width);
  for (auto& w : workers_) {
    for (const uint32_t i : w->reopen) {
      buffer_->unconfirm(i);
      park_pixel(int(i % W), int(i / W), *w);
    }
    w->reopen.clear();
  }
}

void FrustumCaster::tree_changed() {
  const size_t cells = tree_.cells().size();
  marks_->grow(cells);
  for (auto& w : workers_) w->next_cells.clear();  // cells may have become subtrees
  grow_cell_cache(cells);
}

void FrustumCaster::grow_cell_cache(size_t cells) {
  if (cell_cache_count_ >= cells) return;
  // Entries move along (this frame's stay valid; earlier frames' are stale by their stamps);
  // new cells start unstamped. Grown geometrically: a paged walk's tree gains cells every
  // image, and an exact fresh array each time cost page faults over every entry (a fifth of
  // the page-fault time of a pegged exterior orbit).
  const size_t capacity = std::max(cells, cell_cache_count_ + cell_cache_count_ / 2);
  auto bigger = std::make_unique<CellCache[]>(capacity);
  for (size_t c = 0; c < cell_cache_count_; ++c) {
    bigger[c].entries = std::move(cell_cache_[c].entries);
    bigger[c].stamp.store(cell_cache_[c].stamp.load(std::memory_order_relaxed), std::memory_order_relaxed);
    bigger[c].seen.store(cell_cache_[c].seen.load(std::memory_order_relaxed), std::memory_order_relaxed);
  }
  cell_cache_ = std::move(bigger);
  cell_cache_count_ = capacity;
}

// Parked work starts again from the eye: the cell it waited for may have been refined into a
// subtree since, and walking the cells in front of it again finds nothing new (deterministic).
void FrustumCaster::resume_parked() {
  const int32_t eye_cell = tree_.locate(view_.eye, view_.forward);
  for (auto& w : workers_) {
    for (Job job : w->parked) {
      job.cell = eye_cell;
      job.state = kFresh;
      current_.push_back(job);
    }
    w->parked.clear();
  }
  level_ordered_ = false;
}

void FrustumCaster::renumbered() {
  ++frame_;  // every cell's incidence list and first-visit stamp is stale
  arenas_in_.clear();
  marks_->resize(tree_.cells().size());
  marks_->begin_frame();
  tree_changed();
}

uint64_t FrustumCaster::hold_parked(uint64_t pixels) {
  auto area = [](const Job& j) { return uint64_t(j.x1 - j.x0 + 1) * uint64_t(j.y1 - j.y0 + 1); };
  std::vector<Job> jobs;
  jobs.swap(held_);
  for (auto& w : workers_) {
    jobs.insert(jobs.end(), w->parked.begin(), w->parked.end());
    w->parked.clear();
  }
  order_level(jobs, false);
  // The first job alone is larger than asked for: its halves (across its longer side, sharing
  // no pixel, so that every job of more than one pixel splits) take its place.
  while (!jobs.empty() && area(jobs.front()) > std::max<uint64_t>(pixels, 1)) {
    Job first = jobs.front(), second = first;
    if (first.x1 - first.x0 >= first.y1 - first.y0) {
      first.x1 = (first.x0 + first.x1) / 2;
      second.x0 = first.x1 + 1;
    } else {
      first.y1 = (first.y0 + first.y1) / 2;
      second.y0 = first.y1 + 1;
    }
    jobs.front() = second;
    jobs.insert(jobs.begin(), first);
  }
  uint64_t taken = 0;
  size_t k = 0;
  while (k < jobs.size() && (k == 0 || taken + area(jobs[k]) <= pixels)) taken += area(jobs[k++]);
  workers_.front()->parked.assign(jobs.begin(), jobs.begin() + std::ptrdiff_t(k));
  held_.assign(jobs.begin() + std::ptrdiff_t(k), jobs.end());
  return taken;
}

bool FrustumCaster::run(const FrameBudget& budget, Counters& counters) {
  const auto start = std::chrono::steady_clock::now();
  const auto deadline = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                    std::chrono::duration<double, std::milli>(budget.ms));
  auto out_of_budget = [&]() {
    if (count_samples_ && samples_done_.load(std::memory_order_relaxed) >= budget.samples) return true;
    return budget.ms > 0.0 && std::chrono::steady_clock::now() >= deadline;
  };
  for (auto& w : workers_) {
    w->counters = Counters{};
    w->flushed = 0;
  }
  // The shared sample count is only kept while a sample budget needs it (one contended
  // atomic per pixel otherwise). A later run with a sample budget starts counting from there.
  count_samples_ = budget.samples > 0;
  budgeted_ = budget.ms > 0.0 || budget.samples > 0;
  if (count_samples_) samples_done_ = 0;
  if (anchors_next_ < anchors_.size()) {
    if (budget.ms > 0.0 || budget.samples > 0) {
      walk_anchors(out_of_budget);
    } else {
      anchors_next_ = anchors_.size();
    }
  }
  bool interrupted = false;
  while (runnable() && !interrupted) {
    if (current_.empty()) finish_level();
    // A level is put in order once: the jobs an interrupted run leaves keep theirs.
    if (!level_ordered_) order_level(current_, budget.ms > 0.0 || budget.samples > 0);
    level_ordered_ = true;
    std::vector<Job> level;
    level.swap(current_);
    arena_->arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, level.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        Worker& w = current_worker();
        for (size_t i = r.begin(); i != r.end(); ++i) {
          if (out_of_budget()) {
            w.remaining.push_back(level[i]);
          } else {
            process(level[i], w);
            flush_samples(w);
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
  reopen_unshaded();
  for (auto& w : workers_) counters += w->counters;
  counters.ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return complete();
}

// The children the workers made become the next level, and their lists the arenas it reads.
void FrustumCaster::finish_level() {
  level_ordered_ = false;
  arenas_in_.resize(workers_.size());
  for (size_t k = 0; k < workers_.size(); ++k) {
    arenas_in_[k].swap(workers_[k]->arena_out);
    workers_[k]->arena_out.clear();
  }
  for (auto& w : workers_) {
    current_.insert(current_.end(), w->children.begin(), w->children.end());
    w->children.clear();
  }
}

// The order a level's jobs run in: Z order of their corners, so that sibling and neighbouring
// frusta run one after the other and find their cells and lists in cache (the order the
// workers produced them in scattered siblings across their runs). A budgeted frame may stop within the level: there the Z order is cut
// into runs of kOrderRun jobs taken in bit-reversed order, so that the runs done when it stops
// are spread over the screen (§5.2's interleaving) and siblings still run together.
void FrustumCaster::order_level(std::vector<Job>& level, bool budgeted) {
  auto spread = [](uint32_t v) {  // the bits of v at the even positions of a 32-bit word
    v &= 0xFFFFu;
    v = (v | (v << 8)) & 0x00FF00FFu;
    v = (v | (v << 4)) & 0x0F0F0F0Fu;
    v = (v | (v << 2)) & 0x33333333u;
    v = (v | (v << 1)) & 0x55555555u;
    return v;
  };
  std::vector<std::pair<uint32_t, uint32_t>> keys(level.size());  // Z key, job
  for (size_t i = 0; i < level.size(); ++i) {
    keys[i] = {spread(uint32_t(level[i].x0)) | (spread(uint32_t(level[i].y0)) << 1), uint32_t(i)};
  }
  std::sort(keys.begin(), keys.end());
  std::vector<Job> sorted;
  sorted.reserve(level.size());
  for (const auto& key : keys) sorted.push_back(level[key.second]);
  level.swap(sorted);
  if (!budgeted) return;
  const size_t runs = (level.size() + kOrderRun - 1) / kOrderRun;
  int bits = 0;
  while ((size_t{1} << bits) < runs) ++bits;
  std::vector<Job> ordered;
  ordered.reserve(level.size());
  for (size_t k = 0; k < (size_t{1} << bits); ++k) {
    size_t run = 0;  // k with its bits reversed
    for (int b = 0; b < bits; ++b) run |= ((k >> b) & 1u) << (bits - 1 - b);
    if (run >= runs) continue;
    const size_t end = std::min(level.size(), (run + 1) * kOrderRun);
    ordered.insert(ordered.end(), level.begin() + std::ptrdiff_t(run * kOrderRun), level.begin() + std::ptrdiff_t(end));
  }
  level.swap(ordered);
}

// Writes pixel (x, y)'s hit (kNoPrim: background) and its shade, at most once per frame.
// In a paged scene the shadow rays of a hit may cross missing cells: then the pixel is shaded
// before it is claimed, and reopened instead of written when its colour is not final.
void FrustumCaster::confirm(const Job& job, int x, int y, uint32_t prim, double t, const Ray& ray, Worker& w) {
  const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x);
  Rgb color;
  if (gate_ != nullptr && prim != kNoPrim && shade_ && shadows_ && shader_.effects().shadows) {
    if (buffer_->confirmed(i)) return;
    ShadowCells cells{gate_, marks_};
    color = shader_.shade(prim, ray, t, true, w.counters, &cells);
    if (!claim(job, x, y, i)) return;
    if (cells.missing) {
      // Claimed, so that this job and its neighbours go on without it; reopened and parked
      // when the slice ends (reopen_unshaded).
      w.reopen.push_back(static_cast<uint32_t>(i));
      return;
    }
  } else {
    if (!claim(job, x, y, i)) return;
    color = prim == kNoPrim ? shader_.background() : shade_ ? shader_.shade(prim, ray, t, shadows_, w.counters) : Rgb{};
  }
  buffer_->set(i, prim, t, color);
  ++w.counters.samples;
  ++w.counters.rays;
}

// Adds the worker's samples since the last call to the shared count a sample budget reads
// (between jobs, where the budget is checked).
void FrustumCaster::flush_samples(Worker& w) {
  const uint64_t added = w.counters.samples - w.flushed;
  if (count_samples_ && added > 0) samples_done_.fetch_add(added, std::memory_order_relaxed);
  w.flushed = w.counters.samples;
}

}  // namespace frontier
