// StoreModel: a model as the store holds it — the sections `model` (JSON: lattice, codec,
// counts, materials, lights, camera), `tree` (the top k-d tree's nodes) and `cells` (one record
// per top cell: bounds, content bounds, reference count, page), the optional `portals` (the
// building's cells-and-portals graph, src/raster/portals.h), the optional `proxies` (a proxy page
// and error bound per interior node, src/lod/proxy_section.h) — and the decoding of a cell's or
// a proxy's page into primitives. Byte layouts are in store/FORMAT.md ("Model sections", "Cell pages").
//
// The top tree is resident; cell pages are decoded on demand (read_cell) or all at once
// (load_all, for models that fit in memory: the round-trip tests and rendering a small store
// with the in-memory engine). A primitive that straddles cells is stored in every cell it
// overlaps, so load_all yields one scene primitive per reference; ids (sources) are unchanged.
#pragma once

#include "src/codec/cell_codec.h"
#include "src/lod/proxy_section.h"
#include "src/engine/kdtree.h"
#include "src/raster/portals.h"
#include "src/core/scene.h"
#include "src/core/status.h"
#include "store/store_file.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace frontier {

inline constexpr std::string_view kModelSection = "model";
inline constexpr std::string_view kTreeSection = "tree";
inline constexpr std::string_view kCellsSection = "cells";
inline constexpr std::string_view kSdfSection = "sdf";

struct StoreCell {
  static constexpr uint64_t kNoPage = UINT64_MAX;
  Aabb bounds;               // the cell's region
  Aabb content;              // union of its references' bounds clipped to the region
  uint32_t references = 0;   // primitives stored in its page
  uint64_t page = kNoPage;   // store page id; kNoPage for an empty cell
};

// Everything the `model` section says.
struct StoreModelInfo {
  CellCodec codec = CellCodec::Draco;
  Lattice lattice;                    // meaningful for the Draco codec (raw stores exact doubles)
  Aabb bounds;                        // the top tree's root region
  uint64_t input_primitives = 0;      // input primitives over all inputs (ids are < this)
  uint64_t primitives = 0;            // after triangulation and dropping degenerate ones
  uint64_t references = 0;            // sum over cells (straddling primitives count per cell)
  uint64_t triangles = 0;             // distinct triangles
  uint64_t degenerate_dropped = 0;    // by the readers and by snapping to the lattice
  uint32_t cell_prims = 0;            // the build's --cell-prims
  std::vector<std::string> inputs;
  std::vector<Material> materials;
  std::vector<PointLight> lights;
  std::optional<Camera> camera;
  Vec3 background{0.0};
  bool walkable = false;              // an `sdf` section exists
  double sdf_voxel = 0.0;
  double walk_radius = 0.0;           // the walker clearance the grid's band was sized for
  // Set when cell pages carry in-cell trees (src/codec/cell_tree.h): the options they were built
  // with (root aside), how many pages carry one and their bytes in all.
  std::optional<KdBuildOptions> cell_tree;
  uint64_t cell_tree_pages = 0;
  uint64_t cell_tree_bytes = 0;
  // Set (non-zero) when proxy pages carry their trees too: built with cell_tree's options but
  // leaves of up to this many primitives (cell_tree.h proxy_tree_options); how many proxy pages
  // carry one and their trees' bytes. Requires cell_tree.
  uint32_t proxy_tree_cell_prims = 0;
  uint64_t proxy_tree_pages = 0;
  uint64_t proxy_tree_bytes = 0;

  std::vector<uint8_t> to_bytes() const;
  static Result<StoreModelInfo> from_bytes(std::span<const uint8_t> bytes, const std::string& where);
};

// Section encoders (the builder) and decoders (the reader); decoders bounds-check everything.
std::vector<uint8_t> encode_tree(const std::vector<KdTree::Node>& nodes);
std::vector<uint8_t> encode_cells(const std::vector<StoreCell>& cells);

class StoreModel {
 public:
  // Opens a store and checks the model, tree and cells sections (structure only: every node
  // and cell consistent, regions nested, pages in range) and loads the portals section when
  // there is one (Corruption naming the store and the section when it is damaged). Pages are
  // not read.
  static Result<std::unique_ptr<StoreModel>> open(const std::string& path);
  static Result<std::unique_ptr<StoreModel>> open(std::unique_ptr<store::StoreReader> reader);

  const StoreModelInfo& info() const { return info_; }
  const std::vector<KdTree::Node>& nodes() const { return nodes_; }
  const std::vector<StoreCell>& cells() const { return cells_; }
  uint32_t depth() const { return depth_; }
  const store::StoreReader& reader() const { return *reader_; }
  // The cells-and-portals graph of the `portals` section; nullptr when the store has none.
  // Owned by the model and valid as long as it is.
  const PortalGraph* portals() const { return portals_ ? &*portals_ : nullptr; }
  // The `proxies` section: one record per node (indexed like nodes()); empty when the store has
  // none (built with --proxy-triangles 0, or before proxies existed).
  const std::vector<StoreProxy>& proxies() const { return proxies_; }
  // Node `node`'s proxy record when it has a proxy page; nullptr for a leaf, an empty subtree, a
  // node out of range or a store without proxies.
  const StoreProxy* proxy(uint32_t node) const {
    return node < proxies_.size() && proxies_[node].page != StoreProxy::kNoPage ? &proxies_[node] : nullptr;
  }

  // Decodes one cell's page (an empty scene for a cell without a page). Corruption naming the
  // cell and page when the page's checksum or contents are bad. Thread-safe.
  Status read_cell(uint32_t cell, Scene& out) const;
  // The same for a page already read (by the page cache): decodes and checks it. A page's
  // in-cell tree is skipped (not checked) here.
  Status decode_page(uint32_t cell, uint8_t codec, std::span<const uint8_t> payload, Scene& out) const;
  // decode_page, and the cell's in-cell tree in `tree` when the page carries one built with
  // `options` (root aside; same_cell_build): the tree KdTree::build(out, options) would give
  // with options.root = the cell's region. `tree` is left empty when the page carries none or
  // one built with other options (the caller builds it). Corruption naming the cell and page
  // when the tree is damaged. Thread-safe.
  Status decode_page(uint32_t cell, uint8_t codec, std::span<const uint8_t> payload, Scene& out,
                     const KdBuildOptions& options, std::optional<KdTree>& tree) const;
  // read_cell with the page's in-cell tree, as decode_page above.
  Status read_cell(uint32_t cell, Scene& out, const KdBuildOptions& options, std::optional<KdTree>& tree) const;
  // Decodes node `node`'s proxy page into triangles (each with its source and material).
  // InvalidArgument when the node has no proxy page; Corruption naming the node and the page when
  // the page's checksum or contents are bad (a triangle count other than the record's, a bad
  // source or material, a triangle outside the node's region). Thread-safe.
  Status read_proxy(uint32_t node, Scene& out) const;
  // read_proxy with the page's tree, as read_cell with options above: `tree` is the tree
  // KdTree::build(out, options) would give with options.root = the node's region when the page
  // carries one built with `options` (root aside; same_cell_build), else empty.
  Status read_proxy(uint32_t node, Scene& out, const KdBuildOptions& options, std::optional<KdTree>& tree) const;
  // The same for a proxy page already read (by the page cache); with `options` null the page's
  // tree, if any, is skipped (not checked).
  Status decode_proxy_page(uint32_t node, uint8_t codec, std::span<const uint8_t> payload, Scene& out) const;
  Status decode_proxy_page(uint32_t node, uint8_t codec, std::span<const uint8_t> payload, Scene& out,
                           const KdBuildOptions* options, std::optional<KdTree>& tree) const;
  Status read_proxy(uint32_t node, Scene& out, const KdBuildOptions* options, std::optional<KdTree>& tree) const;
  // Node `node`'s region (the root's is info().bounds). REQUIRES: node < nodes().size().
  Aabb node_region(uint32_t node) const;

  // Checks a decoded cell against its record: reference count, and every primitive overlaps
  // the cell's region.
  Status check_cell(uint32_t cell, const Scene& decoded) const;

  // Decodes every page into one scene (materials, lights, camera from the model section) and
  // lists, per top cell, the scene primitives it holds.
  Status load_scene(Scene& scene, std::vector<std::vector<uint32_t>>& cell_prims) const;
  // load_scene, then the in-memory tree: the store's top tree with every cell refined by the
  // SAH builder (`options`, min/max cell size of the in-memory engine).
  Status load_all(Scene& scene, KdTree& tree, const KdBuildOptions& options = {}) const;

 private:
  StoreModel() = default;
  Status parse();
  Status decode_page(uint32_t cell, uint8_t codec, std::span<const uint8_t> payload, Scene& out,
                     const KdBuildOptions* options, std::optional<KdTree>& tree) const;
  // What cell and proxy pages share (see store_model.cpp).
  Status decode_page_payload(uint8_t codec, std::span<const uint8_t> payload, std::string_view no_trees, Scene& out,
                             std::span<const uint8_t>& tree_bytes, bool& has_tree) const;

  std::unique_ptr<store::StoreReader> reader_;
  StoreModelInfo info_;
  std::vector<KdTree::Node> nodes_;
  std::vector<StoreCell> cells_;
  uint32_t depth_ = 0;
  std::optional<PortalGraph> portals_;
  std::vector<StoreProxy> proxies_;
  std::vector<Aabb> node_regions_;  // filled when the store has proxies
};

}  // namespace frontier
