// Running the project's command-line tools from tests as users run them: a child process with
// captured stdout/stderr and its peak RSS (wait4), or one that is killed part way through.
#pragma once

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace frontier::proc {

// The frontier-gen binary of this build.
inline std::string gen_binary() {
#ifdef FRONTIER_GEN_PATH
  return FRONTIER_GEN_PATH;
#else
  return std::string(FRONTIER_BINARY_DIR) + "/data_gen/frontier-gen";
#endif
}

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

struct RunResult {
  int exit_code = -1;  // 128 + signal when killed
  std::string out, err;
  long max_rss_kb = 0;
};

// Starts `bin args...` with stdout/stderr redirected to files in `scratch`. Returns the pid.
inline pid_t spawn(const std::string& bin, const std::vector<std::string>& args, const std::filesystem::path& out,
                   const std::filesystem::path& err) {
  std::vector<std::string> argv_s = {bin};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fo = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int fe = ::open(err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fo, STDOUT_FILENO);
    ::dup2(fe, STDERR_FILENO);
    ::execv(bin.c_str(), argv.data());
    _exit(127);
  }
  return pid;
}

// Waits for `pid`; collects exit code, peak RSS and the captured output.
inline RunResult finish(pid_t pid, const std::filesystem::path& out, const std::filesystem::path& err) {
  RunResult r;
  int status = 0;
  struct rusage ru {};
  ::wait4(pid, &status, 0, &ru);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r.max_rss_kb = ru.ru_maxrss;
  r.out = slurp(out);
  r.err = slurp(err);
  std::error_code ec;
  std::filesystem::remove(out, ec);
  std::filesystem::remove(err, ec);
  return r;
}

// Runs `bin args...` to completion in a child process.
inline RunResult run_binary(const std::string& bin, const std::vector<std::string>& args,
                            const std::filesystem::path& scratch) {
  static int counter = 0;
  const auto out = scratch / ("stdout_" + std::to_string(counter));
  const auto err = scratch / ("stderr_" + std::to_string(counter++));
  return finish(spawn(bin, args, out, err), out, err);
}

}  // namespace frontier::proc
