// The store's on-disk framing (byte layout in store/FORMAT.md; keep the two in step).
//
//   [header 24 B] [page | section]* [directory block] [footer 40 B]
//
// Every block (page, section, directory) is `payload | codec (1 B) | xxHash64(payload|codec) (8 B)`,
// LevelDB style. A Handle {offset, size} names a whole framed block (size includes the 9-byte
// trailer). All integers are little-endian. The decoders here are pure functions over bytes, safe
// on untrusted input: any mismatch or truncation returns Corruption naming the block's offset,
// never reads out of bounds and never throws.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "store/byte_stream.h"
#include "store/status.h"

namespace frontier::store {

inline constexpr std::array<uint8_t, 8> kMagic = {'F', 'R', 'N', 'T', 'S', 'T', 'O', 'R'};
// Format versions, oldest first; a reader accepts versions <= kFormatVersion (FORMAT.md history).
inline constexpr uint32_t kFormatVersion1 = 1;  // header, framed pages, directory, footer
inline constexpr uint32_t kFormatVersion = kFormatVersion1;

inline constexpr size_t kHeaderSize = 24;
inline constexpr size_t kFooterSize = 40;
inline constexpr size_t kBlockTrailerSize = 9;  // codec byte + 8-byte checksum
inline constexpr size_t kMaxSectionName = 255;

// Codec tags. The store never interprets a payload; it only carries the tag. The directory and
// the page index are always raw.
enum : uint8_t { kCodecRaw = 0 };

struct Handle {
  uint64_t offset = 0;
  uint64_t size = 0;  // whole framed block, trailer included
  friend bool operator==(const Handle&, const Handle&) = default;
};

// Integers are written and read with store/byte_stream.h.
uint64_t checksum(std::span<const uint8_t> bytes);  // xxHash64, seed 0

// --- blocks --------------------------------------------------------------------------------
// payload | codec | checksum. The result has payload.size() + kBlockTrailerSize bytes.
std::vector<uint8_t> encode_page(uint8_t codec, std::span<const uint8_t> payload);

struct DecodedPage {
  uint8_t codec = kCodecRaw;
  std::span<const uint8_t> payload;  // view into the bytes passed to decode_page
};
// REQUIRES: `bytes` are what was read at handle.offset (the handle is only used for sizes and
// error messages). Corruption ("page at offset N: ...") on size mismatch or bad checksum.
Result<DecodedPage> decode_page(std::span<const uint8_t> bytes, Handle handle);

// --- header and footer ---------------------------------------------------------------------
struct Header {
  uint32_t version = kFormatVersion;
  uint32_t flags = 0;  // no flags are defined in version 1; readers reject unknown bits
};
std::array<uint8_t, kHeaderSize> encode_header(const Header& header);
// `file` names the store in messages. Corruption on bad magic/checksum, Unsupported on a newer
// version or unknown flags.
Result<Header> decode_header(std::span<const uint8_t> bytes, const std::string& file);

struct Footer {
  Handle directory;
  uint32_t version = kFormatVersion;
};
std::array<uint8_t, kFooterSize> encode_footer(const Footer& footer);
Result<Footer> decode_footer(std::span<const uint8_t> bytes, const std::string& file);

// --- directory: named sections -------------------------------------------------------------
struct Section {
  std::string name;  // 1..255 bytes, unique within a store
  Handle handle;
};
// The directory's payload (to be framed with encode_page, codec raw).
std::vector<uint8_t> encode_directory(const std::vector<Section>& sections);
Result<std::vector<Section>> decode_directory(std::span<const uint8_t> payload, Handle where,
                                              const std::string& file);

// --- page index: the payload of the "pages" section, a list of page handles ----------------
std::vector<uint8_t> encode_page_index(const std::vector<Handle>& pages);
Result<std::vector<Handle>> decode_page_index(std::span<const uint8_t> payload, Handle where,
                                              const std::string& file);

}  // namespace frontier::store
