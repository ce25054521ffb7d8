#include "store/page_format.h"

#include <xxhash.h>

#include <algorithm>
#include <cstring>
#include <set>

namespace frontier::store {
namespace {

std::string at(const std::string& file, const char* what, uint64_t offset) {
  return file + ": " + what + " at offset " + std::to_string(offset) + ": ";
}

}  // namespace

void put_u32(std::vector<uint8_t>& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
void put_u64(std::vector<uint8_t>& out, uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
uint32_t get_u32(const uint8_t* p) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(p[i]) << (8 * i);
  return v;
}
uint64_t get_u64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<uint64_t>(p[i]) << (8 * i);
  return v;
}
uint64_t checksum(std::span<const uint8_t> bytes) { return XXH64(bytes.data(), bytes.size(), 0); }

std::vector<uint8_t> encode_page(uint8_t codec, std::span<const uint8_t> payload) {
  std::vector<uint8_t> out;
  out.reserve(payload.size() + kBlockTrailerSize);
  out.insert(out.end(), payload.begin(), payload.end());
  out.push_back(codec);
  put_u64(out, checksum(out));
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
  put_u32(v, header.version);
  put_u32(v, header.flags);
  put_u64(v, checksum(v));
  std::array<uint8_t, kHeaderSize> out{};
  std::copy(v.begin(), v.end(), out.begin());
  return out;
}

Result<Header> decode_header(std::span<const uint8_t> bytes, const std::string& file) {
  if (bytes.size() != kHeaderSize) return Status::corruption(file + ": header truncated");
  if (!std::equal(kMagic.begin(), kMagic.end(), bytes.begin())) {
    return Status::corruption(file + ": not a frontier store (bad header magic)");
  }
  if (checksum(bytes.first(16)) != get_u64(bytes.data() + 16)) {
    return Status::corruption(file + ": header checksum mismatch");
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
  put_u64(v, footer.directory.offset);
  put_u64(v, footer.directory.size);
  put_u32(v, footer.version);
  put_u32(v, 0);  // reserved
  put_u64(v, checksum(v));
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
  put_u32(out, static_cast<uint32_t>(sections.size()));
  for (const Section& s : sections) {
    out.push_back(static_cast<uint8_t>(s.name.size()));
    out.insert(out.end(), s.name.begin(), s.name.end());
    put_u64(out, s.handle.offset);
    put_u64(out, s.handle.size);
  }
  return out;
}

Result<std::vector<Section>> decode_directory(std::span<const uint8_t> payload, Handle where,
                                              const std::string& file) {
  std::string prefix = at(file, "directory", where.offset);
  if (payload.size() < 4) return Status::corruption(prefix + "truncated count");
  uint32_t count = get_u32(payload.data());
  size_t pos = 4;
  std::vector<Section> sections;
  std::set<std::string> names;
  for (uint32_t i = 0; i < count; ++i) {
    if (pos + 1 > payload.size()) return Status::corruption(prefix + "truncated entry");
    size_t len = payload[pos++];
    if (len == 0 || pos + len + 16 > payload.size()) {
      return Status::corruption(prefix + "bad entry " + std::to_string(i));
    }
    Section s;
    s.name.assign(reinterpret_cast<const char*>(payload.data() + pos), len);
    pos += len;
    s.handle = {get_u64(payload.data() + pos), get_u64(payload.data() + pos + 8)};
    pos += 16;
    if (!names.insert(s.name).second) {
      return Status::corruption(prefix + "duplicate section \"" + s.name + "\"");
    }
    sections.push_back(std::move(s));
  }
  if (pos != payload.size()) return Status::corruption(prefix + "trailing bytes");
  return sections;
}

std::vector<uint8_t> encode_page_index(const std::vector<Handle>& pages) {
  std::vector<uint8_t> out;
  put_u64(out, pages.size());
  for (const Handle& h : pages) {
    put_u64(out, h.offset);
    put_u64(out, h.size);
  }
  return out;
}

Result<std::vector<Handle>> decode_page_index(std::span<const uint8_t> payload, Handle where,
                                              const std::string& file) {
  std::string prefix = at(file, "page index", where.offset);
  if (payload.size() < 8) return Status::corruption(prefix + "truncated count");
  uint64_t count = get_u64(payload.data());
  if ((payload.size() - 8) % 16 != 0 || (payload.size() - 8) / 16 != count) {
    return Status::corruption(prefix + "count " + std::to_string(count) +
                              " does not match size " + std::to_string(payload.size()));
  }
  std::vector<Handle> pages(count);
  for (uint64_t i = 0; i < count; ++i) {
    const uint8_t* p = payload.data() + 8 + 16 * i;
    pages[i] = {get_u64(p), get_u64(p + 8)};
  }
  return pages;
}

}  // namespace frontier::store
