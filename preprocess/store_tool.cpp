// frontier-store: looks inside a store file.
//   info FILE    what the store holds: primitives, cells, depth, bytes per triangle, codec,
//                in-cell trees (pages, bytes, the options they were built with), lattice, collision grid, cells and portals, proxies (pages, bytes apart from the
//                cells', error bound at the root and per depth, and per depth the bound, the
//                measured distance to the original cells and their ratio for up to 4 nodes whose
//                subtrees have at most 200 k triangles), sections, a histogram of cell sizes
//   verify FILE  every checksum, every structural invariant (the portals section included),
//                every cell page decoded and checked against its cell, every in-cell tree
//                assembled over its cell, every collision brick decoded, every proxy page decoded
//                (its tree assembled) and checked against its record, every page owned by exactly one cell, brick or
//                proxy; exit 1 naming the first bad part
//   proxy FILE NODE -o OUT.ply
//                node NODE's proxy (its stand-in triangles, as the viewer draws them) as a PLY mesh,
//                to look at; prints its error bound and triangle count
#include "src/walk/collision_grid.h"
#include "src/core/progress.h"
#include "src/io/ply_writer.h"
#include "src/lod/proxy.h"
#include "src/paging/store_model.h"
#include "store/page_file.h"
#include "store/store_file.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cstdio>
#include <map>
#include <optional>

namespace {

using frontier::StoreCell;
using frontier::StoreModel;

int fail(const frontier::Status& s) {
  std::fprintf(stderr, "frontier-store: %s\n", s.to_string().c_str());
  return 1;
}

std::string vec(const frontier::Vec3& v) { return fmt::format("({:.9g}, {:.9g}, {:.9g})", v.x, v.y, v.z); }

// Nodes measured per depth by `info`, and the most triangles their subtrees may have (reading
// and measuring a subtree of 200 k triangles takes about a quarter of a second).
constexpr size_t kMeasuredPerDepth = 4;
constexpr uint64_t kMeasuredSubtreeTriangles = 200000;  // info --measure-triangles' default

// The two-sided distance between node `node`'s proxy and the original geometry of its subtree
// (cells first .. end of the preorder), measured as the builder measures a proxy against its
// input (proxy.h measured_distance: an upper bound over every original point, the proxy's
// vertices, edge midpoints and centroids), plus the curved primitives' tessellation error.
frontier::Result<double> measured_proxy_distance(const StoreModel& model, uint32_t node, uint32_t end) {
  frontier::ProxyOptions options;
  if (frontier::cell_codec_on_lattice(model.info().codec)) options.lattice = model.info().lattice;
  frontier::Scene cells;
  for (uint32_t n = node; n < end; ++n) {
    if (!model.nodes()[n].is_leaf() || model.cells()[model.nodes()[n].child].page == StoreCell::kNoPage) continue;
    frontier::Scene cell;
    if (frontier::Status s = model.read_cell(model.nodes()[n].child, cell); !s) return s;
    for (uint32_t i = 0; i < cell.size(); ++i) cells.add_from(cell, i);
  }
  const frontier::ProxyMesh original = frontier::proxy_input(cells, options);
  frontier::Scene scene;
  if (frontier::Status s = model.read_proxy(node, scene); !s) return s;
  frontier::ProxyMesh proxy = frontier::proxy_input(scene, options);
  if (original.empty() || proxy.empty()) return 0.0;
  return frontier::measured_distance(original, proxy) + original.chord_error;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t h = v.size() / 2;
  return v.size() % 2 == 1 ? v[h] : 0.5 * (v[h - 1] + v[h]);
}

// The proxies line: pages and bytes (apart from the cells'), and the error bound by depth with
// the measured distance of a few nodes per depth.
frontier::Result<std::string> proxies_info(const StoreModel& model, uint64_t measure_triangles) {
  if (model.proxies().empty()) return std::string("proxies     none\n");
  uint64_t pages = 0, bytes = 0, triangles = 0, model_triangles = std::max<uint64_t>(model.info().triangles, 1);
  struct Depth {
    double smallest = 0.0, largest = 0.0;
    std::vector<uint32_t> small_nodes;  // proxies whose subtrees are small enough to measure
  };
  std::map<uint32_t, Depth> by_depth;
  const size_t count = model.nodes().size();
  std::vector<uint32_t> depth(count, 0), end(count);
  for (size_t i = count; i-- > 0;) {
    end[i] = model.nodes()[i].is_leaf() ? static_cast<uint32_t>(i + 1) : end[model.nodes()[i].child];
  }
  for (uint32_t i = 0; i < count; ++i) {
    const frontier::KdTree::Node& n = model.nodes()[i];
    if (!n.is_leaf()) depth[i + 1] = depth[n.child] = depth[i] + 1;
    const frontier::StoreProxy* p = model.proxy(i);
    if (p == nullptr) continue;
    ++pages;
    bytes += model.reader().page_handle(p->page).size;
    triangles += p->triangles;
    auto [it, fresh] = by_depth.try_emplace(depth[i], Depth{p->error, p->error, {}});
    it->second.smallest = std::min(it->second.smallest, p->error);
    it->second.largest = std::max(it->second.largest, p->error);
    if (p->subtree_triangles <= measure_triangles) it->second.small_nodes.push_back(i);
  }
  std::string out = fmt::format(
      "proxies     {} pages, {} triangles, {} bytes ({:.2f} bytes/triangle of the model), root error {:.4g}\n"
      "            per depth: stored bounds; medians over up to {} nodes whose subtrees have at most {} triangles\n"
      "            of the stored bound, the measured two-sided distance to the original cells and their ratio\n",
      pages, triangles, bytes, static_cast<double>(bytes) / static_cast<double>(model_triangles),
      model.proxies()[0].error, kMeasuredPerDepth, measure_triangles);
  for (const auto& [d, at] : by_depth) {
    out += fmt::format("  depth {:>3}  error {:.4g} .. {:.4g}", d, at.smallest, at.largest);
    std::vector<double> stored, measured, ratio;
    const size_t n = at.small_nodes.size();
    for (size_t k = 0; k < std::min(n, kMeasuredPerDepth); ++k) {
      const uint32_t node = at.small_nodes[k * n / std::min(n, kMeasuredPerDepth)];  // spread over the depth
      auto distance = measured_proxy_distance(model, node, end[node]);
      if (!distance) return distance.status();
      stored.push_back(model.proxies()[node].error);
      measured.push_back(*distance);
      if (*distance > 0.0) ratio.push_back(model.proxies()[node].error / *distance);
    }
    if (!stored.empty()) {
      out += fmt::format("  measured {} nodes: stored {:.4g}, distance {:.4g}, stored/distance {}", stored.size(),
                         median(stored), median(measured), ratio.empty() ? std::string("-") : fmt::format("{:.3g}", median(ratio)));
    }
    out += "\n";
  }
  return out;
}

int info(const std::string& path, uint64_t measure_triangles) {
  auto opened = StoreModel::open(path);
  if (!opened) return fail(opened.status());
  const StoreModel& model = **opened;
  const frontier::StoreModelInfo& in = model.info();
  const auto& reader = model.reader();
  uint64_t empty = 0, page_bytes = 0, largest = 0;
  std::map<uint32_t, uint64_t> histogram;  // bin: references in [2^(b-1), 2^b)
  for (const StoreCell& c : model.cells()) {
    if (c.page == StoreCell::kNoPage) {
      ++empty;
      continue;
    }
    page_bytes += reader.page_handle(c.page).size;
    largest = std::max<uint64_t>(largest, c.references);
    ++histogram[static_cast<uint32_t>(std::bit_width(c.references))];
  }
  const double tris = static_cast<double>(std::max<uint64_t>(in.triangles, 1));
  std::string out;
  out += fmt::format("store       {} ({} bytes, format version {})\n", path, reader.file_size(), reader.version());
  std::string inputs;
  for (const std::string& i : in.inputs) inputs += (inputs.empty() ? "" : ", ") + i;
  out += fmt::format("inputs      {}\n", inputs);
  out += fmt::format("primitives  {} ({} triangles; {} input primitives; {} degenerate dropped)\n", in.primitives,
                     in.triangles, in.input_primitives, in.degenerate_dropped);
  out += fmt::format("references  {} ({:.2f} per primitive: straddling primitives are stored in each cell)\n",
                     in.references,
                     static_cast<double>(in.references) / static_cast<double>(std::max<uint64_t>(in.primitives, 1)));
  out += fmt::format("cells       {} ({} empty, {} pages), depth {}, --cell-prims {}, largest {}\n",
                     model.cells().size(), empty, model.cells().size() - empty, model.depth(), in.cell_prims, largest);
  out += fmt::format("codec       {}\n", frontier::cell_codec_name(in.codec));
  if (in.cell_tree) {
    const frontier::KdBuildOptions& o = *in.cell_tree;
    out += fmt::format("cell trees  in {} of {} pages, {} bytes ({:.2f} bytes/triangle); built with max_cell_prims {}, "
                       "min_cell_prims {}, split share {}, max_depth {}, traversal cost {}, intersection cost {}, "
                       "empty bonus {}, bins {}\n",
                       in.cell_tree_pages, model.cells().size() - empty, in.cell_tree_bytes,
                       static_cast<double>(in.cell_tree_bytes) / tris, o.max_cell_prims, o.min_cell_prims,
                       o.forced_split_max_share, o.max_depth, o.traversal_cost, o.intersection_cost, o.empty_bonus,
                       o.bins);
  } else {
    out += "cell trees  none (frontier-view builds each cell's tree at page-in)\n";
  }
  if (in.proxy_tree_cell_prims > 0) {
    out += fmt::format("proxy trees in {} proxy pages, {} bytes; built as the cell trees with max_cell_prims {}\n",
                       in.proxy_tree_pages, in.proxy_tree_bytes, in.proxy_tree_cell_prims);
  }
  if (frontier::cell_codec_on_lattice(in.codec)) {
    out += fmt::format("lattice     {} bits, step {:.9g} (max error {:.3g} per axis), origin {}\n", in.lattice.bits,
                       in.lattice.step, in.lattice.max_error(), vec(in.lattice.origin));
  }
  out += fmt::format("bounds      {} .. {}\n", vec(in.bounds.lo), vec(in.bounds.hi));
  out += fmt::format("bytes/tri   {:.2f} (whole file), {:.2f} (cell pages)\n",
                     static_cast<double>(reader.file_size()) / tris, static_cast<double>(page_bytes) / tris);
  out += fmt::format("materials   {}, lights {}, camera {}\n", in.materials.size(), in.lights.size(),
                     in.camera ? "yes" : "no");
  if (in.walkable) {
    auto grid = frontier::open_collision_grid(reader);
    if (!grid) return fail(grid.status());
    uint64_t brick_bytes = 0;
    for (uint64_t p : (*grid)->brick_pages()) brick_bytes += reader.page_handle(p).size;
    out += fmt::format("walkable    yes: distance grid, voxel {:.4g}, band {} voxels, {} active voxels in {} bricks "
                       "of {}^3 ({:.1f} MB of pages)\n",
                       (*grid)->voxel_size(), (*grid)->band_voxels(), (*grid)->active_voxels(),
                       (*grid)->counters().bricks, frontier::sdf_format::kBrickVoxels,
                       static_cast<double>(brick_bytes) / 1e6);
  } else {
    out += "walkable    no\n";
  }
  if (const frontier::PortalGraph* portals = model.portals()) {
    out += fmt::format("portals     {} rooms, {} portals (walls {:.4g}, slabs {:.4g})\n", portals->room_count(),
                       portals->portal_count(), portals->wall_thickness(), portals->slab_thickness());
  } else {
    out += "portals     none\n";
  }
  auto proxies = proxies_info(model, measure_triangles);
  if (!proxies) return fail(proxies.status());
  out += *proxies;
  out += "sections   ";
  for (const auto& s : reader.sections()) out += fmt::format(" {} {}B", s.name, s.handle.size);
  out += "\ncell sizes  (references per non-empty cell)\n";
  uint64_t most = 1;
  for (const auto& [bin, n] : histogram) most = std::max(most, n);
  for (const auto& [bin, n] : histogram) {
    const uint64_t lo = bin == 0 ? 0 : uint64_t{1} << (bin - 1), hi = (uint64_t{1} << bin) - 1;
    out += fmt::format("  {:>6}..{:<6} {:>9}  {}\n", lo, hi, n, std::string(1 + 50 * n / most, '#'));
  }
  std::fputs(out.c_str(), stdout);
  return 0;
}

int verify(const std::string& path, bool quiet) {
  frontier::store::PosixFileSystem fs;
  auto reader = frontier::store::StoreReader::open(fs, path);
  if (!reader) return fail(reader.status());
  // Every checksum first (header, footer, directory, sections, pages), then the structure.
  if (frontier::Status s = (*reader)->verify(); !s) return fail(s);
  const size_t pages = (*reader)->page_count();
  auto opened = StoreModel::open(std::move(*reader));
  if (!opened) return fail(opened.status());
  const StoreModel& model = **opened;
  frontier::Scene cell;
  std::optional<frontier::KdTree> tree;
  uint64_t references = 0, decoded_pages = 0, trees = 0, proxy_trees = 0;
  std::vector<uint8_t> page_used(pages, 0);
  frontier::Progress progress("verify", "cells", model.cells().size(), quiet);
  for (uint32_t c = 0; c < model.cells().size(); ++c) {
    const StoreCell& rec = model.cells()[c];
    if (rec.page != StoreCell::kNoPage) {
      if (page_used[rec.page]) {
        return fail(frontier::Status::corruption(fmt::format("{}: page {} belongs to two cells", path, rec.page)));
      }
      page_used[rec.page] = 1;
      // An in-cell tree is decoded and assembled over its cell (structure, references, depth).
      const frontier::KdBuildOptions tree_options = model.info().cell_tree.value_or(frontier::KdBuildOptions{});
      if (frontier::Status s = model.read_cell(c, cell, tree_options, tree); !s) return fail(s);
      trees += tree ? 1 : 0;
      if (cell.size() != rec.references) {
        return fail(frontier::Status::corruption(fmt::format("{}: cell {} page {}: {} primitives, its record says {}",
                                                             path, c, rec.page, cell.size(), rec.references)));
      }
      references += cell.size();
      ++decoded_pages;
    }
    progress.advance(1);
  }
  progress.finish();
  // The collision grid's bricks: each page read, checked and decoded, none shared with a cell.
  uint64_t bricks = 0;
  if (model.info().walkable) {
    auto grid = frontier::open_collision_grid(model.reader());
    if (!grid) return fail(grid.status());
    for (uint64_t p : (*grid)->brick_pages()) {
      if (p >= pages || page_used[p]) {
        return fail(frontier::Status::corruption(fmt::format("{}: sdf brick page {} is missing or belongs to a cell", path, p)));
      }
      page_used[p] = 1;
    }
    if (frontier::Status s = (*grid)->check_all_bricks(); !s) return fail(s);
    bricks = (*grid)->counters().bricks;
  }
  // Proxy pages: each decoded and checked against its record, none shared.
  uint64_t proxies = 0;
  for (uint32_t node = 0; node < model.nodes().size(); ++node) {
    const frontier::StoreProxy* proxy = model.proxy(node);
    if (proxy == nullptr) continue;
    if (page_used[proxy->page]) {
      return fail(frontier::Status::corruption(
          fmt::format("{}: proxy of node {} page {} also belongs to a cell or brick", path, node, proxy->page)));
    }
    page_used[proxy->page] = 1;
    // A proxy's tree, as a cell's, is decoded and assembled over the node's region.
    frontier::KdBuildOptions proxy_options = model.info().cell_tree.value_or(frontier::KdBuildOptions{});
    proxy_options.max_cell_prims = model.info().proxy_tree_cell_prims;
    if (frontier::Status s = model.read_proxy(node, cell, proxy_options, tree); !s) return fail(s);
    proxy_trees += tree ? 1 : 0;
    ++proxies;
  }
  for (size_t p = 0; p < pages; ++p) {
    if (!page_used[p]) return fail(frontier::Status::corruption(fmt::format("{}: page {} belongs to nothing", path, p)));
  }
  if (!quiet) {
    // StoreModel::open has parsed and checked the portals section, if any.
    const std::string portals =
        model.portals() != nullptr
            ? fmt::format(", {} rooms and {} portals", model.portals()->room_count(), model.portals()->portal_count())
            : "";
    const std::string grid = (bricks > 0 ? fmt::format(", {} collision bricks", bricks) : "") +
                             (proxies > 0 ? fmt::format(", {} proxies", proxies) : "") +
                             (trees > 0 ? fmt::format(", {} in-cell trees", trees) : "") +
                             (proxy_trees > 0 ? fmt::format(", {} proxy trees", proxy_trees) : "");
    std::printf("%s: ok: %zu pages checksummed, %llu decoded, %llu references in %zu cells, tree depth %u%s%s\n",
                path.c_str(), pages, static_cast<unsigned long long>(decoded_pages + bricks + proxies),
                static_cast<unsigned long long>(references), model.cells().size(), model.depth(), portals.c_str(),
                grid.c_str());
  }
  return 0;
}

int export_proxy(const std::string& path, uint32_t node, const std::string& out) {
  frontier::store::PosixFileSystem fs;
  auto reader = frontier::store::StoreReader::open(fs, path);
  if (!reader) return fail(reader.status());
  auto opened = StoreModel::open(std::move(*reader));
  if (!opened) return fail(opened.status());
  const StoreModel& model = **opened;
  if (node >= model.nodes().size()) {
    std::fprintf(stderr, "frontier-store: %s: node %u: the top tree has %zu nodes\n", path.c_str(), node,
                 model.nodes().size());
    return 2;
  }
  const frontier::StoreProxy* proxy = model.proxy(node);
  if (proxy == nullptr) {
    std::fprintf(stderr, "frontier-store: %s: node %u has no proxy page\n", path.c_str(), node);
    return 2;
  }
  frontier::Scene scene;
  if (frontier::Status s = model.read_proxy(node, scene); !s) return fail(s);
  frontier::MeshPiece piece;
  for (const frontier::Triangle& t : scene.triangles) {
    for (const frontier::Vec3& v : {t.v0, t.v1, t.v2}) {
      piece.indices.push_back(static_cast<uint32_t>(piece.vertex_count()));
      piece.positions.insert(piece.positions.end(),
                             {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)});
    }
  }
  auto writer = frontier::PlyWriter::create(out, {}, piece.vertex_count(), piece.triangle_count(),
                                            {fmt::format("proxy of node {} of {}, error bound {}", node, path, proxy->error)});
  if (!writer) return fail(writer.status());
  if (frontier::Status s = (*writer)->add(piece); !s) return fail(s);
  if (frontier::Status s = (*writer)->finish(); !s) return fail(s);
  std::printf("node %u: %zu triangles, error bound %.6g, %llu triangles below it -> %s\n", node,
              scene.triangles.size(), proxy->error, static_cast<unsigned long long>(proxy->subtree_triangles),
              out.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"frontier-store: inspect and check frontier store files (layout: store/FORMAT.md).\n"
               "Exit status: 0 ok; 1 a bad store (missing, unreadable or corrupt: the message names the file\n"
               "and the page or byte); 2 bad options.",
               "frontier-store"};
  app.require_subcommand(1);
  std::string path;
  bool quiet = false;
  auto* info_cmd = app.add_subcommand(
      "info", "primitives, cells, depth, bytes per triangle, codec, in-cell trees, lattice, collision grid, rooms and portals, proxies "
      "(pages, bytes, error by depth), sections, cell size histogram");
  info_cmd->add_option("file", path, "store file")->required();
  uint64_t measure_triangles = kMeasuredSubtreeTriangles;
  info_cmd->add_option("--measure-triangles", measure_triangles,
                       "measure the proxies of up to 4 nodes per depth whose subtrees have at most this many triangles "
                       "against their original cells (0: none)")
      ->capture_default_str();
  auto* verify_cmd = app.add_subcommand(
      "verify", "check every checksum and structural invariant and decode every page (cells with their in-cell trees, "
      "collision bricks and proxies with their trees); exit 1 "
      "naming the first bad one");
  verify_cmd->add_option("file", path, "store file")->required();
  verify_cmd->add_flag("-q,--quiet", quiet, "print nothing when the store is good");
  uint32_t node = 0;
  std::string out;
  auto* proxy_cmd = app.add_subcommand("proxy", "write one node's proxy (the triangles standing in for its subtree) as a PLY mesh");
  proxy_cmd->add_option("file", path, "store file")->required();
  proxy_cmd->add_option("node", node, "top-tree node (0 = the root; preorder, as in the store's tree section)")->required();
  proxy_cmd->add_option("-o,--output", out, "PLY file to write")->required();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints the help, or the error and a hint
    return code == 0 ? 0 : 2;  // bad options: 2, as README says (CLI11's own codes are 100+)
  }
  if (info_cmd->parsed()) return info(path, measure_triangles);
  if (proxy_cmd->parsed()) return export_proxy(path, node, out);
  return verify(path, quiet);
}
