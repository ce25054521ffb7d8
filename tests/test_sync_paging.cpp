// Frames whose cells do not fit in the cache at once (issue 24, items 2 and 3): with sync paging
// (or no budget) such a frame still completes and equals the exact render, its samples never
// exceed its pixels, it says that it thrashed (in its report and once on stderr, with the cache
// it needs), a run with that cache does not thrash, and a cache too small for one pixel's
// cells ends the frame with `unfit` instead of looping.
#include "src/engine/ray_walk.h"
#include "src/io/camera_path.h"
#include "src/io/load_scene.h"
#include "src/walk/walkthrough.h"
#include "tests/engine_util.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_sync_paging"); }

// A generated terrain (20 000 triangles), its raw store in cells of at most `cell_prims`
// triangles, and a four-frame orbit around it. About 6 MiB of decoded cells are in view.
struct Terrain {
  std::string model, path;
  std::string store(uint32_t cell_prims) const {
    const std::string out = (scratch() / ("terrain_" + std::to_string(cell_prims) + ".frontier")).string();
    if (!fs::exists(out)) {
      const auto r = run_binary(FRONTIER_BUILD_PATH,
                                {model, "-o", out, "--codec", "raw", "--cell-prims", std::to_string(cell_prims),
                                 "--threads", "2", "--quiet"},
                                scratch());
      EXPECT_EQ(r.exit_code, 0) << r.err;
    }
    return out;
  }
};

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
    return t;
  }();
  return made;
}

std::vector<Camera> orbit() {
  auto cams = read_camera_path(terrain().path);
  EXPECT_TRUE(cams.is_ok()) << cams.status().to_string();
  return cams.is_ok() ? *cams : std::vector<Camera>{};
}

WalkOptions options(uint64_t cache, bool sync) {
  WalkOptions o;
  o.width = 64;
  o.height = 48;
  o.threads = 2;
  o.cache_bytes = cache;
  o.sync_paging = sync;
  return o;
}

// Item 2: a 2 MiB cache holds 1 MiB of decoded cells, a sixth of what the view needs. Every
// sync-paged frame is complete anyway, in several passes, and its ids equal brute force over
// the input triangles (the raw store holds them bit for bit) and the frame of a cache that
// holds everything.
TEST(WalkthroughSyncPaging, FramesLargerThanTheCacheCompleteAndEqualTheExactRender) {
  Scene scene;
  ASSERT_TRUE(load_scene(terrain().model, scene).is_ok());
  const std::string store = terrain().store(64);
  auto small = Walkthrough::open(store, options(2u << 20, true));
  auto large = Walkthrough::open(store, options(256u << 20, true));
  ASSERT_TRUE(small.is_ok() && large.is_ok());
  const std::vector<Camera> cams = orbit();
  ASSERT_GE(cams.size(), 2u);
  for (size_t f = 0; f < 2; ++f) {
    const FrameReport r = (*small)->frame(cams[f]);
    SCOPED_TRACE(r.to_json().dump());
    EXPECT_TRUE(r.complete);
    EXPECT_FALSE(r.unfit);
    EXPECT_EQ(r.image_samples, r.pixels);
    EXPECT_LE(r.samples, r.pixels);
    EXPECT_GT(r.passes, 1u) << "the cache was meant to be too small for the frame";
    EXPECT_TRUE(r.thrashing);
    EXPECT_GT(r.working_set_bytes, 3 * (*small)->world().decoded_budget());
    EXPECT_LE(r.resident_bytes, r.cache_budget);
    std::vector<uint32_t> reference;
    std::vector<uint8_t> tie;
    testing::brute_reference(scene, (*small)->view(), reference, tie);
    const auto cmp = testing::compare_ids(reference, tie, (*small)->ids(), (*small)->view().width);
    EXPECT_EQ(cmp.mismatches, 0u) << cmp.first_mismatch;
    const FrameReport whole = (*large)->frame(cams[f]);
    EXPECT_TRUE(whole.complete);
    EXPECT_EQ(whole.passes, 1u);
    EXPECT_FALSE(whole.thrashing);
    EXPECT_EQ((*small)->ids(), (*large)->ids());
  }
}

// Item 3: a pixel is a sample once per image, whatever the cache: without a budget (the
// frame runs to completion) and under a frame-time peg, samples never exceed pixels.
TEST(WalkthroughSyncPaging, SamplesNeverExceedPixels) {
  const std::string store = terrain().store(64);
  for (const double frame_ms : {0.0, 40.0}) {
    SCOPED_TRACE(frame_ms);
    WalkOptions o = options(2u << 20, false);
    o.budget.ms = frame_ms;
    auto walk = Walkthrough::open(store, o);
    ASSERT_TRUE(walk.is_ok());
    for (const Camera& cam : orbit()) {
      const FrameReport r = (*walk)->frame(cam);
      SCOPED_TRACE(r.to_json().dump());
      EXPECT_LE(r.samples, r.pixels);
      EXPECT_LE(r.image_samples, r.pixels);
      EXPECT_LE(r.rays, r.pixels);
      if (frame_ms == 0.0) {
        EXPECT_TRUE(r.complete);
      }
    }
  }
}

// When one pixel's cells alone do not fit (cells of 20 000 triangles, a decoded share of
// 256 KiB), the frame ends, incomplete, and says so.
TEST(WalkthroughSyncPaging, ACacheTooSmallForOnePixelSaysSo) {
  auto walk = Walkthrough::open(terrain().store(20000), options((1u << 20) + (256u << 10), true));
  ASSERT_TRUE(walk.is_ok());
  const FrameReport r = (*walk)->frame(orbit().front());
  SCOPED_TRACE(r.to_json().dump());
  EXPECT_FALSE(r.complete);
  EXPECT_TRUE(r.unfit);
  EXPECT_TRUE(r.thrashing);
  EXPECT_GT(r.cache_needed, r.cache_budget);
  EXPECT_LE(r.samples, r.pixels);
}

struct ViewRun {
  proc::RunResult run;
  std::vector<nlohmann::json> frames;
  nlohmann::json summary;
};

ViewRun view_walk(const std::string& cache) {
  ViewRun v;
  const std::string report = (scratch() / ("report_" + cache + ".jsonl")).string();
  v.run = run_binary(FRONTIER_VIEW_PATH,
                     {terrain().store(64), "--headless", "--path", terrain().path, "--size", "64x48", "--cache", cache,
                      "--report", report, "--threads", "2", "--pixel-error", "0"},
                     scratch());
  std::ifstream in(report);
  std::string line;
  while (std::getline(in, line)) {
    auto j = nlohmann::json::parse(line);
    if (j.contains("summary")) {
      v.summary = j["summary"];
    } else {
      v.frames.push_back(std::move(j));
    }
  }
  return v;
}

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Item 3: a walk whose frames do not fit says so in every frame's report line and once on
// stderr, naming the cache it needs; a walk with that cache does not thrash. Exact frames
// (--pixel-error 0): with proxies drawing far nodes, which cells a frame needs depends on which
// proxies arrived first.
TEST(WalkthroughSyncPaging, ThrashingIsReportedOnceAndNotWithTheCacheItNames) {
  const ViewRun small = view_walk("2M");
  ASSERT_EQ(small.run.exit_code, 0) << small.run.err;
  ASSERT_EQ(small.frames.size(), 4u);
  uint64_t needed = 0;
  for (const nlohmann::json& j : small.frames) {
    SCOPED_TRACE(j.dump());
    EXPECT_TRUE(j.at("thrashing").get<bool>());
    EXPECT_TRUE(j.at("complete").get<bool>());
    EXPECT_GT(j.at("cache_needed").get<uint64_t>(), j.at("cache_budget").get<uint64_t>());
    needed = std::max(needed, j.at("cache_needed").get<uint64_t>());
  }
  EXPECT_EQ(small.summary.at("thrashing_frames").get<uint64_t>(), 4u);
  EXPECT_EQ(small.summary.at("cache_needed").get<uint64_t>(), needed);
  EXPECT_EQ(count(small.run.err, "thrashing in 4 of 4 frames"), 1u) << small.run.err;
  const std::string advice = "--cache " + std::to_string(needed >> 20) + "M or more";
  EXPECT_EQ(count(small.run.err, advice), 1u) << small.run.err;

  const ViewRun enough = view_walk(std::to_string(needed >> 20) + "M");
  ASSERT_EQ(enough.run.exit_code, 0) << enough.run.err;
  ASSERT_EQ(enough.frames.size(), 4u);
  for (const nlohmann::json& j : enough.frames) {
    SCOPED_TRACE(j.dump());
    EXPECT_FALSE(j.at("thrashing").get<bool>());
    EXPECT_EQ(j.at("passes").get<uint64_t>(), 1u);
    EXPECT_EQ(j.at("cells_reread").get<uint64_t>(), 0u);
  }
  EXPECT_EQ(enough.summary.at("thrashing_frames").get<uint64_t>(), 0u);
  EXPECT_EQ(count(enough.run.err, "thrashing"), 0u) << enough.run.err;
}

}  // namespace
}  // namespace frontier
