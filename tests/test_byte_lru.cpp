// ByteLru: every operation's result against a simple reference model (a clock stamp per entry,
// the victim found by scanning), pinned entries, the budget, values and keys of another type.
#include <gtest/gtest.h>

#include <map>
#include <optional>
#include <random>
#include <string>

#include "store/byte_lru.h"

namespace frontier::store {
namespace {

// The obvious O(n) model: the victim is the unpinned entry used longest ago.
struct Reference {
  struct Entry {
    uint64_t bytes = 0;
    int pins = 0;
    uint64_t last_use = 0;
    int value = 0;
  };
  std::map<int, Entry> entries;
  uint64_t clock = 0;

  std::optional<int> oldest() const {
    std::optional<int> victim;
    for (const auto& [key, e] : entries) {
      if (e.pins == 0 && (!victim || e.last_use < entries.at(*victim).last_use)) victim = key;
    }
    return victim;
  }
  uint64_t resident() const {
    uint64_t b = 0;
    for (const auto& [key, e] : entries) b += e.bytes;
    return b;
  }
  uint64_t pinned() const {
    uint64_t b = 0;
    for (const auto& [key, e] : entries) b += e.pins > 0 ? e.bytes : 0;
    return b;
  }
  size_t evictable() const {
    size_t n = 0;
    for (const auto& [key, e] : entries) n += e.pins == 0 ? 1 : 0;
    return n;
  }
};

void expect_same(ByteLru<int, int>& lru, const Reference& ref, int keys) {
  ASSERT_EQ(lru.size(), ref.entries.size());
  ASSERT_EQ(lru.evictable(), ref.evictable());
  ASSERT_EQ(lru.resident_bytes(), ref.resident());
  ASSERT_EQ(lru.pinned_bytes(), ref.pinned());
  ASSERT_EQ(lru.oldest(), ref.oldest());
  ASSERT_EQ(lru.over_budget(), ref.resident() > lru.budget());
  for (int k = 0; k < keys; ++k) {
    auto it = ref.entries.find(k);
    ASSERT_EQ(lru.contains(k), it != ref.entries.end()) << "key " << k;
    if (it == ref.entries.end()) {
      ASSERT_EQ(lru.find(k), nullptr);
      continue;
    }
    ASSERT_EQ(lru.bytes(k), it->second.bytes);
    ASSERT_EQ(lru.pins(k), it->second.pins);
    ASSERT_NE(lru.find(k), nullptr);
    ASSERT_EQ(*lru.find(k), it->second.value);
  }
}

TEST(ByteLru, MatchesReferenceModel) {
  constexpr int kKeys = 24;
  for (uint32_t seed = 1; seed <= 8; ++seed) {
    std::mt19937 rng(seed);
    ByteLru<int, int> lru(400);
    Reference ref;
    for (int op = 0; op < 4000; ++op) {
      const int key = static_cast<int>(rng() % kKeys);
      auto e = ref.entries.find(key);
      switch (rng() % 6) {
        case 0:  // insert, or touch when resident
          if (e == ref.entries.end()) {
            const uint64_t bytes = rng() % 100;
            lru.insert(key, bytes, op);
            ref.entries[key] = {bytes, 0, ++ref.clock, op};
          } else {
            lru.touch(key);
            if (e->second.pins == 0) e->second.last_use = ++ref.clock;
          }
          break;
        case 1:
          if (e != ref.entries.end()) {
            lru.pin(key);
            ++e->second.pins;
          }
          break;
        case 2:
          if (e != ref.entries.end() && e->second.pins > 0) {
            const bool last = --e->second.pins == 0;
            EXPECT_EQ(lru.unpin(key), last);
            if (last) e->second.last_use = ++ref.clock;
          }
          break;
        case 3:
          lru.erase(key);  // a no-op for a key that is not resident
          ref.entries.erase(key);
          break;
        case 4:
          if (lru.evictable() > 0) {
            const int victim = lru.pop_oldest();
            ASSERT_EQ(std::optional<int>(victim), ref.oldest());
            ref.entries.erase(victim);
          }
          break;
        case 5:  // the owners' loop: evict down to the budget
          while (lru.over_budget() && lru.evictable() > 0) {
            ASSERT_EQ(lru.oldest(), ref.oldest());
            ref.entries.erase(lru.pop_oldest());
          }
          EXPECT_TRUE(!lru.over_budget() || ref.evictable() == 0);
          break;
      }
      expect_same(lru, ref, kKeys);
    }
  }
}

TEST(ByteLru, PinnedEntriesAreNeverVictims) {
  ByteLru<int> lru(100);
  for (int k = 0; k < 6; ++k) lru.insert(k, 50);
  lru.pin(1);
  lru.pin(3);
  lru.pin(3);
  EXPECT_EQ(lru.pinned_bytes(), 100u);
  std::vector<int> victims;
  while (lru.evictable() > 0) victims.push_back(lru.pop_oldest());
  EXPECT_EQ(victims, (std::vector<int>{0, 2, 4, 5}));
  EXPECT_EQ(lru.size(), 2u);
  EXPECT_EQ(lru.resident_bytes(), 100u);
  EXPECT_EQ(lru.oldest(), std::nullopt);
  // touch() leaves a pinned entry where it is; the last unpin makes it the newest.
  lru.touch(1);
  EXPECT_EQ(lru.oldest(), std::nullopt);
  EXPECT_FALSE(lru.unpin(3));
  EXPECT_EQ(lru.oldest(), std::nullopt);
  EXPECT_TRUE(lru.unpin(3));
  EXPECT_EQ(lru.oldest(), 3);
  lru.insert(7, 10);
  EXPECT_TRUE(lru.unpin(1));
  EXPECT_EQ(lru.pop_oldest(), 3);
  EXPECT_EQ(lru.pop_oldest(), 7);
  EXPECT_EQ(lru.pop_oldest(), 1);
  EXPECT_EQ(lru.size(), 0u);
  EXPECT_EQ(lru.resident_bytes(), 0u);
  EXPECT_EQ(lru.pinned_bytes(), 0u);
}

TEST(ByteLru, ErasingAPinnedEntryReleasesItsBytes) {
  ByteLru<int> lru(100);
  lru.insert(1, 30);
  lru.insert(2, 40);
  lru.pin(2);
  lru.erase(2);
  EXPECT_FALSE(lru.contains(2));
  EXPECT_EQ(lru.pinned_bytes(), 0u);
  EXPECT_EQ(lru.resident_bytes(), 30u);
  EXPECT_EQ(lru.evictable(), 1u);
}

TEST(ByteLru, Budget) {
  ByteLru<int> lru(100);
  EXPECT_EQ(lru.budget(), 100u);
  EXPECT_TRUE(lru.fits(100));
  EXPECT_FALSE(lru.fits(101));
  lru.insert(1, 60);
  EXPECT_TRUE(lru.fits(40));
  EXPECT_FALSE(lru.fits(41));
  EXPECT_FALSE(lru.over_budget());
  lru.insert(2, 60);  // the owner decides when to evict: the LRU only reports
  EXPECT_TRUE(lru.over_budget());
  EXPECT_EQ(lru.resident_bytes(), 120u);
  lru.set_budget(200);
  EXPECT_FALSE(lru.over_budget());
  EXPECT_TRUE(lru.fits(80));
}

TEST(ByteLru, ValuesAndOtherKeys) {
  ByteLru<std::string, std::string> lru(1000);
  lru.insert("a", 1, "alpha");
  lru.insert("b", 2, "beta");
  *lru.find("a") += "!";
  lru.touch("a");
  EXPECT_EQ(*lru.find("a"), "alpha!");
  EXPECT_EQ(lru.oldest(), "b");
  // Moving keeps the order (the lists' iterators stay valid).
  ByteLru<std::string, std::string> moved = std::move(lru);
  EXPECT_EQ(moved.pop_oldest(), "b");
  EXPECT_EQ(moved.pop_oldest(), "a");
}

}  // namespace
}  // namespace frontier::store
