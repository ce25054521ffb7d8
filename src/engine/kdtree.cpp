// k-d tree build (binned SAH over clipped primitive bounds), ropes, point location and the
// cell-to-cell step of ray walking.
#include "src/engine/kdtree.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <deque>

#include <fmt/format.h>
#include <tbb/parallel_invoke.h>

namespace frontier {

namespace {

// Empty space cut off by a split earns the SAH bonus only if it is at least this fraction of
// the node's extent on that axis.
constexpr double kMinEmptyFraction = 0.05;

// Subtrees with at least this many items are built in parallel (tbb::parallel_invoke).
constexpr size_t kParallelItems = 50000;

struct Item {
  uint32_t prim;
  Aabb box;  // clipped to the current node
};

// Pads bounds by a relative epsilon so that geometry touching a split plane is referenced on
// both sides (the cure for hits computed a few ulps across a cell boundary).
Aabb padded(const Aabb& b, double scale) {
  const double eps = 1e-9 * scale + 1e-12 * std::max(1.0, b.magnitude());
  Aabb r = b;
  r.lo -= Vec3(eps);
  r.hi += Vec3(eps);
  return r;
}

// Where the binned SAH bins a node's items on one axis: the part of the node's extent they
// occupy, cut into `bins` bins (width 0: the items are flat there and that axis is not split).
struct BinRange {
  double lo, hi, width;
};
BinRange bin_range(const Aabb& box, const Aabb& occupied, int axis, int bins) {
  const double lo = std::max(box.lo[axis], occupied.lo[axis]);
  const double hi = std::min(box.hi[axis], occupied.hi[axis]);
  return {lo, hi, (hi - lo) / bins};
}
double bin_boundary(double lo, double width, int k) { return lo + k * width; }

}  // namespace

class KdBuilder {
 public:
  KdBuilder(KdTree& tree, const KdBuildOptions& options) : tree_(tree), options_(options) {}

  void build(const Scene& scene) {
    std::vector<Item> items = scene_items(scene);
    Aabb root;
    for (const Item& it : items) root.extend(it.box);
    if (options_.root) {
      root = *options_.root;
      clip_to_root(items, root);
    } else {
      if (items.empty()) root = Aabb(Vec3(-1.0), Vec3(1.0));
      const double scale = std::max(glm::length(root.extent()), 1e-300);
      root = KdTree::root_bounds(root);
      clip_items(items, root, scale);
    }
    tree_.bounds_ = root;
    set_max_depth(items.size());
    recurse(std::move(items), root, 0);
    finish(root);
  }

  void refine(const Scene& scene, const std::vector<KdTree::Node>& top, const Aabb& top_bounds,
              const std::vector<std::vector<uint32_t>>& cell_prims) {
    tree_.bounds_ = top_bounds;
    const double scale = std::max(glm::length(top_bounds.extent()), 1e-300);
    size_t largest = 0;
    for (const auto& prims : cell_prims) largest = std::max(largest, prims.size());
    set_max_depth(largest);
    replay(scene, top, 0, top_bounds, cell_prims, scale, 0);
    finish(top_bounds);
  }

  // build() with options.root = root and the splits `splits` names instead of searched ones.
  // An item's bounds at a node are its padded bounds clipped to the root, then to the node's
  // region (build() clips them split by split, one axis at a time: min and max are exact, so
  // the boxes are the same bit for bit), so a node's items are kept as indices into those
  // bounds (lo_ and hi_, by axis) and clipped only where a split or a leaf reads them.
  Status assemble(const Scene& scene, const Aabb& root, KdSplitSource& splits, uint32_t max_depth,
                  size_t max_references) {
    std::vector<Item> items = scene_items(scene);
    clip_to_root(items, root);
    tree_.bounds_ = root;
    prims_.resize(items.size());
    for (int a = 0; a < 3; ++a) {
      lo_[a].resize(items.size());
      hi_[a].resize(items.size());
    }
    for (size_t i = 0; i < items.size(); ++i) {
      prims_[i] = items[i].prim;
      for (int a = 0; a < 3; ++a) {
        lo_[a][i] = items[i].box.lo[a];
        hi_[a][i] = items[i].box.hi[a];
      }
    }
    index_levels_.clear();
    index_levels_.emplace_back(items.size());
    for (uint32_t i = 0; i < items.size(); ++i) index_levels_[0][i] = i;
    max_depth_ = max_depth;
    max_references_ = max_references;
    if (Status s = assemble_node(splits, 0, root); !s) return s;
    finish(root);
    return Status::ok();
  }

 private:
  // The scene's primitives with non-empty bounds, in scene order (build()'s items before clipping).
  static std::vector<Item> scene_items(const Scene& scene) {
    std::vector<Item> items;
    items.reserve(scene.size());
    for (uint32_t i = 0; i < scene.size(); ++i) {
      const Aabb b = scene.prim_bounds(i);
      if (!b.empty()) items.push_back({i, b});
    }
    return items;
  }

  // Clips items to a given root region (options.root: no padding of the root itself).
  static void clip_to_root(std::vector<Item>& items, const Aabb& root) {
    clip_items(items, root, std::max(glm::length(root.extent()), 1e-300));
  }

  // Which side(s) of a split at `pos` on `axis` an item (clipped to the node) goes to: a flat
  // item on the plane goes to both.
  static bool goes_left(const Item& it, int axis, double pos) {
    return it.box.lo[axis] < pos || (it.box.lo[axis] == pos && it.box.hi[axis] == pos);
  }
  static bool goes_right(const Item& it, int axis, double pos) {
    return it.box.hi[axis] > pos || (it.box.lo[axis] == pos && it.box.hi[axis] == pos);
  }

  // One node of assemble(): its items are index_levels_[depth]; children use the deeper levels,
  // so one buffer per depth serves every node (no allocation per node once they have grown).
  Status assemble_node(KdSplitSource& splits, uint32_t depth, const Aabb& box) {
    const auto index = static_cast<uint32_t>(tree_.nodes_.size());
    const auto corrupt = [&](std::string_view what) {
      return Status::corruption(fmt::format("stored tree: node {}: {}", index, what));
    };
    if (depth > max_depth_) return corrupt(fmt::format("deeper than {}", max_depth_));
    tree_.nodes_.push_back({});
    tree_.depth_ = std::max(tree_.depth_, depth);
    const std::vector<uint32_t>& items = index_levels_[depth];
    const int axis = splits.next_axis(items.size());
    if (axis == KdSplitSource::kLeaf) {
      if (tree_.refs_.size() + items.size() > max_references_) {
        return corrupt(fmt::format("more than {} references", max_references_));
      }
      assemble_leaf(index, items, box);
      return Status::ok();
    }
    if (axis < 0 || axis > 2) return corrupt("bad node");
    const double* lo = lo_[axis].data();
    const double* hi = hi_[axis].data();
    const double box_lo = box.lo[axis], box_hi = box.hi[axis];
    // The extent the items occupy on the split axis (all a split source reads of it), as
    // build() extends it over their clipped bounds, item by item.
    Aabb occupied = box;
    occupied.lo[axis] = kInfinity;
    occupied.hi[axis] = -kInfinity;
    for (const uint32_t i : items) {
      occupied.lo[axis] = std::min(occupied.lo[axis], std::max(lo[i], box_lo));
      occupied.hi[axis] = std::max(occupied.hi[axis], std::min(hi[i], box_hi));
    }
    const double pos = splits.split(box, occupied, axis);
    if (!(pos > box.lo[axis] && pos < box.hi[axis])) return corrupt("split outside its region");
    if (index_levels_.size() == depth + 1) index_levels_.emplace_back();  // a deque: references stay valid
    std::vector<uint32_t>& side = index_levels_[depth + 1];
    Aabb lbox = box, rbox = box;
    lbox.hi[axis] = pos;
    rbox.lo[axis] = pos;
    // goes_left / goes_right of the item clipped to this node.
    side.clear();
    for (const uint32_t i : items) {
      const double l = std::max(lo[i], box_lo), h = std::min(hi[i], box_hi);
      if (l < pos || (l == pos && h == pos)) side.push_back(i);
    }
    if (Status s = assemble_node(splits, depth + 1, lbox); !s) return s;
    side.clear();
    for (const uint32_t i : items) {
      const double l = std::max(lo[i], box_lo), h = std::min(hi[i], box_hi);
      if (h > pos || (l == pos && h == pos)) side.push_back(i);
    }
    const auto upper = static_cast<uint32_t>(tree_.nodes_.size());
    if (Status s = assemble_node(splits, depth + 1, rbox); !s) return s;
    tree_.nodes_[index] = {pos, static_cast<uint32_t>(axis), upper};
    return Status::ok();
  }

  // make_leaf() for assemble(): the items' bounds clipped to the leaf's region.
  void assemble_leaf(uint32_t index, const std::vector<uint32_t>& items, const Aabb& box) {
    KdTree::Cell cell;
    cell.bounds = box;
    cell.first = static_cast<uint32_t>(tree_.refs_.size());
    cell.count = static_cast<uint32_t>(items.size());
    for (const uint32_t i : items) {
      Aabb b;
      for (int a = 0; a < 3; ++a) {
        b.lo[a] = std::max(lo_[a][i], box.lo[a]);
        b.hi[a] = std::min(hi_[a][i], box.hi[a]);
      }
      tree_.refs_.push_back(prims_[i]);
      tree_.ref_bounds_.push_back(b);
      cell.content.extend(b);
    }
    tree_.nodes_[index].axis_or_leaf = 3;
    tree_.nodes_[index].child = static_cast<uint32_t>(tree_.cells_.size());
    tree_.cells_.push_back(cell);
  }

  // Pads item bounds and clips them to `box`, dropping items that miss it.
  static void clip_items(std::vector<Item>& items, const Aabb& box, double scale) {
    size_t kept = 0;
    for (Item& it : items) {
      const Aabb b = padded(it.box, scale).intersection(box);
      if (b.empty()) continue;
      items[kept++] = {it.prim, b};
    }
    items.resize(kept);
  }

  void set_max_depth(size_t items) {
    max_depth_ = options_.max_depth != 0
                     ? options_.max_depth
                     : static_cast<uint32_t>(8 + 1.3 * std::log2(std::max<size_t>(items, 1)));
  }

  void finish(const Aabb& root) {
    std::array<int32_t, 6> ropes;
    ropes.fill(KdTree::kNone);
    assign_ropes(0, root, ropes);
  }

  // Copies the given top node (and its subtree) and builds each top cell's primitives below it.
  uint32_t replay(const Scene& scene, const std::vector<KdTree::Node>& top, uint32_t t, const Aabb& box,
                  const std::vector<std::vector<uint32_t>>& cell_prims, double scale, uint32_t depth) {
    const KdTree::Node node = top.at(t);
    if (node.is_leaf()) {
      std::vector<Item> items;
      const auto& prims = cell_prims.at(node.child);
      items.reserve(prims.size());
      for (const uint32_t p : prims) items.push_back({p, scene.prim_bounds(p)});
      clip_items(items, box, scale);
      return recurse(std::move(items), box, depth);
    }
    const uint32_t index = static_cast<uint32_t>(tree_.nodes_.size());
    tree_.nodes_.push_back({});
    const int a = static_cast<int>(node.axis_or_leaf);
    Aabb lbox = box, rbox = box;
    lbox.hi[a] = node.split;
    rbox.lo[a] = node.split;
    replay(scene, top, t + 1, lbox, cell_prims, scale, depth + 1);
    const uint32_t upper = replay(scene, top, node.child, rbox, cell_prims, scale, depth + 1);
    tree_.nodes_[index] = {node.split, node.axis_or_leaf, upper};
    return index;
  }

  struct Split {
    int axis = -1;
    double pos = 0.0;
    double cost = kInfinity;
    size_t left = 0, right = 0;
  };

  Split best_split(const std::vector<Item>& items, const Aabb& box) {
    Split best;
    const int bins = std::max(options_.bins, 2);
    const double area = box.surface_area();
    const Vec3 e = box.extent();
    // Bin over the extent the items actually occupy (clustered items would otherwise share
    // one bin of the node's extent and never separate).
    Aabb occupied;
    for (const Item& it : items) occupied.extend(it.box);
    std::array<double, 3> lo{}, hi{}, width{}, per_width{};
    std::array<bool, 3> binned{};
    for (int axis = 0; axis < 3; ++axis) {
      const BinRange range = bin_range(box, occupied, axis, bins);
      lo[axis] = range.lo;
      hi[axis] = range.hi;
      width[axis] = range.width;
      binned[axis] = width[axis] > 0.0;
      per_width[axis] = binned[axis] ? 1.0 / width[axis] : 0.0;
    }
    // Starts and ends per bin of all three axes, counted in one pass over the items.
    counts_.assign(6 * static_cast<size_t>(bins), 0);
    uint32_t* starts[3] = {counts_.data(), counts_.data() + bins, counts_.data() + 2 * bins};
    uint32_t* ends[3] = {counts_.data() + 3 * bins, counts_.data() + 4 * bins, counts_.data() + 5 * bins};
    for (const Item& it : items) {
      for (int axis = 0; axis < 3; ++axis) {
        if (!binned[axis]) continue;
        // Bin counts only estimate the cost; the split itself sorts items by exact comparisons.
        const int s = std::clamp(static_cast<int>((it.box.lo[axis] - lo[axis]) * per_width[axis]), 0, bins - 1);
        const int t = std::clamp(static_cast<int>((it.box.hi[axis] - lo[axis]) * per_width[axis]), 0, bins - 1);
        ++starts[axis][s];
        ++ends[axis][t];
      }
    }
    const double n = static_cast<double>(items.size());
    const double per_area = options_.intersection_cost / area;  // SAH: hit probability is area / node area
    for (int axis = 0; axis < 3; ++axis) {
      if (!binned[axis]) continue;
      const double box_lo = box.lo[axis], box_hi = box.hi[axis];
      const double min_empty = kMinEmptyFraction * (box_hi - box_lo);
      // A side's surface area from its length on this axis: 2 (b c + length (b + c)) with b, c
      // the node's extents on the other two axes.
      const double bc = e[(axis + 1) % 3] * e[(axis + 2) % 3];
      const double b_plus_c = e[(axis + 1) % 3] + e[(axis + 2) % 3];
      auto side_area = [&](double length) { return 2.0 * (bc + length * b_plus_c); };
      // Cutting off the empty space beside the occupied extent.
      for (const double pos : {lo[axis], hi[axis]}) {
        if (!(pos > box_lo && pos < box_hi)) continue;
        // Only a real slab of empty space is worth a level (not the padding's sliver).
        const double cut = pos == lo[axis] ? pos - box_lo : box_hi - pos;
        if (cut < min_empty) continue;
        const double kept = pos == lo[axis] ? side_area(box_hi - pos) : side_area(pos - box_lo);
        const double cost =
            (options_.traversal_cost + per_area * kept * n) * (1.0 - options_.empty_bonus);
        if (cost < best.cost) {
          best = {axis, pos, cost, pos == lo[axis] ? 0 : items.size(), pos == lo[axis] ? items.size() : 0};
        }
      }
      size_t left = 0, right = items.size();
      for (int k = 1; k < bins; ++k) {
        left += starts[axis][k - 1];
        right -= ends[axis][k - 1];
        const double pos = bin_boundary(lo[axis], width[axis], k);
        if (!(pos > box_lo && pos < box_hi)) continue;
        double cost = options_.traversal_cost +
                      per_area * (side_area(pos - box_lo) * static_cast<double>(left) +
                                  side_area(box_hi - pos) * static_cast<double>(right));
        if ((left == 0 && pos - box_lo >= min_empty) || (right == 0 && box_hi - pos >= min_empty)) {
          cost *= 1.0 - options_.empty_bonus;
        }
        if (cost < best.cost) best = {axis, pos, cost, left, right};
      }
    }
    return best;
  }

  // Appends the subtree for `items` inside `box`; returns its node index.
  uint32_t recurse(std::vector<Item> items, const Aabb& box, uint32_t depth) {
    const uint32_t index = static_cast<uint32_t>(tree_.nodes_.size());
    tree_.nodes_.push_back({});
    tree_.depth_ = std::max(tree_.depth_, depth);
    const double leaf_cost = options_.intersection_cost * static_cast<double>(items.size());
    Split split;
    if (items.size() > options_.min_cell_prims && depth < max_depth_) split = best_split(items, box);
    bool do_split = split.axis >= 0 && split.cost < leaf_cost;
    const double share_cap = std::min(1.0, options_.forced_split_max_share) * static_cast<double>(items.size());
    if (!do_split && split.axis >= 0 && items.size() > options_.max_cell_prims && split.left < items.size() &&
        split.right < items.size() && static_cast<double>(std::max(split.left, split.right)) <= share_cap &&
        split.left + split.right <= items.size() + items.size() / 2) {
      do_split = true;  // the cell-size cap overrides SAH while splitting still separates
    }
    if (!do_split) {
      make_leaf(index, items, box);
      return index;
    }
    const int axis = split.axis;
    const double pos = split.pos;
    Aabb lbox = box, rbox = box;
    lbox.hi[axis] = pos;
    rbox.lo[axis] = pos;
    // Item boxes lie inside `box`, so clipping one to a side changes only the split axis.
    size_t nl = 0, nr = 0;
    for (const Item& it : items) {
      nl += goes_left(it, axis, pos) ? 1 : 0;
      nr += goes_right(it, axis, pos) ? 1 : 0;
    }
    std::vector<Item> left(nl), right(nr);
    Item* l = left.data();
    Item* r = right.data();
    for (const Item& it : items) {
      if (goes_left(it, axis, pos)) {
        *l = it;
        l->box.hi[axis] = std::min(it.box.hi[axis], pos);
        ++l;
      }
      if (goes_right(it, axis, pos)) {
        *r = it;
        r->box.lo[axis] = std::max(it.box.lo[axis], pos);
        ++r;
      }
    }
    // Guard against a split that separates nothing (all items straddle): make a leaf instead
    // of recursing forever.
    if (left.size() == items.size() && right.size() == items.size() && items.size() > 1 &&
        split.cost >= leaf_cost) {
      make_leaf(index, items, box);
      return index;
    }
    items.clear();
    items.shrink_to_fit();
    uint32_t upper;
    if (left.size() + right.size() >= kParallelItems) {
      // Big subtrees: the upper child is built by another builder on another thread, then its
      // nodes, cells and references are appended after the lower child's (preorder is kept).
      KdTree side;
      KdBuilder other(side, options_);
      other.max_depth_ = max_depth_;
      tbb::parallel_invoke([&] { recurse(std::move(left), lbox, depth + 1); },
                           [&] { other.recurse(std::move(right), rbox, depth + 1); });
      upper = append(side);
    } else {
      recurse(std::move(left), lbox, depth + 1);
      upper = recurse(std::move(right), rbox, depth + 1);
    }
    KdTree::Node& node = tree_.nodes_[index];
    node.split = pos;
    node.axis_or_leaf = static_cast<uint32_t>(axis);
    node.child = upper;
    return index;
  }

  // Appends a subtree built by another builder (ropes not yet assigned); returns its root.
  uint32_t append(const KdTree& side) {
    const auto node_base = static_cast<uint32_t>(tree_.nodes_.size());
    const auto cell_base = static_cast<uint32_t>(tree_.cells_.size());
    const auto ref_base = static_cast<uint32_t>(tree_.refs_.size());
    for (KdTree::Node n : side.nodes_) {
      n.child += n.is_leaf() ? cell_base : node_base;
      tree_.nodes_.push_back(n);
    }
    for (KdTree::Cell c : side.cells_) {
      c.first += ref_base;
      tree_.cells_.push_back(c);
    }
    tree_.refs_.insert(tree_.refs_.end(), side.refs_.begin(), side.refs_.end());
    tree_.ref_bounds_.insert(tree_.ref_bounds_.end(), side.ref_bounds_.begin(), side.ref_bounds_.end());
    tree_.depth_ = std::max(tree_.depth_, side.depth_);
    return node_base;
  }

  void make_leaf(uint32_t index, const std::vector<Item>& items, const Aabb& box) {
    KdTree::Cell cell;
    cell.bounds = box;
    cell.first = static_cast<uint32_t>(tree_.refs_.size());
    cell.count = static_cast<uint32_t>(items.size());
    for (const Item& it : items) {
      tree_.refs_.push_back(it.prim);
      tree_.ref_bounds_.push_back(it.box);
      cell.content.extend(it.box);
    }
    tree_.nodes_[index].axis_or_leaf = 3;
    tree_.nodes_[index].child = static_cast<uint32_t>(tree_.cells_.size());
    tree_.cells_.push_back(cell);
  }

  // Moves a rope down the neighbour subtree while one child covers the whole face.
  int32_t tighten(int32_t rope, int face, const Aabb& box) const {
    const int face_axis = face / 2;
    const bool upper = (face & 1) != 0;
    while (rope != KdTree::kNone) {
      const KdTree::Node& n = tree_.nodes_[static_cast<size_t>(rope)];
      if (n.is_leaf()) break;
      const int a = static_cast<int>(n.axis_or_leaf);
      const int32_t lower_child = rope + 1, upper_child = static_cast<int32_t>(n.child);
      if (a == face_axis) {
        rope = upper ? lower_child : upper_child;  // the child adjacent to the face
      } else if (n.split >= box.hi[a]) {
        rope = lower_child;
      } else if (n.split <= box.lo[a]) {
        rope = upper_child;
      } else {
        break;
      }
    }
    return rope;
  }

  void assign_ropes(uint32_t index, const Aabb& box, std::array<int32_t, 6> ropes) {
    for (int f = 0; f < 6; ++f) ropes[f] = tighten(ropes[f], f, box);
    const KdTree::Node node = tree_.nodes_[index];
    if (node.is_leaf()) {
      KdTree::Cell& cell = tree_.cells_[node.child];
      for (int f = 0; f < 6; ++f) cell.rope[f] = ropes[f];
      return;
    }
    const int a = static_cast<int>(node.axis_or_leaf);
    Aabb lbox = box, rbox = box;
    lbox.hi[a] = node.split;
    rbox.lo[a] = node.split;
    std::array<int32_t, 6> lropes = ropes, rropes = ropes;
    lropes[2 * a + 1] = static_cast<int32_t>(node.child);
    rropes[2 * a] = static_cast<int32_t>(index + 1);
    assign_ropes(index + 1, lbox, lropes);
    assign_ropes(node.child, rbox, rropes);
  }

  KdTree& tree_;
  KdBuildOptions options_;
  uint32_t max_depth_ = 0;
  std::vector<uint32_t> counts_;  // best_split's bin counts (a builder runs on one thread at a time)
  // assemble(): the items (indices into prims_ and the bounds by axis lo_, hi_) of the current
  // node per depth, and the limit on references.
  std::deque<std::vector<uint32_t>> index_levels_;
  std::vector<uint32_t> prims_;
  std::array<std::vector<double>, 3> lo_, hi_;
  size_t max_references_ = 0;
};

KdTree KdTree::build(const Scene& scene, const KdBuildOptions& options) {
  KdTree tree;
  KdBuilder builder(tree, options);
  builder.build(scene);
  return tree;
}

double KdTree::split_candidate(const Aabb& region, const Aabb& occupied, int axis, int k, int bins) {
  const BinRange range = bin_range(region, occupied, axis, bins);
  if (k <= 0) return range.lo;
  if (k >= bins) return range.hi;
  return range.width > 0.0 ? bin_boundary(range.lo, range.width, k) : range.lo;
}

Result<KdTree> KdTree::assemble(const Scene& scene, const Aabb& root, KdSplitSource& splits, uint32_t max_depth,
                                size_t max_references) {
  KdTree tree;
  KdBuilder builder(tree, KdBuildOptions{});
  if (Status s = builder.assemble(scene, root, splits, max_depth, max_references); !s) return s;
  return tree;
}

Aabb KdTree::root_bounds(const Aabb& content, double extra) {
  const double scale = std::max(glm::length(content.extent()), 1e-300);
  // The root is padded a little more than the primitives so that no primitive touches it.
  Aabb root = padded(content, 2.0 * scale);
  root.lo -= Vec3(extra);
  root.hi += Vec3(extra);
  // Give flat roots some thickness: cells are never flat.
  for (int a = 0; a < 3; ++a) {
    if (root.hi[a] - root.lo[a] <= 1e-9 * scale) {
      root.lo[a] -= 1e-6 * scale;
      root.hi[a] += 1e-6 * scale;
    }
  }
  return root;
}

KdTree KdTree::refine(const Scene& scene, const std::vector<Node>& top_nodes, const Aabb& top_bounds,
                      const std::vector<std::vector<uint32_t>>& cell_prims, const KdBuildOptions& options) {
  KdTree tree;
  KdBuilder builder(tree, options);
  builder.refine(scene, top_nodes, top_bounds, cell_prims);
  return tree;
}

KdTree KdTree::top_only(const std::vector<Node>& nodes, const Aabb& bounds) {
  size_t cells = 0;
  for (const Node& n : nodes) {
    if (n.is_leaf()) cells = std::max<size_t>(cells, n.child + 1);
  }
  Scene none;
  std::vector<std::vector<uint32_t>> lists(cells);
  KdBuildOptions flat;
  flat.min_cell_prims = UINT32_MAX;
  // refine() keeps node indices (preorder, nothing split) but numbers cells in its own order.
  KdTree t = refine(none, nodes, bounds, lists, flat);
  KdTree out;
  out.bounds_ = t.bounds_;
  out.nodes_ = t.nodes_;
  out.depth_ = t.depth_;
  out.cells_.resize(cells);
  for (size_t n = 0; n < nodes.size(); ++n) {
    if (!nodes[n].is_leaf()) continue;
    out.cells_[nodes[n].child] = t.cells_[t.nodes_[n].child];
    out.nodes_[n].child = nodes[n].child;
  }
  return out;
}

int32_t KdTree::descend(int32_t n, const Vec3& p, const Vec3& dir) const {
  if (links_ > 0 && static_cast<size_t>(n) < parent_.size()) {
    int32_t outer = kNone;
    for (int32_t m = parent_[static_cast<size_t>(n)]; m >= 0; m = parent_[static_cast<size_t>(m)]) {
      if (nodes_[static_cast<size_t>(m)].is_link()) outer = m;
    }
    if (outer != kNone) n = outer;
  }
  while (true) {
    const Node& node = nodes_[static_cast<size_t>(n)];
    if (node.is_leaf()) return static_cast<int32_t>(node.child);
    if (node.is_link()) {
      n = static_cast<int32_t>(node.child);
      continue;
    }
    const int a = static_cast<int>(node.axis_or_leaf);
    bool upper;
    if (p[a] < node.split) {
      upper = false;
    } else if (p[a] > node.split) {
      upper = true;
    } else {
      upper = dir[a] >= 0.0;
    }
    n = upper ? static_cast<int32_t>(node.child) : n + 1;
  }
}

int32_t KdTree::locate(const Vec3& p, const Vec3& dir) const {
  if (!bounds_.contains(p)) return kNone;
  return descend(0, p, dir);
}

KdTree::Exit KdTree::exit(int32_t c, const Ray& ray) const {
  const Aabb& b = cells_[static_cast<size_t>(c)].bounds;
  Exit e;
  for (int a = 0; a < 3; ++a) {
    double t;
    int face;
    if (ray.dir[a] > 0.0) {
      t = (b.hi[a] - ray.origin[a]) * ray.inv_dir[a];
      face = 2 * a + 1;
    } else if (ray.dir[a] < 0.0) {
      t = (b.lo[a] - ray.origin[a]) * ray.inv_dir[a];
      face = 2 * a;
    } else {
      continue;
    }
    if (t < e.t) {
      e.t = t;
      e.face = face;
    }
  }
  return e;
}

int32_t KdTree::arrival(int32_t c, const Ray& ray, const Exit& e) const {
  if (e.face < 0) return kNone;
  const Cell& cell = cells_[static_cast<size_t>(c)];
  const int32_t rope = cell.rope[e.face];
  if (rope == kNone) return kNone;
  const int a = e.face / 2;
  Vec3 p = ray.at(e.t);
  p[a] = (e.face & 1) ? cell.bounds.hi[a] : cell.bounds.lo[a];
  return descend(rope, p, ray.dir);
}

bool KdTree::arrives_in(int32_t c, const Ray& ray, const Exit& e, int32_t n) const {
  if (e.face < 0 || n == kNone) return false;
  const Cell& cell = cells_[static_cast<size_t>(c)];
  const Aabb& to = cells_[static_cast<size_t>(n)].bounds;
  const int a = e.face / 2, b = (a + 1) % 3, d = (a + 2) % 3;
  const double plane = (e.face & 1) ? cell.bounds.hi[a] : cell.bounds.lo[a];
  if (plane != ((e.face & 1) ? to.lo[a] : to.hi[a])) return false;
  const Vec3 p = ray.at(e.t);
  return to.lo[b] < p[b] && p[b] < to.hi[b] && to.lo[d] < p[d] && p[d] < to.hi[d];
}

int32_t KdTree::enter_root(const Ray& ray, double tmin, double& t_enter, int& face) const {
  double t0, t1;
  if (!ray_box_interval(ray, bounds_, t0, t1) || t1 < tmin) return kNone;
  t_enter = std::max(t0, tmin);
  // The entry face: the axis whose slab produced t0.
  face = -1;
  for (int a = 0; a < 3 && face < 0; ++a) {
    if (ray.dir[a] == 0.0) continue;
    const double plane = ray.dir[a] > 0.0 ? bounds_.lo[a] : bounds_.hi[a];
    if ((plane - ray.origin[a]) * ray.inv_dir[a] == t0) face = 2 * a + (ray.dir[a] > 0.0 ? 0 : 1);
  }
  Vec3 p = glm::clamp(ray.at(t_enter), bounds_.lo, bounds_.hi);
  if (face >= 0 && t_enter == t0) {
    const int a = face / 2;
    p[a] = (face & 1) ? bounds_.hi[a] : bounds_.lo[a];
  }
  return descend(0, p, ray.dir);
}

}  // namespace frontier
