// frontier-build's --memory bound: peak RSS of the build (the child's ru_maxrss, from wait4)
// stays within --memory plus the documented constant (kBuildMemoryOverhead, README) on an input
// whose in-core size is many times the budget.
#include "preprocess/build.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_build_memory"); }

// A frontier-gen terrain of about `triangles` triangles (binary PLY, the common large input).
std::string terrain(uint64_t triangles) {
  const fs::path path = scratch() / ("terrain_" + std::to_string(triangles) + ".ply");
  if (!fs::exists(path)) {
    const auto r = run_binary(proc::gen_binary(),
                              {"terrain", "--triangles", std::to_string(triangles), "-o", path.string(), "--quiet"},
                              scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
  }
  return path.string();
}

// One build with `memory` as its budget; returns its peak RSS in bytes (0 when it failed).
uint64_t peak_rss_of_build(const std::string& in, const std::string& memory, uint64_t budget) {
  const fs::path out = scratch() / "memory.frontier";
  const auto r = run_binary(FRONTIER_BUILD_PATH, {in, "-o", out.string(), "--memory", memory, "--threads", "2", "--proxy-triangles", "128"},
                            scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const uint64_t peak = static_cast<uint64_t>(r.max_rss_kb) * 1024;
  std::printf("--memory %s: peak RSS %.1f MiB (allowed %.1f MiB)\n%s", memory.c_str(),
              static_cast<double>(peak) / (1 << 20),
              static_cast<double>(budget + kBuildMemoryOverhead) / (1 << 20), r.err.c_str());
  fs::remove(out);
  return r.exit_code == 0 ? peak : 0;
}

TEST(BuildMemory, PeakRssStaysWithinTheBudgetPlusTheConstant) {
  const uint64_t triangles = 3000000;
  const std::string in = terrain(triangles);
  const uint64_t budget = uint64_t{32} << 20;
  // What the model takes in core is many times the budget, and so is the file itself.
  ASSERT_GE(triangles * kBytesPerPrimitive, 4 * budget);
  ASSERT_GE(fs::file_size(in) * 2, budget);
  const uint64_t peak = peak_rss_of_build(in, "32M", budget);
  ASSERT_GT(peak, 0u);
  EXPECT_LE(peak, budget + kBuildMemoryOverhead);
}

}  // namespace
}  // namespace frontier
