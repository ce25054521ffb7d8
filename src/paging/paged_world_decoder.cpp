// PagedWorld's decoder: a thread that decodes and refines wanted cells whose pages have arrived,
// off the frame's critical path (see "Decoding ahead" in paged_world.h). sync() only places
// what it finished.
#include "src/paging/paged_world.h"
#include "src/paging/paged_world_internal.h"

#include <malloc.h>
#include "src/core/geometry.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>

namespace frontier {

namespace {

// How long the decoder sleeps when nothing is ready (pages arrive from the cache's loader
// thread, which does not signal).
constexpr auto kDecoderIdle = std::chrono::microseconds(500);


}  // namespace

void PagedWorld::start_decoder() {
  decoder_ = std::make_unique<DecoderState>();
  decoder_->cap = std::max<uint64_t>(lru_.budget() / kDecodeAheadShareDivisor, 1);
  publish_room();
  decoder_->thread = std::thread([this] { decoder_loop(); });
}

void PagedWorld::stop_decoder() {
  if (!decoder_) return;
  {
    std::lock_guard<std::mutex> lock(decoder_->mutex);
    decoder_->stop = true;
  }
  decoder_->cv.notify_all();
  decoder_->thread.join();
  decoder_.reset();
}

bool PagedWorld::decoder_blocked() const {
  std::lock_guard<std::mutex> lock(decoder_->mutex);
  return decoder_->blocked;
}

void PagedWorld::set_decode_eye(const Vec3& eye) {
  std::lock_guard<std::mutex> lock(decoder_->mutex);
  decoder_->eye = eye;
  decoder_->has_eye = true;
}

void PagedWorld::publish_room() {
  if (!decoder_) return;
  const uint64_t used = lru_.bytes() + garbage_bytes_ + proxy_bytes_;
  const uint64_t room = used < lru_.budget() ? lru_.budget() - used : 0;
  {
    std::lock_guard<std::mutex> lock(decoder_->mutex);
    decoder_->room = room;
    ++decoder_->room_generation;
  }
  decoder_->cv.notify_all();
}

std::vector<uint32_t> PagedWorld::pick_ready(const Vec3& eye, bool has_eye, size_t count) {
  // The wanted cells whose pages are in (or failed) that span the most pixels: size over
  // distance from the eye (largest screen-space error first). Chosen on a copy of the list, so
  // that render workers' want() never waits for the scan; taken off the list afterwards.
  std::vector<uint32_t> snapshot;
  {
    std::lock_guard<std::mutex> lock(wanted_mutex_);
    snapshot = wanted_;
  }
  if (snapshot.empty()) return {};
  std::vector<store::PageId> pages(snapshot.size());
  for (size_t i = 0; i < snapshot.size(); ++i) pages[i] = model_.cells()[snapshot[i]].page;
  std::vector<uint8_t> in;
  cache_->arrived(pages, in);
  std::vector<std::pair<double, uint32_t>> ranked;
  for (size_t i = 0; i < snapshot.size(); ++i) {
    if (!in[i]) continue;
    ranked.emplace_back(has_eye ? -screen_size(snapshot[i], eye) : 0.0, snapshot[i]);
  }
  count = std::min(count, ranked.size());
  std::partial_sort(ranked.begin(), ranked.begin() + std::ptrdiff_t(count), ranked.end());
  std::vector<uint32_t> chosen;
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  for (size_t k = 0; k < count; ++k) {
    const auto it = std::find(wanted_.begin(), wanted_.end(), ranked[k].second);
    if (it == wanted_.end()) continue;  // taken by sync() meanwhile
    *it = wanted_.back();
    wanted_.pop_back();
    chosen.push_back(ranked[k].second);
  }
  std::lock_guard<std::mutex> dl(decoder_->mutex);
  decoder_->in_flight += chosen.size();
  return chosen;
}

double PagedWorld::screen_size(uint32_t cell, const Vec3& eye) const {
  const Aabb& b = model_.cells()[cell].bounds;
  return glm::length(b.hi - b.lo) / std::max(distance_to_box(eye, b), 1e-12);
}

void PagedWorld::decoder_loop() {
  DecoderState& s = *decoder_;
  uint64_t blocked_at = UINT64_MAX;  // room generation at which a decode did not fit
  while (true) {
    bool trim = false;
    {
      std::lock_guard<std::mutex> lock(s.mutex);
      std::swap(trim, s.trim);
    }
    // Decoded cells and proxies are made on this thread and freed on the frame's, in sizes that
    // leave the allocator's free lists fragmented: they kept a 512 MiB walk's resident set at
    // twice its budget. Whole free pages go back to the system here, off the frame's thread.
    if (trim) malloc_trim(0);
    {
      std::unique_lock<std::mutex> lock(s.mutex);
      if (s.stop) return;
      if (s.paused) {
        s.cv.wait_for(lock, kDecoderIdle);
        continue;
      }
    }
    // Proxies first, whatever the room (they are small, and coarse to fine needs them): decoded
    // and their trees built here; the frame's thread only installs them (load_proxies).
    bool proxies_decoded = false;
    if (!proxy_.empty()) {
      for (const uint32_t node : pick_ready_proxies(kDecodeBatch)) {
        proxies_decoded = true;
        ProxyDecoded p;
        const auto start = std::chrono::steady_clock::now();
        bool decoded = false;
        s.arena.execute([&] { decoded = decode_proxy(node, p); });
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        if (!decoded) {
          requeue_proxy(node);  // its page went: asked for again
          continue;
        }
        std::lock_guard<std::mutex> lock(s.mutex);
        s.ms += ms;
        s.proxies_done.push_back(std::move(p));
      }
    }
    Vec3 eye;
    bool has_eye;
    {
      std::unique_lock<std::mutex> lock(s.mutex);
      if (s.stop) return;
      s.blocked = s.room_generation == blocked_at;
      if (s.done_bytes >= s.cap || s.blocked) {
        if (!proxies_decoded) s.cv.wait_for(lock, kDecoderIdle);
        continue;
      }
      eye = s.eye;
      has_eye = s.has_eye;
    }
    const std::vector<uint32_t> cells = pick_ready(eye, has_eye, kDecodeBatch);
    if (cells.empty()) {
      // Nothing ready: sleep, unless proxies were decoded (more may be ready).
      std::unique_lock<std::mutex> lock(s.mutex);
      if (!s.stop && !proxies_decoded) s.cv.wait_for(lock, kDecoderIdle);
      continue;
    }
    std::vector<uint32_t> back;
    for (const uint32_t cell : cells) {
      bool fits = true;
      {
        std::lock_guard<std::mutex> lock(s.mutex);
        fits = !s.stop && s.done_bytes < s.cap && s.room_generation != blocked_at;
      }
      if (!fits) {
        back.push_back(cell);
        continue;
      }
      const auto start = std::chrono::steady_clock::now();
      Decoded d;
      // In the decoder's own one-thread arena: the subtree build's parallel tasks are then never
      // stolen by a render worker or by sync() waiting in the frame's arena (which would make
      // them wait for this decode), and run here, one after the other.
      s.arena.execute([&] { decode(cell, d); });
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
      std::lock_guard<std::mutex> lock(s.mutex);
      s.ms += ms;
      // Decoded but over the room the world had at the last sync(), or over the cap beside
      // other finished cells (one cell may exceed the cap alone: a small budget's cells are
      // larger than a sixteenth of it): not kept (its memory would not be accounted), wanted
      // again; the decoder waits for the next sync().
      const bool over_cap = !s.done.empty() && s.done_bytes + d.bytes > s.cap;
      if (!d.retry && d.status && (over_cap || s.done_bytes + d.bytes > s.room)) {
        blocked_at = s.room_generation;
        s.blocked = true;
        d.retry = true;
      }
      if (d.retry) {
        back.push_back(cell);
      } else {
        s.done_bytes += d.bytes;
        s.done.push_back(std::move(d));
        --s.in_flight;
      }
    }
    if (!back.empty()) {
      // A page that went between the pick and the decode (the page cache evicted it) is asked
      // for again: nothing else would bring it back while the frame waits for it.
      for (const uint32_t cell : back) cache_->request(model_.cells()[cell].page);
      std::lock_guard<std::mutex> lock(wanted_mutex_);
      wanted_.insert(wanted_.end(), back.begin(), back.end());
      std::lock_guard<std::mutex> dl(s.mutex);
      s.in_flight -= back.size();
    }
  }
}

std::vector<PagedWorld::Decoded> PagedWorld::take_decoded() {
  std::vector<Decoded> out;
  if (!decoder_) return out;
  std::lock_guard<std::mutex> lock(decoder_->mutex);
  out.swap(decoder_->done);
  decoder_->done_bytes = 0;
  counters_.decode_ahead_ms += decoder_->ms;
  decoder_->ms = 0.0;
  return out;
}

void PagedWorld::keep_decoded(std::move_iterator<std::vector<Decoded>::iterator> first,
                              std::move_iterator<std::vector<Decoded>::iterator> last) {
  std::lock_guard<std::mutex> lock(decoder_->mutex);
  std::vector<Decoded> rest(first, last);
  for (const Decoded& d : rest) decoder_->done_bytes += d.bytes;
  // Ahead of what the decoder finished since: they were chosen first.
  decoder_->done.insert(decoder_->done.begin(), std::make_move_iterator(rest.begin()), std::make_move_iterator(rest.end()));
}

}  // namespace frontier
