// Frustum casting, a frustum's way through the cells (§3–§4): process() runs one job — it
// enters the root, resolves what the current cell holds for the frustum, advances into the next
// cell while all four corner rays agree, and when they disagree looks ahead, walks the pixels
// or splits the frustum. Also the ternary classification of bounds against the frustum's
// planes (classify, classify_planes), collecting a cell's list, and split() with straddle
// inheritance.
//
// Invariants: a frustum moves from cell A to B only when all four corner rays leave A through
// one face into B, after A's elements were resolved for its pixels (the exactness argument in
// frustum.h); a child's incidence list keeps every element not outside its planes; a job's
// pixels are either confirmed, parked, or handed on (children, next cell) — never dropped.
#include "src/engine/frustum.h"

#include "src/engine/frustum_internal.h"

#include <array>
#include <cmath>
#include <vector>

namespace frontier {

using namespace frustum_detail;

namespace {

// Resolve a frustum in its cell when the elements' screen footprints add up to at most this
// many times its pixel count; otherwise subdivide.
constexpr double kResolveFactor = 2.0;

// True when the four corner rays agree (same entry/exit face, same next cell).
template <typename T>
bool all_same(const std::array<T, 4>& v) {
  return v[1] == v[0] && v[2] == v[0] && v[3] == v[0];
}

}  // namespace

// Ternary classification of `box` against the plane through the eye with normal `n` (Inside:
// the side n points to), with a tolerance relative to the box's size and distance.
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

// Whether some of `box` lies beyond the near plane.
bool FrustumCaster::in_front(const Aabb& box) const {
  const Vec3 c = box.center() - view_.eye;
  const Vec3 h = 0.5 * box.extent();
  const Vec3& f = view_.forward;
  const double far_point = glm::dot(f, c) + std::abs(f.x) * h.x + std::abs(f.y) * h.y + std::abs(f.z) * h.z;
  return far_point >= view_.near - 1e-9 * (std::abs(far_point) + glm::length(c) + 1e-300);
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

// Runs one job: its corner rays once, then cell by cell until every pixel of it is resolved,
// parked, or handed to children.
void FrustumCaster::process(Job job, Worker& w) {
  if (job.refine != 0) {  // a leaf whose preview is traced: the rest of its pixels
    resolve_by_packets(job, w, job.refine == kRefineFromNext);
    return;
  }
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
    if (job.cell == KdTree::kNone) {
      if (enter_root(job, rays, tmins, w) == Step::Moved) continue;
      return;
    }
    if (marks_->mark(job.cell)) ++w.counters.cells_touched;
    ++w.counters.cell_visits;
    if (gate_missing(job.cell)) {
      park(job, w);
      return;
    }
    if (resolve_cell_elements(job, rays, tmins, w) == Step::Done) return;
    // Nothing left to find in this cell for the open pixels: on to the next cell, if the
    // corners agree on it.
    const Step step = advance(job, rays, w);
    if (step == Step::Moved) continue;
    if (step == Step::Done) return;
    // The frustum goes on through several cells. Before splitting it, ask the tree whether
    // only a few elements (or none) lie ahead of it: then its pixels test just those. Not one
    // level above the leaf size in a scene of triangles: its leaves go on as ray packets, which
    // cost less there than asking the tree (a 20 M terrain's fly-over at 1280x720: 0.13-0.14 of
    // the worst frame's geometry pixels sampled against 0.09, p95 33 ms against 38-39).
    const bool packets_next = packets_apply() && job.small(2 * leaf_);
    if (!packets_next && look_ahead(job, rays, tmins, w)) return;
    if (job.small(leaf_)) {
      resolve_by_packets(job, w, true);
      return;
    }
    split(job, nullptr, 0, w);
    return;
  }
}

// §4 special case: the eye is outside the root; find where the corner rays enter it. Moved
// when they all enter through one face into one cell; otherwise the frustum is walked (small),
// background (it misses the root) or split, and Done.
FrustumCaster::Step FrustumCaster::enter_root(Job& job, const std::array<Ray, 4>& rays,
                                              const std::array<double, 4>& tmins, Worker& w) {
  std::array<int32_t, 4> cells;
  std::array<int, 4> faces;
  for (size_t k = 0; k < 4; ++k) {
    double t_enter;
    cells[k] = tree_.enter_root(rays[k], tmins[k], t_enter, faces[k]);
  }
  if (cells[0] != KdTree::kNone && faces[0] >= 0 && all_same(cells) && all_same(faces)) {
    job.cell = cells[0];
    job.state = kFresh;
    return Step::Moved;
  }
  if (job.small(leaf_)) {
    resolve_by_packets(job, w, false);
    return Step::Done;
  }
  const Aabb& root = tree_.bounds();
  w.counters.plane_tests += 5;
  if (!in_front(root) || classify(column_normal_[static_cast<size_t>(job.x0)], root) == Side::Outside ||
      classify(-column_normal_[static_cast<size_t>(job.x1)], root) == Side::Outside ||
      classify(row_normal_[static_cast<size_t>(job.y0)], root) == Side::Outside ||
      classify(-row_normal_[static_cast<size_t>(job.y1)], root) == Side::Outside) {
    fill_background(job, w);
    return Step::Done;
  }
  split(job, nullptr, 0, w);
  return Step::Done;
}

// The elements of the frustum's cell against its pixels: a plane fill (in the cell, or across
// cells), or either resolving the pixels against the cell's elements now (cheap when the
// elements' screen footprints are small against the frustum) or the corner rays, the §4 fill
// and subdivision (§3.2). Done when nothing is left for this job; Stays when pixels are still
// open after every element of the cell was tested for them.
FrustumCaster::Step FrustumCaster::resolve_cell_elements(const Job& job, const std::array<Ray, 4>& rays,
                                                         const std::array<double, 4>& tmins, Worker& w) {
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
  if (n == 0) return Step::Stays;
  if (fill_plane(job, list, n, rays, tmins, &tree_.cell(job.cell).bounds, w)) return Step::Done;
  if (!job.small(leaf_) && fill_plane_ahead(job, list, n, rays, tmins, w)) return Step::Done;
  const size_t npix = size_t(job.x1 - job.x0 + 1) * size_t(job.y1 - job.y0 + 1);
  const bool have_rects = !job.small(leaf_);
  if (job.small(leaf_) || footprint(job, list, n, w) <= kResolveFactor * double(npix)) {
    return resolve_in_cell(job, list, n, have_rects, w) == 0 ? Step::Done : Step::Stays;
  }
  if (!corners_and_fill(job, list, n, rays, tmins, w)) split(job, list, n, w);
  return Step::Done;
}

// Advances the frustum into the next cell if all corner rays leave through one face into one
// cell (every interior ray then does the same): Moved. The arrival cell is looked up only when
// the faces agree, and only for the first corner: the others are checked against it with a box
// test (a corner on an edge of that cell's face counts as disagreeing, which only costs a
// split). Done when every corner leaves the root through that face (background); Stays when
// the corners disagree.
FrustumCaster::Step FrustumCaster::advance(Job& job, const std::array<Ray, 4>& rays, Worker& w) {
  std::array<KdTree::Exit, 4> exits;
  for (size_t k = 0; k < 4; ++k) exits[k] = tree_.exit(job.cell, rays[k]);
  const std::array<int, 4> faces = {exits[0].face, exits[1].face, exits[2].face, exits[3].face};
  if (faces[0] < 0 || !all_same(faces)) return Step::Stays;
  const int32_t next = tree_.arrival(job.cell, rays[0], exits[0]);
  if (next == KdTree::kNone && tree_.cell(job.cell).rope[faces[0]] == KdTree::kNone) {
    fill_background(job, w);
    return Step::Done;
  }
  bool same = next != KdTree::kNone;
  for (size_t k = 1; k < 4 && same; ++k) same = tree_.arrives_in(job.cell, rays[k], exits[k], next);
  if (!same) return Step::Stays;
  job.cell = next;
  job.state = kFresh;
  return Step::Moved;
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
    Job child{.x0 = r.x0, .y0 = r.y0, .x1 = r.x1, .y1 = r.y1, .cell = job.cell};
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
