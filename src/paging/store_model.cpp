// StoreModel: the model, tree and cells sections of a store, and cell pages decoded on demand.
// Opening parses each section with its own checked decoder, then walks the tree against the
// cells; nothing is trusted before it has been checked (layouts: store/FORMAT.md).
#include "src/paging/store_model.h"

#include "src/codec/cell_tree.h"
#include "src/core/byte_io.h"
#include "store/page_file.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>

namespace frontier {
namespace {

constexpr size_t kNodeBytes = 16;   // f64 split, u32 axis_or_leaf, u32 child
constexpr size_t kCellBytes = 112;  // 12 f64 bounds/content, u32 references, u32 0, u64 page
// Version 2: cell pages may carry in-cell trees (model section `cell_tree`); a store without them
// is still written as version 1, which readers that predate trees open. Version 3: proxy pages
// carry trees too (`cell_tree.proxy_max_cell_prims`); stores without them are written as before.
constexpr int kModelVersion = 3;

nlohmann::json vec_json(const Vec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); }
Vec3 json_vec(const nlohmann::json& j) {
  if (!j.is_array() || j.size() != 3) throw std::runtime_error("expected [x, y, z]");
  return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()};
}

bool finite(const Aabb& b) {
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(b.lo[a]) || !std::isfinite(b.hi[a])) return false;
  }
  return true;
}

// A section every model store has; Corruption (not NotFound) without it: the file is a store,
// but not a model store.
Result<std::vector<uint8_t>> required_section(const store::StoreReader& reader, std::string_view which) {
  auto bytes = reader.read_section(which);
  if (!bytes && bytes.status().code() == Status::Code::NotFound) {
    return Status::corruption(fmt::format("{}: no '{}' section (not a model store?)", reader.name(), which));
  }
  return bytes;
}

// The `tree` section: a node count (at least one) and exactly that many nodes.
Result<std::vector<KdTree::Node>> decode_tree(std::span<const uint8_t> bytes, const std::string& name) {
  GeometryReader r(bytes);
  const uint64_t count = r.u64();
  if (!r.ok() || count == 0 || r.remaining() % kNodeBytes != 0 || r.remaining() / kNodeBytes != count) {
    return Status::corruption(fmt::format("{}: tree section: size {} does not match its node count", name, bytes.size()));
  }
  std::vector<KdTree::Node> nodes(count);
  for (KdTree::Node& n : nodes) {
    n.split = r.f64();
    n.axis_or_leaf = r.u32();
    n.child = r.u32();
  }
  return nodes;
}

// The `cells` section: a cell count and exactly that many records, each consistent on its own
// (finite bounds holding the content, a page in range exactly when it holds references).
Result<std::vector<StoreCell>> decode_cells(std::span<const uint8_t> bytes, const std::string& name,
                                            uint64_t page_count) {
  GeometryReader r(bytes);
  const uint64_t count = r.u64();
  if (!r.ok() || r.remaining() % kCellBytes != 0 || r.remaining() / kCellBytes != count) {
    return Status::corruption(fmt::format("{}: cells section: size {} does not match its cell count", name, bytes.size()));
  }
  std::vector<StoreCell> cells(count);
  for (size_t i = 0; i < cells.size(); ++i) {
    StoreCell& c = cells[i];
    c.bounds = r.box();
    c.content = r.box();
    c.references = r.u32();
    const uint32_t zero = r.u32();
    c.page = r.u64();
    if (c.bounds.empty() || !finite(c.bounds)) return Status::corruption(fmt::format("{}: cell {}: bad bounds", name, i));
    const bool has_page = c.page != StoreCell::kNoPage;
    if (zero != 0 || (has_page && c.page >= page_count) || has_page != (c.references > 0)) {
      return Status::corruption(fmt::format("{}: cell {}: bad page reference", name, i));
    }
    if (!c.content.empty() && !(c.bounds.contains(c.content.lo) && c.bounds.contains(c.content.hi))) {
      return Status::corruption(fmt::format("{}: cell {}: content outside the cell", name, i));
    }
  }
  return cells;
}

// Walks the tree (preorder, lower child = next node): every node visited once, splits strictly
// inside their region, every cell reached once with exactly the region its record states.
// Returns the tree's depth.
Result<uint32_t> check_tree(const std::vector<KdTree::Node>& nodes, const std::vector<StoreCell>& cells,
                            const Aabb& bounds, const std::string& name) {
  struct Visit {
    uint32_t node;
    Aabb region;
    uint32_t depth;
  };
  std::vector<Visit> stack{{0, bounds, 0}};
  std::vector<uint8_t> cell_seen(cells.size(), 0);
  size_t visited = 0;
  uint32_t expected = 0;  // preorder: nodes are visited in index order
  uint32_t depth = 0;
  while (!stack.empty()) {
    const Visit v = stack.back();
    stack.pop_back();
    if (v.node != expected || v.node >= nodes.size()) {
      return Status::corruption(fmt::format("{}: tree node {}: not in preorder", name, v.node));
    }
    ++expected;
    ++visited;
    depth = std::max(depth, v.depth);
    const KdTree::Node& n = nodes[v.node];
    if (n.is_leaf()) {
      if (n.child >= cells.size() || cell_seen[n.child]) {
        return Status::corruption(fmt::format("{}: tree node {}: bad cell {}", name, v.node, n.child));
      }
      cell_seen[n.child] = 1;
      if (!(cells[n.child].bounds.lo == v.region.lo && cells[n.child].bounds.hi == v.region.hi)) {
        return Status::corruption(fmt::format("{}: cell {}: bounds differ from its tree region", name, n.child));
      }
      continue;
    }
    const int a = static_cast<int>(n.axis_or_leaf);
    if (a > 2 || !(n.split > v.region.lo[a] && n.split < v.region.hi[a]) || n.child <= v.node + 1 ||
        n.child >= nodes.size()) {
      return Status::corruption(fmt::format("{}: tree node {}: bad split", name, v.node));
    }
    Aabb lower = v.region, upper = v.region;
    lower.hi[a] = n.split;
    upper.lo[a] = n.split;
    stack.push_back({n.child, upper, v.depth + 1});
    stack.push_back({v.node + 1, lower, v.depth + 1});
  }
  if (visited != nodes.size()) return Status::corruption(fmt::format("{}: tree has unreachable nodes", name));
  for (size_t i = 0; i < cells.size(); ++i) {
    if (!cell_seen[i]) return Status::corruption(fmt::format("{}: cell {} is not in the tree", name, i));
  }
  return depth;
}

// An optional section's bytes (Corruption naming the store and the section when its block is
// damaged); `where` says which ("STORE: NAME section").
Result<std::vector<uint8_t>> read_optional_section(const store::StoreReader& reader, std::string_view name,
                                                   std::string& where) {
  where = fmt::format("{}: {} section", reader.name(), name);
  auto bytes = reader.read_section(name);
  if (!bytes && bytes.status().code() == Status::Code::Corruption) {
    return Status::corruption(fmt::format("{}: {}", where, bytes.status().message()));
  }
  return bytes;
}

// The `portals` section when the store has one (Corruption naming the store and the section
// when it is damaged); `out` stays empty without it.
Status read_portals(const store::StoreReader& reader, std::optional<PortalGraph>& out) {
  if (!reader.section(kPortalsSection)) return Status::ok();
  std::string where;
  auto bytes = read_optional_section(reader, kPortalsSection, where);
  if (!bytes) return bytes.status();
  auto graph = PortalGraph::deserialize(*bytes, where);
  if (!graph) return graph.status();
  out.emplace(std::move(*graph));
  return Status::ok();
}

// Every node's region, by a preorder walk of a checked tree.
std::vector<Aabb> node_regions(const std::vector<KdTree::Node>& nodes, const Aabb& bounds) {
  std::vector<Aabb> regions(nodes.size());
  regions[0] = bounds;
  for (uint32_t i = 0; i < nodes.size(); ++i) {
    const KdTree::Node& n = nodes[i];
    if (n.is_leaf()) continue;
    const int a = static_cast<int>(n.axis_or_leaf);
    regions[i + 1] = regions[i];
    regions[i + 1].hi[a] = n.split;
    regions[n.child] = regions[i];
    regions[n.child].lo[a] = n.split;
  }
  return regions;
}

// The `proxies` section when the store has one: a record per node, pages only at interior nodes.
Status read_proxies(const store::StoreReader& reader, const std::vector<KdTree::Node>& nodes,
                    std::vector<StoreProxy>& out) {
  if (!reader.section(kProxiesSection)) return Status::ok();
  std::string where;
  auto bytes = read_optional_section(reader, kProxiesSection, where);
  if (!bytes) return bytes.status();
  auto proxies = decode_proxies(*bytes, reader.page_count(), where);
  if (!proxies) return proxies.status();
  if (proxies->size() != nodes.size()) {
    return Status::corruption(fmt::format("{}: {} records for {} tree nodes", where, proxies->size(), nodes.size()));
  }
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (nodes[i].is_leaf() && (*proxies)[i].page != StoreProxy::kNoPage) {
      return Status::corruption(fmt::format("{}: node {} is a leaf but has a proxy page", where, i));
    }
  }
  out = std::move(*proxies);
  return Status::ok();
}

}  // namespace

std::vector<uint8_t> StoreModelInfo::to_bytes() const {
  nlohmann::json j;
  j["version"] = proxy_tree_cell_prims > 0 ? kModelVersion : cell_tree ? 2 : 1;
  j["codec"] = std::string(cell_codec_name(codec));
  j["lattice"] = {{"origin", vec_json(lattice.origin)}, {"step", lattice.step}, {"bits", lattice.bits}};
  j["bounds"] = {{"lo", vec_json(bounds.lo)}, {"hi", vec_json(bounds.hi)}};
  j["input_primitives"] = input_primitives;
  j["primitives"] = primitives;
  j["references"] = references;
  j["triangles"] = triangles;
  j["degenerate_dropped"] = degenerate_dropped;
  j["cell_prims"] = cell_prims;
  j["inputs"] = inputs;
  auto& mats = j["materials"] = nlohmann::json::array();
  for (const Material& m : materials) {
    mats.push_back({{"color", vec_json(m.color)}, {"kd", m.kd}, {"ks", m.ks}, {"shine", m.shine},
                    {"transmittance", m.transmittance}, {"ior", m.ior}});
  }
  auto& ls = j["lights"] = nlohmann::json::array();
  for (const PointLight& l : lights) ls.push_back({{"position", vec_json(l.position)}, {"color", vec_json(l.color)}});
  if (camera) {
    const Camera& c = *camera;
    j["camera"] = {{"eye", vec_json(c.eye)}, {"look_at", vec_json(c.look_at)}, {"up", vec_json(c.up)},
                   {"vfov_deg", c.vfov_deg}, {"near", c.near}, {"width", c.width}, {"height", c.height}};
  }
  j["background"] = vec_json(background);
  j["walkable"] = walkable;
  j["sdf_voxel"] = sdf_voxel;
  j["walk_radius"] = walk_radius;
  if (cell_tree) {
    const KdBuildOptions& o = *cell_tree;
    j["cell_tree"] = {{"max_cell_prims", o.max_cell_prims},
                      {"min_cell_prims", o.min_cell_prims},
                      {"forced_split_max_share", o.forced_split_max_share},
                      {"max_depth", o.max_depth},
                      {"traversal_cost", o.traversal_cost},
                      {"intersection_cost", o.intersection_cost},
                      {"empty_bonus", o.empty_bonus},
                      {"bins", o.bins},
                      {"pages", cell_tree_pages},
                      {"bytes", cell_tree_bytes}};
    if (proxy_tree_cell_prims > 0) {
      j["cell_tree"]["proxy_max_cell_prims"] = proxy_tree_cell_prims;
      j["cell_tree"]["proxy_pages"] = proxy_tree_pages;
      j["cell_tree"]["proxy_bytes"] = proxy_tree_bytes;
    }
  }
  const std::string text = j.dump(1);
  return {text.begin(), text.end()};
}

Result<StoreModelInfo> StoreModelInfo::from_bytes(std::span<const uint8_t> bytes, const std::string& where) {
  StoreModelInfo info;
  try {
    const auto j = nlohmann::json::parse(bytes.begin(), bytes.end());
    const int version = j.at("version").get<int>();
    if (version > kModelVersion) {
      return Status::unsupported(fmt::format("{}: model section version {} is newer than this reader ({})", where,
                                             version, kModelVersion));
    }
    const std::string codec = j.at("codec").get<std::string>();
    const std::optional<CellCodec> tag = cell_codec_named(codec);
    if (!tag) return Status::unsupported(fmt::format("{}: unknown codec '{}'", where, codec));
    info.codec = *tag;
    const auto& lat = j.at("lattice");
    info.lattice.origin = json_vec(lat.at("origin"));
    info.lattice.step = lat.at("step").get<double>();
    info.lattice.bits = lat.at("bits").get<int>();
    if (!(info.lattice.step > 0.0) || !std::isfinite(info.lattice.step) || info.lattice.bits < 1 ||
        info.lattice.bits > 30) {
      return Status::corruption(fmt::format("{}: model section: impossible lattice", where));
    }
    info.bounds = Aabb(json_vec(j.at("bounds").at("lo")), json_vec(j.at("bounds").at("hi")));
    info.input_primitives = j.at("input_primitives").get<uint64_t>();
    info.primitives = j.at("primitives").get<uint64_t>();
    info.references = j.at("references").get<uint64_t>();
    info.triangles = j.at("triangles").get<uint64_t>();
    info.degenerate_dropped = j.at("degenerate_dropped").get<uint64_t>();
    info.cell_prims = j.at("cell_prims").get<uint32_t>();
    info.inputs = j.at("inputs").get<std::vector<std::string>>();
    for (const auto& m : j.at("materials")) {
      Material mat;
      mat.color = json_vec(m.at("color"));
      mat.kd = m.at("kd").get<double>();
      mat.ks = m.at("ks").get<double>();
      mat.shine = m.at("shine").get<double>();
      mat.transmittance = m.at("transmittance").get<double>();
      mat.ior = m.at("ior").get<double>();
      info.materials.push_back(mat);
    }
    for (const auto& l : j.at("lights")) info.lights.push_back({json_vec(l.at("position")), json_vec(l.at("color"))});
    if (j.contains("camera")) {
      const auto& c = j.at("camera");
      Camera cam;
      cam.eye = json_vec(c.at("eye"));
      cam.look_at = json_vec(c.at("look_at"));
      cam.up = json_vec(c.at("up"));
      cam.vfov_deg = c.at("vfov_deg").get<double>();
      cam.near = c.at("near").get<double>();
      cam.width = c.at("width").get<int>();
      cam.height = c.at("height").get<int>();
      info.camera = cam;
    }
    info.background = json_vec(j.at("background"));
    info.walkable = j.at("walkable").get<bool>();
    info.sdf_voxel = j.at("sdf_voxel").get<double>();
    info.walk_radius = j.at("walk_radius").get<double>();
    if (j.contains("cell_tree")) {  // stores built before in-cell trees have none
      const auto& t = j.at("cell_tree");
      KdBuildOptions o;
      o.max_cell_prims = t.at("max_cell_prims").get<uint32_t>();
      o.min_cell_prims = t.at("min_cell_prims").get<uint32_t>();
      o.forced_split_max_share = t.at("forced_split_max_share").get<double>();
      o.max_depth = t.at("max_depth").get<uint32_t>();
      o.traversal_cost = t.at("traversal_cost").get<double>();
      o.intersection_cost = t.at("intersection_cost").get<double>();
      o.empty_bonus = t.at("empty_bonus").get<double>();
      o.bins = t.at("bins").get<int>();
      info.cell_tree = o;
      info.cell_tree_pages = t.at("pages").get<uint64_t>();
      info.cell_tree_bytes = t.at("bytes").get<uint64_t>();
      if (t.contains("proxy_max_cell_prims")) {  // stores built before proxy trees have none
        info.proxy_tree_cell_prims = t.at("proxy_max_cell_prims").get<uint32_t>();
        info.proxy_tree_pages = t.at("proxy_pages").get<uint64_t>();
        info.proxy_tree_bytes = t.at("proxy_bytes").get<uint64_t>();
        if (info.proxy_tree_cell_prims == 0) throw std::runtime_error("cell_tree.proxy_max_cell_prims is 0");
      }
    }
  } catch (const std::exception& e) {
    return Status::corruption(fmt::format("{}: model section: {}", where, e.what()));
  }
  if (info.materials.empty()) return Status::corruption(fmt::format("{}: model section: no materials", where));
  if (info.bounds.empty() || !finite(info.bounds)) {
    return Status::corruption(fmt::format("{}: model section: bad bounds", where));
  }
  return info;
}

std::vector<uint8_t> encode_tree(const std::vector<KdTree::Node>& nodes) {
  std::vector<uint8_t> out;
  GeometryWriter w(out);
  w.reserve(8 + kNodeBytes * nodes.size());
  w.u64(nodes.size());
  for (const KdTree::Node& n : nodes) {
    w.f64(n.split);
    w.u32(n.axis_or_leaf);
    w.u32(n.child);
  }
  return out;
}

std::vector<uint8_t> encode_cells(const std::vector<StoreCell>& cells) {
  std::vector<uint8_t> out;
  GeometryWriter w(out);
  w.reserve(8 + kCellBytes * cells.size());
  w.u64(cells.size());
  for (const StoreCell& c : cells) {
    w.box(c.bounds);
    w.box(c.content);
    w.u32(c.references);
    w.u32(0);
    w.u64(c.page);
  }
  return out;
}

Result<std::unique_ptr<StoreModel>> StoreModel::open(const std::string& path) {
  store::PosixFileSystem fs;
  auto reader = store::StoreReader::open(fs, path);
  if (!reader) return reader.status();
  return open(std::move(*reader));
}

Result<std::unique_ptr<StoreModel>> StoreModel::open(std::unique_ptr<store::StoreReader> reader) {
  std::unique_ptr<StoreModel> model(new StoreModel());
  model->reader_ = std::move(reader);
  if (Status s = model->parse(); !s) return s;
  return model;
}

Status StoreModel::parse() {
  const std::string& name = reader_->name();
  auto model_bytes = required_section(*reader_, kModelSection);
  if (!model_bytes) return model_bytes.status();
  auto info = StoreModelInfo::from_bytes(*model_bytes, name);
  if (!info) return info.status();
  info_ = std::move(*info);

  auto tree_bytes = required_section(*reader_, kTreeSection);
  if (!tree_bytes) return tree_bytes.status();
  auto nodes = decode_tree(*tree_bytes, name);
  if (!nodes) return nodes.status();
  nodes_ = std::move(*nodes);

  auto cell_bytes = required_section(*reader_, kCellsSection);
  if (!cell_bytes) return cell_bytes.status();
  auto cells = decode_cells(*cell_bytes, name, reader_->page_count());
  if (!cells) return cells.status();
  cells_ = std::move(*cells);
  uint64_t references = 0;
  for (const StoreCell& c : cells_) references += c.references;
  if (references != info_.references) {
    return Status::corruption(fmt::format("{}: cells hold {} references, the model section says {}", name, references,
                                          info_.references));
  }

  auto depth = check_tree(nodes_, cells_, info_.bounds, name);
  if (!depth) return depth.status();
  depth_ = *depth;
  if (Status s = read_portals(*reader_, portals_); !s) return s;
  if (Status s = read_proxies(*reader_, nodes_, proxies_); !s) return s;
  if (!proxies_.empty()) node_regions_ = node_regions(nodes_, info_.bounds);
  return Status::ok();
}

Aabb StoreModel::node_region(uint32_t node) const {
  return node_regions_.empty() ? node_regions(nodes_, info_.bounds).at(node) : node_regions_.at(node);
}

Status StoreModel::read_proxy(uint32_t node, Scene& out) const {
  std::optional<KdTree> none;
  return read_proxy(node, out, nullptr, none);
}

Status StoreModel::read_proxy(uint32_t node, Scene& out, const KdBuildOptions& options,
                              std::optional<KdTree>& tree) const {
  return read_proxy(node, out, &options, tree);
}

Status StoreModel::read_proxy(uint32_t node, Scene& out, const KdBuildOptions* options,
                              std::optional<KdTree>& tree) const {
  out = Scene{};
  tree.reset();
  const StoreProxy* p = proxy(node);
  if (p == nullptr) return Status::invalid_argument(fmt::format("{}: node {} has no proxy page", reader_->name(), node));
  auto page = reader_->read_page(p->page);
  if (!page) {
    return page.status().prefixed(fmt::format("proxy of node {} page {}: ", node, p->page));
  }
  return decode_proxy_page(node, page->codec, page->payload, out, options, tree);
}

Status StoreModel::decode_proxy_page(uint32_t node, uint8_t codec, std::span<const uint8_t> payload,
                                     Scene& out) const {
  std::optional<KdTree> none;
  return decode_proxy_page(node, codec, payload, out, nullptr, none);
}

// A proxy page: as a cell page (decode_page), its tree built with the proxy options
// (cell_tree.h proxy_tree_options) over the node's region.
Status StoreModel::decode_proxy_page(uint32_t node, uint8_t codec, std::span<const uint8_t> payload, Scene& out,
                                     const KdBuildOptions* options, std::optional<KdTree>& tree) const {
  out = Scene{};
  tree.reset();
  const StoreProxy* p = proxy(node);
  if (p == nullptr) return Status::invalid_argument(fmt::format("{}: node {} has no proxy page", reader_->name(), node));
  const auto corrupt = [&](const std::string& why) {
    out = Scene{};
    tree.reset();
    return Status::corruption(fmt::format("{}: proxy of node {} page {}: {}", reader_->name(), node, p->page, why));
  };
  std::span<const uint8_t> tree_bytes;
  bool has_tree = false;
  const bool trees = info_.cell_tree && info_.proxy_tree_cell_prims != 0;
  if (Status s = decode_page_payload(codec, payload, trees ? "" : "the model section records no proxy trees", out,
                                     tree_bytes, has_tree);
      !s) {
    return corrupt(s.message());
  }
  if (out.size() != p->triangles || out.triangles.size() != out.size()) {
    return corrupt(fmt::format("{} primitives, the proxy record says {} triangles", out.size(), p->triangles));
  }
  // Proxy vertices are vertices of the subtree's primitives, which may reach past the region by
  // as much as a primitive straddling it does: only a vertex outside the model's bounds is wrong.
  Aabb bounds = info_.bounds;
  const double eps = 1e-9 * glm::length(bounds.extent()) + (cell_codec_on_lattice(info_.codec) ? info_.lattice.step : 0.0);
  bounds.lo -= Vec3(eps);
  bounds.hi += Vec3(eps);
  for (uint32_t i = 0; i < out.size(); ++i) {
    const PrimRef& prim = out.prims[i];
    if (prim.material >= info_.materials.size() || prim.source >= info_.input_primitives) {
      return corrupt(fmt::format("triangle {} has a bad material or source", i));
    }
    const Triangle& t = out.triangles[prim.index];
    if (!bounds.contains(t.v0) || !bounds.contains(t.v1) || !bounds.contains(t.v2)) {
      return corrupt(fmt::format("triangle {} lies outside the model", i));
    }
  }
  if (!has_tree || options == nullptr) return Status::ok();
  KdBuildOptions stored = *info_.cell_tree;
  stored.max_cell_prims = info_.proxy_tree_cell_prims;
  if (!same_cell_build(*options, stored)) return Status::ok();
  auto decoded = decode_cell_tree(tree_bytes, out, node_region(node), *options);
  if (!decoded) return corrupt(decoded.status().message());
  tree.emplace(std::move(*decoded));
  return Status::ok();
}

Status StoreModel::read_cell(uint32_t cell, Scene& out) const {
  out = Scene{};
  const StoreCell& c = cells_.at(cell);
  if (c.page == StoreCell::kNoPage) return Status::ok();
  auto page = reader_->read_page(c.page);
  if (!page) return page.status();
  return decode_page(cell, page->codec, page->payload, out);
}

Status StoreModel::decode_page(uint32_t cell, uint8_t codec, std::span<const uint8_t> payload, Scene& out) const {
  std::optional<KdTree> none;
  return decode_page(cell, codec, payload, out, nullptr, none);
}

Status StoreModel::decode_page(uint32_t cell, uint8_t codec, std::span<const uint8_t> payload, Scene& out,
                               const KdBuildOptions& options, std::optional<KdTree>& tree) const {
  return decode_page(cell, codec, payload, out, &options, tree);
}

Status StoreModel::read_cell(uint32_t cell, Scene& out, const KdBuildOptions& options,
                             std::optional<KdTree>& tree) const {
  out = Scene{};
  tree.reset();
  const StoreCell& c = cells_.at(cell);
  if (c.page == StoreCell::kNoPage) return Status::ok();
  auto page = reader_->read_page(c.page);
  if (!page) return page.status();
  return decode_page(cell, page->codec, page->payload, out, &options, tree);
}

// A cell page: the codec's payload, preceded by an in-cell tree when the codec byte says so;
// the tree is decoded only when the caller's options are the ones it was built with.
Status StoreModel::decode_page(uint32_t cell, uint8_t codec, std::span<const uint8_t> payload, Scene& out,
                               const KdBuildOptions* options, std::optional<KdTree>& tree) const {
  out = Scene{};
  tree.reset();
  const StoreCell& c = cells_.at(cell);
  const auto corrupt = [&](std::string_view what) {
    out = Scene{};
    return Status::corruption(fmt::format("{}: cell {} page {}: {}", reader_->name(), cell, c.page, what));
  };
  std::span<const uint8_t> tree_bytes;
  bool has_tree = false;
  if (Status s = decode_page_payload(codec, payload, info_.cell_tree ? "" : "the model section records no tree options",
                                     out, tree_bytes, has_tree);
      !s) {
    return corrupt(s.message());
  }
  if (Status s = check_cell(cell, out); !s) {
    out = Scene{};
    return s;
  }
  if (!has_tree || options == nullptr || !same_cell_build(*options, *info_.cell_tree)) return Status::ok();
  auto decoded = decode_cell_tree(tree_bytes, out, c.bounds, *options);
  if (!decoded) return corrupt(decoded.status().message());
  tree.emplace(std::move(*decoded));
  return Status::ok();
}

// What cell and proxy pages share: an in-cell tree split off the payload when the codec byte
// says the page carries one (`no_trees`: why it may not, empty when it may), then the codec's
// payload decoded into `out`. The caller names the page in any error.
Status StoreModel::decode_page_payload(uint8_t codec, std::span<const uint8_t> payload, std::string_view no_trees,
                                       Scene& out, std::span<const uint8_t>& tree_bytes, bool& has_tree) const {
  tree_bytes = {};
  has_tree = (codec & kCellTreeFlag) != 0;
  if (has_tree) {
    if (!no_trees.empty()) return Status::corruption(fmt::format("carries an in-page tree but {}", no_trees));
    if (Status s = split_tree_page(payload, tree_bytes, payload); !s) return s;
    codec = static_cast<uint8_t>(codec & ~kCellTreeFlag);
  }
  if (!is_cell_codec(codec)) return Status::corruption(fmt::format("unknown codec {}", codec));
  return decode_cell(payload, static_cast<CellCodec>(codec), info_.lattice, out);
}

Status StoreModel::check_cell(uint32_t cell, const Scene& decoded) const {
  const StoreCell& c = cells_.at(cell);
  if (decoded.size() > c.references) {
    return Status::corruption(fmt::format("{}: cell {} page {}: {} primitives, the cell record says {}",
                                          reader_->name(), cell, c.page, decoded.size(), c.references));
  }
  // Snapped or decoded geometry may sit a lattice step across the region: allow that much.
  Aabb region = c.bounds;
  const double slack = cell_codec_on_lattice(info_.codec) ? info_.lattice.step : 0.0;
  const double eps = slack + 1e-9 * glm::length(info_.bounds.extent());
  region.lo -= Vec3(eps);
  region.hi += Vec3(eps);
  for (uint32_t i = 0; i < decoded.size(); ++i) {
    const PrimRef& p = decoded.prims[i];
    if (p.material >= info_.materials.size() || p.source >= info_.input_primitives) {
      return Status::corruption(fmt::format("{}: cell {} page {}: primitive {} has a bad material or source",
                                            reader_->name(), cell, c.page, i));
    }
    if (region.intersection(decoded.prim_bounds(i)).empty()) {
      return Status::corruption(fmt::format("{}: cell {} page {}: primitive {} lies outside the cell", reader_->name(),
                                            cell, c.page, i));
    }
  }
  return Status::ok();
}

Status StoreModel::load_scene(Scene& scene, std::vector<std::vector<uint32_t>>& cell_prims) const {
  scene = Scene{};
  scene.materials = info_.materials;
  scene.lights = info_.lights;
  scene.camera = info_.camera;
  scene.background = info_.background;
  scene.input_primitives = static_cast<uint32_t>(std::min<uint64_t>(info_.input_primitives, UINT32_MAX));
  scene.degenerate_dropped = info_.degenerate_dropped;
  cell_prims.assign(cells_.size(), {});
  Scene cell;
  for (uint32_t c = 0; c < cells_.size(); ++c) {
    if (Status s = read_cell(c, cell); !s) return s;
    const auto first = static_cast<uint32_t>(scene.size());
    for (uint32_t i = 0; i < cell.size(); ++i) scene.add_from(cell, i);
    auto& list = cell_prims[c];
    list.resize(cell.size());
    for (uint32_t i = 0; i < cell.size(); ++i) list[i] = first + i;
  }
  return Status::ok();
}

Status StoreModel::load_all(Scene& scene, KdTree& tree, const KdBuildOptions& options) const {
  std::vector<std::vector<uint32_t>> cell_prims;
  if (Status s = load_scene(scene, cell_prims); !s) return s;
  tree = KdTree::refine(scene, nodes_, info_.bounds, cell_prims, options);
  return Status::ok();
}

}  // namespace frontier
