// PagedWorld's level of detail: one cut per frame, chosen before the first ray (see "Level of
// detail" in paged_world.h and DESIGN.md "Level of detail: one cut per frame").
#include "src/paging/paged_world.h"
#include "src/paging/paged_world_internal.h"
#include "src/codec/cell_tree.h"
#include "src/core/geometry.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace frontier {

void PagedWorld::open_proxies() {
  const auto& proxies = model_.proxies();
  if (proxies.empty()) return;
  const auto& nodes = model_.nodes();
  proxy_.resize(nodes.size());
  parent_.assign(nodes.size(), -1);
  for (size_t n = 0; n < nodes.size(); ++n) {
    if (nodes[n].is_leaf()) continue;
    parent_[n + 1] = static_cast<int32_t>(n);                    // lower child follows its parent
    parent_[nodes[n].child] = static_cast<int32_t>(n);           // upper child
  }
  tree_.parent_ = parent_;  // descend() finds a rope target's linked ancestors through it
  // Cells with pages below each node (preorder: children follow their parents).
  page_cells_under_.assign(nodes.size(), 0);
  for (size_t n = nodes.size(); n-- > 0;) {
    page_cells_under_[n] = nodes[n].is_leaf() ? (model_.cells()[nodes[n].child].page != StoreCell::kNoPage ? 1 : 0)
                                              : page_cells_under_[n + 1] + page_cells_under_[nodes[n].child];
  }
  stand_in_prim_.reserve(scene_.prims.capacity());
  // The root's proxy is there from the first frame (the cut always exists), and the top of the
  // tree breadth first below it, within a small share of the budget: the first frames draw
  // nodes a few levels down wherever the eye looks, instead of the root's blob.
  if (model_.proxy(0) != nullptr) load_now({0});
  preload_top();
}

void PagedWorld::preload_top() {
  const auto& nodes = model_.nodes();
  const uint64_t cap = std::min<uint64_t>(kPreloadTriangles, lru_.budget() / kPreloadBudgetShare / kDecodedBytesPerProxyTriangle);
  std::vector<uint32_t> take;
  uint64_t triangles = 0;
  std::vector<uint32_t> level{0}, next;
  while (!level.empty()) {
    next.clear();
    uint64_t level_triangles = 0;
    for (const uint32_t n : level) {
      if (nodes[n].is_leaf()) continue;  // a root that is a leaf (a store of one cell)
      for (const uint32_t c : {n + 1, nodes[n].child}) {
        if (nodes[c].is_leaf() || model_.proxy(c) == nullptr) continue;
        next.push_back(c);
        level_triangles += model_.proxy(c)->triangles;
      }
    }
    if (next.empty() || triangles + level_triangles > cap) break;  // whole levels only
    triangles += level_triangles;
    take.insert(take.end(), next.begin(), next.end());
    level.swap(next);
  }
  load_now(take);
  counters_.proxies_loaded = 0;  // opening the store, not a frame
}

double PagedWorld::pixels_of(uint32_t node) const {
  const StoreProxy* p = model_.proxy(node);
  if (p == nullptr) return kInfinity;
  // The point of the node's region nearest the eye; its distance stands for the depth (it is
  // at least the depth, so this overestimates the pixels: conservative).
  const double d = distance_to_box(detail_view_.eye, model_.node_region(node));
  if (d <= 0.0) return kInfinity;
  // A length e at distance d spans e * height / (2 d tan(vfov / 2)) pixels.
  return p->error * double(detail_view_.height) / (2.0 * detail_view_.half_h * d);
}

bool PagedWorld::in_view(uint32_t node) const {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  // A region reaching behind the eye may cover any pixel: in view.
  if (!detail_view_.project(model_.node_region(node), x0, y0, x1, y1)) return true;
  return x1 >= -1 && y1 >= -1 && x0 <= detail_view_.width && y0 <= detail_view_.height;
}

void PagedWorld::request_proxy(uint32_t node) {
  ProxySlot& slot = proxy_[node];
  if (slot.graft >= 0 || slot.requested || slot.failed || model_.proxy(node) == nullptr) return;
  slot.requested = true;
  proxy_wanted_.push_back(node);
  cache_->request(model_.proxy(node)->page);
}

std::vector<uint32_t> PagedWorld::pick_ready_proxies(size_t count) {
  std::vector<uint32_t> arrived;
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  std::vector<uint32_t> waiting;
  for (const uint32_t n : proxy_wanted_) {
    const uint64_t page = model_.proxy(n)->page;
    const bool in = arrived.size() < count && (cache_->ready(page) || cache_->failed(page));
    (in ? arrived : waiting).push_back(n);
  }
  proxy_wanted_.swap(waiting);
  return arrived;
}

void PagedWorld::requeue_proxy(uint32_t node) {
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  if (!proxy_[node].requested) return;  // no longer asked for
  proxy_wanted_.push_back(node);
  cache_->request(model_.proxy(node)->page);
}

bool PagedWorld::decode_proxy(uint32_t node, ProxyDecoded& out) const {
  out.node = node;
  const uint64_t page = model_.proxy(node)->page;
  std::optional<store::Pin> pin = cache_->try_pin(page);
  if (!pin) {
    if (!cache_->failed(page)) return false;
    out.page_failed = true;
    out.status = Status::io_error(fmt::format("proxy page {} could not be read", page));
    return true;
  }
  const KdBuildOptions options = proxy_build_options(node);
  std::optional<KdTree> tree;
  out.status = model_.decode_proxy_page(node, pin->codec(), pin->bytes(), out.scene, &options, tree);
  pin->reset();
  if (!out.status) return true;
  out.tree = tree ? std::move(*tree) : KdTree::build(out.scene, options);
  return true;
}

KdBuildOptions PagedWorld::proxy_build_options(uint32_t node) const {
  KdBuildOptions options = proxy_tree_options(cell_build_);
  options.root = model_.node_region(node);
  return options;
}

std::array<int32_t, 6> PagedWorld::node_ropes(uint32_t node) const {
  // As the top tree's builder assigns them (kdtree.cpp assign_ropes), from the root down: a
  // child's face on its parent's split plane leads to its sibling, the others to the parent's.
  std::vector<uint32_t> path;
  for (int32_t n = int32_t(node); n >= 0; n = parent_[size_t(n)]) path.push_back(uint32_t(n));
  std::array<int32_t, 6> ropes;
  ropes.fill(KdTree::kNone);
  const auto& nodes = model_.nodes();
  for (size_t k = path.size() - 1; k > 0; --k) {
    const uint32_t n = path[k], child = path[k - 1];
    const int a = static_cast<int>(nodes[n].axis_or_leaf);
    if (child == n + 1) {
      ropes[size_t(2 * a + 1)] = static_cast<int32_t>(nodes[n].child);  // lower child: upper face
    } else {
      ropes[size_t(2 * a)] = static_cast<int32_t>(n + 1);               // upper child: lower face
    }
  }
  return ropes;
}

bool PagedWorld::graft_proxy(uint32_t node, ProxyDecoded& p) {
  Decoded d;
  d.cell = node;
  d.stand_in = int32_t(node);
  d.scene = std::move(p.scene);
  d.tree = std::move(p.tree);
  d.bytes = d.scene.prims.size() * (sizeof(PrimRef) + sizeof(Triangle)) +
            (d.scene.triangle_normals.empty() && !normals_.load(std::memory_order_relaxed) ? 0 : d.scene.triangles.size()) *
                sizeof(std::array<Vec3, 3>) +
            tree_bytes(d.tree, kPerCellOverhead);
  if (!fits(d.bytes)) {
    p.scene = std::move(d.scene);
    p.tree = std::move(d.tree);
    return false;
  }
  const Graft g = append(d, node_ropes(node), kNoOwner);
  ProxySlot& slot = proxy_[node];
  slot.graft = static_cast<int32_t>(live_.size());
  live_.push_back(g);
  slot.bytes = g.bytes;
  proxy_bytes_ += g.bytes;
  return true;
}

bool PagedWorld::install_proxy(ProxyDecoded& p) {
  ProxySlot& slot = proxy_[p.node];
  const bool asked = slot.requested;
  slot.requested = false;
  if (slot.graft >= 0) return false;  // installed meanwhile
  if (!p.status) {
    slot.failed = true;  // its node is drawn by its children (or a coarser proxy) from now on
    if (!p.page_failed) ++counters_.page_errors;
    return false;
  }
  // The root's proxy always; others only while the cut still asks for them and they fit.
  if (p.node != 0 && !asked) return false;
  if (!graft_proxy(p.node, p)) return false;
  ++proxies_resident_;
  stamp_proxy(p.node);
  ++counters_.proxies_loaded;
  ++installs_;
  return true;
}

bool PagedWorld::load_proxies(std::chrono::steady_clock::time_point deadline) {
  bool any = false;
  // What the decoder thread decoded (and built) ahead: installed here.
  std::vector<ProxyDecoded> ahead;
  if (decoder_) {  // none yet at the cold start (open_proxies)
    std::lock_guard<std::mutex> lock(decoder_->mutex);
    ahead.swap(decoder_->proxies_done);
  }
  for (ProxyDecoded& p : ahead) any = install_proxy(p) || any;
  // In frames that wait for their pages, and before a pegged cut's rays, the frame's threads
  // decode those that arrived, in parallel, in the order asked (largest error first), until the
  // deadline (a batch at least).
  if (frame_decodes()) {
    const std::vector<uint32_t> arrived = pick_ready_proxies(SIZE_MAX);
    const size_t batch = std::max<size_t>(4, 2 * static_cast<size_t>(tbb::info::default_concurrency()));
    size_t k = 0;
    // The first batch even past the deadline: however short the frames, the cut refines.
    for (; k < arrived.size() && (k == 0 || std::chrono::steady_clock::now() < deadline); k += batch) {
      const size_t e = std::min(arrived.size(), k + batch);
      std::vector<ProxyDecoded> decoded(e - k);
      std::vector<uint8_t> ok(e - k, 0);
      tbb::parallel_for(tbb::blocked_range<size_t>(0, decoded.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i) ok[i] = decode_proxy(arrived[k + i], decoded[i]) ? 1 : 0;
      });
      for (size_t i = 0; i < decoded.size(); ++i) {
        if (ok[i]) {
          any = install_proxy(decoded[i]) || any;
        } else {
          requeue_proxy(arrived[k + i]);
        }
      }
    }
    if (k < arrived.size()) {
      std::lock_guard<std::mutex> lock(wanted_mutex_);  // the rest in a later sync()
      proxy_wanted_.insert(proxy_wanted_.end(), arrived.begin() + std::ptrdiff_t(k), arrived.end());
    }
  }
  return any;
}

void PagedWorld::load_now(const std::vector<uint32_t>& nodes) {
  {
    std::lock_guard<std::mutex> lock(wanted_mutex_);
    for (const uint32_t n : nodes) {
      if (proxy_[n].graft >= 0 || proxy_[n].failed || model_.proxy(n) == nullptr) continue;
      proxy_[n].requested = true;
      cache_->request(model_.proxy(n)->page);
    }
  }
  std::vector<uint32_t> todo;
  for (const uint32_t n : nodes) {
    if (!proxy_[n].requested || proxy_[n].graft >= 0) continue;
    todo.push_back(n);
    std::lock_guard<std::mutex> lock(wanted_mutex_);
    std::erase(proxy_wanted_, n);  // decoded here, not by the decoder
  }
  // Read and decoded in parallel (each page read by the thread that decodes it), installed in
  // the order given.
  std::vector<ProxyDecoded> decoded(todo.size());
  std::vector<uint8_t> ok(todo.size(), 1);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, todo.size(), 4), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      // pin() waits for the page (or reads it itself); the pin keeps it until decoded.
      auto pin = cache_->pin(model_.proxy(todo[i])->page);
      if (!pin) {
        decoded[i].node = todo[i];
        decoded[i].page_failed = true;
        decoded[i].status = pin.status();
      } else if (!decode_proxy(todo[i], decoded[i])) {
        ok[i] = 0;  // cannot happen while pinned
      }
    }
  });
  for (size_t i = 0; i < todo.size(); ++i) {
    if (ok[i]) install_proxy(decoded[i]);
  }
}

void PagedWorld::stamp_proxy(uint32_t node) {
  proxy_[node].used = ++proxy_use_;
  proxy_lru_.emplace(proxy_[node].used, node);
  if (proxy_lru_.size() > 4 * proxies_resident_ + 64) {
    // Mostly stale entries: rebuild from the resident proxies' stamps.
    std::vector<std::pair<uint64_t, uint32_t>> live;
    live.reserve(proxies_resident_);
    while (!proxy_lru_.empty()) {
      const auto [used, n] = proxy_lru_.top();
      proxy_lru_.pop();
      if (proxy_[n].graft >= 0 && proxy_[n].used == used) live.emplace_back(used, n);
    }
    proxy_lru_ = decltype(proxy_lru_)(std::greater<>(), std::move(live));
  }
}

void PagedWorld::shed_proxies(uint64_t target) {
  if (proxy_bytes_ <= target) return;
  std::vector<std::pair<uint64_t, uint32_t>> kept;
  while (proxy_bytes_ > target && !proxy_lru_.empty()) {
    const auto [used, n] = proxy_lru_.top();
    proxy_lru_.pop();
    if (proxy_[n].graft < 0 || proxy_[n].used != used) continue;  // stale
    if (n == 0 || proxy_[n].linked) {
      kept.emplace_back(used, n);  // the root's, or drawing now
      continue;
    }
    drop_proxy(n);
  }
  for (const auto& e : kept) proxy_lru_.push(e);
}

int32_t PagedWorld::link_above(uint32_t node) const {
  for (int32_t n = int32_t(node); n >= 0; n = parent_[size_t(n)]) {
    if (proxy_[size_t(n)].linked) return n;
  }
  return -1;
}

void PagedWorld::link_node(uint32_t node) {
  ProxySlot& slot = proxy_[node];
  if (slot.linked) return;
  // The node becomes a link to its proxy's subtree, which covers the node's region: a ray that
  // reaches any part of it goes through the proxy until it leaves the node.
  KdTree::Node& n = tree_.nodes_[node];
  slot.saved = n;
  n.axis_or_leaf = 4;
  n.child = live_[size_t(slot.graft)].node0;
  slot.linked = true;
  linked_nodes_.push_back(node);
  ++tree_.links_;
  ++counters_.stand_ins;
}

void PagedWorld::unlink_node(uint32_t node) {
  ProxySlot& slot = proxy_[node];
  if (!slot.linked) return;
  tree_.nodes_[node] = slot.saved;
  slot.linked = false;
  std::erase(linked_nodes_, node);
  --tree_.links_;
}

void PagedWorld::drop_proxy(uint32_t node) {
  ProxySlot& slot = proxy_[node];
  unlink_node(node);
  if (slot.graft >= 0) {
    remove_graft(slot.graft);
    proxy_bytes_ -= slot.bytes;
    --proxies_resident_;
  }
  slot = ProxySlot();
}

bool PagedWorld::frame_decodes() const { return !budgeted_ || cut_ == CutKind::kPegged; }

bool PagedWorld::drawable(uint32_t node) const {
  const auto& nodes = model_.nodes();
  if (nodes[node].is_leaf()) {
    const uint32_t c = nodes[node].child;
    return model_.cells()[c].page == StoreCell::kNoPage || slot_[c] >= 0 || failed_[c] != 0;
  }
  return proxy_[node].graft >= 0 || (drawable(node + 1) && drawable(nodes[node].child));
}

void PagedWorld::set_detail(const View& view, double pixel_error, bool pegged) {
  detail_view_ = view;
  set_decode_eye(view.eye);
  pixel_error_ = proxy_.empty() ? 0.0 : std::max(0.0, pixel_error);
  budgeted_ = pegged;
  cut_ = pixel_error_ <= 0.0 ? CutKind::kExact : pegged ? CutKind::kPegged : CutKind::kWaited;
  {
    // The decoder thread pauses while a pegged cut's frames run: its decoding would take a core
    // from the rays (whose levels wait for their slowest thread); sync() decodes instead.
    std::lock_guard<std::mutex> lock(decoder_->mutex);
    decoder_->paused = cut_ == CutKind::kPegged;
  }
  decoder_->cv.notify_all();
}

bool PagedWorld::choose_cut() {
  if (proxy_.empty()) return false;
  const auto& nodes = model_.nodes();
  std::vector<uint32_t> cut;   // interior nodes drawn by their proxies
  std::vector<uint32_t> load;  // the waited cut's proxies that are not resident
  cut_bytes_ = 0;
  if (cut_ != CutKind::kExact) {
    std::vector<uint32_t> stack{0};
    while (!stack.empty()) {
      const uint32_t n = stack.back();
      stack.pop_back();
      if (nodes[n].is_leaf()) {
        const int32_t s = slot_[nodes[n].child];
        if (s >= 0) cut_bytes_ += live_[size_t(s)].bytes;
        continue;
      }
      const ProxySlot& slot = proxy_[n];
      const bool own = slot.graft >= 0;
      if (!in_view(n)) {
        // No primary ray goes there: its own proxy if it has one (nothing below is read for it),
        // else the tree as it is.
        if (own) cut.push_back(n);
        continue;
      }
      bool refine;
      if (cut_ == CutKind::kPegged) {
        // REPLACE refinement: finer only where every child can be drawn now. A node without its
        // own proxy is reached only when its children can be drawn (or it is the root).
        refine = !own || (pixels_of(n) >= pixel_error_ && drawable(n + 1) && drawable(nodes[n].child));
      } else {
        // Waited: the proxies fine enough for the view, read now; rays page the rest.
        const bool fine = model_.proxy(n) != nullptr && !slot.failed && pixels_of(n) < pixel_error_;
        if (fine && !own) load.push_back(n);
        refine = !fine;
      }
      if (refine) {
        stack.push_back(nodes[n].child);
        stack.push_back(n + 1);
      } else {
        cut.push_back(n);
      }
    }
  }
  if (!load.empty()) load_now(load);
  // Links of the last cut that are not in this one go first (the cut is an antichain: a node
  // and one above or below it are never linked at once).
  std::sort(cut.begin(), cut.end());
  bool changed = false;
  const std::vector<uint32_t> linked = linked_nodes_;
  for (const uint32_t n : linked) {
    if (!std::binary_search(cut.begin(), cut.end(), n)) {
      unlink_node(n);
      changed = true;
    }
  }
  for (const uint32_t n : cut) {
    if (proxy_[n].graft < 0) continue;  // a waited cut's proxy that failed or did not fit: rays page below
    if (!proxy_[n].linked) {
      link_node(n);
      changed = true;
    }
    cut_bytes_ += proxy_[n].bytes;
  }
  if (changed) ++cut_changes_;
  return changed;
}

void PagedWorld::request_refinements() {
  const auto& nodes = model_.nodes();
  // (projected error of the cut node that asks, levels below it, what): proxies and pages apart.
  struct Ask {
    double error;
    int level;
    uint32_t what;
  };
  std::vector<Ask> proxies, pages;
  const bool full = double(cut_bytes_) > kCutFullShare * double(lru_.budget());
  if (!full) {
    std::vector<std::pair<uint32_t, int>> stack;
    for (const uint32_t n : drawn_nodes_) {
      const double error = pixels_of(n);
      if (!(error >= pixel_error_)) continue;
      // Down from the node to where the bounds project below T (the cut that would be chosen if
      // everything were resident), at most kRequestLevels levels.
      stack.clear();
      stack.emplace_back(nodes[n].child, 1);
      stack.emplace_back(n + 1, 1);
      while (!stack.empty()) {
        const auto [x, level] = stack.back();
        stack.pop_back();
        if (nodes[x].is_leaf()) {
          const uint32_t c = nodes[x].child;
          if (model_.cells()[c].page != StoreCell::kNoPage && slot_[c] < 0 && failed_[c] == 0) pages.push_back({error, level, c});
          continue;
        }
        const ProxySlot& slot = proxy_[x];
        if (model_.proxy(x) != nullptr && !slot.failed && slot.graft < 0) proxies.push_back({error, level, x});
        if (level < kRequestLevels && !(pixels_of(x) < pixel_error_) && in_view(x)) {
          stack.emplace_back(nodes[x].child, level + 1);
          stack.emplace_back(x + 1, level + 1);
        }
      }
    }
  }
  // Largest error first; below one node, level by level (a cut refines a level at a time: the
  // children of every node before any grandchild).
  const auto first = [](const Ask& a, const Ask& b) {
    if (a.error != b.error) return a.error > b.error;
    if (a.level != b.level) return a.level < b.level;
    return a.what < b.what;
  };
  std::sort(proxies.begin(), proxies.end(), first);
  std::sort(pages.begin(), pages.end(), first);
  if (proxies.size() > kMaxProxyRequests) proxies.resize(kMaxProxyRequests);
  if (pages.size() > kMaxPageRequests) pages.resize(kMaxPageRequests);
  std::vector<uint32_t> asked_proxies, asked_pages;
  for (const Ask& a : proxies) asked_proxies.push_back(a.what);
  for (const Ask& a : pages) asked_pages.push_back(a.what);
  // What the last frame asked for and this one does not goes off the lists (the view moved on).
  forget_unasked(asked_pages, asked_proxies);
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  for (const uint32_t x : asked_proxies) request_proxy(x);  // proxies first: they come faster
  for (const uint32_t c : asked_pages) {
    if (wanted_flag_[c].exchange(1, std::memory_order_acq_rel) != 0) continue;
    wanted_.push_back(c);
    cache_->request(model_.cells()[c].page);
  }
}

void PagedWorld::forget_unasked(const std::vector<uint32_t>& cells, const std::vector<uint32_t>& proxies) {
  std::vector<uint32_t> c = cells, p = proxies;
  std::sort(c.begin(), c.end());
  std::sort(p.begin(), p.end());
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  std::erase_if(wanted_, [&](uint32_t cell) {
    if (std::binary_search(c.begin(), c.end(), cell)) return false;
    wanted_flag_[cell].store(0, std::memory_order_release);
    return true;
  });
  std::erase_if(proxy_wanted_, [&](uint32_t node) {
    if (std::binary_search(p.begin(), p.end(), node)) return false;
    proxy_[node].requested = false;
    return true;
  });
}

size_t PagedWorld::requests_outstanding() const {
  std::lock_guard<std::mutex> lock(wanted_mutex_);
  std::lock_guard<std::mutex> dl(decoder_->mutex);
  return wanted_.size() + proxy_wanted_.size() + decoder_->in_flight + decoder_->done.size() +
         decoder_->proxies_done.size();
}

uint64_t PagedWorld::note_drawn(const CellMarks& marks) {
  drawn_nodes_.clear();
  uint64_t bytes = 0;
  for (const uint32_t n : linked_nodes_) {
    const ProxySlot& slot = proxy_[n];
    const Graft& g = live_[size_t(slot.graft)];
    bool drew = false;
    for (uint32_t wc = g.cell0; wc < g.cell0 + g.cells && wc < marks.size() && !drew; ++wc) drew = marks.marked(int32_t(wc));
    if (!drew) continue;
    drawn_nodes_.push_back(n);
    stamp_proxy(n);  // what the image drew is used: kept before what it did not
    bytes += slot.bytes;
  }
  return bytes;
}

StandInReport PagedWorld::stand_in_report() const {
  StandInReport r;
  r.cut_nodes = linked_nodes_.size();
  r.proxy_nodes = drawn_nodes_.size();
  for (const uint32_t n : drawn_nodes_) {
    r.proxy_cells += page_cells_under_[n];
    const double e = std::min(pixels_of(n), StandInReport::kEyeInside);
    if (e > r.cut_error) r.cut_error = e;  // NaN (no view yet) stays out
  }
  r.requests = requests_outstanding();
  return r;
}

}  // namespace frontier
