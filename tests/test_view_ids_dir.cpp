// frontier-view --ids-dir: every frame of a walk along a path as DIR/frame_NNNNN.ids, in the
// --ids layout and numbered like --png-dir, headless and in the window replaying the path; a
// directory that cannot be made is an error naming it (exit 1); without a store, exit 2.
#include "preprocess/build.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_ids_dir"); }

// A small terrain, its store and a 3-frame orbit around it (made once per run).
struct Orbit {
  std::string model, store, path;
};
const Orbit& orbit() {
  static const Orbit o = [] {
    Orbit t;
    t.model = (scratch() / "terrain.ply").string();
    auto r = run_binary(proc::gen_binary(), {"terrain", "--grid", "40", "-q", "-o", t.model}, scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    t.path = (scratch() / "orbit.cam").string();
    r = run_binary(proc::gen_binary(), {"path", "--model", t.model, "--kind", "orbit", "--frames", "3", "-o", t.path},
                   scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    BuildOptions b;
    b.inputs = {t.model};
    b.output = t.store = (scratch() / "terrain.frontier").string();
    b.quiet = true;
    b.threads = 2;
    b.cell_prims = 64;
    auto report = build_store(b);
    EXPECT_TRUE(report.is_ok()) << report.status().to_string();
    return t;
  }();
  return o;
}

std::string bytes_of(const fs::path& p) { return proc::slurp(p); }

// DIR/frame_00000.ids .. frame_0000{frames-1}.ids exist with `bytes` each, and no more.
void expect_frame_files(const fs::path& dir, int frames, uintmax_t bytes) {
  for (int f = 0; f < frames; ++f) {
    const fs::path file = dir / ("frame_0000" + std::to_string(f) + ".ids");
    ASSERT_TRUE(fs::exists(file)) << file;
    EXPECT_EQ(fs::file_size(file), bytes) << file;
  }
  EXPECT_FALSE(fs::exists(dir / ("frame_0000" + std::to_string(frames) + ".ids")));
}

TEST(ViewIdsDir, HeadlessWalkWritesEveryFrame) {
  const Orbit& t = orbit();
  const fs::path dir = scratch() / "ids" / "nested", last = scratch() / "last.ids";
  const auto r = run_binary(FRONTIER_VIEW_PATH,
                            {t.store, "--headless", "--path", t.path, "--size", "64x48", "--cache", "64M", "--sync-paging",
                             "--threads", "2", "--ids-dir", dir.string(), "--ids", last.string()},
                            scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_frame_files(dir, 3, 64u * 48u * 4u);
  const std::string frame2 = bytes_of(dir / "frame_00002.ids");
  EXPECT_EQ(frame2, bytes_of(last)) << "the last frame's file differs from --ids";
  EXPECT_NE(frame2, std::string(frame2.size(), '\xff')) << "all background";
  EXPECT_NE(bytes_of(dir / "frame_00000.ids"), frame2) << "the orbit moved, the ids did not";
}

TEST(ViewIdsDir, ABadDirectoryIsAnError) {
  const Orbit& t = orbit();
  const fs::path file = scratch() / "a_file";
  std::ofstream(file) << "not a directory";
  for (const fs::path& dir : {file, file / "below"}) {
    const auto r = run_binary(FRONTIER_VIEW_PATH,
                              {t.store, "--headless", "--path", t.path, "--size", "32x24", "--ids-dir", dir.string()},
                              scratch());
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_NE(r.err.find("--ids-dir"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(dir.string()), std::string::npos) << r.err;
  }
  // A model file is one frame, not a walk: a bad option.
  const auto r = run_binary(FRONTIER_VIEW_PATH, {t.model, "--headless", "--ids-dir", (scratch() / "m").string()}, scratch());
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("--ids-dir"), std::string::npos) << r.err;
}

// The window replaying --path writes the same files (under Xvfb, as the other window tests).
TEST(ViewIdsDir, WindowReplayWritesEveryFrame) {
  const Orbit& t = orbit();
  ASSERT_EQ(std::system("test -x /usr/bin/xvfb-run"), 0) << "xvfb-run missing: .ci/install-deps installs xvfb";
  const fs::path dir = scratch() / "window_ids";
  const auto r = run_binary("/usr/bin/xvfb-run", {"-a", "-s", "-screen 0 640x480x24", FRONTIER_VIEW_PATH, t.store, "--path",
                                                  t.path, "--size", "48x32", "--threads", "2", "--ids-dir", dir.string()},
                            scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  expect_frame_files(dir, 3, 48u * 32u * 4u);
  // Without a path there are no frames to number: a bad option.
  const auto bad = run_binary(FRONTIER_VIEW_PATH, {t.store, "--ids-dir", dir.string()}, scratch());
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
}

}  // namespace
}  // namespace frontier
