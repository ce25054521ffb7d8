#include "store/store_file.h"

#include <cassert>

namespace frontier::store {

// --- StoreWriter -----------------------------------------------------------------------------

StoreWriter::StoreWriter(FileSystem& fs, std::string path, std::unique_ptr<WritableFile> file)
    : fs_(fs), path_(std::move(path)), tmp_path_(path_ + ".tmp"), file_(std::move(file)) {}

Result<std::unique_ptr<StoreWriter>> StoreWriter::create(FileSystem& fs, std::string path) {
  auto file = fs.create(path + ".tmp");
  if (!file) return file.status();
  std::unique_ptr<StoreWriter> w(new StoreWriter(fs, std::move(path), std::move(file.value())));
  auto header = encode_header(Header{});
  if (Status s = w->file_->append(header); !s) return w->fail(s);
  w->offset_ = kHeaderSize;
  return w;
}

StoreWriter::~StoreWriter() {
  if (!finished_ && error_.is_ok()) {
    file_.reset();
    fs_.remove(tmp_path_);
  }
}

Status StoreWriter::fail(Status s) {
  if (error_.is_ok()) {
    error_ = s;
    file_.reset();
    fs_.remove(tmp_path_);
  }
  return error_;
}

Result<Handle> StoreWriter::append_block(uint8_t codec, std::span<const uint8_t> payload) {
  if (!error_) return error_;
  assert(!finished_ && "StoreWriter used after finish()");
  std::vector<uint8_t> block = encode_page(codec, payload);
  if (Status s = file_->append(block); !s) return fail(s);
  Handle h{offset_, block.size()};
  offset_ += block.size();
  return h;
}

Result<PageId> StoreWriter::add_page(uint8_t codec, std::span<const uint8_t> payload) {
  auto h = append_block(codec, payload);
  if (!h) return h.status();
  pages_.push_back(h.value());
  return static_cast<PageId>(pages_.size() - 1);
}

Status StoreWriter::add_section(std::string_view name, std::span<const uint8_t> payload) {
  if (!error_) return error_;
  if (name.empty() || name.size() > kMaxSectionName || name == kPagesSection) {
    return Status::invalid_argument(path_ + ": bad section name \"" + std::string(name) + "\"");
  }
  for (const Section& s : sections_) {
    if (s.name == name) {
      return Status::invalid_argument(path_ + ": duplicate section \"" + std::string(name) + "\"");
    }
  }
  auto h = append_block(kCodecRaw, payload);
  if (!h) return h.status();
  sections_.push_back({std::string(name), h.value()});
  return Status::ok();
}

Status StoreWriter::finish() {
  if (!error_) return error_;
  assert(!finished_);
  auto index = append_block(kCodecRaw, encode_page_index(pages_));
  if (!index) return index.status();
  std::vector<Section> all = sections_;
  all.push_back({std::string(kPagesSection), index.value()});
  auto dir = append_block(kCodecRaw, encode_directory(all));
  if (!dir) return dir.status();
  auto footer = encode_footer(Footer{dir.value(), kFormatVersion});
  if (Status s = file_->append(footer); !s) return fail(s);
  offset_ += kFooterSize;
  if (Status s = file_->sync(); !s) return fail(s);
  if (Status s = file_->close(); !s) return fail(s);
  if (Status s = fs_.rename(tmp_path_, path_); !s) return fail(s);
  finished_ = true;
  return Status::ok();
}

// --- StoreReader -----------------------------------------------------------------------------

Result<std::unique_ptr<StoreReader>> StoreReader::open(FileSystem& fs, const std::string& path) {
  auto file = fs.open_read(path);
  if (!file) return file.status();
  return open(std::move(file.value()));
}

Result<std::unique_ptr<StoreReader>> StoreReader::open(std::unique_ptr<PageFile> file) {
  std::unique_ptr<StoreReader> r(new StoreReader(std::move(file)));
  const std::string& name = r->file_->name();
  uint64_t size = r->file_->size();
  if (size < kHeaderSize + kFooterSize) {
    return Status::corruption(name + ": truncated store (" + std::to_string(size) +
                              " bytes is smaller than header + footer)");
  }
  std::array<uint8_t, kFooterSize> fbytes{};
  if (Status s = r->file_->read(size - kFooterSize, kFooterSize, fbytes.data()); !s) return s;
  auto footer = decode_footer(fbytes, name);
  if (!footer) return footer.status();

  std::array<uint8_t, kHeaderSize> hbytes{};
  if (Status s = r->file_->read(0, kHeaderSize, hbytes.data()); !s) return s;
  auto header = decode_header(hbytes, name);
  if (!header) return header.status();
  if (header->version != footer->version) {
    return Status::corruption(name + ": header version " + std::to_string(header->version) +
                              " differs from footer version " + std::to_string(footer->version));
  }
  r->version_ = footer->version;

  // The directory must lie between the header and the footer and end where the footer starts.
  Handle dir = footer->directory;
  if (dir.offset < kHeaderSize || dir.offset > size - kFooterSize ||
      dir.size != size - kFooterSize - dir.offset || dir.size < kBlockTrailerSize) {
    return Status::corruption(name + ": directory handle out of bounds");
  }
  r->data_end_ = dir.offset;
  std::vector<uint8_t> dbytes(dir.size);
  if (Status s = r->file_->read(dir.offset, dir.size, dbytes.data()); !s) return s;
  auto decoded = decode_page(dbytes, dir);
  if (!decoded) return Status::corruption(name + ": directory: " + decoded.status().message());
  auto sections = decode_directory(decoded->payload, dir, name);
  if (!sections) return sections.status();
  r->sections_ = std::move(sections.value());
  for (const Section& s : r->sections_) {
    if (Status st = r->check_handle(s.handle, "section"); !st) return st;
  }

  auto index = r->read_section(kPagesSection);
  if (!index) return index.status();
  auto pages = decode_page_index(index.value(), *r->section(kPagesSection), name);
  if (!pages) return pages.status();
  r->pages_ = std::move(pages.value());
  for (const Handle& h : r->pages_) {
    if (Status st = r->check_handle(h, "page"); !st) return st;
  }
  return r;
}

Status StoreReader::check_handle(Handle h, const char* what) const {
  if (h.offset < kHeaderSize || h.offset > data_end_ || h.size > data_end_ - h.offset ||
      h.size < kBlockTrailerSize) {
    return Status::corruption(name() + ": " + what + " handle {" + std::to_string(h.offset) +
                              ", " + std::to_string(h.size) + "} out of bounds");
  }
  return Status::ok();
}

Result<OwnedPage> StoreReader::read_block(Handle handle) const {
  if (Status s = check_handle(handle, "block"); !s) return s;
  std::vector<uint8_t> bytes(handle.size);
  if (Status s = file_->read(handle.offset, handle.size, bytes.data()); !s) return s;
  auto decoded = decode_page(bytes, handle);
  if (!decoded) return Status::corruption(name() + ": " + decoded.status().message());
  OwnedPage page{decoded->codec, {}};
  // The payload is the front of `bytes`: drop the trailer instead of copying.
  bytes.resize(decoded->payload.size());
  page.payload = std::move(bytes);
  return page;
}

Result<OwnedPage> StoreReader::read_page(PageId id) const {
  if (id >= pages_.size()) {
    return Status::invalid_argument(name() + ": page " + std::to_string(id) + " does not exist (" +
                                    std::to_string(pages_.size()) + " pages)");
  }
  return read_block(pages_[id]);
}

std::optional<Handle> StoreReader::section(std::string_view name_) const {
  for (const Section& s : sections_) {
    if (s.name == name_) return s.handle;
  }
  return std::nullopt;
}

Result<std::vector<uint8_t>> StoreReader::read_section(std::string_view section_name) const {
  auto h = section(section_name);
  if (!h) {
    return Status::not_found(name() + ": no section \"" + std::string(section_name) + "\"");
  }
  auto block = read_block(*h);
  if (!block) return block.status();
  if (block->codec != kCodecRaw) {
    return Status::corruption(name() + ": section \"" + std::string(section_name) +
                              "\" is not raw");
  }
  return std::move(block->payload);
}

Status StoreReader::verify() const {
  for (const Section& s : sections_) {
    auto block = read_block(s.handle);
    if (!block) return block.status();
  }
  for (const Handle& h : pages_) {
    auto block = read_block(h);
    if (!block) return block.status();
  }
  return Status::ok();
}

}  // namespace frontier::store
