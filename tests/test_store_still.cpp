// A still headless frame of a store renders what the in-memory render of the same store does
// (issue 24, item 4): the shadows its lights cast, also from geometry outside the view and with
// a cache too small for the frame (shadow rays page in the cells they cross); and a scene that
// declares no lights, or a run with --no-shadows, casts no shadow ray. Stores on a lattice
// (Draco) and without a camera are framed alike by both (issue 43, item 8): the ids differ only
// at ties.
#include "src/io/image.h"
#include "src/paging/store_model.h"
#include "tests/engine_util.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_store_still"); }

// SPD tree with its camera moved to look at the ground beside the tree: the shadows there are
// cast by branches outside the view.
std::string tree_shadow_nff() {
  const std::string out = (scratch() / "tree_shadow.nff").string();
  std::ifstream in(testing::spd("tree"));
  std::ofstream o(out);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("from ", 0) == 0) line = "from 2 -3 2.5";
    if (line.rfind("at ", 0) == 0) line = "at 2 -1 0";
    if (line.rfind("angle ", 0) == 0) line = "angle 40";
    o << line << "\n";
  }
  return out;
}

std::string store_of(const std::string& model, const std::string& name) {
  const std::string out = (scratch() / (name + ".frontier")).string();
  const auto r = run_binary(FRONTIER_BUILD_PATH, {model, "-o", out, "--codec", "raw", "--cell-prims", "32", "--quiet"},
                            scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return out;
}

// Runs frontier-view headless on `args` at `size`, writing `output` (--png or --stats) to the
// scratch file `name`, whose path it returns.
std::string view_frame(std::vector<std::string> args, const char* size, const char* output, const std::string& name) {
  const std::string file = (scratch() / name).string();
  for (const char* a : {"--headless", "--threads", "2", "--size", size, output}) args.emplace_back(a);
  args.push_back(file);
  const auto r = run_binary(FRONTIER_VIEW_PATH, args, scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return file;
}

std::vector<Rgb> frame_png(const std::vector<std::string>& args, const std::string& name) {
  const std::string png = view_frame(args, "96x96", "--png", name + ".png");
  int w = 0, h = 0;
  std::vector<Rgb> pixels;
  EXPECT_TRUE(read_png(png, w, h, pixels).is_ok()) << png;
  return pixels;
}

nlohmann::json frame_stats(const std::vector<std::string>& args, const std::string& name) {
  std::ifstream in(view_frame(args, "48x48", "--stats", name + ".json"));
  std::stringstream text;
  text << in.rdbuf();
  return nlohmann::json::parse(text.str(), nullptr, false);
}

// Pixels whose colours differ by more than one 8-bit level in some channel.
size_t differing(const std::vector<Rgb>& a, const std::vector<Rgb>& b) {
  if (a.size() != b.size()) return std::max(a.size(), b.size());
  size_t n = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    const float d = std::max({std::abs(a[i].r - b[i].r), std::abs(a[i].g - b[i].g), std::abs(a[i].b - b[i].b)});
    n += d > 1.5f / 255.0f ? 1 : 0;
  }
  return n;
}

// The still store frame equals the in-memory render of the store, shadows included: from the
// scene's camera and from one whose shadows come from outside the view, with a cache that
// holds the frame and with one a third of its cells (passes).
TEST(WalkthroughStill, StoreFrameEqualsTheInMemoryRenderWithShadows) {
  const std::vector<std::pair<std::string, std::string>> scenes = {{"tree", store_of(testing::spd("tree"), "tree")},
                                                                   {"shadow", store_of(tree_shadow_nff(), "shadow")}};
  for (const auto& [name, store] : scenes) {
    SCOPED_TRACE(name);
    const std::vector<Rgb> memory = frame_png({store, "--in-memory"}, name + "_memory");
    const std::vector<Rgb> unshadowed = frame_png({store, "--in-memory", "--no-shadows"}, name + "_unshadowed");
    ASSERT_EQ(memory.size(), 96u * 96u);
    ASSERT_GT(differing(memory, unshadowed), memory.size() / 50) << "the view was meant to show shadows";
    for (const char* cache : {"512M", "1300K"}) {
      SCOPED_TRACE(cache);
      const std::vector<Rgb> paged = frame_png({store, "--cache", cache}, name + "_paged_" + cache);
      EXPECT_EQ(differing(paged, memory), 0u);
      const nlohmann::json stats = frame_stats({store, "--cache", cache}, name + "_stats_" + cache);
      ASSERT_TRUE(stats.is_object());
      EXPECT_TRUE(stats.at("complete").get<bool>());
      EXPECT_TRUE(stats.at("shadows").get<bool>());
      EXPECT_GT(stats.at("shadow_rays").get<uint64_t>(), 0u);
    }
  }
}

std::vector<uint32_t> read_ids(const std::string& path) {
  const std::string bytes = proc::slurp(path);
  std::vector<uint32_t> ids(bytes.size() / sizeof(uint32_t));
  std::memcpy(ids.data(), bytes.data(), ids.size() * sizeof(uint32_t));
  return ids;
}

// A Draco store keeps its triangles on a lattice, within half a step of the model's; the store
// records the model's bounds. The in-memory render framed the decoded triangles' bounds instead
// of those, so without a camera in the store it looked from a camera a fraction of a pixel away
// from the paged frame's: 50 of 65 536 pixels differed on a 20 k-triangle terrain, all on edges
// (more here, with a coarse lattice). Now both equal brute force over the store's triangles from
// the camera framing the recorded bounds at every pixel but ties (two hits of different
// primitives within 1e-6 of each other: coplanar walls and floors of a building, where the two
// paths' trees, refined with different --cell-prims, pick different ones).
TEST(WalkthroughStill, LatticeStoreFrameEqualsTheInMemoryRenderUpToTies) {
  constexpr int kSize = 128;
  for (const char* kind : {"terrain", "building"}) {
    SCOPED_TRACE(kind);
    const std::string model = (scratch() / (std::string(kind) + "_draco.ply")).string();
    auto r = run_binary(proc::gen_binary(), {kind, "--triangles", "3000", "-o", model, "--quiet"}, scratch());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const std::string store = (scratch() / (std::string(kind) + "_draco.frontier")).string();
    r = run_binary(FRONTIER_BUILD_PATH, {model, "-o", store, "--codec", "draco", "--quant-bits", "10", "--quiet"},
                   scratch());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto paged = read_ids(view_frame({store}, "128x128", "--ids", std::string(kind) + "_paged.ids"));
    const auto memory =
        read_ids(view_frame({store, "--in-memory"}, "128x128", "--ids", std::string(kind) + "_memory.ids"));

    auto opened = StoreModel::open(store);
    ASSERT_TRUE(opened.is_ok()) << opened.status().to_string();
    Scene scene;
    std::vector<std::vector<uint32_t>> cell_prims;
    ASSERT_TRUE((*opened)->load_scene(scene, cell_prims).is_ok());
    const StoreModelInfo& info = (*opened)->info();
    ASSERT_FALSE(info.camera.has_value()) << "the test is about the automatic camera";
    const View view(automatic_camera(info.bounds), kSize, kSize);
    std::vector<uint32_t> reference;
    std::vector<uint8_t> tie;
    testing::brute_reference(scene, view, reference, tie);

    ASSERT_EQ(paged.size(), reference.size());
    ASSERT_EQ(memory.size(), reference.size());
    const testing::Comparison p = testing::compare_ids(reference, tie, paged, kSize);
    const testing::Comparison m = testing::compare_ids(reference, tie, memory, kSize);
    EXPECT_EQ(p.mismatches, 0u) << "paged: " << p.first_mismatch;
    EXPECT_EQ(m.mismatches, 0u) << "in memory: " << m.first_mismatch;
    size_t differ = 0, at_ties = 0;
    for (size_t i = 0; i < paged.size(); ++i) {
      if (paged[i] == memory[i]) continue;
      ++differ;
      at_ties += tie[i];
    }
    EXPECT_EQ(differ, at_ties) << "paged and in-memory ids differ where no two hits tie";
  }
}

// Demand 3: no shadow rays where the scene declares no lights or --no-shadows is given.
TEST(WalkthroughStill, NoShadowRaysWithoutLightsOrWithNoShadows) {
  const std::string building = (scratch() / "building.ply").string();
  const auto r = run_binary(proc::gen_binary(), {"building", "--triangles", "4000", "-o", building, "--quiet"},
                            scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json unlit = frame_stats({store_of(building, "building")}, "building");
  ASSERT_TRUE(unlit.is_object());
  EXPECT_TRUE(unlit.at("complete").get<bool>());
  EXPECT_FALSE(unlit.at("shadows").get<bool>());
  EXPECT_EQ(unlit.at("shadow_rays").get<uint64_t>(), 0u);
  const nlohmann::json off = frame_stats({store_of(testing::spd("tree"), "tree_off"), "--no-shadows"}, "tree_off");
  ASSERT_TRUE(off.is_object());
  EXPECT_TRUE(off.at("complete").get<bool>());
  EXPECT_FALSE(off.at("shadows").get<bool>());
  EXPECT_EQ(off.at("shadow_rays").get<uint64_t>(), 0u);
}

}  // namespace
}  // namespace frontier
