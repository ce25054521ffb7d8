// Self-describing sections: the framing the engine's binary sections share ("sdf", "portals";
// store/FORMAT.md), so that a section read on its own, outside a store, still says what it is,
// which version wrote it and whether its bytes are intact:
//
//   magic (4 B) | version u32 | payload size u64 | xxHash64(payload) u64 | payload
//
// All integers little-endian. Version 0 is invalid; a reader accepts versions up to the newest
// it knows and refuses newer ones as Unsupported, so an old reader never misreads a new layout.
// Both functions are pure; unframe_section is safe on untrusted bytes.
#pragma once

#include "store/status.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

namespace frontier::store {

using SectionMagic = std::array<uint8_t, 4>;
inline constexpr size_t kSectionHeaderSize = 24;

// The framed section: kSectionHeaderSize + payload.size() bytes.
std::vector<uint8_t> frame_section(const SectionMagic& magic, uint32_t version, std::span<const uint8_t> payload);

struct UnframedSection {
  uint32_t version = 0;
  std::span<const uint8_t> payload;  // a view into the bytes given to unframe_section
};

// Checks the framing of `bytes` and returns its version and payload. Corruption "NAME: ..."
// (truncated header, bad magic, version 0, a payload size that is not exactly the bytes after
// the header, checksum mismatch); Unsupported "NAME: version V is newer than this reader (N)"
// for a version above `newest`. `name` says which section, e.g. "store.frontier: portals section".
Result<UnframedSection> unframe_section(std::span<const uint8_t> bytes, const SectionMagic& magic, uint32_t newest,
                                        std::string_view name);

}  // namespace frontier::store
