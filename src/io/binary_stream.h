// BinaryStream: buffered sequential reads of a binary file body at explicit offsets (pread),
// 1 MiB at a time, for the binary model readers (PLY, STL). It never owns the descriptor.
//
// Invariants: memory is one chunk (less for small files); take(n) hands out n contiguous bytes
// valid until the next call; offset() is the file offset of the next byte handed out.
#pragma once

#include "src/core/status.h"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <memory>
#include <type_traits>

#include <unistd.h>

namespace frontier {

// A T stored at p (unaligned), byte-swapped when `swap`.
template <typename T>
inline T load_scalar(const uint8_t* p, bool swap) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if constexpr (sizeof(T) > 1) {
    if (swap) {
      using U = std::conditional_t<sizeof(T) == 2, uint16_t, std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>;
      U u;
      std::memcpy(&u, &v, sizeof(T));
      if constexpr (sizeof(T) == 2) {
        u = __builtin_bswap16(u);
      } else if constexpr (sizeof(T) == 4) {
        u = __builtin_bswap32(u);
      } else {
        u = __builtin_bswap64(u);
      }
      std::memcpy(&v, &u, sizeof(T));
    }
  }
  return v;
}

// take(n) hands out n contiguous bytes, n <= kChunk.
class BinaryStream {
 public:
  static constexpr size_t kChunk = size_t{1} << 20;

  void init(int fd, uint64_t offset, uint64_t file_size) {
    fd_ = fd;
    buffer_offset_ = offset;
    file_size_ = file_size;
    const uint64_t body = file_size > offset ? file_size - offset : 0;
    capacity_ = static_cast<size_t>(std::min<uint64_t>(kChunk, body + 1));
    buffer_ = std::make_unique<uint8_t[]>(capacity_);
    pos_ = end_ = 0;
  }
  uint64_t offset() const { return buffer_offset_ + pos_; }
  uint64_t remaining() const { return file_size_ > offset() ? file_size_ - offset() : 0; }
  const Status& status() const { return status_; }

  // Next n bytes, or nullptr when the file ends first (or a read fails: see status()).
  const uint8_t* take(size_t n) {
    if (end_ - pos_ < n && !fill(n)) return nullptr;
    const uint8_t* p = buffer_.get() + pos_;
    pos_ += n;
    return p;
  }
  bool skip(uint64_t n) {
    if (n <= end_ - pos_) {
      pos_ += static_cast<size_t>(n);
      return true;
    }
    if (n > remaining()) return false;
    buffer_offset_ = offset() + n;
    pos_ = end_ = 0;
    return true;
  }

 private:
  bool fill(size_t n) {
    if (n > capacity_) {
      // Only possible when the body is smaller than n: the file ends first.
      return false;
    }
    const size_t have = end_ - pos_;
    std::memmove(buffer_.get(), buffer_.get() + pos_, have);
    buffer_offset_ += pos_;
    pos_ = 0;
    end_ = have;
    while (end_ < n) {
      const uint64_t at = buffer_offset_ + end_;
      if (at >= file_size_) return false;
      const size_t want = static_cast<size_t>(std::min<uint64_t>(capacity_ - end_, file_size_ - at));
      const ssize_t r = ::pread(fd_, buffer_.get() + end_, want, static_cast<off_t>(at));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) {
        status_ = Status::io_error(fmt::format("byte {}: read failed: {}", at, std::strerror(errno)));
        return false;
      }
      if (r == 0) return false;
      end_ += static_cast<size_t>(r);
    }
    return true;
  }

  int fd_ = -1;
  std::unique_ptr<uint8_t[]> buffer_;
  size_t capacity_ = 0;
  size_t pos_ = 0;
  size_t end_ = 0;
  uint64_t buffer_offset_ = 0;
  uint64_t file_size_ = 0;
  Status status_;
};

}  // namespace frontier
