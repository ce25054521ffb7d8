// StoreOracle: the exact per-pixel reference for a store — every pixel's ray walked through the
// store's top tree and, inside each store cell, through that cell's own refined subtree, up to
// its first hit. It answers the two questions the walkthrough report asks of a frame: which
// store cells the exact rays pass through up to their first hit (the **oracle** working set,
// DESIGN.md "Working set, defined once") and which input primitive each pixel sees.
//
// It is a diagnostic, independent of the paging renderer: it decodes pages straight from the
// store (not through the page cache, not counted in the working set) and keeps up to
// `max_cells` decoded cells in its own LRU. A page that fails to decode counts as empty.
#pragma once

#include "src/engine/kdtree.h"
#include "src/core/scene.h"
#include "src/paging/store_model.h"
#include "src/core/view.h"

#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <unordered_map>
#include <vector>

namespace frontier {

struct OracleFrame {
  std::vector<uint32_t> cells;  // distinct store cells, ascending
  std::vector<uint32_t> ids;    // per pixel: first-hit source id, kNoPrim for background
  uint64_t page_errors = 0;
};

class StoreOracle {
 public:
  explicit StoreOracle(const StoreModel& model, size_t max_cells = 4096);
  ~StoreOracle();
  OracleFrame frame(const View& view, int threads);

 private:
  struct CellGeometry;
  std::shared_ptr<const CellGeometry> cell(uint32_t c, uint64_t& errors);
  const StoreModel& model_;
  KdTree top_;
  size_t max_cells_;
  std::mutex mutex_;
  std::list<uint32_t> lru_;
  std::unordered_map<uint32_t, std::pair<std::shared_ptr<const CellGeometry>, std::list<uint32_t>::iterator>> cells_;
};

}  // namespace frontier
