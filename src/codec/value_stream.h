// Value streams (store/FORMAT.md "Value streams"): how cell pages store per-primitive integers
// (kinds, sources, materials). A stream of n values, n known to the reader from elsewhere,
// takes no bytes at all when n = 0; otherwise it is a mode byte and either runs (value, length)
// or Draco's rANS entropy coder over the values with an escape for large ones, whichever is
// shorter. Sources are stored as zigzag differences to the previous source, which Draco's face
// order mostly makes +1.
//
// The writers are deterministic (the same values give the same bytes). The readers are safe on
// untrusted bytes; they return false for anything inconsistent and leave the reader after the
// stream. REQUIRES of every reader: n was capped by the caller against the bytes left (it is
// allocated before the stream is known to hold that many).
#pragma once

#include "store/byte_stream.h"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace frontier::cell_page {

void write_values(store::ByteWriter& w, const std::vector<uint32_t>& values);
// n values, each at most max_value.
bool read_values(store::ByteReader& r, size_t n, uint32_t max_value, std::vector<uint32_t>& values);

void write_sources(store::ByteWriter& w, const std::vector<uint32_t>& sources);
// n sources, each in [0, 2^32).
bool read_sources(store::ByteReader& r, size_t n, std::vector<uint32_t>& sources);

}  // namespace frontier::cell_page
