#include "store/mem_file.h"

#include <cassert>
#include <cstring>

namespace frontier::store {
namespace {

class MemPageFile : public PageFile {
 public:
  MemPageFile(std::shared_ptr<MemFileSystem::Node> node, uint64_t size, std::string name)
      : node_(std::move(node)), size_(size), name_(std::move(name)) {}
  Status read(uint64_t offset, size_t n, uint8_t* out) const override {
    std::lock_guard lock(node_->mutex);
    uint64_t now = node_->bytes.size();
    if (offset > size_ || n > size_ - offset || offset + n > now) {
      return Status::corruption(name_ + ": read of " + std::to_string(n) + " bytes at offset " +
                                std::to_string(offset) + " past the end of the file (" +
                                std::to_string(now) + " bytes)");
    }
    if (n > 0) std::memcpy(out, node_->bytes.data() + offset, n);
    return Status::ok();
  }
  uint64_t size() const override { return size_; }
  const std::string& name() const override { return name_; }

 private:
  std::shared_ptr<MemFileSystem::Node> node_;
  uint64_t size_;
  std::string name_;
};

}  // namespace

class MemWritableFile : public WritableFile {
 public:
  MemWritableFile(MemFileSystem* fs, std::shared_ptr<MemFileSystem::Node> node, std::string path)
      : fs_(fs), node_(std::move(node)), path_(std::move(path)) {}
  Status append(std::span<const uint8_t> bytes) override {
    assert(!closed_);
    if (Status s = fs_->before_append(); !s) return Status::io_error(path_ + ": " + s.message());
    std::lock_guard lock(node_->mutex);
    node_->bytes.insert(node_->bytes.end(), bytes.begin(), bytes.end());
    return Status::ok();
  }
  Status sync() override {
    std::lock_guard lock(fs_->mutex_);
    if (fs_->fail_sync_) return Status::io_error(path_ + ": injected sync failure");
    return Status::ok();
  }
  Status close() override {
    closed_ = true;
    return Status::ok();
  }

 private:
  MemFileSystem* fs_;
  std::shared_ptr<MemFileSystem::Node> node_;
  std::string path_;
  bool closed_ = false;
};

Status MemFileSystem::before_append() {
  std::lock_guard lock(mutex_);
  if (appends_until_failure_ > 0 && --appends_until_failure_ == 0) {
    return Status::io_error("injected append failure");
  }
  ++appends_;
  return Status::ok();
}

std::shared_ptr<MemFileSystem::Node> MemFileSystem::node(const std::string& path) const {
  std::lock_guard lock(mutex_);
  auto it = files_.find(path);
  assert(it != files_.end());
  return it->second;
}

Result<std::unique_ptr<PageFile>> MemFileSystem::open_read(const std::string& path) {
  std::shared_ptr<Node> n;
  {
    std::lock_guard lock(mutex_);
    auto it = files_.find(path);
    if (it == files_.end()) return Status::not_found(path + ": no such file");
    n = it->second;
  }
  uint64_t size;
  {
    std::lock_guard lock(n->mutex);
    size = n->bytes.size();
  }
  return std::unique_ptr<PageFile>(new MemPageFile(std::move(n), size, path));
}

Result<std::unique_ptr<WritableFile>> MemFileSystem::create(const std::string& path) {
  auto n = std::make_shared<Node>();
  {
    std::lock_guard lock(mutex_);
    files_[path] = n;
  }
  return std::unique_ptr<WritableFile>(new MemWritableFile(this, std::move(n), path));
}

Status MemFileSystem::rename(const std::string& from, const std::string& to) {
  std::lock_guard lock(mutex_);
  if (fail_rename_) return Status::io_error(from + ": injected rename failure");
  auto it = files_.find(from);
  if (it == files_.end()) return Status::not_found(from + ": no such file");
  files_[to] = it->second;
  files_.erase(from);
  return Status::ok();
}

Status MemFileSystem::remove(const std::string& path) {
  std::lock_guard lock(mutex_);
  files_.erase(path);
  return Status::ok();
}

bool MemFileSystem::exists(const std::string& path) {
  std::lock_guard lock(mutex_);
  return files_.count(path) != 0;
}

void MemFileSystem::fail_nth_append(int n) {
  std::lock_guard lock(mutex_);
  appends_until_failure_ = n > 0 ? n : 0;
}
void MemFileSystem::fail_sync(bool fail) {
  std::lock_guard lock(mutex_);
  fail_sync_ = fail;
}
void MemFileSystem::fail_rename(bool fail) {
  std::lock_guard lock(mutex_);
  fail_rename_ = fail;
}
int MemFileSystem::append_count() const {
  std::lock_guard lock(mutex_);
  return appends_;
}

std::vector<uint8_t> MemFileSystem::contents(const std::string& path) const {
  auto n = node(path);
  std::lock_guard lock(n->mutex);
  return n->bytes;
}
void MemFileSystem::set_contents(const std::string& path, std::vector<uint8_t> bytes) {
  auto n = std::make_shared<Node>();
  n->bytes = std::move(bytes);
  std::lock_guard lock(mutex_);
  files_[path] = std::move(n);
}
void MemFileSystem::flip_byte(const std::string& path, uint64_t offset, uint8_t mask) {
  auto n = node(path);
  std::lock_guard lock(n->mutex);
  assert(offset < n->bytes.size());
  n->bytes[offset] ^= mask;
}
void MemFileSystem::truncate(const std::string& path, uint64_t size) {
  auto n = node(path);
  std::lock_guard lock(n->mutex);
  if (size < n->bytes.size()) n->bytes.resize(size);
}
std::vector<std::string> MemFileSystem::list() const {
  std::lock_guard lock(mutex_);
  std::vector<std::string> names;
  for (const auto& [name, n] : files_) names.push_back(name);
  return names;
}

}  // namespace frontier::store
