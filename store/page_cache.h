// PageCache: a byte budget of decoded pages, pinned by move-only handles, evicted LRU, filled by
// loader threads. It knows nothing of formats: a PageSource turns a page id into owned bytes
// (store/store_page_source.h adapts a StoreReader). The file side (reads, checksums) lives in
// StoreReader and PageFile; this file is only memory (DuckDB's split of the buffer manager).
//
// Each page id has at most one entry, in one of four states:
//   Queued   requested by request(), waiting for a loader thread (no bytes charged)
//   Loading  being read by a loader thread or by a pin() caller (no bytes charged)
//   Resident bytes held; charged to resident_bytes, and in the LRU (store/byte_lru.h), where
//            it is a victim while its pin count is 0.
//   Failed   the source returned an error; the Status is remembered and returned by every pin()
//            of that id (no retry); nothing charged.
// Invariants (all under one mutex):
//   - a page with pin count > 0 is never evicted;
//   - resident_bytes = sum of sizes of Resident entries; pinned_bytes = those with pins > 0;
//   - after every public call returns, resident_bytes <= budget, unless everything resident is
//     pinned except at most one page: the most recently used unpinned page is kept even when it
//     alone breaks the budget, so that a budget smaller than one page still makes progress
//     (request() -> ready() -> pin()) instead of evicting each page as it arrives. Pinned pages
//     may push resident_bytes above the budget for as long as they are pinned.
// Counters are atomics so that a stats reader need not take the lock; resident_bytes_ and
// pinned_bytes_ mirror lru_'s after every change.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <span>
#include <thread>
#include <unordered_map>
#include <vector>

#include "store/byte_lru.h"
#include "store/page_id.h"
#include "store/status.h"

namespace frontier::store {

struct PageData {
  uint8_t codec = 0;
  std::vector<uint8_t> bytes;
};

// Where the cache gets pages from. load() is called from loader threads and from pin() callers
// at the same time (never twice at once for the same id): implementations must be thread-safe.
class PageSource {
 public:
  virtual ~PageSource() = default;
  // The decoded page, owned by the caller, or the error (Corruption, IoError, ...).
  // Should not throw; if it does, the cache records the page as failed with an IoError.
  virtual Result<PageData> load(PageId id) = 0;
};

// A snapshot of the counters.
struct PageCacheStats {
  uint64_t budget_bytes = 0;
  uint64_t resident_bytes = 0;
  uint64_t pinned_bytes = 0;
  uint64_t hits = 0;       // pin/try_pin that found the page resident
  uint64_t misses = 0;     // pin that had to load or wait for a load; try_pin that found nothing
                           // (a pin of a failed page counts in neither; it was counted in errors)
  uint64_t bytes_read = 0; // bytes returned by the source (decoded size)
  uint64_t page_ins = 0;   // successful loads
  uint64_t evictions = 0;
  uint64_t errors = 0;     // failed loads (each id fails at most once)
  double page_in_ms = 0;   // total wall time spent in PageSource::load
};

class PageCache;

// A pinned page: while it exists the page stays resident and bytes() stays valid.
// Move-only; the destructor (or reset()) unpins. REQUIRES: destroyed before its cache.
// A Pin may be moved to and released on any thread.
class Pin {
 public:
  Pin() = default;
  Pin(Pin&& other) noexcept { *this = std::move(other); }
  Pin& operator=(Pin&& other) noexcept;
  Pin(const Pin&) = delete;
  Pin& operator=(const Pin&) = delete;
  ~Pin() { reset(); }

  void reset();
  explicit operator bool() const { return cache_ != nullptr; }
  PageId id() const { return id_; }
  uint8_t codec() const { return codec_; }
  std::span<const uint8_t> bytes() const { return bytes_; }

 private:
  friend class PageCache;
  Pin(PageCache* cache, PageId id, uint8_t codec, std::span<const uint8_t> bytes)
      : cache_(cache), id_(id), codec_(codec), bytes_(bytes) {}
  PageCache* cache_ = nullptr;
  PageId id_ = 0;
  uint8_t codec_ = 0;
  std::span<const uint8_t> bytes_;
};

class PageCache {
 public:
  // `source` must outlive the cache. loader_threads >= 1 (smaller values are treated as 1).
  PageCache(PageSource& source, uint64_t budget_bytes, int loader_threads = 1);
  // REQUIRES: no Pin of this cache is alive. Stops the loader threads (a load in flight finishes).
  ~PageCache();
  PageCache(const PageCache&) = delete;
  PageCache& operator=(const PageCache&) = delete;

  // Blocking: returns the pinned page, loading it on the calling thread if needed (or waiting
  // for a loader that already started it). Returns the page's error if it failed, now or before.
  // Thread-safe.
  Result<Pin> pin(PageId id);
  // Non-blocking: the pinned page if resident, else nullopt (never starts a load; call
  // request()). Thread-safe.
  std::optional<Pin> try_pin(PageId id);
  // Asks a loader thread to page `id` in; returns at once. No-op if the page is already
  // resident, queued, loading or failed. Thread-safe.
  void request(PageId id);
  // True if `id` is resident (a later try_pin may still miss if it is evicted in between).
  bool ready(PageId id) const;
  // True if loading `id` failed; pin(id) returns the error.
  bool failed(PageId id) const;
  // ready() || failed() for each of `ids`, under one lock: out[i] is 1 when ids[i] arrived.
  void arrived(std::span<const PageId> ids, std::vector<uint8_t>& out) const;

  PageCacheStats stats() const;
  uint64_t budget_bytes() const { return budget_; }
  uint64_t resident_bytes() const { return resident_bytes_.load(); }
  uint64_t pinned_bytes() const { return pinned_bytes_.load(); }

 private:
  friend class Pin;
  enum class State { Queued, Loading, Resident, Failed };
  struct Entry {
    State state = State::Queued;
    PageData data;
    Status error;
  };

  void unpin(PageId id);
  // Loads `id` (whose entry the caller set to Loading) without holding the lock, then publishes.
  void load_and_publish(std::unique_lock<std::mutex>& lock, PageId id);
  Pin pin_locked(PageId id, Entry& e);  // REQUIRES: lock held, e Resident
  void evict_to_budget();               // REQUIRES: lock held
  void evict_lru();                     // REQUIRES: lock held, lru_.evictable() > 0
  void loader_main();

  PageSource& source_;
  const uint64_t budget_;

  mutable std::mutex mutex_;
  std::condition_variable loaded_;    // an entry left the Loading state
  std::condition_variable work_;      // the queue grew or stop_ was set
  std::unordered_map<PageId, Entry> entries_;
  ByteLru<PageId> lru_;               // the Resident entries: sizes, pins, order of use
  std::deque<PageId> queue_;
  bool stop_ = false;
  std::vector<std::thread> loaders_;

  std::atomic<uint64_t> resident_bytes_{0};
  std::atomic<uint64_t> pinned_bytes_{0};
  std::atomic<uint64_t> hits_{0};
  std::atomic<uint64_t> misses_{0};
  std::atomic<uint64_t> bytes_read_{0};
  std::atomic<uint64_t> page_ins_{0};
  std::atomic<uint64_t> evictions_{0};
  std::atomic<uint64_t> errors_{0};
  std::atomic<uint64_t> page_in_ns_{0};
};

}  // namespace frontier::store
