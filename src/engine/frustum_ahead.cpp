// Frustum casting, look-ahead (beyond the paper): a frustum that cannot advance, or that sees
// a triangle's plane beyond its cell, asks the whole tree which elements could still lie in it
// ahead of its cell (gather_ahead). With at most a few, its pixels test only those
// (resolve_against_ahead) or take their distance from the triangle's plane (fill_plane_ahead);
// with none, it is background.
//
// Invariants: gather_ahead is conservative — every element a ray of the frustum could hit
// beyond its current cell is found, or the search gives up (too many elements, nodes or
// references, or a cell not paged in) and the caller goes on as if it had not looked. It
// writes only the worker's scratch (w.nodes, w.ahead, w.ahead_cells) and, on success, marks
// the cells it read as touched.
#include "src/engine/frustum.h"

#include "src/engine/frustum_internal.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace frontier {

using namespace frustum_detail;

// Look-ahead (gather_ahead): at most this many tree nodes and references examined, at most
// this many elements found, for frusta one or two levels above the leaf size. Leaf frusta
// mostly find more than the limit, larger ones pay to search and seldom succeed; a larger
// limit, or a smaller or larger budget, did no better.
constexpr size_t kAheadBudget = 256;
constexpr size_t kAheadLimit = 4;
constexpr int kAheadMaxSpan = 4;  // in leaf sizes

// The frustum's planes as gather_ahead tests boxes against them: normal · (p - origin) >= 0 for
// what may lie inside (all but a `before` triangle's plane pass through the eye), the near
// plane, and what lies ahead of the current cell. The tests are classify() and in_front(),
// with the same tolerances.
struct FrustumCaster::AheadPlanes {
  // Bit of the near plane in a mask of planes a box may still straddle; bit k: normal[k].
  static constexpr uint16_t kNearPlane = 0x100;
  std::array<Vec3, 8> normal;
  std::array<Vec3, 8> origin;
  std::array<Vec3, 8> reach;     // |normal| per axis: a box's half extent along the normal
  std::array<double, 8> offset;  // normal · (origin - eye)
  size_t count = 4;
  // Per axis: some direction of the frustum is >= 0 (pos) or <= 0 (neg) along it.
  std::array<bool, 3> pos{}, neg{};
  Aabb here;  // the frustum's current cell
  Vec3 eye, forward, forward_reach;
  double near = 0.0;

  uint16_t all() const { return uint16_t(kNearPlane | ((1u << count) - 1u)); }

  // The planes of `mask` that `box` still straddles, or -1 when it is not ahead of the current
  // cell or lies outside a plane. A box inside a plane has every sub-box inside it, so
  // descendants and references skip that plane.
  int remaining(const Aabb& box, uint16_t mask, Counters& counters) const {
    bool ahead = false;
    for (int a = 0; a < 3; ++a) {
      ahead = ahead || (pos[size_t(a)] && box.hi[a] >= here.hi[a]) || (neg[size_t(a)] && box.lo[a] <= here.lo[a]);
    }
    if (!ahead) return -1;
    const Vec3 c = box.center() - eye;
    const Vec3 h = 0.5 * box.extent();
    for (size_t k = 0; k < count; ++k) {
      if (!(mask & (1u << k))) continue;
      ++counters.plane_tests;
      const double s = glm::dot(normal[k], c) - offset[k], r = glm::dot(reach[k], h);
      const double tol = 1e-9 * (std::abs(s) + std::abs(offset[k]) + r) + 1e-300;
      if (s + r < -tol) return -1;
      if (s - r > tol) mask = uint16_t(mask & ~(1u << k));
    }
    if (mask & kNearPlane) {
      const double s = glm::dot(forward, c), r = glm::dot(forward_reach, h);
      const double tol = 1e-9 * (std::abs(s + r) + glm::length(c) + 1e-300);
      if (s + r < near - tol) return -1;
      if (s - r > near + tol) mask = uint16_t(mask & ~kNearPlane);
    }
    return mask;
  }
};

// A frustum one or two levels above the leaf size whose corners disagree about the next cell:
// when only a few elements (or none) lie ahead of it, its pixels test just those. False, with
// nothing written, for a frustum of another size or when gather_ahead gives up.
bool FrustumCaster::look_ahead(const Job& job, const std::array<Ray, 4>& rays, const std::array<double, 4>& tmins,
                               Worker& w) {
  if (job.small(leaf_) || !job.small(kAheadMaxSpan * leaf_)) return false;
  if (!gather_ahead(job, rays, nullptr, kAheadLimit, w)) return false;
  ++w.counters.frustum_lookaheads;
  resolve_against_ahead(job, rays, tmins, w);
  return true;
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
  const AheadPlanes planes = ahead_planes(job, rays, before);
  w.ahead.clear();
  w.ahead_cells.clear();
  w.nodes.clear();
  w.nodes.push_back({0, planes.all(), tree_.bounds()});
  size_t budget = kAheadBudget;
  while (!w.nodes.empty()) {
    if (budget-- == 0) return false;
    const AheadNode top = w.nodes.back();
    w.nodes.pop_back();
    const KdTree::Node& node = tree_.nodes()[size_t(top.node)];
    if (node.is_link()) {
      w.nodes.push_back({int32_t(node.child), top.planes, top.box});
    } else if (node.is_leaf()) {
      if (!gather_cell(job, int32_t(node.child), top.planes, planes, limit, budget, w)) return false;
    } else {
      push_children(top.node, top.planes, top.box, planes, w);
    }
  }
  for (int32_t c : w.ahead_cells) {
    if (marks_->mark(c)) ++w.counters.cells_touched;
  }
  return true;
}

// gather_ahead's planes for the frustum of `job` (see AheadPlanes), with `before`'s plane.
FrustumCaster::AheadPlanes FrustumCaster::ahead_planes(const Job& job, const std::array<Ray, 4>& rays,
                                                       const Triangle* before) const {
  AheadPlanes p;
  p.normal = {column_normal_[size_t(job.x0)], -column_normal_[size_t(job.x1)], row_normal_[size_t(job.y0)],
              -row_normal_[size_t(job.y1)]};
  p.origin.fill(view_.eye);
  p.count = 4;
  if (before != nullptr) {
    // Only what lies in front of the triangle's plane, seen from the eye, can come before it.
    Vec3 n = glm::cross(before->v1 - before->v0, before->v2 - before->v0);
    if (glm::dot(n, view_.eye - before->v0) < 0.0) n = -n;
    p.normal[p.count] = n;
    p.origin[p.count++] = before->v0;
  }
  // Every ray of the frustum is inside the current cell and leaves it through a face its
  // direction points to: what lies ahead is beyond one of those faces. An axis on which all
  // directions agree in sign also separates: the frustum lies on one side of the eye's plane.
  p.here = tree_.cell(job.cell).bounds;
  for (int a = 0; a < 3; ++a) {
    for (const Ray& corner : rays) {  // every direction of the frustum is a blend of these
      p.pos[size_t(a)] = p.pos[size_t(a)] || corner.dir[a] >= 0.0;
      p.neg[size_t(a)] = p.neg[size_t(a)] || corner.dir[a] <= 0.0;
    }
    if (p.pos[size_t(a)] != p.neg[size_t(a)]) {
      Vec3 n{0.0};
      n[a] = p.pos[size_t(a)] ? 1.0 : -1.0;
      p.normal[p.count++] = n;
    }
  }
  for (size_t k = 0; k < p.count; ++k) {
    p.reach[k] = glm::abs(p.normal[k]);
    p.offset[k] = glm::dot(p.normal[k], p.origin[k] - view_.eye);
  }
  p.eye = view_.eye;
  p.forward = view_.forward;
  p.forward_reach = glm::abs(view_.forward);
  p.near = view_.near;
  return p;
}

// The references of leaf cell `c`, reached with `node_planes` still straddled, that could lie
// in the frustum ahead, into w.ahead (an element found before has its bounds extended). False
// when the search gives up: the cell is not paged in, the budget is spent, or more than
// `limit` elements are found.
bool FrustumCaster::gather_cell(const Job& job, int32_t c, uint16_t node_planes, const AheadPlanes& planes,
                                size_t limit, size_t& budget, Worker& w) const {
  if (c == job.cell) return true;
  const KdTree::Cell& cell = tree_.cell(c);
  const bool missing = gate_ != nullptr && gate_->missing(c);
  if (!(cell.count > 0 || missing)) return true;
  const int cell_planes = planes.remaining(cell.content, node_planes, w.counters);
  if (cell_planes < 0) return true;
  if (missing) return false;
  w.ahead_cells.push_back(c);
  for (uint32_t r = cell.first; r < cell.first + cell.count; ++r) {
    if (budget-- == 0) return false;
    const Aabb& bounds = tree_.ref_bounds(r);
    const int ref_planes = planes.remaining(bounds, uint16_t(cell_planes), w.counters);
    if (ref_planes < 0) continue;
    const uint32_t prim = tree_.ref(r);
    const auto found =
        std::find_if(w.ahead.begin(), w.ahead.end(), [&](const AheadElement& e) { return e.prim == prim; });
    if (found != w.ahead.end()) {
      found->bounds.extend(bounds);
      continue;
    }
    // Only a plane the bounds straddle can have the element wholly behind it.
    bool out = false;
    for (size_t k = 0; k < planes.count && !out; ++k) {
      out = (ref_planes & (1 << k)) && scene_.below_plane(prim, planes.origin[k], planes.normal[k]);
    }
    if (out) continue;
    if (w.ahead.size() == limit) return false;
    w.ahead.push_back({prim, r, bounds});
  }
  return true;
}

// Pushes the children of inner node `index` (region `box`, `node_planes` still straddled)
// that are not outside the frustum onto w.nodes, the nearer child on top: a crowded frustum
// meets its limit sooner.
void FrustumCaster::push_children(int32_t index, uint16_t node_planes, const Aabb& box, const AheadPlanes& planes,
                                  Worker& w) const {
  const KdTree::Node& node = tree_.nodes()[size_t(index)];
  const int a = int(node.axis_or_leaf);
  Aabb lower = box, upper = box;
  lower.hi[a] = node.split;
  upper.lo[a] = node.split;
  const int lower_planes = planes.remaining(lower, node_planes, w.counters);
  const int upper_planes = planes.remaining(upper, node_planes, w.counters);
  const bool upper_near = view_.eye[a] >= node.split;
  if (!upper_near && upper_planes >= 0) w.nodes.push_back({int32_t(node.child), uint16_t(upper_planes), upper});
  if (lower_planes >= 0) w.nodes.push_back({index + 1, uint16_t(lower_planes), lower});
  if (upper_near && upper_planes >= 0) w.nodes.push_back({int32_t(node.child), uint16_t(upper_planes), upper});
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

}  // namespace frontier
