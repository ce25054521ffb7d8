#include "store/page_cache.h"

#include <cassert>
#include <chrono>
#include <exception>
#include <string>

namespace frontier::store {

Pin& Pin::operator=(Pin&& other) noexcept {
  if (this != &other) {
    reset();
    cache_ = other.cache_;
    id_ = other.id_;
    codec_ = other.codec_;
    bytes_ = other.bytes_;
    other.cache_ = nullptr;
    other.bytes_ = {};
  }
  return *this;
}

void Pin::reset() {
  if (cache_ != nullptr) {
    cache_->unpin(id_);
    cache_ = nullptr;
    bytes_ = {};
  }
}

PageCache::PageCache(PageSource& source, uint64_t budget_bytes, int loader_threads)
    : source_(source), budget_(budget_bytes), lru_(budget_bytes) {
  int n = loader_threads < 1 ? 1 : loader_threads;
  for (int i = 0; i < n; ++i) loaders_.emplace_back([this] { loader_main(); });
}

PageCache::~PageCache() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  work_.notify_all();
  for (std::thread& t : loaders_) t.join();
  assert(pinned_bytes_.load() == 0 && "PageCache destroyed while pages are pinned");
}

Pin PageCache::pin_locked(PageId id, Entry& e) {
  assert(e.state == State::Resident);
  lru_.pin(id);
  pinned_bytes_ = lru_.pinned_bytes();
  return Pin(this, id, e.data.codec, e.data.bytes);
}

void PageCache::unpin(PageId id) {
  std::lock_guard lock(mutex_);
  assert(entries_.count(id) != 0 && lru_.pins(id) > 0);
  if (lru_.unpin(id)) {
    pinned_bytes_ = lru_.pinned_bytes();
    evict_to_budget();
  }
}

void PageCache::evict_lru() {
  entries_.erase(lru_.pop_oldest());
  resident_bytes_ = lru_.resident_bytes();
  ++evictions_;
}

void PageCache::evict_to_budget() {
  // Keep the most recently used unpinned page even over budget (see the header).
  while (lru_.over_budget() && lru_.evictable() > 1) evict_lru();
}

void PageCache::load_and_publish(std::unique_lock<std::mutex>& lock, PageId id) {
  lock.unlock();
  auto start = std::chrono::steady_clock::now();
  // A throwing source must not leave the entry Loading forever (waiters would hang).
  Result<PageData> loaded = Status::io_error("page " + std::to_string(id) + ": load threw");
  try {
    loaded = source_.load(id);
  } catch (const std::exception& e) {
    loaded = Status::io_error("page " + std::to_string(id) + ": load threw: " + e.what());
  } catch (...) {
  }
  auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
      std::chrono::steady_clock::now() - start);
  lock.lock();
  page_in_ns_ += static_cast<uint64_t>(ns.count());
  // The entry cannot have been erased: Loading entries are not in the LRU.
  Entry& e = entries_.at(id);
  if (loaded) {
    // Make room first, then charge: resident_bytes_ only ever falls and then rises to its final
    // value, so a lock-free stats() reader never sees more than the post-publish charge.
    uint64_t size = loaded->bytes.size();
    while (lru_.evictable() > 0 && !lru_.fits(size)) evict_lru();
    e.data = std::move(loaded.value());
    e.state = State::Resident;
    lru_.insert(id, size);
    resident_bytes_ = lru_.resident_bytes();
    bytes_read_ += size;
    ++page_ins_;
  } else {
    e.state = State::Failed;
    e.error = loaded.status();
    ++errors_;
  }
  loaded_.notify_all();
}

Result<Pin> PageCache::pin(PageId id) {
  std::unique_lock lock(mutex_);
  bool counted = false;
  for (;;) {
    auto [it, inserted] = entries_.try_emplace(id);  // a new entry starts Queued
    Entry& e = it->second;
    switch (e.state) {
      case State::Resident:
        if (!counted) ++hits_;
        return pin_locked(id, e);
      case State::Failed:
        return e.error;
      case State::Queued:
        // Load on this thread rather than wait behind the loader's queue; a loader that later
        // pops this id skips it because the entry is no longer Queued.
        if (!counted) ++misses_;
        counted = true;
        e.state = State::Loading;
        load_and_publish(lock, id);
        break;  // the lock is held again and the page is the LRU's newest: pin it next round
      case State::Loading:
        if (!counted) ++misses_;
        counted = true;
        // Another thread publishes it; it may be evicted again before we wake (then we load it).
        loaded_.wait(lock, [&] {
          auto f = entries_.find(id);
          return f == entries_.end() || f->second.state != State::Loading;
        });
        break;
    }
  }
}

std::optional<Pin> PageCache::try_pin(PageId id) {
  std::lock_guard lock(mutex_);
  auto it = entries_.find(id);
  if (it == entries_.end() || it->second.state != State::Resident) {
    ++misses_;
    return std::nullopt;
  }
  ++hits_;
  return pin_locked(id, it->second);
}

void PageCache::request(PageId id) {
  {
    std::lock_guard lock(mutex_);
    auto [it, inserted] = entries_.try_emplace(id);
    if (!inserted) return;
    it->second.state = State::Queued;
    queue_.push_back(id);
  }
  work_.notify_one();
}

bool PageCache::ready(PageId id) const {
  std::lock_guard lock(mutex_);
  auto it = entries_.find(id);
  return it != entries_.end() && it->second.state == State::Resident;
}

void PageCache::arrived(std::span<const PageId> ids, std::vector<uint8_t>& out) const {
  out.assign(ids.size(), 0);
  std::lock_guard lock(mutex_);
  for (size_t i = 0; i < ids.size(); ++i) {
    auto it = entries_.find(ids[i]);
    out[i] = it != entries_.end() && (it->second.state == State::Resident || it->second.state == State::Failed) ? 1 : 0;
  }
}

bool PageCache::failed(PageId id) const {
  std::lock_guard lock(mutex_);
  auto it = entries_.find(id);
  return it != entries_.end() && it->second.state == State::Failed;
}

void PageCache::loader_main() {
  std::unique_lock lock(mutex_);
  for (;;) {
    work_.wait(lock, [&] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    PageId id = queue_.front();
    queue_.pop_front();
    auto it = entries_.find(id);
    if (it == entries_.end() || it->second.state != State::Queued) continue;
    it->second.state = State::Loading;
    load_and_publish(lock, id);
  }
}

PageCacheStats PageCache::stats() const {
  PageCacheStats s;
  s.budget_bytes = budget_;
  s.resident_bytes = resident_bytes_.load();
  s.pinned_bytes = pinned_bytes_.load();
  s.hits = hits_.load();
  s.misses = misses_.load();
  s.bytes_read = bytes_read_.load();
  s.page_ins = page_ins_.load();
  s.evictions = evictions_.load();
  s.errors = errors_.load();
  s.page_in_ms = static_cast<double>(page_in_ns_.load()) / 1e6;
  return s;
}

}  // namespace frontier::store
