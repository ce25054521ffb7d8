// PagedWorld: grafting paged-in store cells into one tree and one scene (see paged_world.h).
#include "src/paging/paged_world.h"
#include "src/paging/paged_world_internal.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/info.h>

#include <sys/mman.h>

#include <algorithm>
#include <cstdint>
#include <thread>

namespace frontier {

namespace {

constexpr uint64_t kMinCompressedShare = 1ull << 20;

// Grafting a cell appends to the world's arrays, which were reserved but never touched: with
// 4 KiB pages that was a page fault per 4 KiB, most of a graft's time on a virtual machine (1.5
// ms per 500-triangle cell, perf). Huge pages where the kernel offers them on request
// (transparent_hugepage = madvise): one fault per 2 MiB.
void advise_huge_pages(const void* data, size_t bytes) {
  constexpr uintptr_t kHuge = uintptr_t{2} << 20;
  const uintptr_t lo = (reinterpret_cast<uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
  const uintptr_t hi = (reinterpret_cast<uintptr_t>(data) + bytes) & ~(kHuge - 1);
  if (hi > lo) (void)madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
}
// Gives the memory of a world array past its size back to the system (whole huge pages: the
// array regrows into them at the cost of a fault each), so that the resident set follows what
// the arrays hold after a compaction, not the most they ever held.
template <typename T>
void release_tail(std::vector<T>& v) {
  constexpr uintptr_t kHuge = uintptr_t{2} << 20;
  const uintptr_t lo = (reinterpret_cast<uintptr_t>(v.data() + v.size()) + kHuge - 1) & ~(kHuge - 1);
  const uintptr_t hi = (reinterpret_cast<uintptr_t>(v.data() + v.capacity())) & ~(kHuge - 1);
  if (hi > lo) (void)madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_DONTNEED);
}
// Bytes of the world's arrays that a cell's scene and subtree occupy once grafted (with
// `normals`, the world keeps shading normals for every triangle: Scene's normals are all or none).
uint64_t charge_of(const Scene& s, const KdTree& t, bool normals) {
  const size_t normal_count = normals ? s.triangles.size() : s.triangle_normals.size();
  uint64_t b = s.prims.size() * sizeof(PrimRef) + s.triangles.size() * sizeof(Triangle) +
               normal_count * sizeof(std::array<Vec3, 3>) + s.spheres.size() * sizeof(Sphere) +
               s.boxes.size() * sizeof(Box) + s.cones.size() * sizeof(Cone) + s.quadrics.size() * sizeof(Quadric);
  return b + tree_bytes(t, kPerCellOverhead);
}

}  // namespace


// What one sync() call did so far.
struct PagedWorld::SyncPass {
  bool changed = false;
  bool full = false;               // evicting: the room is full of cells grafted by this call
  std::vector<uint32_t> later;     // wanted again
  std::vector<uint32_t> grafted;
};


PagedWorld::PagedWorld(const StoreModel& model, const PagedWorldOptions& options)
    : model_(model), cell_build_(options.cell_build), budget_(options.budget_bytes) {
  const uint64_t compressed = std::max(kMinCompressedShare, budget_ / 8);
  const uint64_t decoded_budget = budget_ > compressed ? budget_ - compressed : 0;
  source_ = std::make_unique<store::StorePageSource>(model.reader());
  cache_ = std::make_unique<store::PageCache>(*source_, std::min(compressed, budget_), options.io_threads);

  const StoreModelInfo& info = model.info();
  scene_.materials = info.materials;
  scene_.lights = info.lights;
  scene_.camera = info.camera;
  scene_.background = info.background;
  scene_.input_primitives = static_cast<uint32_t>(info.input_primitives);

  // The top tree with ropes; world cell c of the top tree is store cell c.
  const auto& cells = model.cells();
  tree_ = KdTree::top_only(model.nodes(), info.bounds);
  leaf_node_.assign(cells.size(), 0);
  for (size_t n = 0; n < model.nodes().size(); ++n) {
    if (model.nodes()[n].is_leaf()) leaf_node_[model.nodes()[n].child] = static_cast<uint32_t>(n);
  }
  for (size_t c = 0; c < cells.size(); ++c) tree_.cells_[c].content = cells[c].content;
  top_nodes_ = tree_.nodes_.size();
  top_cells_ = tree_.cells_.size();
  missing_.resize(top_cells_);
  owner_.resize(top_cells_);
  for (size_t c = 0; c < top_cells_; ++c) {
    missing_[c] = cells[c].page != StoreCell::kNoPage ? 1 : 0;
    owner_[c] = static_cast<uint32_t>(c);
  }
  slot_.assign(top_cells_, -1);
  failed_.assign(top_cells_, 0);
  lru_ = CellLru(top_cells_, decoded_budget);
  decoded_size_.assign(top_cells_, 0);
  passed_image_.assign(top_cells_, 0);
  grafted_image_.assign(top_cells_, 0);
  wanted_flag_ = std::make_unique<std::atomic<uint8_t>[]>(top_cells_);
  for (size_t c = 0; c < top_cells_; ++c) wanted_flag_[c].store(0, std::memory_order_relaxed);

  // The world's arrays never hold more than the decoded share: reserve what each could reach
  // within it once (address space only: untouched pages cost no memory), so that growing never
  // copies them. Capped, so that a huge --cache does not ask for absurd address space.
  const uint64_t share = std::min<uint64_t>(decoded_budget, uint64_t{16} << 30);
  auto reserve = [&](auto& v, uint64_t bytes_per_item) {
    v.reserve(v.size() + static_cast<size_t>(share / bytes_per_item) + 1);
    advise_huge_pages(v.data(), v.capacity() * sizeof(v[0]));
  };
  const uint64_t per_cell = sizeof(KdTree::Cell) + kPerCellOverhead;
  reserve(tree_.cells_, per_cell);
  reserve(owner_, per_cell);
  reserve(tree_.nodes_, per_cell / 2);  // a subtree has fewer than two nodes per cell
  reserve(tree_.refs_, sizeof(uint32_t) + sizeof(Aabb));
  reserve(tree_.ref_bounds_, sizeof(uint32_t) + sizeof(Aabb));
  reserve(scene_.prims, sizeof(PrimRef) + sizeof(Sphere));  // the smallest primitive
  reserve(scene_.triangles, sizeof(PrimRef) + sizeof(Triangle));
  open_proxies();
  start_decoder();
}

PagedWorld::~PagedWorld() { stop_decoder(); }

void PagedWorld::want(int32_t cell) {
  const auto c = static_cast<size_t>(cell);
  if (c >= top_cells_ || wanted_flag_[c].exchange(1, std::memory_order_acq_rel) != 0) return;
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  wanted_.push_back(static_cast<uint32_t>(c));
  cache_->request(model_.cells()[c].page);
}

size_t PagedWorld::pending() const {
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  std::lock_guard<std::mutex> dl(decoder_->mutex);
  return wanted_.size() + decoder_->in_flight + decoder_->done.size();
}

void PagedWorld::decode(uint32_t cell, Decoded& out) const {
  out.cell = cell;
  const uint64_t page = model_.cells()[cell].page;
  std::optional<store::Pin> pin = cache_->try_pin(page);
  if (!pin) {
    if (cache_->failed(page)) {
      auto r = cache_->pin(page);
      out.status = r ? Status::io_error("page vanished") : r.status();
    } else {
      out.retry = true;
    }
    return;
  }
  // The page's stored in-cell tree when it carries one built with cell_build_; else the build.
  std::optional<KdTree> stored;
  out.status = model_.decode_page(cell, pin->codec(), pin->bytes(), out.scene, cell_build_, stored);
  pin->reset();
  if (!out.status) return;
  if (stored) {
    out.tree = std::move(*stored);
  } else {
    KdBuildOptions options = cell_build_;
    options.root = model_.cells()[cell].bounds;
    out.tree = KdTree::build(out.scene, options);
  }
  out.bytes = charge_of(out.scene, out.tree, normals_.load(std::memory_order_acquire));
}

bool PagedWorld::sync(std::chrono::steady_clock::time_point deadline) { return sync_impl(deadline, false); }

bool PagedWorld::sync_evicting() { return sync_impl(std::chrono::steady_clock::time_point::max(), true); }

bool PagedWorld::unlink_oldest(uint64_t target) {
  while (lru_.bytes() > target) {
    const std::optional<uint32_t> victim = lru_.oldest();
    if (!victim) return false;
    unlink(*victim);
  }
  return true;
}

bool PagedWorld::fits(uint64_t bytes) {
  const uint64_t budget = lru_.budget();
  const uint64_t others = lru_.bytes() + garbage_bytes_ + bytes;
  if (others + proxy_bytes_ <= budget) return true;
  // Proxies nothing draws now give way (least recently drawn first).
  shed_proxies(budget - std::min(budget, others));
  return others + proxy_bytes_ <= budget;
}

bool PagedWorld::evict_for(uint64_t bytes, const std::vector<uint32_t>& keep) {
  const uint64_t budget = lru_.budget();
  if (bytes > budget) return false;
  if (fits(bytes)) return true;
  if (bytes + proxy_bytes_ > budget) return false;
  const uint64_t target = budget - bytes - proxy_bytes_;
  if (!unlink_oldest(target)) {
    // Every cell left was touched in this frame: they go too, in ascending order (the LRU's
    // order among cells of one frame), except those grafted by this sync.
    for (const uint32_t c : lru_.touched_cells()) {
      if (lru_.bytes() <= target) break;
      if (!lru_.resident(c) || std::find(keep.begin(), keep.end(), c) != keep.end()) continue;
      unlink(c);
    }
  }
  if (lru_.bytes() > target) return false;
  if (lru_.bytes() + held_besides_cells() + bytes > budget) compact();
  return true;
}

bool PagedWorld::cells_ready() const {
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  for (const uint32_t c : wanted_) {
    if (cache_->ready(model_.cells()[c].page)) return true;
  }
  return false;
}

std::vector<uint32_t> PagedWorld::take_ready(bool take) {
  std::vector<uint32_t> ready;
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  std::vector<uint32_t> waiting;
  for (const uint32_t c : wanted_) {
    const uint64_t page = model_.cells()[c].page;
    if (cache_->ready(page) || cache_->failed(page)) {
      if (!take) {
        waiting.push_back(c);
        continue;
      }
      ready.push_back(c);
    } else {
      // No-op while queued or loading; again if it was evicted unread.
      cache_->request(page);
      waiting.push_back(c);
    }
  }
  wanted_.swap(waiting);
  return ready;
}

// Once a cell did not fit in this frame, the frame's cells fill the room: a cell is decoded only
// when it is known (from an earlier page-in) to fit, the others are dropped undecoded.
bool PagedWorld::hopeless(uint32_t cell) const {
  const uint64_t size = decoded_size_[cell];
  return !dropped_.empty() && (size == 0 || lru_.bytes() + held_besides_cells() + size > lru_.budget());
}

// Where one decoded (or not decoded) cell goes: grafted, back to the wanted list, failed, or
// dropped for lack of room.
void PagedWorld::place(Decoded& d, bool evict, SyncPass& pass) {
  if (d.retry) {
    pass.later.push_back(d.cell);
  } else if (d.skipped) {
    ++counters_.cells_dropped;
    dropped_.push_back(d.cell);
  } else if (!d.status) {
    // Drawn as missing from now on: an empty cell the walk goes through.
    failed_[d.cell] = 1;
    missing_[d.cell] = 0;
    ++counters_.page_errors;
    pass.changed = true;
  } else if (fits(d.bytes) || (evict && evict_for(d.bytes, pass.grafted))) {
    graft(d);
    pass.grafted.push_back(d.cell);
    pass.changed = true;
  } else if (evict && d.bytes <= lru_.budget()) {
    // Full of cells grafted by this call, which the caller has not drawn yet: the rest
    // comes in with the next call.
    pass.later.push_back(d.cell);
    pass.full = true;
  } else {
    // No room while this frame holds everything else: not again in this frame (the flag
    // stays set), wanted again from the next one.
    ++counters_.cells_dropped;
    dropped_.push_back(d.cell);
    decoded_size_[d.cell] = d.bytes;
  }
}

bool PagedWorld::sync_impl(std::chrono::steady_clock::time_point deadline, bool evict) {
  const auto start = std::chrono::steady_clock::now();
  SyncPass pass;
  // Proxies the decoder finished (grafted, not linked: the cut links them at begin_frame()),
  // then the cells it finished, then what is ready and not taken by the decoder, decoded here
  // until the deadline. While pages of cells wait, the proxies get half of a limited share
  // (and what the cells leave): taken first for all of it, a cut refining over many frames
  // never paged a cell in (an 8 M-triangle mountain's orbit: no page in 16 frames, its spheres
  // drawn by their six-segment tessellations all along).
  const bool limited = deadline != std::chrono::steady_clock::time_point::max();
  const bool cells_wait = limited && !proxy_.empty() && frame_decodes() && cells_ready();
  if (!proxy_.empty()) load_proxies(cells_wait ? start + (deadline - start) / 2 : deadline);
  std::vector<Decoded> ahead = take_decoded();
  // In the decoder's order (most pixels first), until the deadline: the rest stay decoded for
  // the next call.
  size_t placed = 0;
  for (; placed < ahead.size(); ++placed) {
    if (placed > 0 && std::chrono::steady_clock::now() >= deadline) break;
    Decoded& d = ahead[placed];
    if (slot_[d.cell] >= 0) continue;  // already resident
    if (!evict && hopeless(d.cell)) d.skipped = true;
    place(d, evict, pass);
  }
  if (placed < ahead.size()) {
    keep_decoded(std::make_move_iterator(ahead.begin() + std::ptrdiff_t(placed)), std::make_move_iterator(ahead.end()));
    ahead.resize(placed);
  }
  if (!pass.later.empty()) {
    std::lock_guard<std::mutex> lock(wanted_mutex_);
    wanted_.insert(wanted_.end(), pass.later.begin(), pass.later.end());
    pass.later.clear();
  }
  // In frames that may end before every page is in (pegged), the decoder thread decodes alone
  // (unless it waits for room): the frame's thread only grafts, and its time goes to rays (a
  // stand-in, or the reconstruction, covers what is not in yet).
  // A pegged cut's frames decode here, in the paging share before the rays (the decoder thread
  // pauses: it would take a core from the rays).
  const std::vector<uint32_t> ready = take_ready(frame_decodes() || decoder_blocked());
  const size_t batch = std::max<size_t>(4, 2 * static_cast<size_t>(tbb::info::default_concurrency()));
  for (size_t b = 0; b < ready.size(); b += batch) {
    if (pass.full || std::chrono::steady_clock::now() >= deadline) {
      pass.later.insert(pass.later.end(), ready.begin() + static_cast<std::ptrdiff_t>(b), ready.end());
      break;
    }
    const size_t e = std::min(ready.size(), b + batch);
    std::vector<Decoded> decoded(e - b);
    for (size_t i = 0; i < decoded.size(); ++i) {
      decoded[i].cell = ready[b + i];
      decoded[i].skipped = !evict && hopeless(ready[b + i]);
    }
    // One page per task, each starting only before the deadline: a frame overruns its paging
    // share by at most one page's decode and build, not by a whole batch.
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, decoded.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
          for (size_t i = range.begin(); i < range.end(); ++i) {
            if (decoded[i].skipped) continue;
            if (i > 0 && std::chrono::steady_clock::now() >= deadline) {
              decoded[i].retry = true;
            } else {
              decode(ready[b + i], decoded[i]);
            }
          }
        });
    for (Decoded& d : decoded) place(d, evict, pass);
  }
  if (!pass.later.empty()) {
    std::lock_guard<std::mutex> lock(wanted_mutex_);
    wanted_.insert(wanted_.end(), pass.later.begin(), pass.later.end());
  }
  // What the cells left of the share goes to the proxies.
  if (cells_wait && std::chrono::steady_clock::now() < deadline) load_proxies(deadline);
  publish_room();
  // Frame time, whatever it placed (proxies installed, or nothing but the look at what is in).
  counters_.decode_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return pass.changed;
}

double PagedWorld::wait_for_pages(std::chrono::steady_clock::time_point deadline) {
  const auto start = std::chrono::steady_clock::now();
  // In pegged frames the decoder does the decoding, and it may be waiting for the room the next
  // sync() publishes: never wait long without one.
  if (budgeted_) deadline = std::min(deadline, start + std::chrono::milliseconds(20));
  while (std::chrono::steady_clock::now() < deadline) {
    {
      std::lock_guard<std::mutex> lock(wanted_mutex_);
      bool blocked = false;
      {
        std::lock_guard<std::mutex> dl(decoder_->mutex);
        if (!decoder_->done.empty() || !decoder_->proxies_done.empty()) break;
        if (wanted_.empty() && decoder_->in_flight == 0) break;
        blocked = decoder_->blocked;
      }
      // A page in the cache is news only to a sync() that decodes (not in pegged frames: the
      // decoder takes it, and proxy pages too).
      bool any = false;
      const bool decodes_here = !budgeted_ || blocked;
      for (size_t k = 0; k < wanted_.size() && !any; ++k) {
        const uint64_t page = model_.cells()[wanted_[k]].page;
        if (cache_->ready(page) || cache_->failed(page)) {
          any = decodes_here;
        } else {
          // Evicted unread (the page cache made room for later pages), or put back by the
          // decoder after its page went: asked for again, else nothing would bring it.
          cache_->request(page);
        }
      }
      for (size_t k = 0; k < proxy_wanted_.size() && !budgeted_ && !any; ++k) {
        const uint64_t page = model_.proxy(proxy_wanted_[k])->page;
        any = cache_->ready(page) || cache_->failed(page);
      }
      if (any) break;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

PagedWorld::Graft PagedWorld::append(const Decoded& d, const std::array<int32_t, 6>& ropes, uint32_t owner) {
  const KdTree& sub = d.tree;
  Graft g;
  g.cell = d.cell;
  g.node0 = static_cast<uint32_t>(tree_.nodes_.size());
  g.nodes = static_cast<uint32_t>(sub.nodes_.size());
  g.cell0 = static_cast<uint32_t>(tree_.cells_.size());
  g.cells = static_cast<uint32_t>(sub.cells_.size());
  g.ref0 = static_cast<uint32_t>(tree_.refs_.size());
  g.refs = static_cast<uint32_t>(sub.refs_.size());
  g.prim0 = static_cast<uint32_t>(scene_.prims.size());
  g.prims = static_cast<uint32_t>(d.scene.prims.size());
  g.kind0 = {uint32_t(scene_.triangles.size()), uint32_t(scene_.spheres.size()), uint32_t(scene_.boxes.size()),
             uint32_t(scene_.cones.size()), uint32_t(scene_.quadrics.size())};
  g.bytes = d.bytes;
  g.stand_in = d.stand_in >= 0;
  if (!d.scene.triangle_normals.empty() && scene_.triangle_normals.empty()) {
    // The first scene with shading normals (the root's proxy, read at the opening, in a store
    // whose proxies have them): from now on every triangle has them, flat ones for the cells'.
    scene_.triangle_normals.reserve(scene_.triangles.capacity());
    advise_huge_pages(scene_.triangle_normals.data(), scene_.triangle_normals.capacity() * sizeof(std::array<Vec3, 3>));
    normals_.store(true, std::memory_order_release);
  }
  for (uint32_t i = 0; i < d.scene.size(); ++i) scene_.add_from(d.scene, i);
  if (g.stand_in || !stand_in_prim_.empty()) {
    stand_in_prim_.resize(g.prim0, 0);
    stand_in_prim_.resize(scene_.prims.size(), g.stand_in ? 1 : 0);
  }
  g.kinds = {uint32_t(scene_.triangles.size()) - g.kind0[0], uint32_t(scene_.spheres.size()) - g.kind0[1],
             uint32_t(scene_.boxes.size()) - g.kind0[2], uint32_t(scene_.cones.size()) - g.kind0[3],
             uint32_t(scene_.quadrics.size()) - g.kind0[4]};

  for (KdTree::Node n : sub.nodes_) {
    n.child += n.is_leaf() ? g.cell0 : g.node0;
    tree_.nodes_.push_back(n);
  }
  for (KdTree::Cell c : sub.cells_) {
    c.first += g.ref0;
    for (int f = 0; f < 6; ++f) {
      c.rope[f] = c.rope[f] == KdTree::kNone ? ropes[size_t(f)] : c.rope[f] + static_cast<int32_t>(g.node0);
    }
    tree_.cells_.push_back(c);
    owner_.push_back(owner);
  }
  for (uint32_t r : sub.refs_) tree_.refs_.push_back(r + g.prim0);
  tree_.ref_bounds_.insert(tree_.ref_bounds_.end(), sub.ref_bounds_.begin(), sub.ref_bounds_.end());
  tree_.depth_ = std::max<uint32_t>(tree_.depth_, model_.depth() + sub.depth_);
  return g;
}

void PagedWorld::graft(Decoded& d) {
  std::array<int32_t, 6> ropes;
  for (int f = 0; f < 6; ++f) ropes[size_t(f)] = tree_.cells_[d.cell].rope[f];
  const Graft g = append(d, ropes, d.cell);

  KdTree::Node& leaf = tree_.nodes_[leaf_node_[d.cell]];
  leaf.axis_or_leaf = 4;
  leaf.child = g.node0;
  missing_[d.cell] = 0;
  slot_[d.cell] = static_cast<int32_t>(live_.size());
  live_.push_back(g);
  lru_.insert(d.cell, g.bytes);
  decoded_size_[d.cell] = g.bytes;
  if (grafted_image_[d.cell] == image_) ++counters_.cells_reread;
  grafted_image_[d.cell] = image_;
  ++counters_.cells_paged_in;
  ++installs_;
  counters_.primitives_paged_in += g.prims;
}

// Keeps live_ dense: moves the last graft into slot s; its arrays become garbage.
void PagedWorld::remove_graft(int32_t s) {
  garbage_bytes_ += live_[size_t(s)].bytes;
  live_[size_t(s)] = live_.back();
  const Graft& moved = live_[size_t(s)];
  if (moved.stand_in) {
    proxy_[moved.cell].graft = s;
  } else {
    slot_[moved.cell] = s;
  }
  live_.pop_back();
}

void PagedWorld::unlink(uint32_t cell) {
  const int32_t s = slot_[cell];
  if (s < 0) return;
  KdTree::Node& leaf = tree_.nodes_[leaf_node_[cell]];
  leaf.axis_or_leaf = 3;
  leaf.child = cell;
  missing_[cell] = 1;
  wanted_flag_[cell].store(0, std::memory_order_release);
  remove_graft(s);
  slot_[cell] = -1;
  lru_.erase(cell);
  ++counters_.cells_evicted;
}

void PagedWorld::note_touched(const CellMarks& marks) {
  const size_t n = std::min(marks.size(), owner_.size());
  for (size_t c = 0; c < n; ++c) {
    if (marks.marked(static_cast<int32_t>(c)) && owner_[c] < top_cells_) lru_.touch(owner_[c]);
  }
}

std::vector<uint32_t> PagedWorld::image_cells(const CellMarks& marks) const {
  std::vector<uint8_t> seen(top_cells_, 0);
  std::vector<uint32_t> out;
  auto add = [&](uint32_t s) {
    if (!seen[s]) {
      seen[s] = 1;
      out.push_back(s);
    }
  };
  for (const uint32_t s : earlier_cells_) add(s);
  for (const uint32_t s : lru_.touched_cells()) add(s);
  const size_t n = std::min(marks.size(), owner_.size());
  for (size_t c = 0; c < n; ++c) {
    if (marks.marked(static_cast<int32_t>(c)) && owner_[c] < top_cells_) add(owner_[c]);
  }
  std::sort(out.begin(), out.end());
  return out;
}

uint64_t PagedWorld::end_frame(const CellMarks& marks) {
  if (++frames_since_trim_ >= kTrimFrames) {
    frames_since_trim_ = 0;
    std::lock_guard<std::mutex> lock(decoder_->mutex);
    decoder_->trim = true;  // the decoder thread does it when idle (it takes milliseconds)
    decoder_->cv.notify_one();
  }
  note_touched(marks);
  const uint64_t drawn_proxies = proxy_.empty() ? 0 : note_drawn(marks);
  // The cut's nodes the rays entered ask for what lies below them (pegged frames; the waited
  // cut reads its proxies at begin_frame() and its rays page the rest).
  if (cut_ == CutKind::kPegged) request_refinements();
  touched_bytes_ = lru_.touched_bytes();
  const std::vector<uint32_t> cells = image_cells(CellMarks());
  working_set_bytes_ = drawn_proxies;
  for (const uint32_t c : cells) working_set_bytes_ += decoded_size_[c];
  return cells.size();
}

std::vector<uint32_t> PagedWorld::touched_this_frame() const { return lru_.touched_cells(); }

void PagedWorld::forget_dropped() {
  for (const uint32_t c : dropped_) wanted_flag_[c].store(0, std::memory_order_release);
  dropped_.clear();
}

void PagedWorld::begin_frame(CellMarks& marks) {
  // Last frame's cells join the eviction order smallest on screen first, from the new frame's
  // eye (the decoder's priority, the other way round); without an eye, by cell.
  Vec3 eye;
  bool has_eye;
  {
    std::lock_guard<std::mutex> lock(decoder_->mutex);
    eye = decoder_->eye;
    has_eye = decoder_->has_eye;
  }
  if (has_eye) {
    lru_.begin_frame([&](uint32_t c) { return screen_size(c, eye); });
  } else {
    lru_.begin_frame();
  }
  ++image_;
  earlier_cells_.clear();
  forget_dropped();
  // Keep a quarter of the decoded share free for what this frame pages in: when live cells,
  // proxies and garbage fill more than three quarters, make room down to half — first the cells
  // the last frame did not touch (least recently touched first), then the proxies the last image
  // did not draw, and only then, down to three quarters, the last frame's own cells (smallest on
  // screen first: no cell is touched in the new frame yet) — and compact.
  const uint64_t budget = lru_.budget();
  const auto held = [&] { return lru_.bytes() + held_besides_cells(); };
  if (held() > budget / 4 * 3) {
    while (held() > budget / 2) {
      const std::optional<uint32_t> victim = lru_.oldest();
      if (!victim || lru_.last_touched(*victim) + 1 >= lru_.frame()) break;
      unlink(*victim);
    }
    if (held() > budget / 2) shed_proxies(proxy_bytes_ - std::min(proxy_bytes_, held() - budget / 2));
    const uint64_t others = held() - lru_.bytes();
    if (held() > budget / 4 * 3) unlink_oldest(budget / 4 * 3 > others ? budget / 4 * 3 - others : 0);
  }
  if (garbage_bytes_ > 0 && held() > budget / 4 * 3) compact();
  // The image's cut, from what is resident now; the traced tree keeps it until the next image.
  choose_cut();
  marks.resize(tree_.cells_.size());
}

bool PagedWorld::reclaim_untouched(CellMarks& marks) {
  note_touched(marks);
  std::vector<uint32_t> stale;
  for (const Graft& g : live_) {
    if (!g.stand_in && !lru_.touched(g.cell)) stale.push_back(g.cell);
  }
  if (stale.empty() && garbage_bytes_ == 0) return false;
  for (const uint32_t c : stale) unlink(c);
  compact();
  forget_dropped();
  marks.resize(tree_.cells_.size());
  return true;
}

uint64_t PagedWorld::release_pass(CellMarks& marks) {
  note_touched(marks);
  uint64_t demand = lru_.touched_bytes();
  for (const uint32_t c : dropped_) demand += decoded_size_[c];
  for (const uint32_t c : lru_.touched_cells()) {
    if (passed_image_[c] == image_) continue;
    passed_image_[c] = image_;
    earlier_cells_.push_back(c);
  }
  lru_.begin_frame();
  // Every cell goes, and the proxies the cut does not draw (the root's stays).
  if (!proxy_.empty()) shed_proxies(0);
  std::vector<uint32_t> cells;
  for (const Graft& g : live_) {
    if (!g.stand_in) cells.push_back(g.cell);
  }
  for (const uint32_t c : cells) unlink(c);
  compact();
  forget_dropped();
  marks.resize(tree_.cells_.size());
  return demand;
}

uint64_t PagedWorld::budget_for(uint64_t decoded_bytes) {
  // budget = decoded share + max(kMinCompressedShare, budget / 8) (the constructor's split).
  const uint64_t low = decoded_bytes + kMinCompressedShare;
  const uint64_t budget = low <= 8 * kMinCompressedShare ? low : (decoded_bytes * 8 + 6) / 7;
  const uint64_t mib = uint64_t{1} << 20;
  return (budget + mib - 1) / mib * mib;
}

// Slides every live graft down over the garbage, in array order, in place (a graft's ranges
// only ever move to lower indices), and renumbers what points into them.
void PagedWorld::compact() {
  std::vector<size_t> order(live_.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return live_[a].prim0 < live_[b].prim0; });
  uint32_t node_at = static_cast<uint32_t>(top_nodes_), cell_at = static_cast<uint32_t>(top_cells_), ref_at = 0,
           prim_at = 0;
  std::array<uint32_t, 5> kind_at{};
  auto slide = [](auto& v, uint32_t from, uint32_t to, uint32_t count) {
    if (from != to) std::copy(v.begin() + from, v.begin() + from + count, v.begin() + to);
  };
  for (const size_t i : order) {
    Graft& g = live_[i];
    const int32_t node_delta = static_cast<int32_t>(node_at) - static_cast<int32_t>(g.node0);
    const int64_t cell_delta = int64_t(cell_at) - int64_t(g.cell0), ref_delta = int64_t(ref_at) - int64_t(g.ref0),
                  prim_delta = int64_t(prim_at) - int64_t(g.prim0);
    std::array<int64_t, 5> kind_delta;
    for (size_t k = 0; k < 5; ++k) kind_delta[k] = int64_t(kind_at[k]) - int64_t(g.kind0[k]);

    slide(tree_.nodes_, g.node0, node_at, g.nodes);
    for (uint32_t n = node_at; n < node_at + g.nodes; ++n) {
      KdTree::Node& node = tree_.nodes_[n];
      node.child = static_cast<uint32_t>(int64_t(node.child) + (node.is_leaf() ? cell_delta : node_delta));
    }
    slide(tree_.cells_, g.cell0, cell_at, g.cells);
    slide(owner_, g.cell0, cell_at, g.cells);
    for (uint32_t c = cell_at; c < cell_at + g.cells; ++c) {
      KdTree::Cell& cell = tree_.cells_[c];
      cell.first = static_cast<uint32_t>(int64_t(cell.first) + ref_delta);
      for (int32_t& rope : cell.rope) {
        if (rope != KdTree::kNone && size_t(rope) >= top_nodes_) rope += node_delta;
      }
    }
    slide(tree_.refs_, g.ref0, ref_at, g.refs);
    slide(tree_.ref_bounds_, g.ref0, ref_at, g.refs);
    for (uint32_t r = ref_at; r < ref_at + g.refs; ++r) {
      tree_.refs_[r] = static_cast<uint32_t>(int64_t(tree_.refs_[r]) + prim_delta);
    }
    slide(scene_.prims, g.prim0, prim_at, g.prims);
    if (!stand_in_prim_.empty()) slide(stand_in_prim_, g.prim0, prim_at, g.prims);
    for (uint32_t p = prim_at; p < prim_at + g.prims; ++p) {
      PrimRef& ref = scene_.prims[p];
      ref.index = static_cast<uint32_t>(int64_t(ref.index) + kind_delta[size_t(ref.kind)]);
    }
    slide(scene_.triangles, g.kind0[0], kind_at[0], g.kinds[0]);
    slide(scene_.spheres, g.kind0[1], kind_at[1], g.kinds[1]);
    slide(scene_.boxes, g.kind0[2], kind_at[2], g.kinds[2]);
    slide(scene_.cones, g.kind0[3], kind_at[3], g.kinds[3]);
    slide(scene_.quadrics, g.kind0[4], kind_at[4], g.kinds[4]);
    if (!scene_.triangle_normals.empty()) {
      // Normals are either absent or one per triangle: they move with the triangles.
      slide(scene_.triangle_normals, g.kind0[0], kind_at[0], g.kinds[0]);
    }
    if (g.stand_in) {
      if (proxy_[g.cell].linked) tree_.nodes_[g.cell].child = node_at;
    } else {
      tree_.nodes_[leaf_node_[g.cell]].child = node_at;
    }
    g.node0 = node_at;
    g.cell0 = cell_at;
    g.ref0 = ref_at;
    g.prim0 = prim_at;
    g.kind0 = kind_at;
    node_at += g.nodes;
    cell_at += g.cells;
    ref_at += g.refs;
    prim_at += g.prims;
    for (size_t k = 0; k < 5; ++k) kind_at[k] += g.kinds[k];
  }
  tree_.nodes_.resize(node_at);
  tree_.cells_.resize(cell_at);
  owner_.resize(cell_at);
  tree_.refs_.resize(ref_at);
  tree_.ref_bounds_.resize(ref_at);
  scene_.prims.resize(prim_at);
  if (!stand_in_prim_.empty()) stand_in_prim_.resize(prim_at);
  scene_.triangles.resize(kind_at[0]);
  scene_.spheres.resize(kind_at[1]);
  scene_.boxes.resize(kind_at[2]);
  scene_.cones.resize(kind_at[3]);
  scene_.quadrics.resize(kind_at[4]);
  if (!scene_.triangle_normals.empty()) scene_.triangle_normals.resize(kind_at[0]);
  release_tail(tree_.nodes_);
  release_tail(tree_.cells_);
  release_tail(owner_);
  release_tail(tree_.refs_);
  release_tail(tree_.ref_bounds_);
  release_tail(scene_.prims);
  release_tail(scene_.triangles);
  release_tail(scene_.triangle_normals);
  garbage_bytes_ = 0;
  ++generation_;
}

size_t PagedWorld::resident_cells() const {
  return size_t(std::count_if(live_.begin(), live_.end(), [](const Graft& g) { return !g.stand_in; }));
}

PagingCounters PagedWorld::take_counters() {
  PagingCounters c = counters_;
  counters_ = {};
  return c;
}

}  // namespace frontier
