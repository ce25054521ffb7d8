// An in-memory FileSystem for tests, with fault injection: fail the Nth append, fail sync or
// rename, and corrupt stored bytes (flip, truncate, overwrite) after the fact.
//
// Invariants: every method is thread-safe (one mutex for the name table, one per file).
// Readers opened before a file is corrupted see the corruption on their next read; their size()
// stays the size at open time, as with a POSIX file that someone else truncates.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "store/page_file.h"

namespace frontier::store {

class MemFileSystem : public FileSystem {
 public:
  Result<std::unique_ptr<PageFile>> open_read(const std::string& path) override;
  Result<std::unique_ptr<WritableFile>> create(const std::string& path) override;
  Status rename(const std::string& from, const std::string& to) override;
  Status remove(const std::string& path) override;
  bool exists(const std::string& path) override;

  // --- fault injection -------------------------------------------------------------------
  // The n-th append from now on (1-based, counted across all files) returns IoError and writes
  // nothing; n <= 0 disables the fault.
  void fail_nth_append(int n);
  void fail_sync(bool fail);
  void fail_rename(bool fail);
  // Number of successful appends so far (to pick a fault position in range).
  int append_count() const;

  // --- inspection and corruption (REQUIRE: path exists) -------------------------------------
  std::vector<uint8_t> contents(const std::string& path) const;
  void set_contents(const std::string& path, std::vector<uint8_t> bytes);
  void flip_byte(const std::string& path, uint64_t offset, uint8_t mask = 0xFF);
  void truncate(const std::string& path, uint64_t size);
  std::vector<std::string> list() const;

  struct Node {
    mutable std::mutex mutex;
    std::vector<uint8_t> bytes;
  };

 private:
  friend class MemWritableFile;
  Status before_append();
  std::shared_ptr<Node> node(const std::string& path) const;

  mutable std::mutex mutex_;
  std::map<std::string, std::shared_ptr<Node>> files_;
  int appends_until_failure_ = 0;
  int appends_ = 0;
  bool fail_sync_ = false;
  bool fail_rename_ = false;
};

}  // namespace frontier::store
