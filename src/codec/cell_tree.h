// In-cell trees in cell pages (layout: store/FORMAT.md "In-cell trees"). frontier-view refines a
// paged-in store cell into its own k-d tree (KdTree::build with page_refine_options); a store
// built with in-cell trees carries that tree in the cell's page, built once by frontier-build on
// the primitives exactly as a reader decodes them, so page-in is read + checksum + decode.
//
// Only what the SAH search decided is stored: per node, in preorder, one symbol — a leaf, or a
// split axis and which of the builder's candidate positions it took (KdTree::split_candidate:
// the candidates follow from the node's region and its items, so a split costs a few bits and
// no double), entropy-coded as a value stream; a double only for a split no candidate gives.
// KdTree::assemble recomputes the rest from the decoded primitives: references (in the
// builder's order), their clipped bounds, cell bounds, content and ropes.
//
// Invariant: decode_cell_tree(encode_cell_tree(cell, tree), cell, root) is `tree`, node for
// node, cell for cell and reference for reference (encode checks it). Pure functions: safe
// from several threads at once.
#pragma once

#include "src/core/scene.h"
#include "src/core/status.h"
#include "src/engine/kdtree.h"

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

namespace frontier {

// The bit of a page's codec byte saying that its payload starts with an in-cell tree:
// varint tree length L, L bytes of tree, then the codec's payload (codec = byte & 0x7f).
inline constexpr uint8_t kCellTreeFlag = 0x80;

// Proxy pages carry their tree the same way (store/FORMAT.md "In-cell trees"): built with the
// cells' options but leaves of up to kProxyCellPrims (a proxy spans few pixels: its rays are
// cheap, the memory of a finer tree's references is not), root = the node's region.
inline constexpr uint32_t kProxyCellPrims = 64;
inline KdBuildOptions proxy_tree_options(KdBuildOptions cell_options) {
  cell_options.max_cell_prims = std::max(cell_options.max_cell_prims, kProxyCellPrims);
  return cell_options;
}

// Whether two trees are equal bit for bit: bounds, nodes, cells (bounds, content, references,
// ropes), references and their clipped bounds, depth.
bool same_tree(const KdTree& a, const KdTree& b);

// Whether a viewer's page-in options build the same in-cell trees as a store's (every field
// but root, which is each cell's region).
bool same_cell_build(const KdBuildOptions& a, const KdBuildOptions& b);

// The stored form of `tree`, which KdTree::build(cell, options) gave with options.root = the
// cell's region; `cell` is the cell as a reader decodes it (EncodedCell::decoded).
// InvalidArgument when the stored form would not assemble back into `tree` bit for bit (a
// tree build() did not make from `cell`).
Result<std::vector<uint8_t>> encode_cell_tree(const Scene& cell, const KdTree& tree, const KdBuildOptions& options);

// The tree stored in `bytes`, assembled over `cell` (the decoded page) with root `region`.
// Safe on any bytes: Corruption for anything inconsistent (bad symbols, trailing bytes or nodes,
// a split outside its node, deeper than the builder goes under `options`, far more references
// than primitives); memory stays within a constant times the cell's primitives.
Result<KdTree> decode_cell_tree(std::span<const uint8_t> bytes, const Scene& cell, const Aabb& region,
                                const KdBuildOptions& options);

// A page payload carrying a tree (codec byte | kCellTreeFlag) and back. split_tree_page:
// Corruption when the tree's length runs past the payload.
std::vector<uint8_t> join_tree_page(std::span<const uint8_t> tree, std::span<const uint8_t> payload);
Status split_tree_page(std::span<const uint8_t> page, std::span<const uint8_t>& tree,
                       std::span<const uint8_t>& payload);

}  // namespace frontier
