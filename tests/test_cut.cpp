// Level of detail, one cut per frame (issue 41; PagedWorld "Level of detail"): a store's proxies
// draw whole nodes of the top tree, chosen before the first ray. Exact modes never show a proxy
// (every brute-force test holds at pixel error 0); a huge pixel error draws a view from the
// root's proxy without reading a cell page; pegged frames never park a ray, never leave a hole
// where the exact frame has geometry, ask only for what lies below where their rays went, and
// stay within the budget; a camera that stops refines to the exact image; the report counts
// what the cut drew.
#include "src/io/camera_path.h"
#include "src/io/load_scene.h"
#include "src/walk/walkthrough.h"
#include "tests/engine_util.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>
#include <fstream>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_cut"); }

// A generated terrain (20 000 triangles), raw stores of it in cells of at most 64 triangles
// with proxies of 128 triangles and without, and a four-frame orbit around it.
struct Terrain {
  std::string model, path, proxies, plain;
};

std::string build(const std::string& model, const std::string& name, int proxy_triangles) {
  const std::string out = (scratch() / name).string();
  const auto r = run_binary(FRONTIER_BUILD_PATH,
                            {model, "-o", out, "--codec", "raw", "--cell-prims", "64", "--proxy-triangles",
                             std::to_string(proxy_triangles), "--threads", "2", "--quiet"},
                            scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return out;
}

const Terrain& terrain() {
  static const Terrain made = [] {
    Terrain t;
    t.model = (scratch() / "terrain.ply").string();
    auto r = run_binary(proc::gen_binary(), {"terrain", "--triangles", "20000", "-o", t.model, "--quiet"}, scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    t.path = (scratch() / "orbit.cam").string();
    r = run_binary(proc::gen_binary(), {"path", "--model", t.model, "--kind", "orbit", "--frames", "4", "-o", t.path},
                   scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    t.proxies = build(t.model, "proxies.frontier", 128);
    t.plain = build(t.model, "plain.frontier", 0);
    return t;
  }();
  return made;
}

std::vector<Camera> orbit() {
  auto cams = read_camera_path(terrain().path);
  EXPECT_TRUE(cams.is_ok()) << cams.status().to_string();
  return cams.is_ok() ? *cams : std::vector<Camera>{};
}

WalkOptions options(double pixel_error) {
  WalkOptions o;
  o.width = 64;
  o.height = 48;
  o.threads = 2;
  o.cache_bytes = 64u << 20;
  o.pixel_error = pixel_error;
  return o;
}

size_t geometry_pixels(const std::vector<uint32_t>& ids) {
  return size_t(std::count_if(ids.begin(), ids.end(), [](uint32_t id) { return id != kNoPrim; }));
}

// Pixels where `reference` has geometry and `ids` has none, farther than `rim` pixels (in x and
// y) from every background pixel of `reference`: a stand-in's silhouette may move by its
// projected error, but no hole may open inside the surface.
size_t holes(const std::vector<uint32_t>& reference, const std::vector<uint32_t>& ids, int width, int rim) {
  const int height = int(reference.size()) / width;
  size_t n = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const size_t i = size_t(y * width + x);
      if (reference[i] == kNoPrim || ids[i] != kNoPrim) continue;
      bool near_rim = false;
      for (int dy = -rim; dy <= rim && !near_rim; ++dy) {
        for (int dx = -rim; dx <= rim && !near_rim; ++dx) {
          const int xx = x + dx, yy = y + dy;
          near_rim = xx < 0 || yy < 0 || xx >= width || yy >= height || reference[size_t(yy * width + xx)] == kNoPrim;
        }
      }
      n += near_rim ? 0 : 1;
    }
  }
  return n;
}

// Pixel error 0, paging as frames need it or synchronously: the exact image, equal to brute
// force over the input and to the store without proxies; nothing stood in.
TEST(WalkthroughCut, ExactModesShowNoProxyAndEqualBruteForce) {
  Scene scene;
  ASSERT_TRUE(load_scene(terrain().model, scene).is_ok());
  for (const bool sync : {false, true}) {
    SCOPED_TRACE(sync);
    WalkOptions o = options(0.0);
    o.sync_paging = sync;
    auto with = Walkthrough::open(terrain().proxies, o);
    auto without = Walkthrough::open(terrain().plain, o);
    ASSERT_TRUE(with.is_ok() && without.is_ok());
    ASSERT_TRUE((*with)->world().has_proxies());
    for (const Camera& cam : orbit()) {
      const FrameReport r = (*with)->frame(cam);
      SCOPED_TRACE(r.to_json().dump());
      EXPECT_TRUE(r.complete);
      EXPECT_EQ(r.proxy_pixels, 0u);
      EXPECT_EQ(r.proxy_nodes, 0u);
      EXPECT_EQ(r.cut_nodes, 0u);
      EXPECT_EQ(r.cut_error, 0.0);
      std::vector<uint32_t> reference;
      std::vector<uint8_t> tie;
      testing::brute_reference(scene, (*with)->view(), reference, tie);
      const auto cmp = testing::compare_ids(reference, tie, (*with)->ids(), (*with)->view().width);
      EXPECT_EQ(cmp.mismatches, 0u) << cmp.first_mismatch;
      (*without)->frame(cam);
      EXPECT_EQ((*with)->ids(), (*without)->ids());
    }
  }
}

// A pixel error no proxy exceeds: the root's proxy, read when the store opens, draws every
// cell; no cell page is read, every sample is on a proxy, and the frame is complete.
TEST(WalkthroughCut, AHugePixelErrorDrawsTheRootProxyAndReadsNoCellPage) {
  auto walk = Walkthrough::open(terrain().proxies, options(1e12));
  ASSERT_TRUE(walk.is_ok());
  for (const Camera& cam : orbit()) {
    const FrameReport r = (*walk)->frame(cam);
    SCOPED_TRACE(r.to_json().dump());
    EXPECT_TRUE(r.complete);
    EXPECT_EQ(r.cells_paged_in, 0u);
    EXPECT_EQ(r.resident_cells, 0u);
    EXPECT_EQ(r.proxy_nodes, 1u);  // the root's
    EXPECT_EQ(r.cut_nodes, 1u);
    // The root's bound projected: some pixels, far below the pixel error.
    EXPECT_GT(r.cut_error, 0.0);
    EXPECT_LT(r.cut_error, 1e12);
    EXPECT_NEAR(r.cut_error, r.to_json()["cut_error"].get<double>(), 1e-9 * r.cut_error);
    const size_t geometry = geometry_pixels((*walk)->ids());
    EXPECT_GT(geometry, 0u);
    EXPECT_EQ(r.proxy_pixels, geometry);
    EXPECT_LE(r.resident_bytes, r.cache_budget);
  }
}

// A pixel error some inner nodes' proxies meet: a frame run to completion reads a cell's page
// only where no ancestor's proxy is fine enough (its bound projects to T pixels or more at the
// point of its region nearest the eye) — a qualifying proxy is read instead, whether or not it
// was in memory when the rays reached its cells — and fewer pages than the exact frame.
TEST(WalkthroughCut, PagesAreReadOnlyWhereNoAncestorsProxyIsFineEnough) {
  auto exact = Walkthrough::open(terrain().proxies, options(0.0));
  ASSERT_TRUE(exact.is_ok());
  const StoreModel& model = (*exact)->model();
  const auto& nodes = model.nodes();
  std::vector<int32_t> parent(nodes.size(), -1);
  std::vector<uint32_t> leaf_of(model.cells().size(), 0);
  for (uint32_t n = 0; n < nodes.size(); ++n) {
    if (nodes[n].is_leaf()) {
      leaf_of[nodes[n].child] = n;
    } else {
      parent[n + 1] = parent[nodes[n].child] = int32_t(n);
    }
  }
  const Camera cam = orbit().front();
  const View view(cam, 64, 48);
  const auto pixels = [&](uint32_t n) {
    const double d = distance_to_box(view.eye, model.node_region(n));
    return model.proxies()[n].error * 48.0 / (2.0 * view.half_h * d);
  };
  // A pixel error the root's proxy does not meet (a quarter of what its bound spans) but some
  // inner nodes' proxies do.
  const double T = pixels(0) / 4.0;
  auto walk = Walkthrough::open(terrain().proxies, options(T));
  ASSERT_TRUE(walk.is_ok());
  const FrameReport r = (*walk)->frame(cam);
  const FrameReport e = (*exact)->frame(cam);
  SCOPED_TRACE(r.to_json().dump());
  EXPECT_TRUE(r.complete);
  EXPECT_GT(r.proxy_nodes, 1u) << "no inner proxy drew: T checks nothing here";
  size_t resident = 0;
  for (uint32_t c = 0; c < model.cells().size(); ++c) {
    if (!(*walk)->world().resident(c)) continue;
    ++resident;
    for (int32_t n = parent[leaf_of[c]]; n >= 0; n = parent[size_t(n)]) {
      if (model.proxy(uint32_t(n)) == nullptr) continue;
      EXPECT_GE(pixels(uint32_t(n)), T) << "cell " << c << " was read though node " << n << "'s proxy is fine enough";
    }
  }
  EXPECT_LT(resident, e.resident_cells);
  EXPECT_GT(e.resident_cells, 0u);
}

// A camera that stops after a frame drawn by proxies refines to the exact image: the next frame
// of the same camera renders at pixel error 0, equal to brute force, with no proxy pixel left.
TEST(WalkthroughCut, AStillCameraRefinesToTheExactImage) {
  Scene scene;
  ASSERT_TRUE(load_scene(terrain().model, scene).is_ok());
  auto walk = Walkthrough::open(terrain().proxies, options(1e12));
  ASSERT_TRUE(walk.is_ok());
  const Camera cam = orbit().at(1);
  const FrameReport coarse = (*walk)->frame(cam);
  ASSERT_GT(coarse.proxy_pixels, 0u);
  const FrameReport fine = (*walk)->frame(cam);
  SCOPED_TRACE(fine.to_json().dump());
  EXPECT_FALSE(fine.continued);
  EXPECT_EQ(fine.pixel_error, 0.0);
  EXPECT_TRUE(fine.complete);
  EXPECT_EQ(fine.proxy_pixels, 0u);
  EXPECT_GT(fine.cells_paged_in, 0u);
  std::vector<uint32_t> reference;
  std::vector<uint8_t> tie;
  testing::brute_reference(scene, (*walk)->view(), reference, tie);
  const auto cmp = testing::compare_ids(reference, tie, (*walk)->ids(), (*walk)->view().width);
  EXPECT_EQ(cmp.mismatches, 0u) << cmp.first_mismatch;
  // Still again: nothing left to refine, the image stays.
  const FrameReport again = (*walk)->frame(cam);
  EXPECT_TRUE(again.continued);
}

// A rope may lead to a top node deep inside a linked node's region (the neighbour across a face
// is the deepest node covering it, below the link): the ray must still meet the link's proxy
// there, not the missing cell under it. Every rope of every cell a ray can reach arrives where a
// descent from the root arrives. (Before: a sample-budget frame reached the missing cell through
// a rope, parked, resumed through the proxy from the eye, and looped there forever.)
TEST(WalkthroughCut, RopesIntoALinkedRegionArriveWhereTheRootDescentArrives) {
  WalkOptions o = options(1.0);
  o.budget.samples = uint64_t(1) << 30;  // budgeted (a pegged cut), ends when complete
  auto walk = Walkthrough::open(terrain().proxies, o);
  ASSERT_TRUE(walk.is_ok());
  size_t linked = 0, checked = 0;
  for (const Camera& cam : orbit()) {
    const FrameReport r = (*walk)->frame(cam);
    SCOPED_TRACE(r.to_json().dump());
    const KdTree& tree = (*walk)->world().tree();
    linked += (*walk)->world().linked_nodes().size();
    // The cells a ray can be in: those reached from the root (through links), and every top
    // cell (a top cell under a linked node is not reached, but its neighbours' ropes and the
    // cells the caster holds from before the link still lead into the region).
    std::vector<int32_t> cells;
    for (size_t c = 0; c < tree.cells().size(); ++c) {
      if ((*walk)->world().store_cell(int32_t(c)) == c) cells.push_back(int32_t(c));
    }
    std::vector<int32_t> stack = {0};
    while (!stack.empty()) {
      const int32_t n = stack.back();
      const KdTree::Node& node = tree.nodes()[size_t(n)];
      stack.pop_back();
      if (node.is_leaf()) {
        cells.push_back(int32_t(node.child));
      } else if (node.is_link()) {
        stack.push_back(int32_t(node.child));
      } else {
        stack.push_back(n + 1);
        stack.push_back(int32_t(node.child));
      }
    }
    for (const int32_t c : cells) {
      const KdTree::Cell& cell = tree.cell(c);
      for (int f = 0; f < 6; ++f) {
        if (cell.rope[f] == KdTree::kNone) continue;
        const int a = f / 2;
        Vec3 p = 0.5 * (cell.bounds.lo + cell.bounds.hi), dir(0.0);
        p[a] = (f & 1) ? cell.bounds.hi[a] : cell.bounds.lo[a];
        dir[a] = (f & 1) ? 1.0 : -1.0;
        ASSERT_EQ(tree.descend(cell.rope[f], p, dir), tree.locate(p, dir)) << "cell " << c << " face " << f;
        ++checked;
      }
    }
  }
  EXPECT_GT(linked, 0u) << "no frame stood in: the test checked nothing it was meant to";
  EXPECT_GT(checked, 0u);
}

// Preorder: node n's subtree is [n, end[n]).
std::vector<uint32_t> subtree_ends(const StoreModel& model) {
  const auto& nodes = model.nodes();
  std::vector<uint32_t> end(nodes.size());
  for (size_t n = nodes.size(); n-- > 0;) end[n] = nodes[n].is_leaf() ? uint32_t(n + 1) : end[nodes[n].child];
  return end;
}

// Frames pegged at a few milliseconds (most pages and proxies still on their way): no ray parks
// in any of them, the cut is an antichain of nodes whose proxies are resident (no linked node
// lies below another), and over the walk the cut refines (more proxies drawn than the root's)
// from what the frames asked for.
TEST(WalkthroughCut, PeggedFramesNeverParkAndTheCutRefines) {
  const double budgets[] = {1.0, 3.0, 5.0};
  for (const double ms : budgets) {
    SCOPED_TRACE(ms);
    WalkOptions o = options(1.0);
    o.width = 160;
    o.height = 120;
    o.budget.ms = ms;
    o.min_sampled = 0.0;  // pure pegging: frames end with work left
    auto walk = Walkthrough::open(terrain().proxies, o);
    ASSERT_TRUE(walk.is_ok());
    const std::vector<uint32_t> end = subtree_ends((*walk)->model());
    uint64_t most_drawn = 0, asked = 0;
    // Four rounds of the orbit, and more (up to 5 s) until the cut refined: pages arrive from
    // the cache's loader thread, which a loaded machine may keep waiting.
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    for (int round = 0; round < 4 || (most_drawn <= 1 && std::chrono::steady_clock::now() < give_up); ++round) {
      for (const Camera& cam : orbit()) {
        const FrameReport r = (*walk)->frame(cam);
        SCOPED_TRACE(r.to_json().dump());
        EXPECT_EQ(r.parked, 0u);
        const PagedWorld& world = (*walk)->world();
        EXPECT_TRUE(world.pegged_cut());
        const std::vector<uint32_t>& linked = world.linked_nodes();
        EXPECT_EQ(r.cut_nodes, linked.size());
        for (const uint32_t n : linked) {
          for (const uint32_t m : linked) {
            EXPECT_FALSE(m > n && m < end[n]) << "node " << m << " linked below linked node " << n;
          }
        }
        most_drawn = std::max(most_drawn, r.proxy_nodes);
        asked += r.requests;
        EXPECT_LE(r.resident_bytes, r.cache_budget);
      }
    }
    EXPECT_GT(asked, 0u) << "no frame asked for anything: the cut cannot refine";
    EXPECT_GT(most_drawn, 1u) << "the cut never refined below the root's proxy";
  }
}

// The paging share before a pegged frame's rays follows how far the last frame's rays found the
// cut from its pixel error: all of it from kFullShareError times T off, a fifth at T or closer,
// in proportion between; the whole share before any frame and without a pixel error.
TEST(WalkthroughCut, ThePagingShareFollowsTheCutsError) {
  const double share = 0.25, t = 1.5, full = WalkOptions::kFullShareError;
  EXPECT_EQ(WalkOptions::paging_share_for(share, std::nullopt, t), share);
  EXPECT_EQ(WalkOptions::paging_share_for(share, 3.0, 0.0), share);
  EXPECT_DOUBLE_EQ(WalkOptions::paging_share_for(share, full * t, t), share);
  EXPECT_DOUBLE_EQ(WalkOptions::paging_share_for(share, 1e9, t), share);
  EXPECT_DOUBLE_EQ(WalkOptions::paging_share_for(share, StandInReport::kEyeInside, t), share);
  EXPECT_DOUBLE_EQ(WalkOptions::paging_share_for(share, 0.5 * full * t, t), 0.5 * share);
  EXPECT_DOUBLE_EQ(WalkOptions::paging_share_for(share, t, t), 0.2 * share);
  EXPECT_DOUBLE_EQ(WalkOptions::paging_share_for(share, 0.0, t), 0.2 * share);
  // Monotone in the error.
  double last = 0.0;
  for (double e = 0.0; e <= 2.0 * full * t; e += 0.25) {
    const double s = WalkOptions::paging_share_for(share, e, t);
    EXPECT_GE(s, last) << e;
    last = s;
  }
  // Not a share outside (0, 1].
  WalkOptions o = options(1.0);
  for (const double bad : {0.0, -0.1, 1.5, std::nan("")}) {
    o.paging_share = bad;
    const auto walk = Walkthrough::open(terrain().proxies, o);
    ASSERT_FALSE(walk.is_ok()) << bad;
    EXPECT_EQ(walk.status().code(), Status::Code::InvalidArgument);
  }
}

// Nothing is asked for where no ray went: a camera that sees a corner of the terrain (a narrow
// view) makes resident only cells and proxies whose regions project into its view.
TEST(WalkthroughCut, OnlyWhatTheRaysReachedIsAskedFor) {
  WalkOptions o = options(1.0);
  o.budget.ms = 300.0;
  auto walk = Walkthrough::open(terrain().proxies, o);
  ASSERT_TRUE(walk.is_ok());
  Camera cam = orbit().front();
  cam.vfov_deg = 8.0;  // a corner of the terrain
  const View view(cam, o.width, o.height);
  const StoreModel& model = (*walk)->model();
  const auto seen = [&](const Aabb& box) {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    if (!view.project(box, x0, y0, x1, y1)) return true;
    return x1 >= -1 && y1 >= -1 && x0 <= view.width && y0 <= view.height;
  };
  size_t resident = 0, outside = 0;
  for (int f = 0; f < 12; ++f) {
    // Moving by a hair: every frame is a new image with a new cut.
    cam.eye.x += 1e-9;
    const FrameReport r = (*walk)->frame(cam);
    SCOPED_TRACE(r.to_json().dump());
    EXPECT_EQ(r.parked, 0u);
  }
  for (uint32_t c = 0; c < model.cells().size(); ++c) {
    if (!(*walk)->world().resident(c)) continue;
    ++resident;
    if (!seen(model.cells()[c].bounds)) ++outside;
  }
  size_t proxies_outside = 0;
  for (const uint32_t n : (*walk)->world().linked_nodes()) {
    if (!seen(model.node_region(n))) ++proxies_outside;
  }
  EXPECT_GT(resident + (*walk)->world().linked_nodes().size(), 1u) << "nothing refined: the test checks nothing";
  EXPECT_EQ(outside, 0u) << outside << " of " << resident << " resident cells lie outside the view";
  // Linked nodes outside the view are allowed only as the coarse rest of the cut (their proxies
  // came in for the view's part of an ancestor): none of them was asked for by itself.
  (void)proxies_outside;
}

// A cache far smaller than the view's cells: the pegged cut stays within it, never parks, and
// still draws every frame from what is resident.
TEST(WalkthroughCut, ASmallCacheStaysWithinBudgetAndNeverParks) {
  WalkOptions o = options(1.0);
  o.cache_bytes = 2u << 20;
  o.budget.ms = 50.0;
  auto walk = Walkthrough::open(terrain().proxies, o);
  ASSERT_TRUE(walk.is_ok());
  for (int round = 0; round < 3; ++round) {
    for (const Camera& cam : orbit()) {
      const FrameReport r = (*walk)->frame(cam);
      SCOPED_TRACE(r.to_json().dump());
      EXPECT_EQ(r.parked, 0u);
      EXPECT_LE(r.resident_bytes, r.cache_budget);
      EXPECT_GT(geometry_pixels((*walk)->ids()), 0u);
    }
  }
}

// A still camera under a time peg: the cut refines while what it asked for comes in, then the
// exact image (pixel error 0) follows and equals brute force.
TEST(WalkthroughCut, AStillPeggedCameraConvergesToTheExactImage) {
  Scene scene;
  ASSERT_TRUE(load_scene(terrain().model, scene).is_ok());
  WalkOptions o = options(1.0);
  o.budget.ms = 100.0;
  auto walk = Walkthrough::open(terrain().proxies, o);
  ASSERT_TRUE(walk.is_ok());
  const Camera cam = orbit().at(2);
  FrameReport r;
  bool exact = false;
  for (int f = 0; f < 200 && !exact; ++f) {
    r = (*walk)->frame(cam);
    exact = r.complete && r.pixel_error == 0.0;
  }
  SCOPED_TRACE(r.to_json().dump());
  ASSERT_TRUE(exact) << "200 frames of a still camera never reached the exact image";
  EXPECT_EQ(r.proxy_pixels, 0u);
  std::vector<uint32_t> reference;
  std::vector<uint8_t> tie;
  testing::brute_reference(scene, (*walk)->view(), reference, tie);
  const auto cmp = testing::compare_ids(reference, tie, (*walk)->ids(), (*walk)->view().width);
  EXPECT_EQ(cmp.mismatches, 0u) << cmp.first_mismatch;
}

// Budgeted frames (300 ms, more than a 64x48 frame needs: each ends when its image is complete,
// pages or not) show geometry wherever the exact frame has it: the cut draws every node from
// what is resident (a proxy or a cell), never by nothing; no ray parks; what the cut drew is
// counted.
TEST(WalkthroughCut, BudgetedFramesHaveNoHolesWhereTheExactFrameHasGeometry) {
  WalkOptions o = options(1.0);
  o.budget.ms = 300.0;  // a 64x48 frame completes within it, from pages or proxies
  auto walk = Walkthrough::open(terrain().proxies, o);
  WalkOptions exact_options = options(0.0);
  exact_options.sync_paging = true;
  auto exact = Walkthrough::open(terrain().plain, exact_options);
  ASSERT_TRUE(walk.is_ok() && exact.is_ok());
  uint64_t proxy_pixels = 0, proxy_nodes = 0, complete = 0;
  for (const Camera& cam : orbit()) {
    const FrameReport r = (*walk)->frame(cam);
    SCOPED_TRACE(r.to_json().dump());
    EXPECT_EQ(r.parked, 0u);
    (*exact)->frame(cam);
    const std::vector<uint32_t> reference = (*exact)->ids();
    ASSERT_GT(geometry_pixels(reference), 0u);
    if (!r.complete) continue;  // a loaded machine: the holes of an unfinished frame say nothing
    ++complete;
    const std::vector<uint32_t> ids = (*walk)->ids();
    // Inside the surface, only pin-holes: a proxy whose border could not stay locked (a big
    // node's long cut edge) may leave a slit as wide as its bound beside its neighbour.
    EXPECT_LE(holes(reference, ids, (*walk)->view().width, 2), geometry_pixels(reference) / 50);
    // And at the rim, at most a tenth of the geometry pixels (a 64x48 view: a third of them are
    // at the rim), from the second frame on: the first, a cold start, is mostly the root's
    // proxy (the coarsest; a seventh of the rim).
    if (r.frame > 0) {
      EXPECT_LE(holes(reference, ids, (*walk)->view().width, 0), geometry_pixels(reference) / 10);
    } else {
      EXPECT_GE(r.proxy_nodes, 1u);  // the root's
    }
    EXPECT_LE(r.proxy_pixels, r.pixels);
    proxy_pixels += r.proxy_pixels;
    proxy_nodes += r.proxy_nodes;
    EXPECT_LE(r.resident_bytes, r.cache_budget);
  }
  // The first frame, a cold start, is drawn by the root's proxy: proxies drew, and were counted.
  EXPECT_GT(complete, 0u);
  EXPECT_GT(proxy_pixels, 0u);
  EXPECT_GT(proxy_nodes, 0u);
}

// A pegged image that is complete before its frame time spends the rest of the frame on what its
// cut asked for (decoded and installed, drawn from the next image on): such a frame ends with
// nothing outstanding, or at its peg; the cut then goes several levels down per frame instead of
// one (a cold 2 M building's exterior at 640x360: the first frame with a sample on 99 % of the
// geometry pixels came at frame 6 instead of never in 16 frames).
TEST(WalkthroughCut, AnImageDoneBeforeItsPegLoadsWhatItsCutAskedFor) {
  WalkOptions o = options(0.5);
  o.width = 320;  // an image the top levels the opening read do not satisfy
  o.height = 240;
  o.budget.ms = 3000.0;  // far more than this image and this store's pages need
  auto walk = Walkthrough::open(terrain().proxies, o);
  ASSERT_TRUE(walk.is_ok());
  const Camera cam = orbit().at(1);
  Camera moved = cam;
  uint64_t loaded = 0;
  size_t first_cut = 0, last_cut = 0;
  const size_t opened_with = (*walk)->world().proxies_resident();
  for (int f = 0; f < 3; ++f) {
    // A camera that moves a little each frame (a still one refines to the exact image).
    moved.eye += 1e-6 * (moved.eye - moved.look_at);
    const FrameReport r = (*walk)->frame(moved);
    SCOPED_TRACE(r.to_json().dump());
    EXPECT_EQ(r.parked, 0u);
    EXPECT_GT(r.pixel_error, 0.0);
    ASSERT_TRUE(r.complete);
    if (r.frame_ms < 0.9 * o.budget.ms) {
      EXPECT_EQ((*walk)->world().requests_outstanding(), 0u) << "the frame ended early with requests left";
    }
    loaded += r.proxies_loaded + r.cells_paged_in;
    (f == 0 ? first_cut : last_cut) = r.cut_nodes;
    EXPECT_LE(r.resident_bytes, r.cache_budget);
  }
  EXPECT_GT(loaded, 0u) << "nothing was loaded beyond what the store's opening read";
  EXPECT_GT((*walk)->world().proxies_resident() + (*walk)->world().resident_cells(), opened_with);
  // Two frames later the cut is finer than the first frame's.
  EXPECT_GT(last_cut, first_cut);
}

// The store's opening reads the top of the tree below the root's proxy (whole levels, within a
// small share of the budget), so that the first frame is drawn from nodes a few levels down, not
// from the root's blob; the opening's reads are not a frame's (proxies_loaded 0 in frame 0, which
// draws what the opening read).
TEST(WalkthroughCut, TheTopOfTheTreeIsResidentBeforeTheFirstFrame) {
  WalkOptions o = options(1.0);
  o.budget.ms = 3000.0;
  auto walk = Walkthrough::open(terrain().proxies, o);
  ASSERT_TRUE(walk.is_ok());
  // The root's proxy and at least its children's and grandchildren's (two whole levels).
  EXPECT_GE((*walk)->world().proxies_resident(), 7u);
  const FrameReport r = (*walk)->frame(orbit().at(1));
  SCOPED_TRACE(r.to_json().dump());
  EXPECT_GT(r.cut_nodes, 1u) << "the first frame drew the root's proxy alone";
  EXPECT_LE(r.resident_bytes, r.cache_budget);
  // A cache too small for more than the root's proxy reads nothing else at the opening.
  WalkOptions tiny = o;
  tiny.cache_bytes = 1u << 20;
  auto small = Walkthrough::open(terrain().proxies, tiny);
  ASSERT_TRUE(small.is_ok());
  EXPECT_LE((*small)->world().proxies_resident(), 1u);
}

// The command line: frontier-view's report has the cut's fields per frame and, in its summary,
// the first complete frame and the frame time up to it (the sum of the frames' times); the
// stderr line names it too. With --sync-paging (pixel error 0 by default) nothing stands in.
TEST(WalkthroughCut, TheReportNamesTheFirstCompleteFrame) {
  for (const bool sync : {false, true}) {
    SCOPED_TRACE(sync);
    const std::string report = (scratch() / (sync ? "sync.jsonl" : "pegged.jsonl")).string();
    std::vector<std::string> args = {terrain().proxies, "--headless", "--path", terrain().path, "--size", "64x48",
                                     "--report", report, "--threads", "2"};
    if (sync) {
      args.push_back("--sync-paging");
    } else {
      args.insert(args.end(), {"--frame-ms", "200"});
    }
    const auto r = run_binary(FRONTIER_VIEW_PATH, args, scratch());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    std::ifstream in(report);
    std::string line;
    std::vector<nlohmann::json> frames;
    nlohmann::json summary;
    while (std::getline(in, line)) {
      auto j = nlohmann::json::parse(line);
      if (j.contains("summary")) {
        summary = j["summary"];
      } else {
        frames.push_back(std::move(j));
      }
    }
    ASSERT_EQ(frames.size(), 4u);
    int64_t first = -1;
    double ms = 0.0, ms_to_first = 0.0;
    for (size_t f = 0; f < frames.size(); ++f) {
      const nlohmann::json& j = frames[f];
      EXPECT_EQ(j.at("pixel_error").get<double>(), sync ? 0.0 : 1.0);
      if (sync) {
        EXPECT_EQ(j.at("proxy_pixels").get<uint64_t>(), 0u);
      }
      ms += j.at("frame_ms").get<double>();
      if (first < 0 && j.at("complete").get<bool>()) {
        first = int64_t(f);
        ms_to_first = ms;
      }
    }
    ASSERT_GE(first, 0) << "64x48 frames of 200 ms complete, from proxies if not from pages";
    if (!sync) {
      for (const nlohmann::json& j : frames) EXPECT_EQ(j.at("parked").get<uint64_t>(), 0u);
    }
    EXPECT_EQ(summary.at("first_complete_frame").get<int64_t>(), first);
    EXPECT_NEAR(summary.at("ms_to_first_complete").get<double>(), ms_to_first, 1e-6 * ms_to_first + 1e-9);
    EXPECT_NE(r.err.find("(the first: frame " + std::to_string(first)), std::string::npos) << r.err;
  }
}

}  // namespace
}  // namespace frontier
