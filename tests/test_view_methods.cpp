// frontier-view's immediate-mode and BSP methods on a model file: IMR's ids equal ray walking's,
// the tessellated, Mesa and BSP images show the same objects at most pixels, every method writes
// its counters, and impossible options are refused with a message and a non-zero exit.
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

namespace frontier {
namespace {

const std::filesystem::path& scratch() { return testing::scratch_dir("frontier_view_methods"); }

std::vector<uint32_t> read_ids(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<uint32_t> ids;
  uint32_t v;
  while (in.read(reinterpret_cast<char*>(&v), sizeof v)) ids.push_back(v);
  return ids;
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

// Renders rings with `method` (plus `extra` options); returns its ids and stats.
struct Frame {
  std::vector<uint32_t> ids;
  nlohmann::json stats;
};
Frame render(const std::string& method, std::vector<std::string> extra = {}) {
  const std::string ids = (scratch() / (method + ".ids")).string(), stats = (scratch() / (method + ".json")).string();
  std::vector<std::string> args = {testing::spd("rings"), "--headless", "--size", "97x97", "--method", method,
                                   "--ids", ids, "--stats", stats, "--threads", "2", "--no-shadows"};
  args.insert(args.end(), extra.begin(), extra.end());
  const auto r = proc::run_binary(FRONTIER_VIEW_PATH, args, scratch());
  EXPECT_EQ(r.exit_code, 0) << method << ": " << r.err;
  return {read_ids(ids), read_json(stats)};
}

double agreement(const std::vector<uint32_t>& a, const std::vector<uint32_t>& b) {
  size_t same = 0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) same += a[i] == b[i];
  return a.empty() ? 0.0 : double(same) / double(a.size());
}

TEST(ViewMethods, ImrTessellatedMesaAndBspRenderTheModel) {
  const Frame reference = render("raywalk");
  ASSERT_EQ(reference.ids.size(), 97u * 97u);

  const Frame imr = render("imr", {"--order", "front-to-back"});
  ASSERT_EQ(imr.ids.size(), reference.ids.size());
  EXPECT_GE(agreement(imr.ids, reference.ids), 0.999);  // exact but ties
  EXPECT_GT(imr.stats["ray_object_tests"].get<uint64_t>(), 0u);
  EXPECT_LE(imr.stats["ray_object_hits"].get<uint64_t>(), imr.stats["ray_object_tests"].get<uint64_t>());
  EXPECT_EQ(imr.stats["texture_fetches"].get<uint64_t>(), 0u);
  EXPECT_EQ(imr.stats["order"], "front-to-back");

  for (const char* method : {"tessellated", "mesa"}) {
    const Frame f = render(method, {"--tessellation", "16"});
    EXPECT_GE(agreement(f.ids, reference.ids), 0.85) << method;
    EXPECT_EQ(f.stats["vertices_lit"].get<uint64_t>(), 3 * f.stats["triangles_issued"].get<uint64_t>()) << method;
    EXPECT_EQ(f.stats["triangles"].get<uint64_t>(), f.stats["triangles_issued"].get<uint64_t>()) << method;
    if (std::string(method) == "mesa") {
      EXPECT_NE(f.stats["renderer"].get<std::string>().find("llvmpipe"), std::string::npos) << f.stats["renderer"];
    }
  }

  const std::string tree_stats = (scratch() / "bsp_tree.json").string();
  const Frame painters = render("bsp", {"--tessellation", "6", "--bsp-candidates", "3", "--bsp-stats", tree_stats});
  EXPECT_GE(agreement(painters.ids, reference.ids), 0.85);
  const nlohmann::json tree = read_json(tree_stats);
  EXPECT_GE(tree["output_polygons"].get<uint64_t>(), tree["input_polygons"].get<uint64_t>());
  EXPECT_EQ(painters.stats["order"], "back-to-front");
  const Frame masked = render("bsp", {"--tessellation", "6", "--aa", "4x4"});
  EXPECT_GE(agreement(masked.ids, reference.ids), 0.85);
  EXPECT_EQ(masked.stats["aa"].get<int>(), 4);
}

TEST(ViewMethods, ImpossibleOptionsAreRefused) {
  for (const std::vector<std::string>& bad : std::vector<std::vector<std::string>>{
           {"--method", "bsp", "--aa", "3x3"},
           {"--method", "imr", "--bound-slices", "2"},
           {"--method", "imr", "--order", "sideways"},
           {"--method", "zbuffer"}}) {
    std::vector<std::string> args = {testing::spd("rings"), "--headless", "--size", "33x33"};
    args.insert(args.end(), bad.begin(), bad.end());
    const auto r = proc::run_binary(FRONTIER_VIEW_PATH, args, scratch());
    EXPECT_NE(r.exit_code, 0) << bad[1];
    EXPECT_NE(r.err.find(bad[bad.size() - 2]), std::string::npos) << r.err;
  }
}

}  // namespace
}  // namespace frontier
