// In-cell trees: the symbol stream of a tree's splits and its assembly over a decoded cell
// (contracts: cell_tree.h; layout: store/FORMAT.md "In-cell trees").
//
// Tree bytes: u8 version 0x4B, varint bins B, varint node count N, a value stream of N symbols
// (0 leaf; 1 + axis·(B+1) + k: the axis's split candidate k in 0..B; 1 + 3·(B+1) + axis: a split
// stored as a double), then one f64 per double-stored split, in preorder, and nothing more.
#include "src/paging/cell_tree.h"

#include "src/core/byte_io.h"
#include "src/paging/value_stream.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>

namespace frontier {
namespace {

constexpr uint8_t kTreeVersion = 0x4B;
constexpr int kMaxBins = 1024;
// A stored tree is refused when it would hold more references than this many per primitive
// (plus a constant): real trees hold a few per primitive; the cap bounds a damaged page's memory.
constexpr size_t kMaxReferencesPerPrim = 64;
constexpr size_t kMaxNodesPerPrim = 64;

int effective_bins(const KdBuildOptions& options) { return std::max(options.bins, 2); }

// The deepest node KdBuilder makes for a cell of `prims` primitives (its max_depth_).
uint32_t depth_limit(const KdBuildOptions& options, size_t prims) {
  if (options.max_depth != 0) return options.max_depth;
  return static_cast<uint32_t>(8 + 1.3 * std::log2(static_cast<double>(std::max<size_t>(prims, 1))));
}

size_t reference_limit(size_t prims) { return kMaxReferencesPerPrim * prims + 1024; }

bool same_box(const Aabb& a, const Aabb& b) { return a.lo == b.lo && a.hi == b.hi; }

uint32_t escape_symbol(int bins, int axis) { return 1 + 3 * static_cast<uint32_t>(bins + 1) + static_cast<uint32_t>(axis); }

// Reads a built tree's nodes in preorder and names each split by its candidate (encoding).
class SymbolWriter final : public KdSplitSource {
 public:
  SymbolWriter(const KdTree& tree, int bins) : tree_(tree), bins_(bins) {}

  int next_axis() override {
    if (next_ >= tree_.nodes().size()) return kBad;
    const KdTree::Node& n = tree_.nodes()[next_++];
    if (n.is_leaf()) {
      symbols_.push_back(0);
      return kLeaf;
    }
    return n.axis_or_leaf <= 2 ? static_cast<int>(n.axis_or_leaf) : kBad;
  }

  double split(const Aabb& region, const Aabb& occupied, int axis) override {
    const double pos = tree_.nodes()[next_ - 1].split;
    for (int k = 0; k <= bins_; ++k) {
      if (std::bit_cast<uint64_t>(KdTree::split_candidate(region, occupied, axis, k, bins_)) ==
          std::bit_cast<uint64_t>(pos)) {
        symbols_.push_back(1 + static_cast<uint32_t>(axis * (bins_ + 1) + k));
        return pos;
      }
    }
    symbols_.push_back(escape_symbol(bins_, axis));
    doubles_.push_back(pos);
    return pos;
  }

  size_t consumed() const { return next_; }
  const std::vector<uint32_t>& symbols() const { return symbols_; }
  const std::vector<double>& doubles() const { return doubles_; }

 private:
  const KdTree& tree_;
  int bins_;
  size_t next_ = 0;
  std::vector<uint32_t> symbols_;
  std::vector<double> doubles_;
};

// Reads stored symbols back into splits (decoding).
class SymbolReader final : public KdSplitSource {
 public:
  SymbolReader(const std::vector<uint32_t>& symbols, const std::vector<double>& doubles, int bins)
      : symbols_(symbols), doubles_(doubles), bins_(bins) {}

  int next_axis() override {
    if (next_ >= symbols_.size()) return kBad;
    const uint32_t s = symbols_[next_++];
    if (s == 0) return kLeaf;
    const auto per_axis = static_cast<uint32_t>(bins_ + 1);
    if (s <= 3 * per_axis) {
      candidate_ = static_cast<int>((s - 1) % per_axis);
      return static_cast<int>((s - 1) / per_axis);
    }
    candidate_ = -1;
    if (next_double_ >= doubles_.size()) return kBad;
    return static_cast<int>(s - escape_symbol(bins_, 0));
  }

  double split(const Aabb& region, const Aabb& occupied, int axis) override {
    if (candidate_ < 0) return doubles_[next_double_++];
    return KdTree::split_candidate(region, occupied, axis, candidate_, bins_);
  }

  bool all_read() const { return next_ == symbols_.size() && next_double_ == doubles_.size(); }

 private:
  const std::vector<uint32_t>& symbols_;
  const std::vector<double>& doubles_;
  int bins_;
  size_t next_ = 0, next_double_ = 0;
  int candidate_ = -1;
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
  if (!assembled || writer.consumed() != tree.nodes().size() ||
      writer.symbols().size() > kMaxNodesPerPrim * cell.size() + 1024 || !same_tree(*assembled, tree)) {
    return Status::invalid_argument(fmt::format("in-cell tree of {} nodes does not assemble back from its splits{}",
                                                tree.nodes().size(),
                                                assembled ? "" : ": " + assembled.status().message()));
  }
  std::vector<uint8_t> out;
  GeometryWriter w(out);
  w.u8(kTreeVersion);
  w.varint(static_cast<uint64_t>(bins));
  w.varint(writer.symbols().size());
  cell_page::write_values(w, writer.symbols());
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
  const uint64_t nodes = r.varint();
  if (!r.ok() || nodes == 0 || nodes > kMaxNodesPerPrim * cell.size() + 1024) return corrupt("bad node count", r.offset());
  std::vector<uint32_t> symbols;
  const uint32_t max_symbol = escape_symbol(static_cast<int>(bins), 2);
  if (!cell_page::read_values(r, nodes, max_symbol, symbols)) return corrupt("bad node symbols", r.offset());
  size_t stored = 0;
  for (const uint32_t s : symbols) stored += s >= escape_symbol(static_cast<int>(bins), 0) ? 1 : 0;
  if (stored > r.remaining() / 8) return corrupt("stored splits run past the end", r.offset());
  std::vector<double> doubles(stored);
  for (double& d : doubles) d = r.f64();
  if (!r.ok() || r.remaining() != 0) return corrupt("trailing bytes", r.offset());
  SymbolReader reader(symbols, doubles, static_cast<int>(bins));
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
