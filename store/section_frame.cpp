// Section framing (contract and layout: section_frame.h). The checks run in the order the
// header's fields lie, so the message names the first thing wrong.
#include "store/section_frame.h"

#include "store/byte_stream.h"
#include "store/page_format.h"

#include <algorithm>
#include <string>

namespace frontier::store {

std::vector<uint8_t> frame_section(const SectionMagic& magic, uint32_t version, std::span<const uint8_t> payload) {
  std::vector<uint8_t> out;
  out.reserve(kSectionHeaderSize + payload.size());
  ByteWriter w(out);
  w.bytes(magic);
  w.u32(version);
  w.u64(payload.size());
  w.u64(checksum(payload));
  w.bytes(payload);
  return out;
}

Result<UnframedSection> unframe_section(std::span<const uint8_t> bytes, const SectionMagic& magic, uint32_t newest,
                                        std::string_view name) {
  const std::string prefix = std::string(name) + ": ";
  const auto corrupt = [&](const std::string& what) { return Status::corruption(prefix + what); };
  ByteReader r(bytes);
  const std::span<const uint8_t> found = r.bytes(magic.size());
  const uint32_t version = r.u32();
  const uint64_t size = r.u64();
  const uint64_t sum = r.u64();
  if (!r.ok()) return corrupt("truncated header (" + std::to_string(bytes.size()) + " bytes)");
  if (!std::equal(magic.begin(), magic.end(), found.begin())) return corrupt("bad magic");
  if (version == 0) return corrupt("bad version 0");
  if (version > newest) {
    return Status::unsupported(prefix + "version " + std::to_string(version) + " is newer than this reader (" +
                               std::to_string(newest) + ")");
  }
  if (size != r.remaining()) {
    return corrupt("payload size " + std::to_string(size) + " but " + std::to_string(r.remaining()) +
                   " bytes follow the header");
  }
  const std::span<const uint8_t> payload = r.bytes(r.remaining());
  if (checksum(payload) != sum) return corrupt("checksum mismatch");
  return UnframedSection{version, payload};
}

}  // namespace frontier::store
