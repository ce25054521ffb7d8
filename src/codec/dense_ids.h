// DenseIds: dense ids 0, 1, 2, ... for distinct keys (arrays of 3 or 4 32-bit values) in the
// order they are first seen, as the Draco cell codec numbers vertices, points and faces. An
// open-addressing table of ids into the key list, never more than half full: several times
// faster than std::unordered_map here, which dominated encoding time. Not thread-safe; one per
// encode.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace frontier::cell_page {

template <typename Key>
class DenseIds {
 public:
  static constexpr uint32_t kNone = UINT32_MAX;
  explicit DenseIds(size_t expected) { rehash(expected); }

  // The key's id, a new one (the number of keys seen so far) if it is new.
  uint32_t insert(const Key& key) {
    size_t i = hash(key) & mask_;
    for (;; i = (i + 1) & mask_) {
      const uint32_t slot = slots_[i];
      if (slot == 0) break;
      if (keys_[slot - 1] == key) return slot - 1;
    }
    keys_.push_back(key);
    slots_[i] = static_cast<uint32_t>(keys_.size());
    if (2 * keys_.size() > slots_.size()) rehash(keys_.size());
    return static_cast<uint32_t>(keys_.size() - 1);
  }
  // The key's id, kNone if it was never inserted.
  uint32_t find(const Key& key) const {
    for (size_t i = hash(key) & mask_;; i = (i + 1) & mask_) {
      const uint32_t slot = slots_[i];
      if (slot == 0) return kNone;
      if (keys_[slot - 1] == key) return slot - 1;
    }
  }
  // The keys by id.
  const std::vector<Key>& keys() const { return keys_; }

 private:
  static uint64_t mix64(uint64_t h) {  // MurmurHash3's finalizer
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdull;
    h ^= h >> 33;
    h *= 0xc4ceb9fe1a85ec53ull;
    return h ^ (h >> 33);
  }
  static uint64_t hash(const Key& key) {
    const auto u = [&](size_t k) { return k < key.size() ? static_cast<uint64_t>(static_cast<uint32_t>(key[k])) : 0; };
    return mix64((u(0) | u(1) << 32) ^ mix64(u(2) | u(3) << 32));
  }
  void rehash(size_t keys) {
    size_t capacity = 16;
    while (capacity < 4 * keys) capacity *= 2;  // load factor <= 1/4 after growing
    slots_.assign(capacity, 0);
    mask_ = capacity - 1;
    for (uint32_t id = 0; id < keys_.size(); ++id) {
      size_t i = hash(keys_[id]) & mask_;
      while (slots_[i] != 0) i = (i + 1) & mask_;
      slots_[i] = id + 1;
    }
  }
  std::vector<uint32_t> slots_;  // 0: empty, else id + 1
  std::vector<Key> keys_;
  size_t mask_ = 0;
};

}  // namespace frontier::cell_page
