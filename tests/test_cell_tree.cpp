// In-cell trees (src/codec/cell_tree.h): a store's cell pages carry the k-d tree frontier-view
// builds when it pages a cell in. Loading it must give exactly the tree KdTree::build gives on
// the decoded cell — node for node, cell for cell, reference for reference — for terrain,
// building and curved-primitive cells under every codec; stores without trees, and viewers
// with other refine options, build as before and render the same ids; damaged trees are
// Corruption naming the page, never a crash.
#include "preprocess/build.h"
#include "src/codec/cell_tree.h"
#include "src/paging/store_model.h"
#include "src/walk/walkthrough.h"
#include "src/io/camera_path.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <random>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_cell_tree"); }

KdBuildOptions viewer_refine() { return page_refine_options(WalkOptions{}); }

// A frontier-gen model (cached within the run).
std::string generated(const std::string& kind, int triangles) {
  const std::string out = (scratch() / (kind + std::to_string(triangles) + ".ply")).string();
  if (fs::exists(out)) return out;
  const auto r = run_binary(proc::gen_binary(), {kind, "--triangles", std::to_string(triangles), "-o", out, "--quiet"},
                            scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return out;
}

std::string store_of(const std::string& input, const std::string& name, CellCodec codec, bool trees) {
  const std::string out = (scratch() / (name + ".frontier")).string();
  if (fs::exists(out)) return out;
  BuildOptions o;
  o.inputs = {input};
  o.output = out;
  o.codec = codec;
  o.quiet = true;
  o.threads = 2;
  o.cell_prims = 256;  // many cells of a small model
  o.cell_trees = trees;
  auto report = build_store(o);
  EXPECT_TRUE(report.is_ok()) << report.status().to_string();
  if (report.is_ok()) {
    EXPECT_EQ(report->cell_tree_pages, trees ? report->pages : 0u);
  }
  return out;
}

// Every page of the store carries its tree, and it equals the viewer's build on the decoded cell.
void expect_stored_trees_equal_builds(const std::string& store) {
  auto model = StoreModel::open(store);
  ASSERT_TRUE(model.is_ok()) << model.status().to_string();
  const StoreModelInfo& info = (*model)->info();
  ASSERT_TRUE(info.cell_tree.has_value());
  EXPECT_TRUE(same_cell_build(*info.cell_tree, viewer_refine()));
  uint64_t pages = 0, nodes = 0, references = 0;
  for (uint32_t c = 0; c < (*model)->cells().size(); ++c) {
    const StoreCell& rec = (*model)->cells()[c];
    if (rec.page == StoreCell::kNoPage) continue;
    Scene cell;
    std::optional<KdTree> stored;
    const Status s = (*model)->read_cell(c, cell, viewer_refine(), stored);
    ASSERT_TRUE(s.is_ok()) << s.to_string();
    ASSERT_TRUE(stored.has_value()) << "cell " << c;
    KdBuildOptions o = viewer_refine();
    o.root = rec.bounds;
    const KdTree built = KdTree::build(cell, o);
    ASSERT_TRUE(same_tree(*stored, built)) << "cell " << c;
    ++pages;
    nodes += stored->nodes().size();
    references += stored->reference_count();
  }
  EXPECT_EQ(pages, info.cell_tree_pages);
  EXPECT_GT(info.cell_tree_bytes, 0u);
  EXPECT_GT(nodes, pages);  // cells were refined, not single leaves
  EXPECT_GE(references, info.references);
}

TEST(StoreCellTree, StoredTreesEqualTheViewersBuildForEveryCodec) {
  const std::vector<std::pair<std::string, std::string>> models = {
      {"terrain", generated("terrain", 20000)},
      {"building", generated("building", 20000)},
      {"tree", testing::spd("tree")},  // spheres and cones
      {"rings", testing::spd("rings")},
  };
  for (const auto& [name, input] : models) {
    for (const CellCodec codec : {CellCodec::Raw, CellCodec::Draco, CellCodec::Meshopt}) {
      const std::string label = name + "_" + std::string(cell_codec_name(codec));
      SCOPED_TRACE(label);
      expect_stored_trees_equal_builds(store_of(input, label, codec, true));
    }
  }
}

// Hard cases straight through encode/decode: flat and axis-parallel input far from the origin,
// degenerate and duplicate (coplanar, overlapping) triangles, a tight cluster in a large region
// (chains of empty-space cuts), and splits that are no candidate of the stored bins (stored as
// doubles).
TEST(StoreCellTree, HardCasesAssembleExactly) {
  std::mt19937_64 rng(25);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<std::pair<std::string, Scene>> cases;
  {
    Scene flat;  // a grid of triangles on z = 1e6, far from the origin
    const Vec3 o(1e6, -2e6, 1e6);
    for (int i = 0; i < 30; ++i) {
      for (int j = 0; j < 30; ++j) {
        const Vec3 a = o + Vec3(i * 0.01, j * 0.01, 0.0);
        flat.add_triangle({a, a + Vec3(0.01, 0, 0), a + Vec3(0, 0.01, 0)}, static_cast<uint32_t>(i * 30 + j), 0);
      }
    }
    cases.emplace_back("flat far", flat);
  }
  {
    Scene degenerate;  // points, segments, and 40 copies of one triangle among random ones
    for (int i = 0; i < 200; ++i) {
      const Vec3 a(unit(rng), unit(rng), unit(rng));
      const Vec3 b = a + Vec3(0.05 * unit(rng), 0.05 * unit(rng), 0.0);
      if (i % 3 == 0) degenerate.add_triangle({a, a, a}, i, 0);
      else if (i % 3 == 1) degenerate.add_triangle({a, b, b}, i, 0);
      else degenerate.add_triangle({a, b, a + Vec3(0, 0, 0.05)}, i, 0);
    }
    for (int i = 0; i < 40; ++i) degenerate.add_triangle({Vec3(0.5), Vec3(0.6, 0.5, 0.5), Vec3(0.5, 0.6, 0.5)}, 500 + i, 0);
    cases.emplace_back("degenerate", degenerate);
  }
  {
    Scene cluster;  // a tight cluster of spheres and boxes in a corner of a large region
    for (int i = 0; i < 300; ++i) {
      const Vec3 c = Vec3(100.0) + 1e-3 * Vec3(unit(rng), unit(rng), unit(rng));
      if (i % 2 == 0) {
        cluster.add_sphere({c, 1e-4}, i, 0);
      } else {
        Box box;
        box.bounds = Aabb(c, c + Vec3(1e-4, 2e-4, 0.0));  // flat boxes
        cluster.add_box(box, i, 0);
      }
    }
    cases.emplace_back("cluster", cluster);
  }
  for (const auto& [name, scene] : cases) {
    SCOPED_TRACE(name);
    Aabb region = KdTree::root_bounds(scene.bounds());
    if (name == "cluster") region = Aabb(Vec3(0.0), Vec3(200.0));
    for (const int built_bins : {32, 7}) {
      KdBuildOptions o = viewer_refine();
      o.bins = built_bins;
      o.root = region;
      const KdTree built = KdTree::build(scene, o);
      // Stored with the viewer's 32 bins: a tree built with 7 has splits that are no candidate.
      auto bytes = encode_cell_tree(scene, built, viewer_refine());
      ASSERT_TRUE(bytes.is_ok()) << bytes.status().to_string();
      auto loaded = decode_cell_tree(*bytes, scene, region, viewer_refine());
      ASSERT_TRUE(loaded.is_ok()) << loaded.status().to_string();
      EXPECT_TRUE(same_tree(*loaded, built));
      EXPECT_GT(built.nodes().size(), 1u);
      if (built_bins == 32) {
        EXPECT_LT(bytes->size(), 64 + 2 * built.nodes().size());  // a few bits a node, no doubles
      }
    }
  }
}

// A tree that is not the one build() makes from the cell is refused at encoding time.
TEST(StoreCellTree, EncodingRefusesATreeOfOtherPrimitives) {
  Scene a, b;
  for (int i = 0; i < 100; ++i) {
    const Vec3 p(i * 0.1, (i % 7) * 0.1, (i % 3) * 0.1);
    a.add_triangle({p, p + Vec3(0.05, 0, 0), p + Vec3(0, 0.05, 0.05)}, i, 0);
    b.add_triangle({p + Vec3(0.01), p + Vec3(0.2, 0, 0), p + Vec3(0, 0.05, 0.05)}, i, 0);
  }
  KdBuildOptions o = viewer_refine();
  Aabb both = a.bounds();
  both.extend(b.bounds());
  o.root = KdTree::root_bounds(both);
  const KdTree tree = KdTree::build(a, o);
  EXPECT_TRUE(encode_cell_tree(a, tree, viewer_refine()).is_ok());
  const auto wrong = encode_cell_tree(b, tree, viewer_refine());
  ASSERT_FALSE(wrong.is_ok());
  EXPECT_EQ(wrong.status().code(), Status::Code::InvalidArgument);
}

// Stores without trees (built before them, or with --no-cell-trees) and viewers whose refine
// options differ from the store's build the trees at page-in: the same frames, id for id.
TEST(StoreCellTree, StoresWithoutTreesAndOtherOptionsRenderTheSameIds) {
  const std::string model = generated("building", 20000);
  const std::string with = store_of(model, "building_draco", CellCodec::Draco, true);
  const std::string without = store_of(model, "building_draco_notrees", CellCodec::Draco, false);
  auto plain = StoreModel::open(without);
  ASSERT_TRUE(plain.is_ok());
  EXPECT_FALSE((*plain)->info().cell_tree.has_value());
  for (uint32_t c = 0; c < (*plain)->cells().size(); ++c) {
    Scene cell;
    std::optional<KdTree> tree;
    ASSERT_TRUE((*plain)->read_cell(c, cell, viewer_refine(), tree).is_ok());
    EXPECT_FALSE(tree.has_value());
  }
  auto treed = StoreModel::open(with);
  ASSERT_TRUE(treed.is_ok());
  // Model section version 2 only with trees: readers that predate them refuse those at open.
  const auto version = [](const StoreModel& m) {
    auto bytes = m.reader().read_section(kModelSection);
    return bytes.is_ok() ? nlohmann::json::parse(bytes->begin(), bytes->end()).at("version").get<int>() : 0;
  };
  EXPECT_EQ(version(**plain), 1);
  EXPECT_EQ(version(**treed), 2);
  KdBuildOptions other = viewer_refine();
  other.max_cell_prims = 8;
  for (uint32_t c = 0; c < (*treed)->cells().size(); ++c) {
    Scene cell;
    std::optional<KdTree> tree;
    ASSERT_TRUE((*treed)->read_cell(c, cell, other, tree).is_ok());
    EXPECT_FALSE(tree.has_value()) << "options differ: no stored tree";
  }

  const fs::path path = scratch() / "walk.cam";
  auto r = run_binary(proc::gen_binary(),
                      {"path", "--model", model, "--kind", "orbit", "--frames", "4", "-o", path.string()}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto cams = read_camera_path(path.string());
  ASSERT_TRUE(cams.is_ok());
  struct Variant {
    std::string store;
    uint32_t cell_prims;
  };
  const std::vector<Variant> variants = {{with, 16}, {without, 16}, {with, 8}, {without, 8}};
  std::vector<std::vector<std::vector<uint32_t>>> ids(variants.size());
  for (size_t v = 0; v < variants.size(); ++v) {
    WalkOptions o;
    o.width = o.height = 64;
    o.threads = 2;
    o.sync_paging = true;
    o.cell_prims = variants[v].cell_prims;
    o.cell_build_from_store = false;  // the options above, also for the store with trees
    auto walk = Walkthrough::open(variants[v].store, o);
    ASSERT_TRUE(walk.is_ok()) << walk.status().to_string();
    uint64_t paged = 0;
    for (const Camera& cam : *cams) {
      const FrameReport f = (*walk)->frame(cam);
      EXPECT_TRUE(f.complete);
      EXPECT_EQ(f.page_errors, 0u);
      paged += f.cells_paged_in;
      ids[v].push_back((*walk)->ids());
    }
    EXPECT_GT(paged, 0u);
  }
  EXPECT_EQ(ids[0], ids[1]) << "stored trees render what rebuilt trees render";
  EXPECT_EQ(ids[2], ids[3]) << "other options: both stores rebuild";
}

// A walk refines a store's pages with the options the store records, also when the viewer's
// defaults have changed since it was built (its trees are then used as stored, not rebuilt at
// every page-in); options given for the walk (frontier-view --cell-prims) override them.
TEST(StoreCellTree, WalksRefineWithTheOptionsTheStoreRecords) {
  const std::string with = store_of(generated("building", 20000), "options_with_trees", CellCodec::Draco, true);
  auto model = StoreModel::open(with);
  ASSERT_TRUE(model.is_ok()) << model.status().to_string();
  ASSERT_TRUE((*model)->info().cell_tree.has_value());
  const KdBuildOptions stored = *(*model)->info().cell_tree;
  WalkOptions o;
  o.width = o.height = 32;
  o.threads = 2;
  o.cell_traversal_cost = stored.traversal_cost / 2.0;  // a viewer whose defaults differ from the builder's
  auto walk = Walkthrough::open(with, o);
  ASSERT_TRUE(walk.is_ok()) << walk.status().to_string();
  EXPECT_TRUE(same_cell_build((*walk)->world().cell_build(), stored));
  EXPECT_EQ((*walk)->world().cell_build().traversal_cost, stored.traversal_cost);
  o.cell_build_from_store = false;
  auto own = Walkthrough::open(with, o);
  ASSERT_TRUE(own.is_ok()) << own.status().to_string();
  EXPECT_FALSE(same_cell_build((*own)->world().cell_build(), stored));
  EXPECT_EQ((*own)->world().cell_build().traversal_cost, o.cell_traversal_cost);
}

// Damage to a page's tree (past its checksum: the page cache hands decode_page the bytes) is
// Corruption naming the cell and page, or a tree that still assembles; never a crash.
TEST(StoreCellTree, DamagedTreesAreCorruptionNamingThePage) {
  const std::string store = store_of(generated("terrain", 20000), "terrain_meshopt", CellCodec::Meshopt, true);
  auto model = StoreModel::open(store);
  ASSERT_TRUE(model.is_ok());
  const StoreModel& m = **model;
  uint32_t tried = 0, corrupt = 0;
  for (uint32_t c = 0; c < m.cells().size() && tried < 3; ++c) {
    const StoreCell& rec = m.cells()[c];
    if (rec.page == StoreCell::kNoPage) continue;
    ++tried;
    auto page = m.reader().read_page(rec.page);
    ASSERT_TRUE(page.is_ok());
    ASSERT_NE(page->codec & kCellTreeFlag, 0);
    std::span<const uint8_t> tree, payload;
    ASSERT_TRUE(split_tree_page(page->payload, tree, payload).is_ok());
    const std::string names = "page " + std::to_string(rec.page);
    const auto check = [&](const std::vector<uint8_t>& damaged, uint8_t codec) {
      Scene cell;
      std::optional<KdTree> loaded;
      const Status s = m.decode_page(c, codec, damaged, cell, viewer_refine(), loaded);
      if (s.is_ok()) {
        EXPECT_TRUE(loaded.has_value());
        return;
      }
      ++corrupt;
      EXPECT_EQ(s.code(), Status::Code::Corruption) << s.to_string();
      EXPECT_NE(s.message().find(names), std::string::npos) << s.to_string();
      EXPECT_FALSE(loaded.has_value());
      EXPECT_EQ(cell.size(), 0u);
    };
    const size_t header = page->payload.size() - payload.size() - tree.size();  // the tree's length varint
    std::mt19937_64 rng(c);
    for (size_t at = 0; at < header + tree.size(); ++at) {
      for (const uint8_t flip : {uint8_t{0x01}, uint8_t{0x80}, static_cast<uint8_t>(rng() | 1)}) {
        std::vector<uint8_t> damaged = page->payload;
        damaged[at] ^= flip;
        check(damaged, page->codec);
      }
    }
    // Cut short, a tree that takes the whole page, a version byte nobody wrote, and a page that
    // claims a tree it does not have.
    std::vector<uint8_t> whole(page->payload.begin(), page->payload.begin() + static_cast<long>(header + tree.size() / 2));
    check(whole, page->codec);
    std::vector<uint8_t> version = page->payload;
    version[header] ^= 0x40;
    check(version, page->codec);
    check(std::vector<uint8_t>(payload.begin(), payload.end()), page->codec);
  }
  EXPECT_EQ(tried, 3u);
  EXPECT_GT(corrupt, 3u * 3u);
}

// Proxy pages carry their trees too: loading one gives exactly the viewer's build of the proxy
// over its node's region (proxy_tree_options), above and inside the parts of a store split on
// disk, under every codec; a store without trees has none, and a damaged proxy tree is
// Corruption naming the node and page. (Six builds: its own suite name keeps it out of the
// sanitized subset; the walkthrough tests there load proxy trees.)
TEST(ProxyTrees, ProxyPagesCarryTheViewersProxyTrees) {
  const std::string input = generated("terrain", 20000);
  for (const CellCodec codec : {CellCodec::Raw, CellCodec::Draco, CellCodec::Meshopt}) {
    for (const bool trees : {true, false}) {
      if (!trees && codec != CellCodec::Draco) continue;
      const std::string name = std::string("proxytrees_") + std::string(cell_codec_name(codec)) + (trees ? "" : "_none");
      SCOPED_TRACE(name);
      BuildOptions o;
      o.inputs = {input};
      o.output = (scratch() / (name + ".frontier")).string();
      o.codec = codec;
      o.quiet = true;
      o.threads = 2;
      o.cell_prims = 64;
      o.proxy_triangles = 256;
      o.part_primitives = 4000;  // several parts: nodes above them get proxies as well
      o.cell_trees = trees;
      auto report = build_store(o);
      ASSERT_TRUE(report.is_ok()) << report.status().to_string();
      ASSERT_GT(report->parts, 2u);
      auto model = StoreModel::open(o.output);
      ASSERT_TRUE(model.is_ok()) << model.status().to_string();
      const StoreModel& m = **model;
      const StoreModelInfo& info = m.info();
      EXPECT_EQ(report->proxy_tree_pages, trees ? report->proxy_pages : 0u);
      EXPECT_EQ(info.proxy_tree_pages, report->proxy_tree_pages);
      EXPECT_EQ(info.proxy_tree_cell_prims, trees ? kProxyCellPrims : 0u);
      const KdBuildOptions proxy_options = proxy_tree_options(viewer_refine());
      uint64_t loaded = 0, above_parts = 0, inner_nodes = 0;
      for (uint32_t n = 0; n < m.nodes().size(); ++n) {
        if (m.proxy(n) == nullptr) continue;
        Scene proxy;
        std::optional<KdTree> stored;
        const Status s = m.read_proxy(n, proxy, proxy_options, stored);
        ASSERT_TRUE(s.is_ok()) << s.to_string();
        ASSERT_EQ(stored.has_value(), trees) << "node " << n;
        if (!stored) continue;
        KdBuildOptions built_options = proxy_options;
        built_options.root = m.node_region(n);
        ASSERT_TRUE(same_tree(*stored, KdTree::build(proxy, built_options))) << "node " << n;
        ++loaded;
        above_parts += m.proxy(n)->subtree_triangles > o.part_primitives ? 1 : 0;
        inner_nodes += stored->nodes().size() > 1 ? 1 : 0;
        // A tree built with other options is not loaded (the viewer builds its own).
        KdBuildOptions other = proxy_options;
        other.max_cell_prims = proxy_options.max_cell_prims + 1;
        ASSERT_TRUE(m.read_proxy(n, proxy, other, stored).is_ok());
        EXPECT_FALSE(stored.has_value());
      }
      if (!trees) {
        EXPECT_EQ(loaded, 0u);
        continue;
      }
      EXPECT_EQ(loaded, report->proxy_pages);
      EXPECT_GT(above_parts, 0u);
      EXPECT_GT(inner_nodes, 0u);  // proxies were refined, not single leaves
      // Damage: flipped bytes in the tree or its length are Corruption naming node and page.
      const uint32_t root_page = static_cast<uint32_t>(m.proxy(0)->page);
      auto page = m.reader().read_page(root_page);
      ASSERT_TRUE(page.is_ok());
      ASSERT_NE(page->codec & kCellTreeFlag, 0);
      std::span<const uint8_t> tree, payload;
      ASSERT_TRUE(split_tree_page(page->payload, tree, payload).is_ok());
      const size_t span = page->payload.size() - payload.size();
      uint32_t corrupt = 0;
      std::mt19937_64 rng(7);
      for (size_t at = 0; at < span; ++at) {
        std::vector<uint8_t> damaged = page->payload;
        damaged[at] ^= static_cast<uint8_t>(rng() | 1);
        Scene proxy;
        std::optional<KdTree> t;
        const Status s = m.decode_proxy_page(0, page->codec, damaged, proxy, &proxy_options, t);
        if (s.is_ok()) {
          EXPECT_TRUE(t.has_value());
          continue;
        }
        ++corrupt;
        EXPECT_EQ(s.code(), Status::Code::Corruption) << s.to_string();
        EXPECT_NE(s.message().find("proxy of node 0 page " + std::to_string(root_page)), std::string::npos)
            << s.to_string();
        EXPECT_FALSE(t.has_value());
        EXPECT_EQ(proxy.size(), 0u);
      }
      EXPECT_GT(corrupt, 0u);
      // frontier-store verify loads every proxy tree; info names them.
      if (codec == CellCodec::Draco) {
        auto r = run_binary(FRONTIER_STORE_PATH, {"verify", o.output}, scratch());
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_NE(r.out.find(std::to_string(report->proxy_pages) + " proxy trees"), std::string::npos) << r.out;
        r = run_binary(FRONTIER_STORE_PATH, {"info", o.output}, scratch());
        ASSERT_EQ(r.exit_code, 0) << r.err;
        EXPECT_NE(r.out.find("proxy trees in " + std::to_string(report->proxy_pages)), std::string::npos) << r.out;
      }
    }
  }
}

// frontier-store info names the trees and their build options; verify assembles every tree.
TEST(StoreCellTree, StoreToolReportsAndVerifiesTrees) {
  const std::string store = store_of(generated("terrain", 20000), "terrain_draco", CellCodec::Draco, true);
  auto r = run_binary(FRONTIER_STORE_PATH, {"info", store}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("cell trees  in "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("max_cell_prims 16"), std::string::npos) << r.out;
  r = run_binary(FRONTIER_STORE_PATH, {"verify", store}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("in-cell trees"), std::string::npos) << r.out;
  const std::string plain = store_of(generated("terrain", 20000), "terrain_draco_notrees", CellCodec::Draco, false);
  r = run_binary(FRONTIER_STORE_PATH, {"info", plain}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("cell trees  none"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace frontier
