// Value streams (layout: store/FORMAT.md "Value streams"; contracts: value_stream.h).
//
// A stream of n > 0 values (n known to the reader; no bytes at all when n = 0) is a mode byte,
// then either
//   runs:    varint run count, then per run varint value, varint length  (few runs), or
//   symbols: varint byte length, Draco's entropy coder (draco::EncodeSymbols, rANS) over
//            min(value, kEscape), then one varint (value - kEscape) per escaped value, in order.
// The writer keeps the shorter. The escape exists because draco::EncodeSymbols sizes a
// histogram by the largest value (it crashes on 2^32 - 1 and allocates gigabytes near it).
// Sources are stored as zigzag differences to the previous source (the first to 0): Draco's
// face order mostly follows the input order, so most differences are +1 and entropy-code to a
// fraction of a bit.
#include "src/codec/value_stream.h"

#include <draco/compression/config/compression_shared.h>
#include <draco/compression/entropy/symbol_decoding.h>
#include <draco/compression/entropy/symbol_encoding.h>
#include <draco/core/decoder_buffer.h>
#include <draco/core/encoder_buffer.h>

#include <algorithm>
#include <cstdint>
#include <exception>
#include <span>
#include <utility>

namespace frontier::cell_page {
namespace {

using store::ByteReader;
using store::ByteWriter;

uint64_t zigzag(int64_t v) { return (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63); }
int64_t unzigzag(uint64_t v) { return static_cast<int64_t>(v >> 1) ^ -static_cast<int64_t>(v & 1); }

constexpr uint8_t kStreamRuns = 0;
constexpr uint8_t kStreamSymbols = 1;
constexpr uint32_t kEscape = 1023;

void write_stream(ByteWriter& w, const std::vector<uint64_t>& values) {
  if (values.empty()) return;  // nothing at all, not even the mode byte
  std::vector<uint8_t> runs;
  ByteWriter rw(runs);
  std::vector<std::pair<uint64_t, uint64_t>> list;
  for (uint64_t v : values) {
    if (list.empty() || list.back().first != v) list.emplace_back(v, 0);
    ++list.back().second;
  }
  rw.varint(list.size());
  for (const auto& [value, length] : list) {
    rw.varint(value);
    rw.varint(length);
  }
  if (list.size() > 2 && values.size() <= INT32_MAX) {
    std::vector<uint32_t> symbols;
    std::vector<uint8_t> escaped;
    ByteWriter ew(escaped);
    symbols.reserve(values.size());
    for (uint64_t v : values) {
      symbols.push_back(static_cast<uint32_t>(std::min<uint64_t>(v, kEscape)));
      if (v >= kEscape) ew.varint(v - kEscape);
    }
    draco::EncoderBuffer buffer;
    if (draco::EncodeSymbols(symbols.data(), static_cast<int>(symbols.size()), 1, nullptr, &buffer) &&
        buffer.size() + escaped.size() + 4 < runs.size()) {
      w.u8(kStreamSymbols);
      w.varint(buffer.size());
      w.bytes(reinterpret_cast<const uint8_t*>(buffer.data()), buffer.size());
      w.bytes(escaped.data(), escaped.size());
      return;
    }
  }
  w.u8(kStreamRuns);
  w.bytes(runs.data(), runs.size());
}

// Reads n values, each at most max_value. REQUIRES: n was capped by the caller (it is
// allocated before the stream is known to hold that many).
bool read_stream(ByteReader& r, size_t n, uint64_t max_value, std::vector<uint64_t>& values) {
  values.clear();
  if (n == 0) return true;
  values.reserve(n);
  const uint8_t mode = r.u8();
  if (!r.ok()) return false;
  if (mode == kStreamRuns) {
    const uint64_t count = r.varint();
    if (!r.ok() || count > n || count > r.remaining() / 2) return false;
    for (uint64_t i = 0; i < count; ++i) {
      const uint64_t value = r.varint();
      const uint64_t length = r.varint();
      if (!r.ok() || value > max_value || length == 0 || length > n - values.size()) return false;
      values.insert(values.end(), length, value);
    }
    return values.size() == n;
  }
  if (mode != kStreamSymbols || n == 0 || n > INT32_MAX) return false;
  const uint64_t size = r.varint();
  if (!r.ok() || size > r.remaining()) return false;
  const std::span<const uint8_t> bytes = r.bytes(size);
  std::vector<uint32_t> symbols(n);
  try {
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(bytes.data()), bytes.size(), draco::kDracoMeshBitstreamVersion);
    if (!draco::DecodeSymbols(static_cast<uint32_t>(n), 1, &buffer, symbols.data())) return false;
  } catch (const std::exception&) {  // std::bad_alloc from a damaged table size
    return false;
  }
  for (uint32_t symbol : symbols) {
    if (symbol > kEscape) return false;
    uint64_t v = symbol;
    if (symbol == kEscape) {
      const uint64_t extra = r.varint();
      if (!r.ok() || extra > UINT64_MAX - kEscape) return false;
      v += extra;
    }
    if (v > max_value) return false;
    values.push_back(v);
  }
  return true;
}

}  // namespace

void write_sources(ByteWriter& w, const std::vector<uint32_t>& sources) {
  std::vector<uint64_t> deltas;
  deltas.reserve(sources.size());
  int64_t previous = 0;
  for (uint32_t v : sources) {
    deltas.push_back(zigzag(static_cast<int64_t>(v) - previous));
    previous = v;
  }
  write_stream(w, deltas);
}

bool read_sources(ByteReader& r, size_t n, std::vector<uint32_t>& sources) {
  std::vector<uint64_t> deltas;
  if (!read_stream(r, n, UINT64_MAX, deltas)) return false;
  sources.resize(n);
  int64_t previous = 0;
  for (size_t i = 0; i < n; ++i) {
    const int64_t d = unzigzag(deltas[i]);
    if (d > int64_t{UINT32_MAX} || d < -int64_t{UINT32_MAX}) return false;
    const int64_t v = previous + d;
    if (v < 0 || v > int64_t{UINT32_MAX}) return false;
    sources[i] = static_cast<uint32_t>(v);
    previous = v;
  }
  return true;
}

void write_values(ByteWriter& w, const std::vector<uint32_t>& values) {
  write_stream(w, std::vector<uint64_t>(values.begin(), values.end()));
}

bool read_values(ByteReader& r, size_t n, uint32_t max_value, std::vector<uint32_t>& values) {
  std::vector<uint64_t> wide;
  if (!read_stream(r, n, max_value, wide)) return false;
  values.assign(wide.begin(), wide.end());
  return true;
}

}  // namespace frontier::cell_page
