// frontier-build's temporaries (preprocess/temp_dir.h): a killed build's leftovers are removed by
// the next build, which says so, whatever output that build writes; a live build's are never
// touched; a build stopped by SIGTERM or SIGINT removes its own; --tmp-dir puts them elsewhere
// and is checked like any option.
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <sys/file.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_build_temporaries"); }

// A terrain whose build with --memory 16M spills parts for a second or two.
std::string terrain() {
  const fs::path path = scratch() / "terrain.ply";
  if (!fs::exists(path)) {
    const auto r = run_binary(proc::gen_binary(), {"terrain", "--triangles", "1000000", "-o", path.string(), "--quiet"},
                              scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
  }
  return path.string();
}

// The build temporary directories (".NAME.build-XXXXXX") in `dir`.
std::vector<fs::path> temp_dirs(const fs::path& dir) {
  std::vector<fs::path> found;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().filename().string().find(".build-") != std::string::npos) found.push_back(it->path());
  }
  return found;
}

bool holds_files(const fs::path& dir) {
  std::error_code ec;
  size_t n = 0;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) ++n;
  return n > 1;  // more than its lock
}

// A temporary directory as a build makes it, with its lock file; `fd` (when not null) receives the
// lock file, flock()ed as a live build holds it.
fs::path fake_temp_dir(const fs::path& dir, const std::string& name, int* fd) {
  const fs::path path = dir / name;
  fs::create_directories(path);
  std::ofstream(path / "lock") << "frontier-build pid 1\n";
  std::ofstream(path / "part-0") << std::string(100000, 'x');
  if (fd != nullptr) {
    *fd = ::open((path / "lock").c_str(), O_RDONLY);
    EXPECT_EQ(::flock(*fd, LOCK_EX | LOCK_NB), 0);
  }
  return path;
}

TEST(BuildTemporaries, KilledBuildsLeftoversAreRemovedByTheNextBuildWhichSaysSo) {
  const std::string in = terrain();
  const fs::path dir = scratch() / "killed";
  fs::create_directories(dir);
  const fs::path out = dir / "k.frontier";
  const auto so = scratch() / "kill_out", se = scratch() / "kill_err";
  const pid_t pid = proc::spawn(FRONTIER_BUILD_PATH, {in, "-o", out.string(), "--quiet", "--memory", "16M"}, so, se);
  // Killed once it has spilled something.
  const auto start = std::chrono::steady_clock::now();
  std::vector<fs::path> temps;
  while (std::chrono::steady_clock::now() - start < std::chrono::seconds(60)) {
    temps = temp_dirs(dir);
    if (temps.size() == 1 && holds_files(temps[0])) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  ::kill(pid, SIGKILL);
  const auto killed = proc::finish(pid, so, se);
  ASSERT_EQ(killed.exit_code, 128 + SIGKILL) << killed.err;
  ASSERT_EQ(temps.size(), 1u);
  ASSERT_TRUE(fs::exists(temps[0]));
  ASSERT_TRUE(fs::exists(out.string() + ".tmp"));

  const auto next = run_binary(FRONTIER_BUILD_PATH, {testing::spd("rings"), "-o", out.string(), "--quiet"}, scratch());
  ASSERT_EQ(next.exit_code, 0) << next.err;
  EXPECT_NE(next.err.find("removed leftovers of a killed build: " + temps[0].string() + " ("), std::string::npos)
      << next.err;
  EXPECT_NE(next.err.find("removed leftovers of a killed build: " + out.string() + ".tmp ("), std::string::npos)
      << next.err;
  EXPECT_FALSE(fs::exists(temps[0]));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
  EXPECT_TRUE(temp_dirs(dir).empty());
}

// Waits until the build `pid` writing `out` in `dir` has spilled something and started OUT.tmp.
bool wait_until_spilling(const fs::path& dir, const fs::path& out) {
  const auto start = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - start < std::chrono::seconds(60)) {
    const std::vector<fs::path> temps = temp_dirs(dir);
    std::error_code ec;
    if (temps.size() == 1 && holds_files(temps[0]) && fs::file_size(out.string() + ".tmp", ec) >= 8 && !ec) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return false;
}

// Issue 43, item 1: the store a killed build was writing stayed through any number of builds of
// other outputs. Any dead build's `*.tmp` store beside the output is removed; a live build's, and
// a `*.tmp` that is not a store, are left.
TEST(BuildTemporaries, KilledBuildsStoreIsRemovedByABuildOfAnotherOutput) {
  const std::string in = terrain();
  const fs::path dir = scratch() / "killed_other";
  fs::create_directories(dir);
  const fs::path a = dir / "a.frontier", b = dir / "b.frontier";
  const auto so = scratch() / "kill_other_out", se = scratch() / "kill_other_err";
  const pid_t pid = proc::spawn(FRONTIER_BUILD_PATH, {in, "-o", a.string(), "--quiet", "--memory", "16M"}, so, se);
  const bool spilling = wait_until_spilling(dir, a);
  ::kill(pid, SIGKILL);
  const auto killed = proc::finish(pid, so, se);
  ASSERT_TRUE(spilling) << killed.err;
  ASSERT_EQ(killed.exit_code, 128 + SIGKILL) << killed.err;
  const std::string dead_store = a.string() + ".tmp";
  ASSERT_TRUE(fs::exists(dead_store));
  // A live build's store (locked) and a file of someone else's.
  const std::string live_store = (dir / "c.frontier.tmp").string(), foreign = (dir / "notes.tmp").string();
  std::ofstream(live_store) << "FRNTSTOR and the rest of a live build's store";
  std::ofstream(foreign) << "not a store";
  const int live_fd = ::open(live_store.c_str(), O_RDONLY);
  ASSERT_EQ(::flock(live_fd, LOCK_EX | LOCK_NB), 0);

  const auto next = run_binary(FRONTIER_BUILD_PATH, {testing::spd("rings"), "-o", b.string(), "--quiet"}, scratch());
  ASSERT_EQ(next.exit_code, 0) << next.err;
  EXPECT_NE(next.err.find("removed leftovers of a killed build: " + dead_store + " ("), std::string::npos) << next.err;
  EXPECT_FALSE(fs::exists(dead_store));
  EXPECT_TRUE(temp_dirs(dir).empty());
  EXPECT_TRUE(fs::exists(b));
  EXPECT_EQ(proc::slurp(live_store), "FRNTSTOR and the rest of a live build's store");
  EXPECT_EQ(proc::slurp(foreign), "not a store");
  EXPECT_EQ(next.err.find("c.frontier.tmp"), std::string::npos) << next.err;
  EXPECT_EQ(next.err.find("notes.tmp"), std::string::npos) << next.err;
  ::close(live_fd);
}

// Issue 43, item 2: SIGTERM (timeout, kill) and SIGINT (Ctrl-C) left the spill and OUT.tmp. The
// build removes what it wrote, says so and exits with 128 + the signal.
TEST(BuildTemporaries, StoppedBuildRemovesWhatItWroteAndSaysSo) {
  const std::string in = terrain();
  for (const int sig : {SIGTERM, SIGINT}) {
    const std::string name = sig == SIGTERM ? "SIGTERM" : "SIGINT";
    SCOPED_TRACE(name);
    const fs::path dir = scratch() / ("stopped_" + name);
    fs::create_directories(dir);
    const fs::path out = dir / "s.frontier";
    const auto so = scratch() / "stop_out", se = scratch() / "stop_err";
    const pid_t pid = proc::spawn(FRONTIER_BUILD_PATH, {in, "-o", out.string(), "--quiet", "--memory", "16M"}, so, se);
    const bool spilling = wait_until_spilling(dir, out);
    const std::vector<fs::path> temps = temp_dirs(dir);
    ::kill(pid, sig);
    const auto stopped = proc::finish(pid, so, se);
    ASSERT_TRUE(spilling) << stopped.err;
    EXPECT_EQ(stopped.exit_code, 128 + sig) << stopped.err;
    EXPECT_NE(stopped.err.find("frontier-build: stopped by " + name + "; removed "), std::string::npos) << stopped.err;
    ASSERT_EQ(temps.size(), 1u);
    EXPECT_NE(stopped.err.find(temps[0].string() + " ("), std::string::npos) << stopped.err;
    EXPECT_NE(stopped.err.find(out.string() + ".tmp ("), std::string::npos) << stopped.err;
    std::error_code ec;
    EXPECT_TRUE(fs::is_empty(dir, ec)) << "left in " << dir;
  }
}

TEST(BuildTemporaries, OnlyDeadBuildsTemporariesAreRemoved) {
  const fs::path dir = scratch() / "live";
  fs::create_directories(dir);
  const fs::path out = dir / "l.frontier";
  int live_fd = -1;
  // A live build of the same output (the old rule removed every ".l.frontier.build-*") and a dead
  // build of another output.
  const fs::path live = fake_temp_dir(dir, ".l.frontier.build-LIVE01", &live_fd);
  const fs::path dead = fake_temp_dir(dir, ".other.frontier.build-DEAD01", nullptr);
  const auto r = run_binary(FRONTIER_BUILD_PATH, {testing::spd("rings"), "-o", out.string(), "--quiet"}, scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::exists(live / "part-0")) << "a live build's temporaries were removed";
  EXPECT_EQ(r.err.find(live.string()), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dead));
  EXPECT_NE(r.err.find("removed leftovers of a killed build: " + dead.string() + " (0.1 MB)"), std::string::npos)
      << r.err;
  ::close(live_fd);
}

TEST(BuildTemporaries, ABuildOfAnOutputBeingBuiltIsRefused) {
  const fs::path dir = scratch() / "busy";
  fs::create_directories(dir);
  const fs::path out = dir / "b.frontier";
  const std::string staging = out.string() + ".tmp";
  std::ofstream(staging) << "a live build's store";
  const int fd = ::open(staging.c_str(), O_RDONLY);
  ASSERT_EQ(::flock(fd, LOCK_EX | LOCK_NB), 0);
  const auto r = run_binary(FRONTIER_BUILD_PATH, {testing::spd("rings"), "-o", out.string(), "--quiet"}, scratch());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find(staging + ": another frontier-build is writing"), std::string::npos) << r.err;
  EXPECT_EQ(proc::slurp(staging), "a live build's store");
  EXPECT_FALSE(fs::exists(out));
  EXPECT_TRUE(temp_dirs(dir).empty());
  ::close(fd);
}

TEST(BuildTemporaries, TmpDirHoldsTheTemporariesInsteadOfTheOutputFolder) {
  const std::string in = terrain();
  const fs::path dir = scratch() / "outdir", tmp = scratch() / "tmpdir";
  fs::create_directories(dir);
  fs::create_directories(tmp);
  const fs::path out = dir / "t.frontier";
  const auto so = scratch() / "tmp_out", se = scratch() / "tmp_err";
  const pid_t pid = proc::spawn(FRONTIER_BUILD_PATH,
                                {in, "-o", out.string(), "--quiet", "--memory", "16M", "--tmp-dir", tmp.string()}, so, se);
  // Watched until it exits (not reaped: proc::finish collects it).
  const auto running = [pid] {
    siginfo_t info{};
    return ::waitid(P_PID, static_cast<id_t>(pid), &info, WEXITED | WNOHANG | WNOWAIT) == 0 && info.si_pid == 0;
  };
  bool spilled_in_tmp = false, temp_beside_output = false;
  while (running()) {
    for (const fs::path& t : temp_dirs(tmp)) spilled_in_tmp |= holds_files(t);
    temp_beside_output |= !temp_dirs(dir).empty();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const auto r = proc::finish(pid, so, se);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(spilled_in_tmp);
  EXPECT_FALSE(temp_beside_output);
  EXPECT_TRUE(fs::exists(out));
  EXPECT_TRUE(temp_dirs(tmp).empty());
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
}

TEST(BuildTemporaries, BadTmpDirIsABadOption) {
  const fs::path out = scratch() / "bad_tmp.frontier";
  const fs::path missing = scratch() / "no_such_dir";
  auto r = run_binary(FRONTIER_BUILD_PATH, {testing::spd("rings"), "-o", out.string(), "--tmp-dir", missing.string()},
                      scratch());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("--tmp-dir " + missing.string()), std::string::npos) << r.err;
  const fs::path file = scratch() / "a_file";
  std::ofstream(file) << "x";
  r = run_binary(FRONTIER_BUILD_PATH, {testing::spd("rings"), "-o", out.string(), "--tmp-dir", file.string()},
                 scratch());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("not a directory"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out.string() + ".tmp"));
}

}  // namespace
}  // namespace frontier
