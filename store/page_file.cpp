// POSIX implementation of the store's file interface.
#include "store/page_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace frontier::store {
namespace {

Status posix_error(const std::string& path, const char* what) {
  return Status::io_error(path + ": " + what + ": " + std::strerror(errno));
}

class PosixPageFile : public PageFile {
 public:
  PosixPageFile(int fd, uint64_t size, std::string name, bool cold)
      : fd_(fd), size_(size), name_(std::move(name)), cold_(cold) {}
  ~PosixPageFile() override { ::close(fd_); }

  Status read(uint64_t offset, size_t n, uint8_t* out) const override {
    if (offset > size_ || n > size_ - offset) {
      return Status::corruption(name_ + ": read of " + std::to_string(n) + " bytes at offset " +
                                std::to_string(offset) + " past the end of the file (" +
                                std::to_string(size_) + " bytes)");
    }
    size_t done = 0;
    while (done < n) {
      ssize_t r = ::pread(fd_, out + done, n - done, static_cast<off_t>(offset + done));
      if (r < 0) {
        if (errno == EINTR) continue;
        return posix_error(name_, "pread");
      }
      if (r == 0) {
        return Status::corruption(name_ + ": file shrank while reading at offset " +
                                  std::to_string(offset + done));
      }
      done += static_cast<size_t>(r);
    }
    if (cold_) {
      ::posix_fadvise(fd_, static_cast<off_t>(offset), static_cast<off_t>(n), POSIX_FADV_DONTNEED);
    }
    return Status::ok();
  }
  uint64_t size() const override { return size_; }
  const std::string& name() const override { return name_; }

 private:
  int fd_;
  uint64_t size_;
  std::string name_;
  bool cold_;
};

class PosixWritableFile : public WritableFile {
 public:
  PosixWritableFile(int fd, std::string path) : fd_(fd), path_(std::move(path)) {}
  ~PosixWritableFile() override {
    if (fd_ >= 0) ::close(fd_);
  }
  Status append(std::span<const uint8_t> bytes) override {
    size_t done = 0;
    while (done < bytes.size()) {
      ssize_t w = ::write(fd_, bytes.data() + done, bytes.size() - done);
      if (w < 0) {
        if (errno == EINTR) continue;
        return posix_error(path_, "write");
      }
      done += static_cast<size_t>(w);
    }
    return Status::ok();
  }
  Status sync() override {
    if (::fsync(fd_) != 0) return posix_error(path_, "fsync");
    return Status::ok();
  }
  Status close() override {
    int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) return posix_error(path_, "close");
    return Status::ok();
  }

 private:
  int fd_;
  std::string path_;
};

}  // namespace

Result<std::unique_ptr<PageFile>> PosixFileSystem::open_read(const std::string& path) {
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return Status::not_found(path + ": no such file");
    return posix_error(path, "open");
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    Status s = posix_error(path, "fstat");
    ::close(fd);
    return s;
  }
  return std::unique_ptr<PageFile>(
      new PosixPageFile(fd, static_cast<uint64_t>(st.st_size), path, cold_reads_));
}

Result<std::unique_ptr<WritableFile>> PosixFileSystem::create(const std::string& path) {
  int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return posix_error(path, "create");
  return std::unique_ptr<WritableFile>(new PosixWritableFile(fd, path));
}

Status PosixFileSystem::rename(const std::string& from, const std::string& to) {
  if (::rename(from.c_str(), to.c_str()) != 0) return posix_error(from, "rename");
  // Make the rename itself durable: fsync the directory that holds `to`.
  std::string dir = ".";
  if (auto slash = to.find_last_of('/'); slash != std::string::npos) {
    dir = slash == 0 ? "/" : to.substr(0, slash);
  }
  int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd < 0) return posix_error(dir, "open directory");
  int rc = ::fsync(dfd);
  ::close(dfd);
  if (rc != 0) return posix_error(dir, "fsync directory");
  return Status::ok();
}

Status PosixFileSystem::remove(const std::string& path) {
  if (::unlink(path.c_str()) != 0 && errno != ENOENT) return posix_error(path, "unlink");
  return Status::ok();
}

bool PosixFileSystem::exists(const std::string& path) { return ::access(path.c_str(), F_OK) == 0; }

}  // namespace frontier::store
