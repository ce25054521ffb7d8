// Files of the tests: the shared test scenes and per-process scratch directories.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <system_error>

namespace frontier::testing {

// An SPD scene of ../shared/data/spd/ by name ("rings", "tree", "shells", ...).
inline std::string spd(const std::string& name) { return std::string(FRONTIER_DATA_DIR) + "/spd/" + name + ".nff"; }

// TMPDIR/PREFIX_PID, created on first use and removed with everything in it when the test
// program exits (child processes exec at once, so they never remove it).
inline const std::filesystem::path& scratch_dir(const std::string& prefix) {
  struct Dir {
    std::filesystem::path path;
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static std::mutex mutex;
  static std::map<std::string, Dir> dirs;
  std::lock_guard<std::mutex> lock(mutex);
  auto [it, fresh] = dirs.try_emplace(prefix);
  if (fresh) {
    it->second.path = std::filesystem::temp_directory_path() / (prefix + "_" + std::to_string(::getpid()));
    std::filesystem::create_directories(it->second.path);
  }
  return it->second.path;
}

}  // namespace frontier::testing
