// CellLru: which decoded cells a PagedWorld evicts first, and which ones it may not evict.
//
// The policy (paged_world.h): least recently touched frame first; among the cells of one frame,
// ascending rank (PagedWorld's: the cell's screen-space size from the new frame's eye, the key
// its decoder serves requests by; 0 when there is no eye), then ascending store cell; cells
// touched in the current frame are not victims. It is a ByteLru (store/byte_lru.h) over the
// resident cells in which this frame's cells are pinned: begin_frame() unpins last frame's
// cells in ascending (rank, cell) order, so they join the evictable list as its newest
// entries, after every cell of an earlier frame. Hence, at every moment,
//   - the evictable entries, oldest first, are the resident cells not touched in this frame,
//     in ascending (frame last touched, rank in that frame's begin_frame, cell);
//   - the pinned entries are the resident cells touched in this frame; touched_cells() lists
//     every cell touched in it (resident or not) in ascending order, for the callers that may
//     go on to evict those too (PagedWorld::sync_evicting).
// Touches are counted once per cell and frame. Not thread-safe: the PagedWorld's owner calls it
// between frame slices.
#pragma once

#include "store/byte_lru.h"

#include <algorithm>
#include <cstdint>
#include <optional>
#include <vector>

namespace frontier {

class CellLru {
 public:
  CellLru() = default;
  // Store cells 0 .. cells - 1; none resident or touched. The budget is the decoded share.
  CellLru(size_t cells, uint64_t budget_bytes) : stamp_(cells, 0), lru_(budget_bytes) {}

  uint64_t frame() const { return frame_; }
  // Ends the current frame and starts the next.
  void begin_frame() { begin_frame([](uint32_t) { return 0.0; }); }
  // The same, the ending frame's cells joining the order by ascending rank(cell) (ties by
  // cell): among them, the lowest rank is evicted first.
  template <typename Rank>
  void begin_frame(const Rank& rank) {
    std::vector<std::pair<double, uint32_t>> order;
    order.reserve(touched_cells().size());
    for (const uint32_t c : touched_cells()) {
      if (lru_.contains(c)) order.emplace_back(rank(c), c);
    }
    std::sort(order.begin(), order.end());
    for (const auto& [r, c] : order) lru_.unpin(c);
    ++frame_;
    touched_.clear();
  }

  // Records that the current frame used `cell` (resident or not).
  void touch(uint32_t cell) {
    if (stamp(cell) && lru_.contains(cell)) lru_.pin(cell);
  }
  bool touched(uint32_t cell) const { return stamp_[cell] == frame_; }
  // The last frame that touched `cell` (0: none).
  uint64_t last_touched(uint32_t cell) const { return stamp_[cell]; }
  // The cells touched in the current frame, ascending.
  const std::vector<uint32_t>& touched_cells() const {
    if (!sorted_) {
      std::sort(touched_.begin(), touched_.end());
      sorted_ = true;
    }
    return touched_;
  }

  // `cell` became resident, taking `bytes`: touched by the current frame.
  // REQUIRES: !resident(cell).
  void insert(uint32_t cell, uint64_t bytes) {
    lru_.insert(cell, bytes);
    lru_.pin(cell);
    stamp(cell);
  }
  void erase(uint32_t cell) { lru_.erase(cell); }
  bool resident(uint32_t cell) const { return lru_.contains(cell); }

  // The resident cell to evict first among those not touched in this frame, if any.
  std::optional<uint32_t> oldest() const { return lru_.oldest(); }

  uint64_t budget() const { return lru_.budget(); }
  // Bytes of the resident cells; of those touched in this frame.
  uint64_t bytes() const { return lru_.resident_bytes(); }
  uint64_t touched_bytes() const { return lru_.pinned_bytes(); }

 private:
  // Stamps `cell` with the current frame; true if it was not stamped yet.
  bool stamp(uint32_t cell) {
    if (stamp_[cell] == frame_) return false;
    stamp_[cell] = frame_;
    if (!touched_.empty() && touched_.back() > cell) sorted_ = false;
    touched_.push_back(cell);
    return true;
  }

  // Starts at 1 so that no cell counts as touched before the first frame.
  uint64_t frame_ = 1;
  std::vector<uint64_t> stamp_;  // cell -> the last frame that touched it (0: none)
  mutable std::vector<uint32_t> touched_;  // cells stamped with frame_, sorted when sorted_
  mutable bool sorted_ = true;
  store::ByteLru<uint32_t> lru_;  // resident cells; pinned: touched in this frame
};

}  // namespace frontier
