// Encoders and checked decoders of the store's framing (layout and contracts: page_format.h,
// store/FORMAT.md). Decoders parse with ByteReader, so a count or length they have not checked
// never moves a read outside the bytes they were given.
#include "store/page_format.h"

#include <xxhash.h>

#include <algorithm>
#include <set>

namespace frontier::store {
namespace {

std::string at(const std::string& file, const char* what, uint64_t offset) {
  return file + ": " + what + " at offset " + std::to_string(offset) + ": ";
}

}  // namespace

uint64_t checksum(std::span<const uint8_t> bytes) { return XXH64(bytes.data(), bytes.size(), 0); }

std::vector<uint8_t> encode_page(uint8_t codec, std::span<const uint8_t> payload) {
  std::vector<uint8_t> out;
  out.reserve(payload.size() + kBlockTrailerSize);
  out.insert(out.end(), payload.begin(), payload.end());
  out.push_back(codec);
  ByteWriter(out).u64(checksum(out));
  return out;
}

Result<DecodedPage> decode_page(std::span<const uint8_t> bytes, Handle handle) {
  std::string where = "page at offset " + std::to_string(handle.offset) + ": ";
  if (bytes.size() != handle.size) {
    return Status::corruption(where + "expected " + std::to_string(handle.size) + " bytes, got " +
                              std::to_string(bytes.size()));
  }
  if (bytes.size() < kBlockTrailerSize) {
    return Status::corruption(where + "block of " + std::to_string(bytes.size()) +
                              " bytes is shorter than its trailer");
  }
  size_t body = bytes.size() - 8;
  if (checksum(bytes.first(body)) != get_u64(bytes.data() + body)) {
    return Status::corruption(where + "checksum mismatch");
  }
  return DecodedPage{bytes[body - 1], bytes.first(body - 1)};
}

std::array<uint8_t, kHeaderSize> encode_header(const Header& header) {
  std::vector<uint8_t> v(kMagic.begin(), kMagic.end());
  ByteWriter w(v);
  w.u32(header.version);
  w.u32(header.flags);
  w.u64(checksum(v));
  std::array<uint8_t, kHeaderSize> out{};
  std::copy(v.begin(), v.end(), out.begin());
  return out;
}

Result<Header> decode_header(std::span<const uint8_t> bytes, const std::string& file) {
  if (bytes.size() != kHeaderSize) return Status::corruption(file + ": header truncated");
  if (!std::equal(kMagic.begin(), kMagic.end(), bytes.begin())) {
    return Status::corruption(file + ": damaged header (bytes 0-7 are not the magic FRNTSTOR)");
  }
  if (checksum(bytes.first(16)) != get_u64(bytes.data() + 16)) {
    return Status::corruption(file + ": damaged header (the checksum at byte 16 does not match bytes 0-15)");
  }
  Header h{get_u32(bytes.data() + 8), get_u32(bytes.data() + 12)};
  if (h.version > kFormatVersion || h.version == 0) {
    return Status::unsupported(file + ": format version " + std::to_string(h.version) +
                               " is newer than this reader (" + std::to_string(kFormatVersion) +
                               ")");
  }
  if (h.flags != 0) {
    return Status::unsupported(file + ": unknown header flags " + std::to_string(h.flags));
  }
  return h;
}

std::array<uint8_t, kFooterSize> encode_footer(const Footer& footer) {
  std::vector<uint8_t> v;
  ByteWriter w(v);
  w.u64(footer.directory.offset);
  w.u64(footer.directory.size);
  w.u32(footer.version);
  w.u32(0);  // reserved
  w.u64(checksum(v));
  v.insert(v.end(), kMagic.begin(), kMagic.end());
  std::array<uint8_t, kFooterSize> out{};
  std::copy(v.begin(), v.end(), out.begin());
  return out;
}

Result<Footer> decode_footer(std::span<const uint8_t> bytes, const std::string& file) {
  if (bytes.size() != kFooterSize) return Status::corruption(file + ": footer truncated");
  if (!std::equal(kMagic.begin(), kMagic.end(), bytes.begin() + 32)) {
    return Status::corruption(file +
                              ": not a frontier store or truncated (bad footer magic)");
  }
  // The checksum is checked before the version: a flipped version byte is corruption, and the
  // 40-byte footer layout is frozen across versions so that old readers can say "too new".
  if (checksum(bytes.first(24)) != get_u64(bytes.data() + 24)) {
    return Status::corruption(file + ": footer checksum mismatch");
  }
  Footer f;
  f.directory = {get_u64(bytes.data()), get_u64(bytes.data() + 8)};
  f.version = get_u32(bytes.data() + 16);
  if (f.version > kFormatVersion || f.version == 0) {
    return Status::unsupported(file + ": format version " + std::to_string(f.version) +
                               " is newer than this reader (" + std::to_string(kFormatVersion) +
                               ")");
  }
  if (get_u32(bytes.data() + 20) != 0) {
    return Status::unsupported(file + ": unknown footer flags");
  }
  return f;
}

std::vector<uint8_t> encode_directory(const std::vector<Section>& sections) {
  std::vector<uint8_t> out;
  ByteWriter w(out);
  w.u32(static_cast<uint32_t>(sections.size()));
  for (const Section& s : sections) {
    w.u8(static_cast<uint8_t>(s.name.size()));
    w.bytes(reinterpret_cast<const uint8_t*>(s.name.data()), s.name.size());
    w.u64(s.handle.offset);
    w.u64(s.handle.size);
  }
  return out;
}

Result<std::vector<Section>> decode_directory(std::span<const uint8_t> payload, Handle where,
                                              const std::string& file) {
  std::string prefix = at(file, "directory", where.offset);
  ByteReader r(payload);
  const uint32_t count = r.u32();
  if (!r.ok()) return Status::corruption(prefix + "truncated count");
  std::vector<Section> sections;
  std::set<std::string> names;
  for (uint32_t i = 0; i < count; ++i) {
    const size_t len = r.u8();
    if (!r.ok()) return Status::corruption(prefix + "truncated entry");
    if (len == 0 || len + 16 > r.remaining()) {
      return Status::corruption(prefix + "bad entry " + std::to_string(i));
    }
    Section s;
    const std::span<const uint8_t> name = r.bytes(len);
    s.name.assign(name.begin(), name.end());
    s.handle.offset = r.u64();
    s.handle.size = r.u64();
    if (!names.insert(s.name).second) {
      return Status::corruption(prefix + "duplicate section \"" + s.name + "\"");
    }
    sections.push_back(std::move(s));
  }
  if (r.remaining() != 0) return Status::corruption(prefix + "trailing bytes");
  return sections;
}

std::vector<uint8_t> encode_page_index(const std::vector<Handle>& pages) {
  std::vector<uint8_t> out;
  ByteWriter w(out);
  w.reserve(8 + 16 * pages.size());
  w.u64(pages.size());
  for (const Handle& h : pages) {
    w.u64(h.offset);
    w.u64(h.size);
  }
  return out;
}

Result<std::vector<Handle>> decode_page_index(std::span<const uint8_t> payload, Handle where,
                                              const std::string& file) {
  std::string prefix = at(file, "page index", where.offset);
  ByteReader r(payload);
  const uint64_t count = r.u64();
  if (!r.ok()) return Status::corruption(prefix + "truncated count");
  if (r.remaining() % 16 != 0 || r.remaining() / 16 != count) {
    return Status::corruption(prefix + "count " + std::to_string(count) +
                              " does not match size " + std::to_string(payload.size()));
  }
  std::vector<Handle> pages(count);
  for (Handle& h : pages) {
    h.offset = r.u64();
    h.size = r.u64();
  }
  return pages;
}

}  // namespace frontier::store
