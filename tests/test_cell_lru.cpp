// CellLru: the PagedWorld's eviction order equals the policy it had as frame stamps and a sort
// (least recently touched frame first, ties by ascending cell; this frame's cells not victims,
// then, for sync_evicting, in ascending order), on random walks of touches, page-ins,
// evictions and frames.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <optional>
#include <random>
#include <vector>

#include "src/paging/cell_lru.h"

namespace frontier {
namespace {

// The policy as PagedWorld wrote it before CellLru: a frame stamp per cell, victims sorted.
struct Reference {
  explicit Reference(size_t cells) : last_touched(cells, 0) {}
  uint64_t frame = 1;
  std::vector<uint64_t> last_touched;
  std::map<uint32_t, uint64_t> resident;  // cell -> bytes

  // Every resident cell in eviction order.
  std::vector<uint32_t> order() const {
    std::vector<uint32_t> cells;
    for (const auto& [c, bytes] : resident) cells.push_back(c);
    std::sort(cells.begin(), cells.end(), [&](uint32_t a, uint32_t b) {
      return last_touched[a] != last_touched[b] ? last_touched[a] < last_touched[b] : a < b;
    });
    return cells;
  }
  std::optional<uint32_t> oldest() const {
    const std::vector<uint32_t> o = order();
    if (o.empty() || last_touched[o.front()] == frame) return std::nullopt;
    return o.front();
  }
  std::vector<uint32_t> touched() const {
    std::vector<uint32_t> out;
    for (uint32_t c = 0; c < last_touched.size(); ++c) {
      if (last_touched[c] == frame) out.push_back(c);
    }
    return out;
  }
  uint64_t bytes(bool touched_only) const {
    uint64_t b = 0;
    for (const auto& [c, n] : resident) b += !touched_only || last_touched[c] == frame ? n : 0;
    return b;
  }
};

TEST(CellLru, MatchesFrameStampsAndSort) {
  constexpr uint32_t kCells = 40;
  for (uint32_t seed = 1; seed <= 10; ++seed) {
    std::mt19937 rng(seed);
    CellLru lru(kCells, 1000);
    Reference ref(kCells);
    for (int op = 0; op < 6000; ++op) {
      const uint32_t c = rng() % kCells;
      switch (rng() % 8) {
        case 0:
        case 1:
        case 2:
          lru.touch(c);
          ref.last_touched[c] = ref.frame;
          break;
        case 3:
          if (!ref.resident.count(c)) {
            const uint64_t bytes = 1 + rng() % 50;
            lru.insert(c, bytes);
            ref.resident[c] = bytes;
            ref.last_touched[c] = ref.frame;
          }
          break;
        case 4:
          lru.erase(c);
          ref.resident.erase(c);
          break;
        case 5:  // begin_frame's and evict_for's first round: the oldest untouched cells
          for (int n = int(rng() % 4); n > 0; --n) {
            const std::optional<uint32_t> victim = lru.oldest();
            ASSERT_EQ(victim, ref.oldest()) << "seed " << seed << " op " << op;
            if (!victim) break;
            lru.erase(*victim);
            ref.resident.erase(*victim);
          }
          break;
        case 6: {  // evict_for's second round: this frame's cells in ascending order
          std::vector<uint32_t> second;
          for (const uint32_t t : lru.touched_cells()) {
            if (lru.resident(t)) second.push_back(t);
          }
          std::vector<uint32_t> expected;
          for (const uint32_t t : ref.order()) {
            if (ref.last_touched[t] == ref.frame) expected.push_back(t);
          }
          ASSERT_EQ(second, expected);
          break;
        }
        case 7:
          if (rng() % 4 == 0) {
            lru.begin_frame();
            ++ref.frame;
          }
          break;
      }
      ASSERT_EQ(lru.oldest(), ref.oldest());
      ASSERT_EQ(lru.touched_cells(), ref.touched());
      ASSERT_EQ(lru.touched(c), ref.last_touched[c] == ref.frame);
      ASSERT_EQ(lru.resident(c), ref.resident.count(c) != 0);
      ASSERT_EQ(lru.bytes(), ref.bytes(false));
      ASSERT_EQ(lru.touched_bytes(), ref.bytes(true));
    }
  }
}

TEST(CellLru, LastFrameJoinsTheOrderByCell) {
  CellLru lru(10, 100);
  lru.insert(7, 1);
  lru.insert(2, 1);
  lru.touch(5);  // not resident: counted, not ordered
  lru.insert(5, 1);
  EXPECT_EQ(lru.oldest(), std::nullopt);  // all touched in this frame
  EXPECT_EQ(lru.touched_cells(), (std::vector<uint32_t>{2, 5, 7}));
  lru.begin_frame();
  EXPECT_TRUE(lru.touched_cells().empty());
  lru.insert(1, 1);
  lru.touch(2);
  // Frame 1's cells 5 and 7 in cell order; 2 and 1 are this frame's.
  EXPECT_EQ(lru.oldest(), 5u);
  lru.erase(5);
  EXPECT_EQ(lru.oldest(), 7u);
  lru.begin_frame();
  lru.erase(7);
  EXPECT_EQ(lru.oldest(), 1u);
  lru.erase(1);
  EXPECT_EQ(lru.oldest(), 2u);
}

// Ranked frames: the ending frame's cells join the order by ascending rank, ties by cell; the
// cells of older frames still go before them.
TEST(CellLru, LastFrameJoinsTheOrderByRank) {
  CellLru lru(10, 100);
  for (const uint32_t c : {4u, 8u, 3u}) lru.insert(c, 1);
  lru.begin_frame();  // frame 1's 3, 4, 8: by cell
  for (const uint32_t c : {1u, 6u, 9u, 2u}) lru.insert(c, 1);
  const std::vector<double> rank = {0, 5.0, 0.5, 9, 9, 9, 0.5, 9, 9, 7.0};
  lru.begin_frame([&](uint32_t c) { return rank[c]; });
  std::vector<uint32_t> order;
  while (const std::optional<uint32_t> c = lru.oldest()) {
    order.push_back(*c);
    lru.erase(*c);
  }
  EXPECT_EQ(order, (std::vector<uint32_t>{3, 4, 8, 2, 6, 1, 9}));
}

}  // namespace
}  // namespace frontier
