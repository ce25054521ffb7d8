// The temporaries of a store build (preprocess/README.md "Temporaries") and how a build tells
// a dead build's leftovers from a live build's files.
//
//   DIR/.NAME.build-XXXXXX/   the spill files (parts, the ingest file, the collision grid's
//                             spill); DIR is --tmp-dir, or the output's folder by default.
//        lock                 "frontier-build pid P" — flock()ed (exclusive) by the build for
//                             its whole life: the kernel drops the lock when the process dies,
//                             however it dies.
//   OUT.tmp                   the store being written (StoreWriter), always beside OUT so that
//                             the rename is atomic; flock()ed likewise while the build runs.
//
// A directory or OUT.tmp whose lock can be taken belongs to no live build: it is a leftover, and
// the next build that looks removes it and says so. One that is locked is never touched. A
// directory without a lock file (made by a build killed between mkdtemp and the lock, or by a
// frontier-build older than the lock) is a leftover once it is 10 s old. Any `*.tmp` beside OUT
// that starts with the store magic is a store being written by some build (of any output): it
// is a leftover when its lock can be taken. A `*.tmp` without the magic is not ours and is left.
//
// A build stopped by a signal removes its own temporaries before it exits (remove_own_temporaries,
// called from the thread that handles the signal): every live BuildTempDir and StagingLock of the
// process is registered until its destructor runs.
#pragma once

#include "src/core/status.h"

#include <cstdint>
#include <string>
#include <vector>

namespace frontier {

// Something a dead build left behind and this build removed.
struct Leftover {
  std::string path;
  uint64_t bytes = 0;
};

// The bytes of the regular files under `dir` (0 when it cannot be read).
uint64_t bytes_under(const std::string& dir);

// "removed leftovers of a killed build: PATH (N MB)".
std::string describe(const Leftover& leftover);

// The build's temporary directory; removed with everything in it on destruction (the lock goes
// with it). Move-only.
class BuildTempDir {
 public:
  // Removes the leftovers of dead builds in `dir` (appended to `removed`), then creates and
  // locks DIR/.NAME.build-XXXXXX, NAME being the output's file name. IoError if it cannot.
  static Result<BuildTempDir> create(const std::string& dir, const std::string& output,
                                     std::vector<Leftover>& removed);
  BuildTempDir() = default;
  BuildTempDir(BuildTempDir&& o) noexcept;
  BuildTempDir& operator=(BuildTempDir&&) = delete;
  ~BuildTempDir();

  std::string file(const std::string& name) const;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  int lock_fd_ = -1;
};

// Ok when `dir` is an existing directory this process may create files in; else InvalidArgument
// "OPTION DIR: why" (a bad --tmp-dir is a bad option).
Status check_temp_dir(const std::string& dir, const std::string& option);

// Removes the leftovers of dead builds in `dir` (temporary directories of any output), appending
// them to `removed`. Locked (live) ones are left alone.
void remove_dead_temp_dirs(const std::string& dir, std::vector<Leftover>& removed);

// Ok when the file system of `dir` has `needed` bytes free for this user; else IoError "DIR: not
// enough free space for WHAT: about N MB needed, M MB free" (a failed write, found up front).
Status check_free_space(const std::string& dir, uint64_t needed, const std::string& what);

// Whether two existing paths are on one file system (false when either cannot be looked at).
bool same_file_system(const std::string& a, const std::string& b);

// Removes the stores dead builds were writing in `dir` (`*.tmp` files that start with the store
// magic and whose lock can be taken), appending them to `removed`.
void remove_dead_staging_files(const std::string& dir, std::vector<Leftover>& removed);

// Removes what this process's live BuildTempDirs and StagingLocks hold (the directories, and
// OUT.tmp while it is still the file the lock holds), appending them to `removed`. Leaves the
// registry locked: any thread that would make or release a temporary after this waits for ever.
// For the thread that handles a stopping signal; the process must _exit right after.
void remove_own_temporaries(std::vector<Leftover>& removed);

// OUT.tmp, claimed for this build: created if missing and locked until destruction. First the
// stores dead builds left in OUT's folder are removed (remove_dead_staging_files, reported in
// `removed`); one a live build holds at OUT.tmp makes claim() fail (IoError naming it): two builds
// of one output at once would write one file.
class StagingLock {
 public:
  static Result<StagingLock> claim(const std::string& output, std::vector<Leftover>& removed);
  StagingLock() = default;
  StagingLock(StagingLock&& o) noexcept;
  StagingLock& operator=(StagingLock&&) = delete;
  ~StagingLock();

 private:
  int fd_ = -1;
};

}  // namespace frontier
