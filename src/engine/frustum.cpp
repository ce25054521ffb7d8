// Frustum casting: the job queue, frustum advance, incidence lists and the fill test.
#include "src/engine/frustum.h"

#include "src/engine/ray_walk.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>

namespace frontier {

namespace {

constexpr uint8_t kLeft = 1, kRight = 2, kBottom = 4, kTop = 8;  // straddle bits per plane
constexpr uint32_t kMaxFillOccluders = 6;
// Look-ahead (gather_ahead): at most this many tree nodes and references examined, at most
// this many elements found, for frusta one or two levels above the leaf size. Leaf frusta
// mostly find more than the limit, larger ones pay to search and seldom succeed; a larger
// limit, or a smaller or larger budget, did no better.
constexpr size_t kAheadBudget = 256;
constexpr size_t kAheadLimit = 4;
constexpr int kAheadMaxSpan = 4;  // in leaf sizes
// Frusta of at least this many pixels try the plane fill (fill_plane).
constexpr int kPlaneFillMinPixels = 16;
// Triangles covering the frustum whose corners it tests (a quad's two halves both cover it).
constexpr uint32_t kPlaneFillCandidates = 3;
// Resolve a frustum in its cell when the elements' screen footprints add up to at most this
// many times its pixel count; otherwise subdivide.
constexpr double kResolveFactor = 2.0;
// Frusta up to this many pixels count their open pixels exactly after resolving in a cell.
constexpr size_t kExactOpenCount = 64;
// Small frusta (pixels × elements up to this) resolve pixel by pixel with depth early-out.
constexpr size_t kPixelMajorWork = 4096;
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

// True when the four corner rays agree (same entry/exit face, same next cell).
template <typename T>
bool all_same(const std::array<T, 4>& v) {
  return v[1] == v[0] && v[2] == v[0] && v[3] == v[0];
}

}  // namespace

struct FrustumCaster::Job {
  int32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // inclusive pixel rectangle; corners are its rays
  int32_t cell = KdTree::kNone;            // current cell; kNone = not yet inside the root
  uint32_t inc_begin = 0, inc_count = 0;   // incidence list in arenas_in_[arena]
  uint16_t arena = 0;
  uint8_t state = 0;                       // kFresh, kEmpty or kList
  bool small(int leaf) const { return x1 - x0 < leaf && y1 - y0 < leaf; }
};

namespace {
constexpr uint8_t kFresh = 0, kEmpty = 1, kList = 2;
}

namespace {

struct Pixel {
  int x = 0, y = 0;
  Ray ray;
  double tmin = 0.0, tmax = 0.0;
  RayHit hit;
};

}  // namespace

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

struct FrustumCaster::CellCache {
  std::atomic<uint32_t> stamp{0};  // frame whose entries these are
  std::atomic<uint32_t> seen{0};   // frame in which a lone pixel walk tested the cell directly
  std::vector<Incidence> entries;
};

namespace {
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
}  // namespace

struct FrustumCaster::Worker {
  std::vector<Job> children;                 // next level
  std::vector<Incidence> arena_out;          // incidence lists of those children
  std::vector<Job> remaining;                // jobs skipped because the budget ran out
  std::vector<Job> parked;                   // jobs that reached a missing cell (paging)
  std::vector<Incidence> scratch;            // a freshly collected list
  std::vector<double> fill_t;                // per-pixel hits of the fill element
  std::vector<uint32_t> occluders;
  std::vector<PixelRect> rects;              // screen footprints of the incidence list
  // resolve_in_cell's sparse per-pixel state: slot_stamp[i] == stamp marks pixel i as seen in
  // this call, slot[i] indexes `open` (a frame-sized map without clearing).
  std::vector<uint32_t> slot_stamp, slot;
  uint32_t stamp = 0;
  std::vector<Pixel> open;
  NextCells next_cells;                         // lone pixel walks' arrivals
  std::vector<AheadNode> nodes;                 // gather_ahead's descent stack,
  std::vector<AheadElement> ahead;              // the elements it found
  std::vector<int32_t> ahead_cells;             // and the cells it read them from
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
  ++frame_;
  if (cell_cache_count_ < tree_.cells().size()) {
    cell_cache_count_ = tree_.cells().size();
    cell_cache_ = std::make_unique<CellCache[]>(cell_cache_count_);
  }
  cone_terms_.clear();
  sphere_terms_.clear();
  if (gate_ == nullptr && scene_.cones.size() <= kMaxEyeTerms && scene_.spheres.size() <= kMaxEyeTerms) {
    cone_terms_.reserve(scene_.cones.size());
    for (const Cone& c : scene_.cones) cone_terms_.push_back(cone_from_origin(c, view.eye));
    sphere_terms_.reserve(scene_.spheres.size());
    for (const Sphere& sphere : scene_.spheres) sphere_terms_.push_back(sphere_from_origin(sphere, view.eye));
  }
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
    // The stamps run on across frames (a 1 MB clear per worker per frame otherwise); a new
    // image size starts them again.
    if (w->slot_stamp.size() != view.pixels()) {
      w->slot_stamp.assign(view.pixels(), 0u);
      w->slot.resize(view.pixels());
      w->stamp = 0;
    }
    w->children.clear();
    w->arena_out.clear();
    w->remaining.clear();
    w->parked.clear();
    w->next_cells.clear();
  }
  arenas_in_.clear();
  current_.clear();
  if (anchor_width_ != view.width || anchor_height_ != view.height) plan_anchors(view.width, view.height);
  anchors_next_ = 0;
  Job root;
  root.x0 = 0;
  root.y0 = 0;
  root.x1 = view.width - 1;
  root.y1 = view.height - 1;
  root.cell = tree_.locate(view.eye, view.forward);
  root.state = kFresh;
  // The first levels of the subdivision are done up front (splitting is always allowed, and
  // a fresh child collects its own elements), so that every worker has jobs from the start
  // instead of waiting for one root frustum to fan out.
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

bool FrustumCaster::complete() const { return !runnable() && parked() == 0; }

size_t FrustumCaster::parked() const {
  size_t n = 0;
  for (const auto& w : workers_) n += w->parked.size();
  return n;
}

bool FrustumCaster::gate_missing(int32_t cell) const {
  if (gate_ == nullptr || !gate_->missing(cell)) return false;
  gate_->want(cell);
  return true;
}

void FrustumCaster::park(const Job& job, Worker& w) const {
  Job parked = job;
  parked.state = kFresh;
  parked.inc_count = 0;
  w.parked.push_back(parked);
}

void FrustumCaster::tree_changed() {
  const size_t cells = tree_.cells().size();
  marks_->grow(cells);
  for (auto& w : workers_) w->next_cells.clear();  // cells may have become subtrees
  if (cell_cache_count_ < cells) {
    // Entries of this frame move along; new cells start unstamped. Grown geometrically: a
    // walk grafts a few cells at a time.
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

bool FrustumCaster::run(const FrameBudget& budget, Counters& counters) {
  const auto start = std::chrono::steady_clock::now();
  const auto deadline = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                    std::chrono::duration<double, std::milli>(budget.ms));
  auto out_of_budget = [&]() {
    if (count_samples_ && samples_done_.load(std::memory_order_relaxed) >= budget.samples) return true;
    return budget.ms > 0.0 && std::chrono::steady_clock::now() >= deadline;
  };
  for (auto& w : workers_) w->counters = Counters{};
  // The shared sample count is only kept while a sample budget needs it (one contended
  // atomic per pixel otherwise). A later run with a sample budget starts counting from there.
  count_samples_ = budget.samples > 0;
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

// offer_primitive for a ray from the eye: cones and spheres use this frame's eye terms
// (bit-identical to intersect_cone and intersect_sphere; a cone test costs about a third less).
[[gnu::always_inline]] inline void FrustumCaster::offer(uint32_t prim, const Ray& ray, double tmin, double tmax, RayHit& best,
                          Counters& counters) const {
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

// A pixel strictly inside a job's rectangle belongs to that job alone (live jobs are never
// nested and overlap only on the edges they share with siblings), so it is claimed without an
// atomic read-modify-write, which costs much of a frame where one element fills the view.
bool FrustumCaster::claim(const Job& job, int x, int y, size_t i) const {
  const bool interior = x > job.x0 && x < job.x1 && y > job.y0 && y < job.y1;
  return interior ? buffer_->claim_exclusive(i) : buffer_->claim(i);
}

void FrustumCaster::confirm(const Job& job, int x, int y, uint32_t prim, double t, const Ray& ray, Worker& w) {
  const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x);
  if (!claim(job, x, y, i)) return;
  const Rgb color = prim == kNoPrim ? shader_.background()
                    : shade_        ? shader_.shade(prim, ray, t, shadows_, w.counters)
                                    : Rgb{};
  buffer_->set(i, prim, t, color);
  ++w.counters.samples;
  ++w.counters.rays;
  if (count_samples_) samples_done_.fetch_add(1, std::memory_order_relaxed);
}

void FrustumCaster::fill_background(const Job& job, Worker& w) {
  const Rgb bg = shader_.background();
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) {
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x);
      if (!claim(job, x, y, i)) continue;
      buffer_->set(i, kNoPrim, kInfinity, bg);
      ++w.counters.samples;
      ++w.counters.rays;
      if (count_samples_) samples_done_.fetch_add(1, std::memory_order_relaxed);
    }
  }
}

void FrustumCaster::resolve_by_walking(const Job& job, Worker& w, bool from_next_cell) {
  for (int y = job.y0; y <= job.y1; ++y) {
    for (int x = job.x0; x <= job.x1; ++x) {
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x);
      if (buffer_->confirmed(i)) continue;
      const Ray ray = view_.ray(x, y);
      const double tmin = view_.tmin(ray);
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
      Job job;
      job.x0 = job.x1 = x;
      job.y0 = job.y1 = y;
      park(job, w);
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

// Builds the incidence list of job.cell into w.scratch: references whose clipped bounds are not
// outside any frustum plane. Returns false when the list is empty.
bool FrustumCaster::collect(const Job& job, Worker& w) {
  w.scratch.clear();
  const std::vector<Incidence>& entries = cell_entries(job.cell);
  w.counters.primitives_tested += entries.size();
  for (const Incidence& e : entries) {
    ++w.counters.plane_tests;
    if (e.bounded) {
      if (e.x1 < job.x0 || e.x0 > job.x1 || e.y1 < job.y0 || e.y0 > job.y1) continue;
      w.scratch.push_back(e);
      continue;
    }
    Incidence inc = e;
    if (classify_planes(job.x0, job.x1, job.y0, job.y1, tree_.ref_bounds(e.ref), 0xF, inc.straddle)) {
      w.scratch.push_back(inc);
    }
  }
  return !w.scratch.empty();
}

// Classifies bounds against the planes named in `planes` (kLeft... bits) of the frustum
// x0..x1, y0..y1; updates the straddle bits. False when some plane rejects the bounds.
bool FrustumCaster::classify_planes(int x0, int x1, int y0, int y1, const Aabb& box, uint8_t planes,
                                    uint8_t& straddle) const {
  auto test = [&](uint8_t bit, const Vec3& normal) {
    if (!(planes & bit)) return true;
    const Side side = classify(normal, box);
    if (side == Side::Outside) return false;
    if (side == Side::Straddle) {
      straddle |= bit;
    } else {
      straddle &= static_cast<uint8_t>(~bit);
    }
    return true;
  };
  return test(kLeft, column_normal_[size_t(x0)]) && test(kRight, -column_normal_[size_t(x1)]) &&
         test(kBottom, row_normal_[size_t(y0)]) && test(kTop, -row_normal_[size_t(y1)]);
}

void FrustumCaster::process(Job job, Worker& w) {
  const std::array<std::array<int, 2>, 4> corner = {{{job.x0, job.y0}, {job.x1, job.y0},
                                                     {job.x0, job.y1}, {job.x1, job.y1}}};
  std::array<Ray, 4> rays;
  std::array<double, 4> tmins;
  for (size_t k = 0; k < 4; ++k) {
    rays[k] = view_.ray(corner[k][0], corner[k][1]);
    tmins[k] = view_.tmin(rays[k]);
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
      if (cells[0] != KdTree::kNone && faces[0] >= 0 && all_same(cells) && all_same(faces)) {
        job.cell = cells[0];
        job.state = kFresh;
        continue;
      }
      if (job.small(leaf_)) {
        resolve_by_walking(job, w, false);
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
    if (gate_missing(job.cell)) {
      park(job, w);
      return;
    }
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

    if (n > 0 && fill_plane(job, list, n, rays, tmins, &tree_.cell(job.cell).bounds, w)) return;
    if (n > 0 && !job.small(leaf_) && fill_plane_ahead(job, list, n, rays, tmins, w)) return;
    if (n > 0) {
      // Either resolve the frustum's pixels against this cell's elements now (cheap when the
      // elements' screen footprints are small against the frustum), or subdivide (§3.2).
      const size_t npix = size_t(job.x1 - job.x0 + 1) * size_t(job.y1 - job.y0 + 1);
      const bool have_rects = !job.small(leaf_);
      if (job.small(leaf_) || footprint(job, list, n, w) <= kResolveFactor * double(npix)) {
        if (resolve_in_cell(job, list, n, have_rects, w) == 0) return;
      } else {
        if (corners_and_fill(job, list, n, rays, tmins, w)) return;
        split(job, list, n, w);
        return;
      }
    }

    // Nothing left to find in this cell for the unresolved pixels: advance if all corner rays
    // leave through one face into one cell (every interior ray then does the same).
    // The arrival cell is looked up only when the faces agree, and only for the first corner:
    // the others are checked against it with a box test (a corner on an edge of that cell's
    // face counts as disagreeing, which only costs a split).
    std::array<KdTree::Exit, 4> exits;
    for (size_t k = 0; k < 4; ++k) exits[k] = tree_.exit(job.cell, rays[k]);
    const std::array<int, 4> faces = {exits[0].face, exits[1].face, exits[2].face, exits[3].face};
    if (faces[0] >= 0 && all_same(faces)) {
      const int32_t next = tree_.arrival(job.cell, rays[0], exits[0]);
      if (next == KdTree::kNone && tree_.cell(job.cell).rope[faces[0]] == KdTree::kNone) {
        fill_background(job, w);  // every corner leaves the root through this face
        return;
      }
      bool same = next != KdTree::kNone;
      for (size_t k = 1; k < 4 && same; ++k) same = tree_.arrives_in(job.cell, rays[k], exits[k], next);
      if (same) {
        job.cell = next;
        job.state = kFresh;
        continue;
      }
    }
    // The frustum goes on through several cells. Before splitting it, ask the tree whether
    // only a few elements (or none) lie ahead of it: then its pixels test just those.
    if (!job.small(leaf_) && job.small(kAheadMaxSpan * leaf_) && gather_ahead(job, rays, nullptr, kAheadLimit, w)) {
      ++w.counters.frustum_lookaheads;
      resolve_against_ahead(job, rays, tmins, w);
      return;
    }
    if (job.small(leaf_)) {
      resolve_by_walking(job, w, true);
      return;
    }
    split(job, nullptr, 0, w);
    return;
  }
}

// The elements that could still be hit inside the frustum beyond its current cell, into
// w.ahead (with `before`, only those that could come before that triangle's plane): a descent
// of the whole tree keeping nodes whose bounds are not outside the frustum's planes, then the
// references of the cells it reaches, each tested by its bounds and by its own shape
// (Scene::below_plane). False when it gives up: more than `limit` elements, more than
// kAheadBudget nodes and references examined, or a cell not paged in.
// Nothing is missed: every ray of the frustum has already tested what lies in and before its
// current cell (the frustum crossed those cells whole), and leaves the current cell through a
// face its direction points to, so what lies ahead is beyond that face. On success, the cells
// whose references it read count as touched.
bool FrustumCaster::gather_ahead(const Job& job, const std::array<Ray, 4>& rays, const Triangle* before,
                                 size_t limit, Worker& w) const {
  // Planes as normal · (p - origin) >= 0 for what may lie inside; all but `before`'s pass
  // through the eye.
  std::array<Vec3, 8> planes = {column_normal_[size_t(job.x0)], -column_normal_[size_t(job.x1)],
                                row_normal_[size_t(job.y0)], -row_normal_[size_t(job.y1)]};
  std::array<Vec3, 8> origins;
  origins.fill(view_.eye);
  size_t plane_count = 4;
  if (before != nullptr) {
    // Only what lies in front of the triangle's plane, seen from the eye, can come before it.
    Vec3 n = glm::cross(before->v1 - before->v0, before->v2 - before->v0);
    if (glm::dot(n, view_.eye - before->v0) < 0.0) n = -n;
    planes[plane_count] = n;
    origins[plane_count++] = before->v0;
  }
  // Every ray of the frustum is inside the current cell and leaves it through a face its
  // direction points to: what lies ahead is beyond one of those faces. An axis on which all
  // directions agree in sign also separates: the frustum lies on one side of the eye's plane.
  const Aabb& here = tree_.cell(job.cell).bounds;
  std::array<bool, 3> pos{}, neg{};
  for (int a = 0; a < 3; ++a) {
    for (const Ray& corner : rays) {  // every direction of the frustum is a blend of these
      pos[size_t(a)] = pos[size_t(a)] || corner.dir[a] >= 0.0;
      neg[size_t(a)] = neg[size_t(a)] || corner.dir[a] <= 0.0;
    }
    if (pos[size_t(a)] != neg[size_t(a)]) {
      Vec3 n{0.0};
      n[a] = pos[size_t(a)] ? 1.0 : -1.0;
      planes[plane_count++] = n;
    }
  }
  std::array<Vec3, 8> reach;  // |normal| per axis: a box's half extent along the normal
  std::array<double, 8> offset;  // normal · (origin - eye)
  for (size_t k = 0; k < plane_count; ++k) {
    reach[k] = glm::abs(planes[k]);
    offset[k] = glm::dot(planes[k], origins[k] - view_.eye);
  }
  const Vec3& f = view_.forward;
  const Vec3 f_reach = glm::abs(f);
  // The planes a box may still straddle, as bits (kNearPlane: the near plane); a box inside a
  // plane has every sub-box inside it, so descendants and references skip that plane. The
  // tests are classify() and in_front(), with the same tolerances.
  constexpr uint16_t kNearPlane = 0x100;
  const uint16_t all_planes = uint16_t(kNearPlane | ((1u << plane_count) - 1u));
  // The remaining planes of `box`, or -1 when it is not ahead or lies outside a plane.
  auto inside = [&](const Aabb& box, uint16_t mask) -> int {
    bool ahead = false;
    for (int a = 0; a < 3; ++a) {
      ahead = ahead || (pos[size_t(a)] && box.hi[a] >= here.hi[a]) || (neg[size_t(a)] && box.lo[a] <= here.lo[a]);
    }
    if (!ahead) return -1;
    const Vec3 c = box.center() - view_.eye;
    const Vec3 h = 0.5 * box.extent();
    for (size_t k = 0; k < plane_count; ++k) {
      if (!(mask & (1u << k))) continue;
      ++w.counters.plane_tests;
      const double s = glm::dot(planes[k], c) - offset[k], r = glm::dot(reach[k], h);
      const double tol = 1e-9 * (std::abs(s) + std::abs(offset[k]) + r) + 1e-300;
      if (s + r < -tol) return -1;
      if (s - r > tol) mask = uint16_t(mask & ~(1u << k));
    }
    if (mask & kNearPlane) {
      const double s = glm::dot(f, c), r = glm::dot(f_reach, h);
      const double tol = 1e-9 * (std::abs(s + r) + glm::length(c) + 1e-300);
      if (s + r < view_.near - tol) return -1;
      if (s - r > view_.near + tol) mask = uint16_t(mask & ~kNearPlane);
    }
    return mask;
  };
  w.ahead.clear();
  w.ahead_cells.clear();
  w.nodes.clear();
  w.nodes.push_back({0, all_planes, tree_.bounds()});
  size_t budget = kAheadBudget;
  while (!w.nodes.empty()) {
    if (budget-- == 0) return false;
    const AheadNode top = w.nodes.back();
    w.nodes.pop_back();
    const KdTree::Node& node = tree_.nodes()[size_t(top.node)];
    if (node.is_link()) {
      w.nodes.push_back({int32_t(node.child), top.planes, top.box});
      continue;
    }
    if (node.is_leaf()) {
      const int32_t c = int32_t(node.child);
      if (c == job.cell) continue;
      const KdTree::Cell& cell = tree_.cell(c);
      const bool missing = gate_ != nullptr && gate_->missing(c);
      if (!(cell.count > 0 || missing)) continue;
      const int cell_planes = inside(cell.content, top.planes);
      if (cell_planes < 0) continue;
      if (missing) return false;
      w.ahead_cells.push_back(c);
      for (uint32_t r = cell.first; r < cell.first + cell.count; ++r) {
        if (budget-- == 0) return false;
        const Aabb& bounds = tree_.ref_bounds(r);
        const int ref_planes = inside(bounds, uint16_t(cell_planes));
        if (ref_planes < 0) continue;
        const uint32_t prim = tree_.ref(r);
        const auto found = std::find_if(w.ahead.begin(), w.ahead.end(),
                                        [&](const AheadElement& e) { return e.prim == prim; });
        if (found != w.ahead.end()) {
          found->bounds.extend(bounds);
          continue;
        }
        // Only a plane the bounds straddle can have the element wholly behind it.
        bool out = false;
        for (size_t k = 0; k < plane_count && !out; ++k) {
          out = (ref_planes & (1 << k)) && scene_.below_plane(prim, origins[k], planes[k]);
        }
        if (out) continue;
        if (w.ahead.size() == limit) return false;
        w.ahead.push_back({prim, r, bounds});
      }
      continue;
    }
    const int a = int(node.axis_or_leaf);
    Aabb lower = top.box, upper = top.box;
    lower.hi[a] = node.split;
    upper.lo[a] = node.split;
    const int lower_planes = inside(lower, top.planes), upper_planes = inside(upper, top.planes);
    // Nearer child on top of the stack: a crowded frustum meets its limit sooner.
    const bool upper_near = view_.eye[a] >= node.split;
    if (!upper_near && upper_planes >= 0) w.nodes.push_back({int32_t(node.child), uint16_t(upper_planes), upper});
    if (lower_planes >= 0) w.nodes.push_back({top.node + 1, uint16_t(lower_planes), lower});
    if (upper_near && upper_planes >= 0) w.nodes.push_back({int32_t(node.child), uint16_t(upper_planes), upper});
  }
  for (int32_t c : w.ahead_cells) {
    if (marks_->mark(c)) ++w.counters.cells_touched;
  }
  return true;
}

// Every open pixel of the frustum against the elements gather_ahead found, along the whole
// ray: they are listed like a cell's elements (screen rectangles, nearest first), and a pixel
// that hits none of them is background. When the corner rays all hit one of them, a triangle,
// inside, the pixels take their distance from its plane (fill_plane with no cell to stay in:
// nothing else lies ahead but the other elements found).
void FrustumCaster::resolve_against_ahead(const Job& job, const std::array<Ray, 4>& rays,
                                          const std::array<double, 4>& tmins, Worker& w) {
  if (w.ahead.empty()) {
    fill_background(job, w);
    return;
  }
  w.scratch.clear();
  for (const AheadElement& e : w.ahead) w.scratch.push_back(incidence(e.ref, e.bounds));
  std::sort(w.scratch.begin(), w.scratch.end(),
            [](const Incidence& a, const Incidence& b) { return a.distance < b.distance; });
  const Incidence* list = w.scratch.data();
  const uint32_t n = uint32_t(w.scratch.size());
  w.counters.primitives_tested += n;
  if (fill_plane(job, list, n, rays, tmins, nullptr, w)) return;
  resolve_pixel_major(job, list, n, true, w);
}

// The references of a cell with their screen rectangles and eye distances, sorted nearest
// first, built once per frame by the first thread that needs them (the others wait on a
// striped lock or read the finished list). For bounds in front of the eye, testing the
// rectangle against a frustum's pixel rectangle is the ternary classification against its
// four planes (every pixel column and row is one plane through the eye), done once per frame
// instead of once per frustum. Bounds wholly behind the near plane are left out.
bool FrustumCaster::first_pixel_visit(int32_t cell) const {
  CellCache& cache = cell_cache_[size_t(cell)];
  if (cache.stamp.load(std::memory_order_acquire) == frame_) return false;  // listed already
  if (cache.seen.load(std::memory_order_relaxed) == frame_) return false;
  return cache.seen.exchange(frame_, std::memory_order_relaxed) != frame_;
}

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
          w.open.push_back(p);
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

// The §4 fill across cells, for a triangle of the list whose plane the corner rays reach
// beyond this cell (a floor seen across many cells). When they hit its interior anywhere along
// the rays, every ray of the frustum hits it (fill_plane's argument without the cell). What
// could come nearer is an element of this cell nearer than the farthest corner hit, or one
// ahead of this cell in front of the triangle's plane (gather_ahead with that plane; the
// cells before this one held nothing for the open pixels). With at most kMaxFillOccluders of
// them, every pixel takes its distance from the plane and tests those.
bool FrustumCaster::fill_plane_ahead(const Job& job, const Incidence* list, uint32_t n,
                                     const std::array<Ray, 4>& rays, const std::array<double, 4>& tmins, Worker& w) {
  Vec3 normal;
  double max_t = 0.0;
  const uint32_t candidate = plane_candidate(job, list, n, rays, tmins, nullptr, normal, max_t, w);
  if (candidate == n) return false;
  const uint32_t element = tree_.ref(list[candidate].ref);
  // The limit leaves room for the triangle itself, which lies on its own plane.
  if (!gather_ahead(job, rays, &scene_.triangles[scene_.prims[element].index], kMaxFillOccluders + 1, w)) {
    return false;
  }
  w.occluders.clear();
  for (const AheadElement& e : w.ahead) {
    if (e.prim != element && !coplanar(e.prim, element, normal)) w.occluders.push_back(e.prim);
  }
  if (w.occluders.size() > kMaxFillOccluders || !add_list_occluders(job, list, n, element, normal, max_t, w)) {
    return false;
  }
  fill_from_plane(job, element, normal, w);
  ++w.counters.frustum_fills;
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
        bool parked = false;
        const RayHit hit = walk_pixel(x, y, ray, tmin, job.cell, w, parked);
        if (!parked) confirm(job, x, y, hit.prim, hit.t, ray, w);
        continue;
      }
      RayHit best{element, te};
      for (uint32_t prim : w.occluders) {
        offer(prim, ray, tmin, kInfinity, best, w.counters);
      }
      confirm(job, x, y, best.prim, best.t, ray, w);
    }
  }
  return true;
}

// Splits the frustum into two or four children in the same cell. With an incidence list, each
// child inherits the elements not rejected by its new planes; straddle bits carry over.
void FrustumCaster::split(const Job& job, const Incidence* list, uint32_t n, Worker& w) {
  const bool split_x = job.x1 - job.x0 >= 2, split_y = job.y1 - job.y0 >= 2;
  const int xm = (job.x0 + job.x1) / 2, ym = (job.y0 + job.y1) / 2;
  struct Rect { int x0, y0, x1, y1; };
  std::array<Rect, 4> rects;
  int count = 0;
  if (split_x && split_y) {
    rects[0] = {job.x0, job.y0, xm, ym};
    rects[1] = {xm, job.y0, job.x1, ym};
    rects[2] = {job.x0, ym, xm, job.y1};
    rects[3] = {xm, ym, job.x1, job.y1};
    count = 4;
  } else if (split_x) {
    rects[0] = {job.x0, job.y0, xm, job.y1};
    rects[1] = {xm, job.y0, job.x1, job.y1};
    count = 2;
  } else {
    rects[0] = {job.x0, job.y0, job.x1, ym};
    rects[1] = {job.x0, ym, job.x1, job.y1};
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
        ++w.counters.plane_tests;
        if (inc.bounded) {
          if (inc.x1 < r.x0 || inc.x0 > r.x1 || inc.y1 < r.y0 || inc.y0 > r.y1) continue;
          w.arena_out.push_back(inc);
          continue;
        }
        // Straddle inheritance (§4): bounds straddling both planes of an axis straddle every
        // plane between them, so descendants never test that axis again.
        uint8_t s = inc.straddle;
        const bool spans_x = (s & (kLeft | kRight)) == (kLeft | kRight);
        const bool spans_y = (s & (kBottom | kTop)) == (kBottom | kTop);
        uint8_t planes = 0;
        if (new_left && !spans_x) planes |= kLeft;
        if (new_right && !spans_x) planes |= kRight;
        if (new_bottom && !spans_y) planes |= kBottom;
        if (new_top && !spans_y) planes |= kTop;
        if (classify_planes(r.x0, r.x1, r.y0, r.y1, tree_.ref_bounds(inc.ref), planes, s)) {
          Incidence kept = inc;
          kept.straddle = s;
          w.arena_out.push_back(kept);
        }
      }
      child.inc_count = static_cast<uint32_t>(w.arena_out.size()) - child.inc_begin;
      child.state = child.inc_count > 0 ? kList : kEmpty;
    }
    w.children.push_back(child);
  }
}

}  // namespace frontier
