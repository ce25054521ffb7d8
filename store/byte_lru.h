// ByteLru: the one least-recently-used bookkeeping behind every byte budget (the PageCache's
// pages, the PagedWorld's decoded cells, the collision grid's bricks). It holds, per key, a size
// in bytes, a pin count and an optional value, and answers "which entry goes first" in O(1).
// It never evicts by itself: each owner has its own rule for when to stop (keep the newest page,
// keep the brick just read, free down to half the share), so it asks oldest() / pop_oldest()
// in its own loop, against budget() and resident_bytes().
//
// Two lists, as in LevelDB's cache: every entry is on exactly one of them.
//   evictable_  entries with no pins, oldest at the front, newest at the back: the victims;
//   pinned_     entries with pins > 0, in no particular order: never victims.
// insert() and the last unpin() put an entry at the back of evictable_; touch() moves an
// unpinned one there. Lists are spliced, never reallocated, so every operation is O(1) (average,
// for the hash map lookup).
// Invariants: resident_bytes() = sum of all entries' sizes; pinned_bytes() = sum over pinned_;
// evictable() = evictable_.size(). Not thread-safe: owners hold their own lock.
#pragma once

#include <cassert>
#include <cstdint>
#include <functional>
#include <list>
#include <optional>
#include <unordered_map>
#include <utility>

namespace frontier::store {

// The value of a ByteLru that only orders keys (its owner keeps the data elsewhere).
struct NoValue {};

template <class Key, class Value = NoValue, class Hash = std::hash<Key>>
class ByteLru {
 public:
  explicit ByteLru(uint64_t budget_bytes = 0) : budget_(budget_bytes) {}
  // Moving keeps the lists' iterators valid; a copy would not.
  ByteLru(ByteLru&&) = default;
  ByteLru& operator=(ByteLru&&) = default;
  ByteLru(const ByteLru&) = delete;
  ByteLru& operator=(const ByteLru&) = delete;

  uint64_t budget() const { return budget_; }
  void set_budget(uint64_t budget_bytes) { budget_ = budget_bytes; }
  // Bytes of every entry, pinned or not.
  uint64_t resident_bytes() const { return resident_; }
  uint64_t pinned_bytes() const { return pinned_bytes_; }
  bool over_budget() const { return resident_ > budget_; }
  // True if `more` bytes fit beside what is resident.
  bool fits(uint64_t more) const { return resident_ + more <= budget_; }
  // Entries, pinned included; entries that may be victims.
  size_t size() const { return entries_.size(); }
  size_t evictable() const { return evictable_.size(); }

  bool contains(const Key& key) const { return entries_.count(key) != 0; }
  // The value of `key`, or null if it is not resident.
  Value* find(const Key& key) {
    auto it = entries_.find(key);
    return it == entries_.end() ? nullptr : &it->second.value;
  }
  // REQUIRES: contains(key).
  uint64_t bytes(const Key& key) const { return entry(key).bytes; }
  int pins(const Key& key) const { return entry(key).pins; }

  // Adds `key` as the newest unpinned entry. REQUIRES: !contains(key).
  Value& insert(const Key& key, uint64_t bytes, Value value = {}) {
    [[maybe_unused]] auto [it, inserted] = entries_.try_emplace(key);
    assert(inserted && "ByteLru::insert of a resident key");
    Entry& e = it->second;
    e.value = std::move(value);
    e.bytes = bytes;
    e.pos = evictable_.insert(evictable_.end(), key);
    resident_ += bytes;
    return e.value;
  }
  // Makes an unpinned entry the newest; a pinned one becomes the newest when it is unpinned.
  // REQUIRES: contains(key).
  void touch(const Key& key) {
    Entry& e = entry(key);
    if (e.pins == 0) evictable_.splice(evictable_.end(), evictable_, e.pos);
  }
  // A pinned entry is never a victim. REQUIRES: contains(key).
  void pin(const Key& key) {
    Entry& e = entry(key);
    if (e.pins++ == 0) {
      pinned_.splice(pinned_.end(), evictable_, e.pos);
      pinned_bytes_ += e.bytes;
    }
  }
  // Returns true when that was the last pin: the entry is now the newest unpinned one.
  // REQUIRES: pins(key) > 0.
  bool unpin(const Key& key) {
    Entry& e = entry(key);
    assert(e.pins > 0 && "ByteLru::unpin of an unpinned key");
    if (--e.pins > 0) return false;
    evictable_.splice(evictable_.end(), pinned_, e.pos);
    pinned_bytes_ -= e.bytes;
    return true;
  }
  // Removes `key`, pinned or not; no-op if it is not resident.
  void erase(const Key& key) {
    auto it = entries_.find(key);
    if (it == entries_.end()) return;
    Entry& e = it->second;
    if (e.pins > 0) {
      pinned_.erase(e.pos);
      pinned_bytes_ -= e.bytes;
    } else {
      evictable_.erase(e.pos);
    }
    resident_ -= e.bytes;
    entries_.erase(it);
  }

  // The least recently used unpinned key, or nullopt when every entry is pinned (or none).
  std::optional<Key> oldest() const {
    if (evictable_.empty()) return std::nullopt;
    return evictable_.front();
  }
  // Removes the oldest unpinned entry and returns its key. REQUIRES: evictable() > 0.
  Key pop_oldest() {
    assert(!evictable_.empty());
    Key key = evictable_.front();
    erase(key);
    return key;
  }

 private:
  struct Entry {
    Value value{};
    uint64_t bytes = 0;
    int pins = 0;
    typename std::list<Key>::iterator pos;  // in evictable_ if pins == 0, else in pinned_
  };
  Entry& entry(const Key& key) {
    auto it = entries_.find(key);
    assert(it != entries_.end() && "ByteLru: key not resident");
    return it->second;
  }
  const Entry& entry(const Key& key) const {
    auto it = entries_.find(key);
    assert(it != entries_.end() && "ByteLru: key not resident");
    return it->second;
  }

  uint64_t budget_ = 0;
  uint64_t resident_ = 0;
  uint64_t pinned_bytes_ = 0;
  std::unordered_map<Key, Entry, Hash> entries_;
  std::list<Key> evictable_;  // front = oldest
  std::list<Key> pinned_;
};

}  // namespace frontier::store
