// The in-memory k-d tree: interior nodes (axis, split) and leaf cells. Every cell knows its
// bounds, the bounds of its content, its primitive references and its ropes — for each of its
// six faces the deepest node that covers the whole region across that face (or none at the
// root boundary) — so a ray leaving a cell finds its arrival cell without a root descent.
//
// Invariants:
// - Splits lie strictly inside their node's bounds, so no cell is flat.
// - A primitive is referenced by every cell its (slightly padded) bounds overlap; each
//   reference carries the primitive bounds clipped to the cell (what frusta are tested against).
// - Ties are broken deterministically: a point exactly on a split plane goes to the side the
//   given direction points to (the upper side when the direction is 0 on that axis).
#pragma once

#include "src/core/geometry.h"
#include "src/core/scene.h"
#include "src/core/status.h"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace frontier {

struct KdBuildOptions {
  uint32_t max_cell_prims = 8;   // cells above this size split even if SAH prefers a leaf
  uint32_t min_cell_prims = 0;   // cells at or below this size never split (coarse cells)
  // A cell above max_cell_prims that SAH would keep is split anyway only if the larger side
  // keeps at most this share of its items (1: any split that separates one item, the store
  // builder's hard cap for its pages), and never by a split that copies more than half of the
  // items into both sides. Below 1 the cap is soft: cells full of large straddling primitives
  // (walls and floors crossing a store cell) stay leaves instead of being cut until max_depth,
  // which copied each primitive into ~8 cells of a paged-in building cell; and clusters no
  // plane separates (fans around a vertex, stacks of overlapping spheres) stay one cell instead
  // of doubling at every level (tessellated shells.nff took 22 GB with the hard cap).
  double forced_split_max_share = 0.75;
  uint32_t max_depth = 0;        // 0: 8 + 1.3 log2(n)
  double traversal_cost = 2.0;  // relative to one ray–primitive test; measured on SPD + building models
  double intersection_cost = 1.0;
  double empty_bonus = 0.2;      // SAH discount for cutting off empty space
  int bins = 32;
  // When set, the root is exactly this box (no padding) and primitives are clipped to it:
  // how the out-of-core builder builds one partition, and how a store's cells are refined.
  std::optional<Aabb> root;
};

// Where KdTree::assemble() finds a tree's splits: asked node by node in preorder (the order in
// which build() makes nodes), as a stored in-cell tree is read back.
class KdSplitSource {
 public:
  static constexpr int kLeaf = -1;
  static constexpr int kBad = -2;
  virtual ~KdSplitSource() = default;
  // The next node, which holds `items` items: kLeaf, its split axis (0..2), or kBad when the
  // stored tree is damaged.
  virtual int next_axis(size_t items) = 0;
  // The split position on `axis` of the node next_axis() just named, given its region and the
  // extent its items occupy on `axis` (their bounds clipped to the region; see
  // KdTree::split_candidate, which reads no other axis of it; assemble() passes the region there).
  virtual double split(const Aabb& region, const Aabb& occupied, int axis) = 0;
};

class KdTree {
 public:
  static constexpr int32_t kNone = -1;

  struct Node {
    double split = 0.0;
    uint32_t axis_or_leaf = 3;  // 0..2 split axis, 3 leaf, 4 link (PagedWorld only)
    uint32_t child = 0;         // interior: index of the upper child (lower child is this + 1);
                                // leaf: cell index; link: root node of a grafted subtree
    bool is_leaf() const { return axis_or_leaf == 3; }
    bool is_link() const { return axis_or_leaf == 4; }
  };

  struct Cell {
    Aabb bounds;
    Aabb content;            // union of the clipped bounds of its references
    uint32_t first = 0;      // into refs / ref_bounds
    uint32_t count = 0;
    int32_t rope[6] = {kNone, kNone, kNone, kNone, kNone, kNone};  // face = 2*axis + (upper?1:0)
  };

  // Where a ray leaves a cell.
  struct Exit {
    double t = kInfinity;
    int face = -1;          // 2*axis + upper
  };

  static KdTree build(const Scene& scene, const KdBuildOptions& options = {});
  // The root region build() gives content with these bounds: padded by a relative epsilon
  // (plus `extra`, e.g. a lattice step) so no primitive touches it, and never flat.
  static Aabb root_bounds(const Aabb& content, double extra = 0.0);
  // A tree whose upper levels are given — `top_nodes` over `top_bounds`, as a store's top tree
  // (Node::child of a leaf indexes `cell_prims`) — and whose top cells are each built further
  // by the SAH builder from the scene primitives listed for them. Ties, padding and ropes as in
  // build(); with options.min_cell_prims = UINT32_MAX the top cells stay as they are.
  static KdTree refine(const Scene& scene, const std::vector<Node>& top_nodes, const Aabb& top_bounds,
                       const std::vector<std::vector<uint32_t>>& cell_prims, const KdBuildOptions& options = {});

  // Split candidate k (0..bins) on `axis` of a node over `region` whose items occupy `occupied`:
  // exactly the positions build()'s binned SAH tries (k = 0 and k = bins: the ends of the
  // occupied extent, cutting off empty space; in between, the bin boundaries). Not strictly
  // inside the region when build() would not try it there (items flat on that axis).
  static double split_candidate(const Aabb& region, const Aabb& occupied, int axis, int k, int bins);
  // The tree build(scene, options) gives, with options.root = `root`, when its nodes split where
  // `splits` says: the same items, clipping, ties, references (in the same order), cell bounds,
  // content, ropes and depth, without the SAH search (how a paged-in cell's stored tree is
  // loaded). Corruption naming the node when `splits` reports damage, a split does not lie
  // strictly inside its node, the tree gets deeper than `max_depth` or would hold more than
  // `max_references` references; `splits` is not asked again after a failure.
  static Result<KdTree> assemble(const Scene& scene, const Aabb& root, KdSplitSource& splits, uint32_t max_depth,
                                 size_t max_references);

  // The tree of `nodes` over `bounds` alone — a store's top tree — with ropes, every cell empty
  // and numbered as its leaf node's `child` says (cell c is the store's cell c).
  static KdTree top_only(const std::vector<Node>& nodes, const Aabb& bounds);
  const Aabb& bounds() const { return bounds_; }
  const std::vector<Node>& nodes() const { return nodes_; }
  const std::vector<Cell>& cells() const { return cells_; }
  const Cell& cell(int32_t c) const { return cells_[static_cast<size_t>(c)]; }
  // Primitive index of a cell reference, and its bounds clipped to the cell.
  uint32_t ref(uint32_t r) const { return refs_[r]; }
  const Aabb& ref_bounds(uint32_t r) const { return ref_bounds_[r]; }
  uint32_t depth() const { return depth_; }
  size_t reference_count() const { return refs_.size(); }

  // Cell containing p, ties broken by `dir`; kNone if p is outside the root.
  int32_t locate(const Vec3& p, const Vec3& dir) const;
  // Descends from node `n` to the leaf cell containing p (p assumed inside n), ties by dir.
  int32_t descend(int32_t n, const Vec3& p, const Vec3& dir) const;
  // Where `ray` leaves cell c (the ray is assumed to be in or on the cell).
  Exit exit(int32_t c, const Ray& ray) const;
  // The cell a ray enters after leaving c through `e`; kNone when it leaves the root.
  int32_t arrival(int32_t c, const Ray& ray, const Exit& e) const;
  // Whether a ray leaving c through `e` surely arrives in cell n: its exit point lies inside
  // n's entry face, strictly in the two other axes (on an edge of that face it answers false,
  // where arrival() would break the tie by direction). A box test instead of a rope descent.
  bool arrives_in(int32_t c, const Ray& ray, const Exit& e, int32_t n) const;
  // Where a ray from outside enters the root: the cell and the entry parameter. kNone if it
  // misses the root.
  int32_t enter_root(const Ray& ray, double tmin, double& t_enter, int& face) const;

 private:
  Aabb bounds_;
  std::vector<Node> nodes_;
  std::vector<Cell> cells_;
  std::vector<uint32_t> refs_;
  std::vector<Aabb> ref_bounds_;
  uint32_t depth_ = 0;
  // PagedWorld only: each top node's parent (-1 for the root) and how many top nodes are linked
  // (axis 4). A rope may lead to a node deep inside a linked node's region, past the link:
  // descend() starts at its outermost linked ancestor instead, so the ray meets what the link
  // draws there. Found by walking up (the tree's depth) rather than kept per node, which made
  // every link and unlink cost its whole subtree.
  std::vector<int32_t> parent_;
  uint32_t links_ = 0;

  friend class KdBuilder;
  friend class PagedWorld;  // grafts and unlinks the subtrees of paged-in store cells
};

}  // namespace frontier
