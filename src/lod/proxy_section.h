// The `proxies` section of a model store: one record per node of the top tree (store/FORMAT.md
// "proxies"). An interior node's record names its proxy page (a cell-codec page of triangles
// standing in for the whole subtree, src/lod/proxy.h) and the proxy's object-space error bound;
// a leaf's record has no page. Framed by store/section_frame.h (magic `FPXY`), so a damaged or
// newer section is refused with a clear error. Both functions are pure; decode is safe on
// untrusted bytes.
#pragma once

#include "src/core/status.h"

#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace frontier {

inline constexpr std::string_view kProxiesSection = "proxies";

struct StoreProxy {
  static constexpr uint64_t kNoPage = std::numeric_limits<uint64_t>::max();
  uint64_t page = kNoPage;         // the proxy page; kNoPage for a leaf or an empty subtree
  double error = 0.0;              // object-space bound: proxy <-> the subtree's geometry (0: leaf)
  uint64_t triangles = 0;          // triangles in the proxy page
  uint64_t subtree_triangles = 0;  // triangles of the subtree (curved primitives tessellated)
};

std::vector<uint8_t> encode_proxies(const std::vector<StoreProxy>& proxies);

// Checks the framing and every record on its own: finite error >= 0, a page below `page_count`
// exactly when the record has triangles, no page named twice. `name` prefixes every error
// ("STORE: proxies section").
Result<std::vector<StoreProxy>> decode_proxies(std::span<const uint8_t> bytes, uint64_t page_count,
                                               const std::string& name);

}  // namespace frontier
