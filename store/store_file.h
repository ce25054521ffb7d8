// StoreWriter and StoreReader: one store file (layout in store/FORMAT.md).
//
// Writer protocol (why a killed build never leaves a half store under the real name):
//   create NAME.tmp -> header -> pages and sections -> "pages" index -> directory -> footer
//   -> fsync -> close -> rename(NAME.tmp, NAME) -> fsync the directory.
// On any error the writer removes NAME.tmp at once and every later call returns that first error;
// a writer destroyed without finish() (an exception, an early return) removes NAME.tmp too. A
// process killed mid-write can leave NAME.tmp behind (nothing can remove it); it is never read,
// and the next writer for NAME truncates it. An existing NAME is replaced only by the rename.
//
// Reader: open() validates footer, header and directory (all checksummed) and the bounds of
// every handle before returning; pages are read and checked lazily by read_page(), or all at
// once by verify(). A reader is immutable after open and all const methods are thread-safe.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "store/page_file.h"
#include "store/page_format.h"
#include "store/page_id.h"

namespace frontier::store {

inline constexpr std::string_view kPagesSection = "pages";

// A decoded block owned by the caller.
struct OwnedPage {
  uint8_t codec = kCodecRaw;
  std::vector<uint8_t> payload;
};

class StoreWriter {
 public:
  // Creates path + ".tmp". `fs` must outlive the writer. Not thread-safe.
  static Result<std::unique_ptr<StoreWriter>> create(FileSystem& fs, std::string path);
  ~StoreWriter();  // removes the .tmp unless finish() succeeded
  StoreWriter(const StoreWriter&) = delete;
  StoreWriter& operator=(const StoreWriter&) = delete;

  // Appends a page; its id is the number of pages added before it.
  Result<PageId> add_page(uint8_t codec, std::span<const uint8_t> payload);
  // Appends a named section ("cells", "tree", "sdf", ...), stored as one raw block.
  // InvalidArgument for an empty, too long, duplicate or reserved ("pages") name.
  Status add_section(std::string_view name, std::span<const uint8_t> payload);
  // Writes the page index, directory and footer, syncs and renames to the final name.
  Status finish();

  const std::string& path() const { return path_; }

 private:
  StoreWriter(FileSystem& fs, std::string path, std::unique_ptr<WritableFile> file);
  Result<Handle> append_block(uint8_t codec, std::span<const uint8_t> payload);
  Status fail(Status s);  // records the first error and removes the .tmp

  FileSystem& fs_;
  std::string path_;
  std::string tmp_path_;
  std::unique_ptr<WritableFile> file_;
  uint64_t offset_ = 0;
  std::vector<Handle> pages_;
  std::vector<Section> sections_;
  Status error_;
  bool finished_ = false;
};

class StoreReader {
 public:
  // Opens and validates a store. NotFound, IoError, Corruption (naming the bad part), or
  // Unsupported (newer version). `fs` is only used during open.
  static Result<std::unique_ptr<StoreReader>> open(FileSystem& fs, const std::string& path);
  static Result<std::unique_ptr<StoreReader>> open(std::unique_ptr<PageFile> file);

  uint32_t version() const { return version_; }
  uint64_t file_size() const { return file_->size(); }
  const std::string& name() const { return file_->name(); }

  size_t page_count() const { return pages_.size(); }
  // REQUIRES: id < page_count().
  Handle page_handle(PageId id) const { return pages_.at(id); }
  // Reads and checks one page. Corruption naming the page's offset on a mismatch. Thread-safe.
  Result<OwnedPage> read_page(PageId id) const;
  // Reads and checks any block by handle (bounds-checked against the data region).
  Result<OwnedPage> read_block(Handle handle) const;

  const std::vector<Section>& sections() const { return sections_; }
  std::optional<Handle> section(std::string_view name) const;
  // NotFound if there is no such section.
  Result<std::vector<uint8_t>> read_section(std::string_view name) const;

  // Reads every section and every page and checks every checksum; returns the first bad one.
  Status verify() const;

 private:
  explicit StoreReader(std::unique_ptr<PageFile> file) : file_(std::move(file)) {}
  Status check_handle(Handle h, const char* what) const;

  std::unique_ptr<PageFile> file_;
  uint32_t version_ = 0;
  uint64_t data_end_ = 0;  // directory offset: pages and sections lie in [kHeaderSize, data_end_)
  std::vector<Section> sections_;
  std::vector<Handle> pages_;
};

}  // namespace frontier::store
