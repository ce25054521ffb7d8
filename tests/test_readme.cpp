// README.md's quick start is what a new user runs first: these tests hold its two commands to
// what the README says they do.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace {

// The ```sh blocks of README.md, in order.
std::vector<std::string> shell_blocks() {
  std::ifstream in(std::string(FRONTIER_SOURCE_DIR) + "/README.md");
  std::vector<std::string> blocks;
  std::string line, block;
  bool inside = false;
  while (std::getline(in, line)) {
    if (!inside && line == "```sh") {
      inside = true;
      block.clear();
    } else if (inside && line == "```") {
      inside = false;
      blocks.push_back(block);
    } else if (inside) {
      block += line + "\n";
    }
  }
  return blocks;
}

}  // namespace

// The main job builds exactly the programs it runs: no test binaries, no benchmarks (a fresh
// machine built 98 targets before doing anything).
TEST(Readme, MainJobBuildsOnlyTheProgramsItRuns) {
  const std::vector<std::string> blocks = shell_blocks();
  ASSERT_GE(blocks.size(), 2u);
  const std::string& main_job = blocks[0];
  std::set<std::string> run;
  const std::regex program(R"(build/[a-z_]+/(frontier-[a-z]+))");
  for (auto it = std::sregex_iterator(main_job.begin(), main_job.end(), program); it != std::sregex_iterator(); ++it) {
    run.insert((*it)[1]);
  }
  EXPECT_FALSE(run.empty());
  const std::regex build(R"(cmake --build build((?: --target(?: [a-z_-]+)+)?) )");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(main_job, m, build)) << main_job;
  std::set<std::string> targets;
  std::istringstream words(m[1].str());
  for (std::string w; words >> w;) {
    if (w != "--target") targets.insert(w);
  }
  EXPECT_EQ(targets, run) << "the main job must build exactly the programs it runs";
}

// The test command is the one CI runs (.ci/run).
TEST(Readme, TestCommandIsWhatCiRuns) {
  const std::vector<std::string> blocks = shell_blocks();
  ASSERT_GE(blocks.size(), 2u);
  std::ifstream ci(std::string(FRONTIER_SOURCE_DIR) + "/.ci/run");
  std::stringstream text;
  text << ci.rdbuf();
  std::string command = blocks[1];
  while (!command.empty() && command.back() == '\n') command.pop_back();
  EXPECT_NE(text.str().find(command), std::string::npos) << "README's test command is not in .ci/run";
}
