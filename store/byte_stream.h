// Little-endian byte streams: the one way frontier writes and parses the integers of its
// on-disk blocks, sections and pages (byte layouts in store/FORMAT.md). Geometry (doubles,
// points, boxes) is layered on top in src/core/byte_io.h; this file knows bytes only.
//
// ByteWriter appends to a vector it does not own. ByteReader reads a span front to back and
// never reads outside it: every read checks the bytes left, the first failure is kept and all
// later reads fail too (returning zeros), so a parser may check ok() once after a group of
// reads and turn a failure into Corruption with its own context. Neither throws (beyond
// std::bad_alloc from the vector) and both are cheap to construct: one per parse.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace frontier::store {

// Fixed-width little-endian integers at `p`. REQUIRES: 4 (8) readable bytes at p; parsers of
// untrusted bytes use ByteReader, these serve fixed-size blocks whose size was checked.
inline uint32_t get_u32(const uint8_t* p) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(p[i]) << (8 * i);
  return v;
}
inline uint64_t get_u64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
  return v;
}

class ByteWriter {
 public:
  explicit ByteWriter(std::vector<uint8_t>& out) : out_(out) {}

  void u8(uint8_t v) { out_.push_back(v); }
  void u32(uint32_t v) { fixed<4>(v); }
  void u64(uint64_t v) { fixed<8>(v); }
  // Unsigned LEB128: 7 bits a byte, least significant group first, high bit = more follow.
  void varint(uint64_t v) {
    while (v >= 0x80) {
      out_.push_back(static_cast<uint8_t>(v | 0x80));
      v >>= 7;
    }
    out_.push_back(static_cast<uint8_t>(v));
  }
  void bytes(std::span<const uint8_t> data) { out_.insert(out_.end(), data.begin(), data.end()); }
  void bytes(const uint8_t* data, size_t n) { out_.insert(out_.end(), data, data + n); }
  // Room for `more` bytes beyond what the vector holds now.
  void reserve(size_t more) { out_.reserve(out_.size() + more); }
  size_t size() const { return out_.size(); }

 private:
  template <int N>
  void fixed(uint64_t v) {
    uint8_t b[N];  // appended at once: the raw codec writes millions of these
    for (int i = 0; i < N; ++i) b[i] = static_cast<uint8_t>(v >> (8 * i));
    out_.insert(out_.end(), b, b + N);
  }
  std::vector<uint8_t>& out_;
};

class ByteReader {
 public:
  explicit ByteReader(std::span<const uint8_t> bytes) : bytes_(bytes) {}

  bool ok() const { return ok_; }
  // Marks the stream failed (a parser found a value it refuses); later reads fail too.
  void fail() { ok_ = false; }
  size_t offset() const { return pos_; }  // bytes consumed by successful reads
  size_t remaining() const { return bytes_.size() - pos_; }

  uint8_t u8() { return take(1) ? bytes_[pos_ - 1] : 0; }
  uint32_t u32() { return take(4) ? get_u32(bytes_.data() + pos_ - 4) : 0; }
  uint64_t u64() { return take(8) ? get_u64(bytes_.data() + pos_ - 8) : 0; }
  // ByteWriter::varint's encoding; fails past 10 bytes or on a value over 64 bits.
  uint64_t varint() {
    uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      if (!take(1)) return 0;
      const uint8_t b = bytes_[pos_ - 1];
      if (shift == 63 && b > 1) break;  // would overflow 64 bits
      v |= static_cast<uint64_t>(b & 0x7f) << shift;
      if ((b & 0x80) == 0) return v;
    }
    ok_ = false;
    return 0;
  }
  // The next n bytes, a view into the reader's span (empty on failure).
  std::span<const uint8_t> bytes(size_t n) { return take(n) ? bytes_.subspan(pos_ - n, n) : std::span<const uint8_t>(); }

 private:
  bool take(size_t n) {
    if (!ok_ || n > remaining()) {
      ok_ = false;
      return false;
    }
    pos_ += n;
    return true;
  }
  std::span<const uint8_t> bytes_;
  size_t pos_ = 0;
  bool ok_ = true;
};

}  // namespace frontier::store
