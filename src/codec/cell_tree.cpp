// In-cell trees: the symbol streams of a tree's splits and its assembly over a decoded cell
// (contracts: cell_tree.h; layout: store/FORMAT.md "In-cell trees").
//
// Tree bytes: u8 version 0x4C, varint bins B, varint node symbol count N, a value stream of N
// node symbols, a value stream of the bin splits' candidates, then one f64 per split stored as a
// double, and nothing more. A node without items is a leaf (the builder never splits one) and
// takes no symbol; any other node's symbol is 0 for a leaf, else 1 + 4·axis + kind, kind 0 = the
// low end of the occupied extent (candidate 0), 1 = its high end (candidate B), 2 = a bin boundary
// (candidate 1..B-1, in the second stream), 3 = a stored double. Two small alphabets instead of
// one of 3·(B+1) + 4 symbols: the entropy coder's per-page tables are most of a page's tree.
#include "src/codec/cell_tree.h"

#include "src/codec/value_stream.h"
#include "src/core/byte_io.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>

namespace frontier {
namespace {

constexpr uint8_t kTreeVersion = 0x4C;
constexpr int kMaxBins = 1024;
// A stored tree is refused when it would hold more references (nodes) than this many per
// primitive, plus a constant: real trees hold a few; the caps bound a damaged page's memory.
constexpr size_t kMaxReferencesPerPrim = 64;
constexpr size_t kMaxNodesPerPrim = 64;

enum SplitKind : uint32_t { kLowEnd = 0, kHighEnd = 1, kBin = 2, kStored = 3 };
constexpr uint32_t kLeafSymbol = 0;
constexpr uint32_t kMaxNodeSymbol = 1 + 4 * 2 + kStored;

uint32_t node_symbol(int axis, SplitKind kind) { return 1 + 4 * static_cast<uint32_t>(axis) + kind; }

int effective_bins(const KdBuildOptions& options) { return std::max(options.bins, 2); }

// The deepest node KdBuilder makes for a cell of `prims` primitives (its max_depth_).
uint32_t depth_limit(const KdBuildOptions& options, size_t prims) {
  if (options.max_depth != 0) return options.max_depth;
  return static_cast<uint32_t>(8 + 1.3 * std::log2(static_cast<double>(std::max<size_t>(prims, 1))));
}

size_t reference_limit(size_t prims) { return kMaxReferencesPerPrim * prims + 1024; }
size_t node_limit(size_t prims) { return kMaxNodesPerPrim * prims + 1024; }

bool same_box(const Aabb& a, const Aabb& b) { return a.lo == b.lo && a.hi == b.hi; }
bool same_double(double a, double b) { return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b); }

// Reads a built tree's nodes in preorder and names each split by its candidate (encoding).
class SymbolWriter final : public KdSplitSource {
 public:
  SymbolWriter(const KdTree& tree, int bins) : tree_(tree), bins_(bins) {}

  int next_axis(size_t items) override {
    if (next_ >= tree_.nodes().size()) return kBad;
    const KdTree::Node& n = tree_.nodes()[next_++];
    if (items == 0) return n.is_leaf() ? kLeaf : kBad;  // implied: no symbol
    if (n.is_leaf()) {
      nodes_.push_back(kLeafSymbol);
      return kLeaf;
    }
    return n.axis_or_leaf <= 2 ? static_cast<int>(n.axis_or_leaf) : kBad;
  }

  double split(const Aabb& region, const Aabb& occupied, int axis) override {
    const double pos = tree_.nodes()[next_ - 1].split;
    if (same_double(KdTree::split_candidate(region, occupied, axis, 0, bins_), pos)) {
      nodes_.push_back(node_symbol(axis, kLowEnd));
    } else if (same_double(KdTree::split_candidate(region, occupied, axis, bins_, bins_), pos)) {
      nodes_.push_back(node_symbol(axis, kHighEnd));
    } else {
      for (int k = 1; k < bins_; ++k) {
        if (same_double(KdTree::split_candidate(region, occupied, axis, k, bins_), pos)) {
          nodes_.push_back(node_symbol(axis, kBin));
          bins_taken_.push_back(static_cast<uint32_t>(k - 1));
          return pos;
        }
      }
      nodes_.push_back(node_symbol(axis, kStored));
      doubles_.push_back(pos);
    }
    return pos;
  }

  size_t consumed() const { return next_; }
  const std::vector<uint32_t>& nodes() const { return nodes_; }
  const std::vector<uint32_t>& bins_taken() const { return bins_taken_; }
  const std::vector<double>& doubles() const { return doubles_; }

 private:
  const KdTree& tree_;
  int bins_;
  size_t next_ = 0;
  std::vector<uint32_t> nodes_, bins_taken_;
  std::vector<double> doubles_;
};

// Reads stored symbols back into splits (decoding).
class SymbolReader final : public KdSplitSource {
 public:
  SymbolReader(const std::vector<uint32_t>& nodes, const std::vector<uint32_t>& bins_taken,
               const std::vector<double>& doubles, int bins)
      : nodes_(nodes), bins_taken_(bins_taken), doubles_(doubles), bins_(bins) {}

  int next_axis(size_t items) override {
    if (items == 0) return kLeaf;
    if (next_ >= nodes_.size()) return kBad;
    const uint32_t s = nodes_[next_++];
    if (s == kLeafSymbol) return kLeaf;
    kind_ = static_cast<SplitKind>((s - 1) % 4);
    if ((kind_ == kBin && next_bin_ >= bins_taken_.size()) || (kind_ == kStored && next_double_ >= doubles_.size())) {
      return kBad;
    }
    return static_cast<int>((s - 1) / 4);
  }

  double split(const Aabb& region, const Aabb& occupied, int axis) override {
    switch (kind_) {
      case kLowEnd: return KdTree::split_candidate(region, occupied, axis, 0, bins_);
      case kHighEnd: return KdTree::split_candidate(region, occupied, axis, bins_, bins_);
      case kBin:
        return KdTree::split_candidate(region, occupied, axis, static_cast<int>(bins_taken_[next_bin_++]) + 1, bins_);
      case kStored: break;
    }
    return doubles_[next_double_++];
  }

  bool all_read() const {
    return next_ == nodes_.size() && next_bin_ == bins_taken_.size() && next_double_ == doubles_.size();
  }

 private:
  const std::vector<uint32_t>& nodes_;
  const std::vector<uint32_t>& bins_taken_;
  const std::vector<double>& doubles_;
  int bins_;
  size_t next_ = 0, next_bin_ = 0, next_double_ = 0;
  SplitKind kind_ = kLowEnd;
};

}  // namespace

bool same_tree(const KdTree& a, const KdTree& b) {
  if (!same_box(a.bounds(), b.bounds()) || a.depth() != b.depth() || a.nodes().size() != b.nodes().size() ||
      a.cells().size() != b.cells().size() || a.reference_count() != b.reference_count()) {
    return false;
  }
  for (size_t i = 0; i < a.nodes().size(); ++i) {
    const KdTree::Node& x = a.nodes()[i];
    const KdTree::Node& y = b.nodes()[i];
    if (std::bit_cast<uint64_t>(x.split) != std::bit_cast<uint64_t>(y.split) || x.axis_or_leaf != y.axis_or_leaf ||
        x.child != y.child) {
      return false;
    }
  }
  for (size_t i = 0; i < a.cells().size(); ++i) {
    const KdTree::Cell& x = a.cells()[i];
    const KdTree::Cell& y = b.cells()[i];
    if (!same_box(x.bounds, y.bounds) || !same_box(x.content, y.content) || x.first != y.first ||
        x.count != y.count || !std::equal(std::begin(x.rope), std::end(x.rope), std::begin(y.rope))) {
      return false;
    }
  }
  for (uint32_t r = 0; r < a.reference_count(); ++r) {
    if (a.ref(r) != b.ref(r) || !same_box(a.ref_bounds(r), b.ref_bounds(r))) return false;
  }
  return true;
}

bool same_cell_build(const KdBuildOptions& a, const KdBuildOptions& b) {
  return a.max_cell_prims == b.max_cell_prims && a.min_cell_prims == b.min_cell_prims &&
         a.forced_split_max_share == b.forced_split_max_share && a.max_depth == b.max_depth &&
         a.traversal_cost == b.traversal_cost && a.intersection_cost == b.intersection_cost &&
         a.empty_bonus == b.empty_bonus && effective_bins(a) == effective_bins(b);
}

Result<std::vector<uint8_t>> encode_cell_tree(const Scene& cell, const KdTree& tree, const KdBuildOptions& options) {
  const int bins = effective_bins(options);
  SymbolWriter writer(tree, bins);
  auto assembled = KdTree::assemble(cell, tree.bounds(), writer, depth_limit(options, cell.size()),
                                    reference_limit(cell.size()));
  if (!assembled || writer.consumed() != tree.nodes().size() || writer.nodes().size() > node_limit(cell.size()) ||
      !same_tree(*assembled, tree)) {
    return Status::invalid_argument(fmt::format("in-cell tree of {} nodes does not assemble back from its splits{}",
                                                tree.nodes().size(),
                                                assembled ? "" : ": " + assembled.status().message()));
  }
  std::vector<uint8_t> out;
  GeometryWriter w(out);
  w.u8(kTreeVersion);
  w.varint(static_cast<uint64_t>(bins));
  w.varint(writer.nodes().size());
  cell_page::write_values(w, writer.nodes());
  cell_page::write_values(w, writer.bins_taken());
  for (const double d : writer.doubles()) w.f64(d);
  return out;
}

Result<KdTree> decode_cell_tree(std::span<const uint8_t> bytes, const Scene& cell, const Aabb& region,
                                const KdBuildOptions& options) {
  const auto corrupt = [&](std::string_view what, size_t offset) {
    return Status::corruption(fmt::format("in-cell tree: {} (at byte {})", what, offset));
  };
  GeometryReader r(bytes);
  const uint8_t version = r.u8();
  if (!r.ok() || version != kTreeVersion) return corrupt("unknown version", 0);
  const uint64_t bins = r.varint();
  if (!r.ok() || bins < 2 || bins > kMaxBins || static_cast<int>(bins) != effective_bins(options)) {
    return corrupt("bad bin count", r.offset());
  }
  const uint64_t count = r.varint();
  if (!r.ok() || count > node_limit(cell.size())) return corrupt("bad node count", r.offset());
  std::vector<uint32_t> nodes, bins_taken;
  if (!cell_page::read_values(r, count, kMaxNodeSymbol, nodes)) return corrupt("bad node symbols", r.offset());
  size_t bin_splits = 0, stored = 0;
  for (const uint32_t s : nodes) {
    if (s == kLeafSymbol) continue;
    bin_splits += (s - 1) % 4 == kBin ? 1 : 0;
    stored += (s - 1) % 4 == kStored ? 1 : 0;
  }
  if (!cell_page::read_values(r, bin_splits, static_cast<uint32_t>(bins - 2), bins_taken)) {
    return corrupt("bad bin splits", r.offset());
  }
  if (stored > r.remaining() / 8) return corrupt("stored splits run past the end", r.offset());
  std::vector<double> doubles(stored);
  for (double& d : doubles) d = r.f64();
  if (!r.ok() || r.remaining() != 0) return corrupt("trailing bytes", r.offset());
  SymbolReader reader(nodes, bins_taken, doubles, static_cast<int>(bins));
  auto tree = KdTree::assemble(cell, region, reader, depth_limit(options, cell.size()), reference_limit(cell.size()));
  if (!tree) return Status::corruption("in-cell tree: " + tree.status().message());
  if (!reader.all_read()) return corrupt("nodes past the end of the tree", bytes.size());
  return tree;
}

std::vector<uint8_t> join_tree_page(std::span<const uint8_t> tree, std::span<const uint8_t> payload) {
  std::vector<uint8_t> out;
  store::ByteWriter w(out);
  w.reserve(10 + tree.size() + payload.size());
  w.varint(tree.size());
  w.bytes(tree);
  w.bytes(payload);
  return out;
}

Status split_tree_page(std::span<const uint8_t> page, std::span<const uint8_t>& tree,
                       std::span<const uint8_t>& payload) {
  store::ByteReader r(page);
  const uint64_t length = r.varint();
  if (!r.ok() || length > r.remaining()) {
    return Status::corruption("in-cell tree: its length runs past the page (at byte 0)");
  }
  tree = r.bytes(static_cast<size_t>(length));
  payload = page.subspan(r.offset());
  return Status::ok();
}

}  // namespace frontier
