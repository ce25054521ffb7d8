// The out-of-core walkthrough: paged frames equal brute force, the working set stays within the
// cache budget and close to the oracle, parked work resumes, eviction and compaction keep the
// world exact, a corrupted page is walked past, and frontier-view's headless report.
#include "preprocess/build.h"
#include "src/io/camera_path.h"
#include "src/engine/ray_walk.h"
#include "src/io/load_scene.h"
#include "src/walk/collision_grid.h"
#include "src/io/image.h"
#include "src/paging/paged_world.h"
#include "src/paging/store_model.h"
#include "src/walk/walkthrough.h"
#include "store/page_file.h"
#include "store/store_file.h"
#include "tests/engine_util.h"
#include "tests/input_files.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>


#include <filesystem>
#include <fstream>
#include <set>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_walk"); }
using testing::spd;

std::string store_of(const std::vector<std::string>& inputs, const std::string& name, CellCodec codec,
                     uint32_t cell_prims) {
  const std::string out = (scratch() / (name + ".frontier")).string();
  if (fs::exists(out)) return out;
  BuildOptions o;
  o.inputs = inputs;
  o.output = out;
  o.codec = codec;
  o.quiet = true;
  o.threads = 2;
  o.cell_prims = cell_prims;
  auto report = build_store(o);
  EXPECT_TRUE(report.is_ok()) << report.status().to_string();
  return out;
}

// A generated building and a walk path through it (cached within the run).
struct BuildingWalk {
  std::string model, store, path;
};
const BuildingWalk& building_walk() {
  static const BuildingWalk w = [] {
    BuildingWalk b;
    b.model = (scratch() / "building.ply").string();
    auto r = run_binary(proc::gen_binary(), {"building", "--triangles", "60000", "-o", b.model, "--quiet"}, scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    b.path = (scratch() / "walk.cam").string();
    r = run_binary(proc::gen_binary(),
                   {"path", "--model", b.model, "--kind", "walk", "--frames", "24", "--step", "0.4", "-o", b.path},
                   scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    b.store = store_of({b.model}, "building", CellCodec::Draco, 256);
    return b;
  }();
  return w;
}

std::vector<Camera> walk_cameras() {
  auto cams = read_camera_path(building_walk().path);
  EXPECT_TRUE(cams.is_ok()) << cams.status().to_string();
  return cams.is_ok() ? *cams : std::vector<Camera>{};
}

WalkOptions sync_options(int size, uint64_t cache) {
  WalkOptions o;
  o.width = size;
  o.height = size;
  o.threads = 2;
  o.cache_bytes = cache;
  o.sync_paging = true;
  return o;
}

// With sync paging a paged frame is exact: its ids equal brute force over the input scene
// (raw codec: the store holds the input primitives bit for bit), for the SPD scenes cut into
// many small cells, from the scene camera and from a second camera after it.
TEST(Walkthrough, SyncPagingFramesEqualBruteForce) {
  for (const char* name : {"rings", "tree", "shells"}) {
    SCOPED_TRACE(name);
    Scene scene;
    ASSERT_TRUE(load_scene(spd(name), scene).is_ok());
    const std::string store = store_of({spd(name)}, std::string(name) + "_raw", CellCodec::Raw, 32);
    auto walk = Walkthrough::open(store, sync_options(97, 64u << 20));
    ASSERT_TRUE(walk.is_ok()) << walk.status().to_string();
    Camera cam = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
    cam.width = cam.height = 0;
    Camera moved = cam;
    moved.eye = cam.eye + 0.25 * (cam.look_at - cam.eye);
    for (const Camera& c : {cam, moved}) {
      const FrameReport r = (*walk)->frame(c);
      EXPECT_TRUE(r.complete);
      EXPECT_EQ(r.image_samples, r.pixels);
      EXPECT_GT(r.cells_paged_in + ((*walk)->world().resident_cells() > 0 ? 1 : 0), 0u);
      std::vector<uint32_t> reference;
      std::vector<uint8_t> tie;
      testing::brute_reference(scene, (*walk)->view(), reference, tie);
      const auto cmp = testing::compare_ids(reference, tie, (*walk)->ids(), 97);
      EXPECT_EQ(cmp.mismatches, 0u) << cmp.first_mismatch;
    }
  }
}

// Nothing is paged before it is needed: the first frame pages in exactly the cells it touched
// that have pages, and every touched cell with a page is resident afterwards.
TEST(Walkthrough, PagesInOnlyWhatTheFrameTouches) {
  const std::string store = store_of({spd("shells")}, "shells_raw", CellCodec::Raw, 32);
  auto walk = Walkthrough::open(store, sync_options(64, 64u << 20));
  ASSERT_TRUE(walk.is_ok());
  const Camera cam = *(*walk)->model().info().camera;
  const FrameReport r = (*walk)->frame(cam);
  const auto touched = (*walk)->touched_cells();
  EXPECT_EQ(touched.size(), r.cells_touched);
  size_t with_pages = 0;
  for (uint32_t c : touched) {
    if ((*walk)->model().cells()[c].page == StoreCell::kNoPage) continue;
    ++with_pages;
    EXPECT_TRUE((*walk)->world().resident(c)) << "touched cell " << c << " not resident";
  }
  EXPECT_EQ(r.cells_paged_in, with_pages);
  EXPECT_EQ((*walk)->world().resident_cells(), with_pages);
  EXPECT_LT(with_pages, (*walk)->model().cells().size()) << "the view should not need every cell";
  EXPECT_GT(r.bytes_read, 0u);
}

// Prefetch: after two frames moving along a straight line, the store cells the eye will be in
// over the next frames (if it keeps going) are resident or already asked for.
TEST(Walkthrough, CellsAheadOfAMovingEyeAreRequested) {
  const BuildingWalk& b = building_walk();
  auto walk = Walkthrough::open(b.store, sync_options(32, 64u << 20));
  ASSERT_TRUE(walk.is_ok());
  const StoreModel& model = (*walk)->model();
  const KdTree top = KdTree::top_only(model.nodes(), model.info().bounds);
  Camera cam = walk_cameras().front();
  const Vec3 step(1.5, 0.0, 0.0);
  cam.look_at = cam.eye + Vec3(0.0, 1.0, 0.0);  // looking sideways: the cells ahead are not in view
  (*walk)->frame(cam);
  cam.eye += step;
  cam.look_at += step;
  (*walk)->frame(cam);
  int checked = 0;
  for (int ahead = 1; ahead <= 4; ++ahead) {
    const int32_t c = top.locate(cam.eye + double(ahead) * step, step);
    if (c == KdTree::kNone || model.cells()[size_t(c)].page == StoreCell::kNoPage) continue;
    ++checked;
    EXPECT_TRUE((*walk)->world().resident(uint32_t(c)) || (*walk)->world().wanted(uint32_t(c)))
        << "cell " << c << " " << ahead << " steps ahead was not requested";
  }
  EXPECT_GT(checked, 0);
}

// A time budget far below what the first frame needs: frames end with parked work instead of
// waiting; the same camera again continues the image, and it converges to the exact image.
TEST(Walkthrough, ParkedWorkResumesAndConverges) {
  Scene scene;
  ASSERT_TRUE(load_scene(spd("tree"), scene).is_ok());
  const std::string store = store_of({spd("tree")}, "tree_raw", CellCodec::Raw, 32);
  WalkOptions o = sync_options(97, 64u << 20);
  o.sync_paging = false;
  o.budget.ms = 1.0;
  o.min_sampled = 0.0;  // pure frame-time pegging
  auto walk = Walkthrough::open(store, o);
  ASSERT_TRUE(walk.is_ok());
  Camera cam = *scene.camera;
  FrameReport first = (*walk)->frame(cam);
  EXPECT_FALSE(first.complete) << "a 1 ms first frame cannot page in the whole view";
  bool complete = false;
  uint64_t last_samples = first.image_samples;
  for (int f = 0; f < 2000 && !complete; ++f) {
    const FrameReport r = (*walk)->frame(cam);
    EXPECT_TRUE(r.continued);
    EXPECT_GE(r.image_samples, last_samples) << "a continued image lost samples";
    last_samples = r.image_samples;
    complete = r.complete;
  }
  ASSERT_TRUE(complete);
  std::vector<uint32_t> reference;
  std::vector<uint8_t> tie;
  testing::brute_reference(scene, (*walk)->view(), reference, tie);
  const auto cmp = testing::compare_ids(reference, tie, (*walk)->ids(), 97);
  EXPECT_EQ(cmp.mismatches, 0u) << cmp.first_mismatch;
}

// The sample floor under a frame-time peg far below what the view needs: with it every moving
// frame of the building walk samples at least half its pixels or runs until the floor's cap;
// without it no frame runs past its peg, and the frames sample less. A frame after one that
// needed the floor previews its leaves; none does without a floor.
TEST(Walkthrough, SampleFloorHoldsUnderATightFrameTimePeg) {
  const std::vector<Camera> cams = walk_cameras();
  ASSERT_FALSE(cams.empty());
  auto walk_with = [&](double min_sampled) {
    WalkOptions o = sync_options(128, 64u << 20);
    o.sync_paging = false;
    o.budget.ms = 0.5;
    o.min_sampled = min_sampled;
    auto walk = Walkthrough::open(building_walk().store, o);
    EXPECT_TRUE(walk.is_ok()) << walk.status().to_string();
    std::vector<FrameReport> out;
    if (!walk.is_ok()) return out;
    for (const Camera& cam : cams) out.push_back((*walk)->frame(cam));
    return out;
  };
  const double cap_ms = (1.0 + Walkthrough::kFloorMaxOvertime) * 0.5;
  uint64_t with = 0, without = 0, floored = 0, previews = 0;
  bool last_floored = false;
  for (const FrameReport& r : walk_with(0.5)) {
    EXPECT_TRUE(2 * r.samples >= r.pixels || r.frame_ms >= cap_ms)
        << "frame " << r.frame << ": " << r.samples << " of " << r.pixels << " samples in " << r.frame_ms << " ms";
    with += r.samples;
    floored += r.floor_ms > 0.0 ? 1 : 0;
    // A frame after one that needed the floor previews its leaves (FrustumCaster::set_preview).
    EXPECT_EQ(r.preview, last_floored) << "frame " << r.frame;
    previews += r.preview ? 1 : 0;
    last_floored = r.floor_ms > 0.0;
  }
  for (const FrameReport& r : walk_with(0.0)) {
    EXPECT_EQ(r.floor_ms, 0.0) << "frame " << r.frame;
    EXPECT_FALSE(r.preview) << "frame " << r.frame << ": no floor, no previews";
    without += r.samples;
  }
  EXPECT_GT(floored, 0u) << "a 0.5 ms peg was meant to need the floor";
  EXPECT_GT(previews, 0u);
  EXPECT_GT(with, without);
}

// Whether pixel i's ids `a` and `b` (sources) are a tie: each has a resident primitive hit by
// the pixel's ray at the nearest hit of any resident primitive (coplanar copies of a wall in two
// cells, or two walls meeting in the plane: which one a walk reports depends on the leaves the
// ray meets them in, as for brute force with another order).
bool tie_at_pixel(const Walkthrough& walk, size_t i, uint32_t a, uint32_t b) {
  if (a == kNoPrim || b == kNoPrim) return false;
  const Scene& scene = walk.world().scene();
  const View& view = walk.view();
  const Ray ray = view.ray(int(i % size_t(view.width)), int(i / size_t(view.width)));
  const double tmin = view.tmin(ray);
  double nearest = kInfinity, ta = kInfinity, tb = kInfinity;
  for (uint32_t p = 0; p < scene.size(); ++p) {
    double t = 0.0;
    if (!scene.intersect(p, ray, tmin, kInfinity, t)) continue;
    nearest = std::min(nearest, t);
    if (scene.prims[p].source == a) ta = std::min(ta, t);
    if (scene.prims[p].source == b) tb = std::min(tb, t);
  }
  // Copies of one triangle decoded in two cells may differ in the last bits of t.
  const double slack = 1e-12 * std::max(1.0, nearest);
  return ta <= nearest + slack && tb <= nearest + slack;
}

// The building walk with a cache far smaller than the model: resident bytes never exceed the
// budget, cells are evicted and compacted away, every frame is still exact (ids equal the
// oracle's exact two-level walk, but for ties), and the touched cells stay close to the oracle's.
TEST(Walkthrough, SmallCacheStaysWithinBudgetAndExactAlongTheBuildingWalk) {
  const BuildingWalk& b = building_walk();
  auto model = StoreModel::open(b.store);
  ASSERT_TRUE(model.is_ok());
  uint64_t page_bytes = 0;
  for (const StoreCell& c : (*model)->cells()) {
    if (c.page != StoreCell::kNoPage) page_bytes += (*model)->reader().page_handle(c.page).size;
  }
  WalkOptions o = sync_options(96, 6u << 20);  // in-cell trees of traversal cost 8: 8 MiB no longer evicts
  o.oracle = true;
  auto walk = Walkthrough::open(b.store, o);
  ASSERT_TRUE(walk.is_ok());
  uint64_t evicted = 0;
  double worst = 0.0;
  for (const Camera& cam : walk_cameras()) {
    const FrameReport r = (*walk)->frame(cam);
    SCOPED_TRACE(r.to_json().dump());
    EXPECT_LE(r.resident_bytes, r.cache_budget) << "frame " << r.frame;
    EXPECT_TRUE(r.complete) << "frame " << r.frame;
    ASSERT_TRUE(r.oracle_cells.has_value());
    ASSERT_GT(*r.oracle_cells, 0u);
    worst = std::max(worst, double(r.cells_touched) / double(*r.oracle_cells));
    // Every cell an exact ray passes is one the renderer touched.
    const auto touched = (*walk)->touched_cells();
    const std::set<uint32_t> t(touched.begin(), touched.end());
    for (uint32_t c : (*walk)->last_oracle()->cells) EXPECT_TRUE(t.count(c)) << "oracle cell " << c << " untouched";
    const auto ids = (*walk)->ids();
    const auto& oracle_ids = (*walk)->last_oracle()->ids;
    ASSERT_EQ(ids.size(), oracle_ids.size());
    size_t ties = 0;
    for (size_t i = 0; i < ids.size(); ++i) {
      if (ids[i] == oracle_ids[i]) continue;
      EXPECT_TRUE(tie_at_pixel(**walk, i, ids[i], oracle_ids[i]))
          << "frame " << r.frame << " pixel " << i << ": " << ids[i] << " against the oracle's " << oracle_ids[i];
      ++ties;
    }
    EXPECT_LE(ties, ids.size() / 100) << "frame " << r.frame << ": ties are rare";
    evicted += r.cells_evicted;
  }
  EXPECT_GT(evicted, 0u) << "the budget was meant to force eviction";
  EXPECT_LT(worst, 1.3) << "cells_touched / oracle_cells";
  (void)page_bytes;
}

// A cache smaller than one view's cells under a frame-time peg: frames degrade (fewer samples,
// cells dropped) instead of failing, and resident bytes still never exceed the budget. (With
// sync paging they complete in passes: tests/test_sync_paging.cpp.)
TEST(Walkthrough, CacheSmallerThanTheViewDegrades) {
  const BuildingWalk& b = building_walk();
  WalkOptions o = sync_options(96, 2u << 20);
  o.sync_paging = false;
  o.budget.ms = 50.0;
  o.min_sampled = 0.0;
  auto walk = Walkthrough::open(b.store, o);
  ASSERT_TRUE(walk.is_ok());
  uint64_t dropped = 0, incomplete = 0;
  for (const Camera& cam : walk_cameras()) {
    const FrameReport r = (*walk)->frame(cam);
    SCOPED_TRACE(r.to_json().dump());
    EXPECT_LE(r.resident_bytes, r.cache_budget);
    EXPECT_GT(r.image_samples, 0u);
    EXPECT_LE(r.samples, r.pixels);
    dropped += r.cells_dropped;
    incomplete += r.complete ? 0 : 1;
  }
  EXPECT_GT(dropped, 0u) << "the budget was meant to be too small";
  EXPECT_GT(incomplete, 0u);
}

// §5.3: a still camera refines its image to completion with immediate effects only, then
// renders it again with the deferred shadows; moving drops back to immediate effects. A scene
// without lights never casts a shadow ray.
TEST(Walkthrough, StillCameraRefinesThenAddsDeferredShadows) {
  Scene scene;
  ASSERT_TRUE(load_scene(spd("tree"), scene).is_ok());
  ASSERT_FALSE(scene.lights.empty());
  const std::string store = store_of({spd("tree")}, "walk_tree_raw", CellCodec::Raw, 32);
  WalkOptions o = sync_options(64, 64u << 20);
  o.sync_paging = false;  // no budget: each frame runs to completion anyway
  auto walk = Walkthrough::open(store, o);
  ASSERT_TRUE(walk.is_ok());
  const Camera cam = *scene.camera;
  FrameReport r = (*walk)->frame(cam);
  EXPECT_TRUE(r.complete);
  EXPECT_FALSE(r.shadows);
  EXPECT_EQ(r.shadow_rays, 0u) << "a moving (first) frame has immediate effects only";
  r = (*walk)->frame(cam);
  EXPECT_TRUE(r.complete);
  EXPECT_TRUE(r.shadows);
  EXPECT_FALSE(r.continued);
  EXPECT_GT(r.shadow_rays, 0u);
  r = (*walk)->frame(cam);
  EXPECT_TRUE(r.continued);
  EXPECT_EQ(r.samples, 0u) << "a complete image needs no more work";
  Camera moved = cam;
  moved.eye += 0.1 * (cam.look_at - cam.eye);
  r = (*walk)->frame(moved);
  EXPECT_FALSE(r.shadows);
  EXPECT_EQ(r.shadow_rays, 0u);

  // The generated building declares no lights.
  auto plain = Walkthrough::open(building_walk().store, sync_options(48, 64u << 20));
  ASSERT_TRUE(plain.is_ok());
  ASSERT_TRUE((*plain)->model().info().lights.empty());
  const Camera c = walk_cameras().front();
  for (int f = 0; f < 3; ++f) EXPECT_EQ((*plain)->frame(c).shadow_rays, 0u);
}

// A walkable store of `model`, and its distance grid.
struct WalkableStore {
  std::string path;
  std::unique_ptr<StoreModel> model;  // the grid reads its bricks through the model's reader
  std::unique_ptr<CollisionGrid> grid;
  double radius = 0.0;
};
WalkableStore walkable_store(const std::string& model, const std::string& name) {
  WalkableStore w;
  w.path = (scratch() / (name + ".frontier")).string();
  BuildOptions bo;
  bo.inputs = {model};
  bo.output = w.path;
  bo.quiet = true;
  bo.threads = 2;
  bo.cell_prims = 256;
  bo.walkable = true;
  auto built = build_store(bo);
  EXPECT_TRUE(built.is_ok()) << built.status().to_string();
  auto m = StoreModel::open(w.path);
  EXPECT_TRUE(m.is_ok());
  if (!m.is_ok()) return w;
  auto grid = open_collision_grid((*m)->reader());
  EXPECT_TRUE(grid.is_ok());
  if (grid.is_ok()) w.grid = std::move(*grid);
  w.radius = (*m)->info().walk_radius;
  w.model = std::move(*m);
  return w;
}

// 60 frames of 0.25 m from `start` along the horizontal direction `dir`, looking that way.
std::string path_along(const Vec3& start, const Vec3& dir, const std::string& name) {
  std::vector<Camera> path;
  for (int f = 0; f < 60; ++f) {
    Camera c;
    c.eye = start + dir * (0.25 * f);
    c.look_at = c.eye + dir;
    c.up = Vec3(0.0, 0.0, 1.0);
    path.push_back(c);
  }
  const std::string cam = (scratch() / (name + ".cam")).string();
  EXPECT_TRUE(write_camera_path(cam, path).is_ok());
  return cam;
}

// Walks `cam` through `store` with frontier-view; returns the last frame's eye and collision
// queries.
std::pair<Vec3, uint64_t> walk_to_end(const std::string& store, const std::string& cam, bool walk_mode) {
  const std::string report = (scratch() / "walk_end.jsonl").string();
  std::vector<std::string> args = {store, "--headless", "--path", cam, "--size", "32x24", "--report", report};
  if (walk_mode) args.push_back("--walk");
  const auto r = run_binary(FRONTIER_VIEW_PATH, args, scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::ifstream in(report);
  std::string line;
  std::pair<Vec3, uint64_t> out{Vec3(0.0), 0};
  while (std::getline(in, line)) {
    const auto j = nlohmann::json::parse(line);
    if (!j.contains("eye")) continue;
    out.first = Vec3(j["eye"][0].get<double>(), j["eye"][1].get<double>(), j["eye"][2].get<double>());
    out.second = j["collision_queries"].get<uint64_t>();
  }
  return out;
}

// Walk mode on a path aimed straight at a wall (a floor and one wall, z up): the eye stops at
// its radius from the wall instead of passing through; without --walk it goes through and no
// collision query is made.
TEST(ViewCommand, WalkModeStopsTheEyeAtItsRadiusFromAWall) {
  const std::string off = (scratch() / "wall.off").string();
  {
    std::ofstream f(off);
    f << "OFF\n8 2 0\n0 -10 0\n20 -10 0\n20 10 0\n0 10 0\n8 -10 0\n8 10 0\n8 10 3\n8 -10 3\n"
      << "4 0 1 2 3\n4 4 5 6 7\n";
  }
  const WalkableStore w = walkable_store(off, "wall");
  ASSERT_TRUE(w.grid);
  const std::string cam = path_along(Vec3(2.0, 0.0, 1.7), Vec3(1.0, 0.0, 0.0), "at_wall");
  const auto [flown, no_queries] = walk_to_end(w.path, cam, false);
  EXPECT_NEAR(flown.x, 2.0 + 0.25 * 59, 1e-9) << "without walk mode the eye follows the path";
  EXPECT_EQ(no_queries, 0u);
  const auto [walked, queries] = walk_to_end(w.path, cam, true);
  EXPECT_GT(queries, 0u);
  const double h = w.grid->voxel_size();
  EXPECT_NEAR(walked.x, 8.0 - w.radius, 0.94 * h) << "the eye should stop at its radius from the wall";
  EXPECT_NEAR(walked.z, 1.7, 1e-3) << "standing on the floor at eye height";
  EXPECT_GE(w.grid->distance(walked), w.radius - 1e-6);
}

// The collision grid is paged: a walk reads a few bricks, keeps them within --collision-cache,
// and walks the same path whatever the budget (a brick evicted is read again, identically).
TEST(ViewCommand, WalkModePagesTheCollisionGridWithinItsBudget) {
  const BuildingWalk& b = building_walk();
  const WalkableStore w = walkable_store(b.model, "building_walkable");
  ASSERT_TRUE(w.grid);
  const auto walk = [&](const std::string& budget) {
    const std::string report = (scratch() / ("walk_budget_" + budget + ".jsonl")).string();
    const auto r = run_binary(FRONTIER_VIEW_PATH,
                              {w.path, "--headless", "--walk", "--path", b.path, "--frames", "60", "--size", "32x24",
                               "--collision-cache", budget, "--report", report},
                              scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    std::vector<nlohmann::json> lines;
    std::ifstream in(report);
    for (std::string line; std::getline(in, line);) lines.push_back(nlohmann::json::parse(line));
    return lines;
  };
  const std::vector<nlohmann::json> big = walk("256M"), small = walk("1M");
  ASSERT_EQ(big.size(), 61u);
  ASSERT_EQ(small.size(), big.size());
  for (size_t f = 0; f + 1 < big.size(); ++f) {
    ASSERT_EQ(small[f]["eye"], big[f]["eye"]) << "frame " << f;
    EXPECT_GT(big[f]["collision_bricks"].get<uint64_t>(), 0u);
    EXPECT_EQ(big[f]["collision_errors"].get<uint64_t>(), 0u);
  }
  const nlohmann::json& bs = big.back()["summary"];
  const nlohmann::json& ss = small.back()["summary"];
  EXPECT_EQ(ss["collision_cache_budget"].get<uint64_t>(), uint64_t{1} << 20);
  EXPECT_GT(bs["max_collision_bytes"].get<uint64_t>(), 0u);
  EXPECT_LE(ss["max_collision_bytes"].get<uint64_t>(), bs["max_collision_bytes"].get<uint64_t>());
  EXPECT_GE(ss["collision_loads"].get<uint64_t>(), bs["collision_loads"].get<uint64_t>());
  // A walk reads a small part of the grid: what it held is less than the grid as bare floats.
  EXPECT_LT(bs["max_collision_bytes"].get<uint64_t>(), 4 * w.grid->active_voxels());
  std::printf("collision grid: %llu active voxels; walk held at most %llu bytes (budget 256M), %llu (budget 1M) "
              "with %llu and %llu brick loads\n",
              static_cast<unsigned long long>(w.grid->active_voxels()),
              static_cast<unsigned long long>(bs["max_collision_bytes"].get<uint64_t>()),
              static_cast<unsigned long long>(ss["max_collision_bytes"].get<uint64_t>()),
              static_cast<unsigned long long>(bs["collision_loads"].get<uint64_t>()),
              static_cast<unsigned long long>(ss["collision_loads"].get<uint64_t>()));
}

// The same on the generated building, straight along +x and -x from the walk's first eye:
// the eye never gets past the first wall a horizontal ray from it meets (it may stop earlier,
// at furniture too high to step over).
TEST(ViewCommand, WalkModeNeverPassesTheBuildingsWalls) {
  const BuildingWalk& b = building_walk();
  const WalkableStore w = walkable_store(b.model, "building_walkable");
  ASSERT_TRUE(w.grid);
  Scene scene;
  ASSERT_TRUE(load_scene(b.model, scene).is_ok());
  const Vec3 start = walk_cameras().front().eye;
  for (const Vec3 dir : {Vec3(1.0, 0.0, 0.0), Vec3(-1.0, 0.0, 0.0), Vec3(0.0, 1.0, 0.0), Vec3(0.0, -1.0, 0.0)}) {
    SCOPED_TRACE(dir.x + 2 * dir.y);
    Counters counters;
    const RayHit wall = brute_force_hit(scene, Ray(start, dir), 0.0, counters);
    ASSERT_TRUE(wall.hit());
    const std::string cam = path_along(start, dir, "building_dir");
    const auto [walked, queries] = walk_to_end(w.path, cam, true);
    EXPECT_GT(queries, 0u);
    EXPECT_LE(glm::dot(walked - start, dir), wall.t - w.radius + 0.94 * w.grid->voxel_size())
        << "the eye passed the wall " << wall.t << " m ahead";
    EXPECT_GE(w.grid->distance(walked), w.radius - 1e-6);
  }
}

// A page with a flipped byte: the walk goes on to the end, the error is counted, and the cell
// is drawn as missing (no crash, no exception).
TEST(Walkthrough, CorruptedPageIsCountedAndTheWalkGoesOn) {
  const BuildingWalk& b = building_walk();
  const std::string bad = (scratch() / "corrupt.frontier").string();
  fs::copy_file(b.store, bad, fs::copy_options::overwrite_existing);
  auto model = StoreModel::open(bad);
  ASSERT_TRUE(model.is_ok());
  // Damage every fourth page the walk's first frame needs, so the walk must meet one.
  auto probe = Walkthrough::open(b.store, sync_options(64, 64u << 20));
  ASSERT_TRUE(probe.is_ok());
  const auto cams = walk_cameras();
  ASSERT_FALSE(cams.empty());
  (*probe)->frame(cams.front());
  std::vector<uint64_t> offsets;
  size_t k = 0;
  for (uint32_t c : (*probe)->touched_cells()) {
    const StoreCell& cell = (*model)->cells()[c];
    if (cell.page == StoreCell::kNoPage || k++ % 4 != 0) continue;
    const auto h = (*model)->reader().page_handle(cell.page);
    offsets.push_back(h.offset + h.size / 2);
  }
  ASSERT_FALSE(offsets.empty());
  {
    std::fstream f(bad, std::ios::in | std::ios::out | std::ios::binary);
    for (uint64_t off : offsets) {
      f.seekg(static_cast<std::streamoff>(off));
      char byte = 0;
      f.read(&byte, 1);
      byte = static_cast<char>(byte ^ 0x5A);
      f.seekp(static_cast<std::streamoff>(off));
      f.write(&byte, 1);
    }
  }
  auto walk = Walkthrough::open(bad, sync_options(64, 64u << 20));
  ASSERT_TRUE(walk.is_ok());
  FrameReport last;
  for (const Camera& cam : cams) last = (*walk)->frame(cam);
  EXPECT_EQ(last.frame + 1, cams.size());
  EXPECT_GE(last.page_errors, offsets.size());
  EXPECT_TRUE(last.complete);
}

// frontier-view --headless --path ... --report: one JSON line per frame with every field of the
// working-set definition, then a summary; resident_bytes within the budget.
TEST(ViewCommand, HeadlessWalkWritesTheReport) {
  const BuildingWalk& b = building_walk();
  const std::string report = (scratch() / "frames.jsonl").string();
  const std::string pngs = (scratch() / "pngs").string();
  const auto r = run_binary(FRONTIER_VIEW_PATH,
                            {b.store, "--headless", "--path", b.path, "--frames", "10", "--size", "80x60", "--cache",
                             "8M", "--report", report, "--png-dir", pngs, "--oracle", "--sync-paging", "--threads", "2"},
                            scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::ifstream in(report);
  std::string line;
  int frames = 0;
  bool summary = false;
  while (std::getline(in, line)) {
    const auto j = nlohmann::json::parse(line);
    if (j.contains("summary")) {
      summary = true;
      for (const char* k : {"p50_frame_ms", "p95_frame_ms", "mean_samples", "peak_rss_mib", "total_bytes_read",
                            "mean_touched_oracle_ratio"}) {
        EXPECT_TRUE(j["summary"].contains(k)) << k;
      }
      continue;
    }
    EXPECT_EQ(j["frame"].get<int>(), frames);
    for (const char* k : {"cells_touched", "cells_paged_in", "bytes_read", "resident_bytes", "pinned_bytes",
                          "cache_budget", "primitives_tested", "ray_primitive_tests", "rays", "samples", "frame_ms",
                          "stall_ms", "floor_ms", "preview", "oracle_cells", "collision_queries", "cut_error"}) {
      EXPECT_TRUE(j.contains(k)) << k;
    }
    EXPECT_LE(j["resident_bytes"].get<uint64_t>(), j["cache_budget"].get<uint64_t>());
    EXPECT_EQ(j["collision_queries"].get<uint64_t>(), 0u) << "no walk mode, no collision work";
    ++frames;
  }
  EXPECT_EQ(frames, 10);
  EXPECT_TRUE(summary);
  EXPECT_FALSE(fs::is_empty(pngs));
}

// --ids, --png and --stats with --path write the path's last frame (they were ignored before):
// the sync-paged walk's last ids equal those of a walk whose path is that camera alone.
TEST(ViewCommand, HeadlessWalkWritesItsLastFrame) {
  const BuildingWalk& b = building_walk();
  std::ifstream in(b.path);
  std::string line, header, third;
  for (int cameras = 0; std::getline(in, line) && cameras < 3;) {
    if (!line.empty() && line[0] == '#') {
      header += line + "\n";
    } else if (!line.empty() && ++cameras == 3) {
      third = line;
    }
  }
  ASSERT_FALSE(third.empty());
  const std::string one = testing::write_file(scratch() / "third.cam", header + third + "\n");
  const auto walk_ids = [&](const std::string& path, const std::string& name) {
    const fs::path ids = scratch() / (name + ".ids"), png = scratch() / (name + ".png"), stats = scratch() / (name + ".json");
    const auto r = run_binary(FRONTIER_VIEW_PATH,
                              {b.store, "--headless", "--path", path, "--frames", "3", "--size", "80x60", "--cache", "64M",
                               "--sync-paging", "--threads", "2", "--ids", ids.string(), "--png", png.string(), "--stats",
                               stats.string()},
                              scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::exists(png)) << png;
    EXPECT_TRUE(fs::exists(stats)) << stats;
    std::ifstream f(ids, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), {});
  };
  const std::string walked = walk_ids(b.path, "walked");
  const std::string still = walk_ids(one, "still");
  ASSERT_EQ(walked.size(), size_t(80 * 60 * 4));
  EXPECT_NE(walked, std::string(walked.size(), '\xff')) << "not all background";
  EXPECT_EQ(walked, still);
}

// The window under Xvfb (CI installs xvfb): opens, renders frames with scripted keys... here
// with --frames N and a path, exits cleanly, and the saved frame (HUD included) is not blank.
TEST(ViewCommand, WindowRendersUnderXvfbAndExits) {
  const BuildingWalk& b = building_walk();
  ASSERT_EQ(std::system("test -x /usr/bin/xvfb-run"), 0) << "xvfb-run missing: .ci/install-deps installs xvfb";
  const std::string shot = (scratch() / "window.png").string();
  const std::string report = (scratch() / "window.jsonl").string();
  const auto r = run_binary("/usr/bin/xvfb-run", {"-a", "-s", "-screen 0 1024x768x24", FRONTIER_VIEW_PATH, b.store, "--path",
                                         b.path, "--frames", "12", "--size", "160x120", "--frame-ms", "40", "--png",
                                         shot, "--report", report, "--threads", "2"},
                            scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  int w = 0, h = 0;
  std::vector<Rgb> pixels;
  ASSERT_TRUE(read_png(shot, w, h, pixels).is_ok());
  ASSERT_GT(w * h, 0);
  std::set<int> levels;
  for (const Rgb& p : pixels) levels.insert(int(p.r * 255.0f) * 65536 + int(p.g * 255.0f) * 256 + int(p.b * 255.0f));
  EXPECT_GT(levels.size(), 50u) << "the saved frame looks blank";
  std::ifstream in(report);
  std::string line;
  int frames = 0;
  while (std::getline(in, line)) frames += nlohmann::json::parse(line).contains("frame") ? 1 : 0;
  EXPECT_EQ(frames, 12);
}

TEST(ViewCommand, BadOptionsFailCleanly) {
  const BuildingWalk& b = building_walk();
  auto r = run_binary(FRONTIER_VIEW_PATH, {b.store, "--headless", "--cache", "lots"}, scratch());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--cache"), std::string::npos) << r.err;
  r = run_binary(FRONTIER_VIEW_PATH, {b.store, "--headless", "--path", "/nonexistent.cam", "--report", "x"}, scratch());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("nonexistent.cam"), std::string::npos) << r.err;
  r = run_binary(FRONTIER_VIEW_PATH, {b.store, "--headless", "--walk", "--path", b.path, "--report", "x"}, scratch());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("walk"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace frontier
