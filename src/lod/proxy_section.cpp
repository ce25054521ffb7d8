// The `proxies` section: framing and records (layout in store/FORMAT.md "proxies").
#include "src/lod/proxy_section.h"

#include "src/core/byte_io.h"
#include "store/section_frame.h"

#include <fmt/format.h>

#include <cmath>
#include <unordered_set>

namespace frontier {
namespace {

constexpr store::SectionMagic kMagic = {'F', 'P', 'X', 'Y'};
constexpr uint32_t kVersion = 1;
constexpr size_t kRecordBytes = 32;  // page u64, error f64, triangles u64, subtree triangles u64

}  // namespace

std::vector<uint8_t> encode_proxies(const std::vector<StoreProxy>& proxies) {
  std::vector<uint8_t> payload;
  GeometryWriter w(payload);
  w.reserve(8 + kRecordBytes * proxies.size());
  w.u64(proxies.size());
  for (const StoreProxy& p : proxies) {
    w.u64(p.page);
    w.f64(p.error);
    w.u64(p.triangles);
    w.u64(p.subtree_triangles);
  }
  return store::frame_section(kMagic, kVersion, payload);
}

Result<std::vector<StoreProxy>> decode_proxies(std::span<const uint8_t> bytes, uint64_t page_count,
                                               const std::string& name) {
  auto section = store::unframe_section(bytes, kMagic, kVersion, name);
  if (!section) return section.status();
  GeometryReader r(section->payload);
  const uint64_t count = r.u64();
  if (!r.ok() || r.remaining() % kRecordBytes != 0 || r.remaining() / kRecordBytes != count) {
    return Status::corruption(fmt::format("{}: size {} does not match its record count", name, bytes.size()));
  }
  std::vector<StoreProxy> proxies(count);
  std::unordered_set<uint64_t> pages;
  for (size_t i = 0; i < proxies.size(); ++i) {
    StoreProxy& p = proxies[i];
    p.page = r.u64();
    p.error = r.f64();
    p.triangles = r.u64();
    p.subtree_triangles = r.u64();
    const bool has_page = p.page != StoreProxy::kNoPage;
    if (!std::isfinite(p.error) || p.error < 0.0) {
      return Status::corruption(fmt::format("{}: node {}: bad error bound {}", name, i, p.error));
    }
    if ((has_page && p.page >= page_count) || has_page != (p.triangles > 0) || (has_page && !pages.insert(p.page).second)) {
      return Status::corruption(fmt::format("{}: node {}: bad proxy page reference", name, i));
    }
  }
  return proxies;
}

}  // namespace frontier
