// The store's only contact with the operating system: a narrow file interface that tests replace
// with an in-memory one (store/mem_file.h). Everything above this layer (framing, the store
// reader and writer, the page cache) goes through these three interfaces.
//
// Invariants:
//  - PageFile is read-only and its read() may be called from any number of threads at once.
//  - WritableFile is single-threaded: one writer appends, syncs and closes.
//  - A failed call returns a non-ok Status naming the path; nothing throws.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "store/status.h"

namespace frontier::store {

// A random-access read-only file.
class PageFile {
 public:
  virtual ~PageFile() = default;
  // Reads exactly n bytes at offset into out (caller owns out, at least n bytes).
  // Returns Corruption if [offset, offset+n) reaches past the end of the file, IoError on a
  // failed read. Thread-safe.
  virtual Status read(uint64_t offset, size_t n, uint8_t* out) const = 0;
  // File size in bytes at open time. Thread-safe.
  virtual uint64_t size() const = 0;
  // Name used in error messages.
  virtual const std::string& name() const = 0;
};

// An append-only file being written. Not thread-safe.
class WritableFile {
 public:
  virtual ~WritableFile() = default;
  virtual Status append(std::span<const uint8_t> bytes) = 0;
  // Makes everything appended so far durable (fsync).
  virtual Status sync() = 0;
  // Closes the file; further calls are programmer errors. The destructor closes silently.
  virtual Status close() = 0;
};

// Creating, opening, renaming and removing files: the seam that tests replace.
class FileSystem {
 public:
  virtual ~FileSystem() = default;
  // Opens an existing file for reading. NotFound if it does not exist.
  virtual Result<std::unique_ptr<PageFile>> open_read(const std::string& path) = 0;
  // Creates (or truncates) a file for writing.
  virtual Result<std::unique_ptr<WritableFile>> create(const std::string& path) = 0;
  // Atomically replaces `to` with `from` and makes the rename durable.
  virtual Status rename(const std::string& from, const std::string& to) = 0;
  // Removes a file; removing a file that does not exist is ok.
  virtual Status remove(const std::string& path) = 0;
  virtual bool exists(const std::string& path) = 0;
};

// The real file system (POSIX pread/write/fsync/rename). Thread-safe.
class PosixFileSystem : public FileSystem {
 public:
  // cold_reads: after each read, posix_fadvise(DONTNEED) the range so that the next read of it
  // goes to the disk again. The OS page cache otherwise hides I/O cost (DESIGN.md, Known traps).
  explicit PosixFileSystem(bool cold_reads = false) : cold_reads_(cold_reads) {}
  Result<std::unique_ptr<PageFile>> open_read(const std::string& path) override;
  Result<std::unique_ptr<WritableFile>> create(const std::string& path) override;
  Status rename(const std::string& from, const std::string& to) override;
  Status remove(const std::string& path) override;
  bool exists(const std::string& path) override;

 private:
  bool cold_reads_;
};

}  // namespace frontier::store
