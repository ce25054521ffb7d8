// A build's temporaries and their locks (contract and layout in temp_dir.h).
#include "preprocess/temp_dir.h"

#include "store/page_format.h"

#include <fmt/format.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <utility>

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

namespace frontier {
namespace {

namespace fs = std::filesystem;

constexpr const char* kLockName = "lock";
constexpr const char* kLockSignature = "frontier-build";
// A directory without a finished lock is this old before it counts as a leftover: a live build
// writes its lock microseconds after mkdtemp.
constexpr auto kUnlockedGrace = std::chrono::seconds(10);

// .NAME.build-XXXXXX (mkdtemp's six characters).
bool is_temp_dir_name(const std::string& name) {
  const size_t at = name.rfind(".build-");
  return name.size() > 1 && name[0] == '.' && at != std::string::npos && at > 0 && name.size() == at + 7 + 6;
}

// The temporaries this process holds now, for remove_own_temporaries: the directories, and each
// OUT.tmp with the descriptor that holds its lock. Each is made and enrolled under the mutex, so
// that once remove_own_temporaries holds it nothing new appears. Never destroyed: a signal may
// come while the process exits.
struct Registry {
  std::mutex mutex;
  std::vector<std::string> dirs;
  std::vector<std::pair<std::string, int>> staging;
};

Registry& registry() {
  static Registry* r = new Registry;
  return *r;
}

void forget_dir(const std::string& path) {
  Registry& r = registry();
  std::lock_guard<std::mutex> hold(r.mutex);
  std::erase(r.dirs, path);
}

void forget_staging(int fd) {
  Registry& r = registry();
  std::lock_guard<std::mutex> hold(r.mutex);
  std::erase_if(r.staging, [fd](const auto& s) { return s.second == fd; });
}

// Whether `fd` is the file at `path` now (not one removed and made again under its name).
bool is_named(int fd, const std::string& path) {
  struct stat held {}, named {};
  return ::fstat(fd, &held) == 0 && ::lstat(path.c_str(), &named) == 0 && held.st_dev == named.st_dev &&
         held.st_ino == named.st_ino;
}

std::string folder_of(const std::string& file) {
  const fs::path p(file);
  return p.has_parent_path() ? p.parent_path().string() : std::string(".");
}

bool older_than_grace(const fs::path& p) {
  std::error_code ec;
  const auto written = fs::last_write_time(p, ec);
  return !ec && fs::file_time_type::clock::now() - written > kUnlockedGrace;
}

// Whether the temporary directory `dir` belongs to no live build. `lock_fd` receives the lock
// file, held locked when the answer is yes (the caller closes it after removing the directory).
bool is_dead(const fs::path& dir, int& lock_fd) {
  lock_fd = ::open((dir / kLockName).c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
  if (lock_fd < 0) return errno == ENOENT && older_than_grace(dir);
  if (::flock(lock_fd, LOCK_EX | LOCK_NB) != 0) return false;  // a live build holds it
  char head[32] = {};
  const ssize_t got = ::pread(lock_fd, head, sizeof(head) - 1, 0);
  const bool signed_lock = got > 0 && std::strncmp(head, kLockSignature, std::strlen(kLockSignature)) == 0;
  // A lock without the signature is not ours; an empty one may be a live build's between
  // creating its lock and writing it.
  if (got > 0 ? signed_lock : older_than_grace(dir / kLockName)) return true;
  ::close(lock_fd);
  lock_fd = -1;
  return false;
}

}  // namespace

uint64_t bytes_under(const std::string& dir) {
  uint64_t bytes = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code size_ec;
    if (it->is_regular_file(size_ec)) bytes += it->file_size(size_ec);
  }
  return bytes;
}

Status check_temp_dir(const std::string& dir, const std::string& option) {
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0) {
    return Status::invalid_argument(fmt::format("{} {}: {}", option, dir, std::strerror(errno)));
  }
  if (!S_ISDIR(st.st_mode)) return Status::invalid_argument(fmt::format("{} {}: not a directory", option, dir));
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    return Status::invalid_argument(fmt::format("{} {}: not writable: {}", option, dir, std::strerror(errno)));
  }
  return Status::ok();
}

Status check_free_space(const std::string& dir, uint64_t needed, const std::string& what) {
  struct statvfs fs {};
  if (::statvfs(dir.c_str(), &fs) != 0) return Status::ok();  // cannot tell: the writes will
  const uint64_t free = static_cast<uint64_t>(fs.f_bavail) * fs.f_frsize;
  if (needed <= free) return Status::ok();
  return Status::io_error(fmt::format("{}: not enough free space for {}: about {:.1f} MB needed, {:.1f} MB free", dir,
                                      what, static_cast<double>(needed) / 1e6, static_cast<double>(free) / 1e6));
}

bool same_file_system(const std::string& a, const std::string& b) {
  struct stat sa {}, sb {};
  return ::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev;
}

std::string describe(const Leftover& leftover) {
  return fmt::format("removed leftovers of a killed build: {} ({:.1f} MB)", leftover.path,
                     static_cast<double>(leftover.bytes) / 1e6);
}

void remove_dead_temp_dirs(const std::string& dir, std::vector<Leftover>& removed) {
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path path = it->path();
    std::error_code type_ec;
    if (!is_temp_dir_name(path.filename().string()) || !fs::is_directory(fs::symlink_status(path, type_ec))) continue;
    int lock_fd = -1;
    if (is_dead(path, lock_fd)) {
      Leftover leftover{path.string(), bytes_under(path.string())};
      std::error_code remove_ec;
      fs::remove_all(path, remove_ec);
      if (!remove_ec) removed.push_back(std::move(leftover));
    }
    if (lock_fd >= 0) ::close(lock_fd);
  }
}

Result<BuildTempDir> BuildTempDir::create(const std::string& dir, const std::string& output,
                                          std::vector<Leftover>& removed) {
  remove_dead_temp_dirs(dir, removed);
  std::string pattern = (fs::path(dir) / ("." + fs::path(output).filename().string() + ".build-XXXXXX")).string();
  BuildTempDir t;
  {
    std::lock_guard<std::mutex> hold(registry().mutex);
    if (::mkdtemp(pattern.data()) == nullptr) {
      return Status::io_error(fmt::format("{}: cannot create a temporary directory: {}", pattern, std::strerror(errno)));
    }
    t.path_ = pattern;  // from here on the destructor removes it
    registry().dirs.push_back(pattern);
  }
  const std::string lock = t.file(kLockName);
  t.lock_fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (t.lock_fd_ < 0 || ::flock(t.lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    return Status::io_error(fmt::format("{}: cannot create and lock: {}", lock, std::strerror(errno)));
  }
  const std::string text = fmt::format("{} pid {}\n", kLockSignature, ::getpid());
  if (::pwrite(t.lock_fd_, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size())) {
    return Status::io_error(fmt::format("{}: cannot write: {}", lock, std::strerror(errno)));
  }
  return t;
}

BuildTempDir::BuildTempDir(BuildTempDir&& o) noexcept
    : path_(std::exchange(o.path_, {})), lock_fd_(std::exchange(o.lock_fd_, -1)) {}

BuildTempDir::~BuildTempDir() {
  std::error_code ec;
  if (!path_.empty()) {
    forget_dir(path_);
    fs::remove_all(path_, ec);  // before the lock goes: no one else removes it
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

std::string BuildTempDir::file(const std::string& name) const { return (fs::path(path_) / name).string(); }

void remove_dead_staging_files(const std::string& dir, std::vector<Leftover>& removed) {
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path path = it->path();
    const std::string name = path.filename().string();
    std::error_code type_ec;
    if (name.size() <= 4 || !name.ends_with(".tmp") || !fs::is_regular_file(fs::symlink_status(path, type_ec))) {
      continue;
    }
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
    if (fd < 0) continue;
    // Locked: a live build's. Without the magic: not a store (an empty one may be a live build's
    // between creating and locking it), so not ours to judge.
    char head[store::kMagic.size()] = {};
    struct stat st {};
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0 && ::pread(fd, head, sizeof head, 0) == static_cast<ssize_t>(sizeof head) &&
        std::memcmp(head, store::kMagic.data(), sizeof head) == 0 && ::fstat(fd, &st) == 0 &&
        is_named(fd, path.string()) && ::unlink(path.c_str()) == 0) {
      removed.push_back({path.string(), static_cast<uint64_t>(st.st_size)});
    }
    ::close(fd);
  }
}

void remove_own_temporaries(std::vector<Leftover>& removed) {
  Registry& r = registry();
  r.mutex.lock();  // never unlocked: the process exits next
  for (const auto& [path, fd] : r.staging) {
    struct stat st {};
    // After the rename the lock holds OUT, and OUT.tmp, if any, is another build's.
    if (::fstat(fd, &st) == 0 && is_named(fd, path) && ::unlink(path.c_str()) == 0) {
      removed.push_back({path, static_cast<uint64_t>(st.st_size)});
    }
  }
  for (const std::string& dir : r.dirs) {
    Leftover leftover{dir, bytes_under(dir)};
    // The build's threads may still be making files in it: go on until it is gone.
    std::error_code ec;
    for (int attempt = 0; attempt < 100 && fs::exists(dir, ec); ++attempt) fs::remove_all(dir, ec);
    if (!fs::exists(dir, ec)) removed.push_back(std::move(leftover));
  }
}

Result<StagingLock> StagingLock::claim(const std::string& output, std::vector<Leftover>& removed) {
  remove_dead_staging_files(folder_of(output), removed);
  const std::string path = output + ".tmp";
  StagingLock l;
  // Another build may remove a dead store at `path` between our open and our lock; the lock then
  // holds a file no longer there, and the path is opened again.
  for (int attempt = 0;; ++attempt) {
    {
      std::lock_guard<std::mutex> hold(registry().mutex);
      l.fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
      if (l.fd_ < 0) return Status::io_error(fmt::format("{}: cannot create: {}", path, std::strerror(errno)));
      registry().staging.emplace_back(path, l.fd_);
    }
    if (::flock(l.fd_, LOCK_EX | LOCK_NB) != 0) {
      return Status::io_error(fmt::format("{}: another frontier-build is writing {} now", path, output));
    }
    if (is_named(l.fd_, path) || attempt == 2) break;
    forget_staging(l.fd_);
    ::close(l.fd_);
    l.fd_ = -1;
  }
  struct stat st {};
  if (::fstat(l.fd_, &st) == 0 && st.st_size > 0) {  // a dead build's store, cut short
    removed.push_back({path, static_cast<uint64_t>(st.st_size)});
    if (::ftruncate(l.fd_, 0) != 0) return Status::io_error(fmt::format("{}: cannot empty: {}", path, std::strerror(errno)));
  }
  return l;
}

StagingLock::StagingLock(StagingLock&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}

StagingLock::~StagingLock() {
  if (fd_ >= 0) {
    forget_staging(fd_);
    ::close(fd_);
  }
}

}  // namespace frontier
