// PagedWorld's stand-ins: proxies of top-tree nodes drawing cells whose pages are missing or
// not worth their detail (see "Stand-ins" in paged_world.h).
#include "src/paging/paged_world.h"
#include "src/paging/paged_world_internal.h"
#include "src/core/geometry.h"

#include <fmt/format.h>

#include <algorithm>
#include <unordered_set>
#include <cmath>

namespace frontier {


namespace {
// Proxies decoded per sync() even past its deadline (progress).
constexpr size_t kMinStandInWork = 8;


}  // namespace

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
  // Preorder: a node's subtree is the nodes from it to subtree_end_ (exclusive).
  subtree_end_.assign(nodes.size(), 0);
  leaves_under_.assign(nodes.size(), 0);
  for (size_t n = nodes.size(); n-- > 0;) {
    if (nodes[n].is_leaf()) {
      subtree_end_[n] = uint32_t(n + 1);
      leaves_under_[n] = 1;
    } else {
      subtree_end_[n] = subtree_end_[nodes[n].child];
      leaves_under_[n] = leaves_under_[n + 1] + leaves_under_[nodes[n].child];
    }
  }
  tree_.parent_ = parent_;  // descend() finds a rope target's linked ancestors through it
  stand_in_prim_.reserve(scene_.prims.capacity());
  // The root's proxy is there from the first frame: read now, through the cache.
  if (model_.proxy(0) != nullptr) {
    proxy_[0].requested = true;
    proxy_wanted_.push_back(0);
    cache_->request(model_.proxy(0)->page);
    const auto pin = cache_->pin(model_.proxy(0)->page);
    (void)pin;  // load_proxies() decodes it (it stays in the cache until then)
    load_proxies(std::chrono::steady_clock::time_point::max());
  }
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

bool PagedWorld::detail_ok(int32_t node) const {
  return node >= 0 && proxy_[size_t(node)].resident && pixels_of(uint32_t(node)) < pixel_error_;
}

int32_t PagedWorld::detail_node(uint32_t cell) const {
  if (pixel_error_ <= 0.0) return -1;
  int32_t best = -1;
  for (int32_t n = parent_[leaf_node_[cell]]; n >= 0; n = parent_[size_t(n)]) {
    if (detail_ok(n)) best = n;
  }
  return best;
}

int32_t PagedWorld::detail_target(uint32_t cell) const {
  if (pixel_error_ <= 0.0) return -1;
  // A node's bound and region contain its children's: pixels_of() shrinks down a path, so the
  // nodes that qualify are the path's lower part, and the highest of them is the last found.
  int32_t best = -1;
  for (int32_t n = parent_[leaf_node_[cell]]; n >= 0; n = parent_[size_t(n)]) {
    const ProxySlot& slot = proxy_[size_t(n)];
    if (slot.failed || model_.proxy(uint32_t(n)) == nullptr) continue;
    if (!(pixels_of(uint32_t(n)) < pixel_error_)) break;
    best = n;
  }
  return best;
}

void PagedWorld::request_proxy(uint32_t node) {
  ProxySlot& slot = proxy_[node];
  if (slot.resident || slot.requested || slot.failed || model_.proxy(node) == nullptr) return;
  slot.requested = true;
  proxy_wanted_.push_back(node);
  cache_->request(model_.proxy(node)->page);
}

int32_t PagedWorld::borrowed_from(uint32_t node) const {
  return node < proxy_.size() ? proxy_[node].borrowed : -1;
}

int32_t PagedWorld::nearest_proxy(uint32_t cell) const { return resident_above(leaf_node_[cell]); }

int32_t PagedWorld::resident_above(uint32_t node) const {
  for (int32_t n = parent_[node]; n >= 0; n = parent_[size_t(n)]) {
    if (proxy_[size_t(n)].resident) return n;
  }
  return -1;
}

int32_t PagedWorld::free_node_on_path(uint32_t above, uint32_t cell) const {
  std::vector<uint32_t> path;  // from the cell's leaf up to below `above`
  for (int32_t n = int32_t(leaf_node_[cell]); n >= 0 && uint32_t(n) != above; n = parent_[size_t(n)]) {
    path.push_back(uint32_t(n));
  }
  const auto& nodes = model_.nodes();
  for (size_t k = path.size(); k-- > 0;) {
    const uint32_t n = path[k];
    if (nodes[n].is_leaf()) break;  // a leaf is the cell's own page's place
    if (!linked_below(n)) return int32_t(n);
  }
  return -1;
}

void PagedWorld::request_proxies(uint32_t cell) {
  // Coarse to fine, one level at a time: the ancestor just below the deepest resident one, unless
  // a resident ancestor is already fine enough for the pixel error (then nothing finer is read).
  int32_t below = -1;
  for (int32_t n = parent_[leaf_node_[cell]]; n >= 0; n = parent_[size_t(n)]) {
    const ProxySlot& slot = proxy_[size_t(n)];
    if (slot.resident) {
      if (pixel_error_ > 0.0 && pixels_of(uint32_t(n)) < pixel_error_) return;
      break;
    }
    if (!slot.failed && model_.proxy(uint32_t(n)) != nullptr) below = n;
  }
  if (below >= 0) request_proxy(uint32_t(below));
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
  out.status = model_.decode_proxy_page(node, pin->codec(), pin->bytes(), out.scene);
  pin->reset();
  if (!out.status) return true;
  out.tree = KdTree::build(out.scene, proxy_build_options(node));
  return true;
}

KdBuildOptions PagedWorld::proxy_build_options(uint32_t node) const {
  KdBuildOptions options = cell_build_;
  options.max_cell_prims = std::max(options.max_cell_prims, kProxyCellPrims);
  options.root = model_.node_region(node);
  return options;
}

bool PagedWorld::install_proxy(ProxyDecoded& p) {
  ProxySlot& slot = proxy_[p.node];
  slot.requested = false;
  if (!p.status) {
    slot.failed = true;  // drawn by a coarser proxy (or the page) from now on
    if (!p.page_failed) ++counters_.page_errors;
    return false;
  }
  slot.data = std::make_unique<ProxySlot::Data>(ProxySlot::Data{std::move(p.scene), std::move(p.tree)});
  const Scene& scene = slot.data->scene;
  const uint64_t own = scene.triangles.size() * (sizeof(Triangle) + sizeof(PrimRef)) +
                       scene.triangle_normals.size() * sizeof(std::array<Vec3, 3>) +
                       tree_bytes(slot.data->tree, 0);
  // Linked to an ancestor's proxy meanwhile (a borrowed subtree exists only while linked): its
  // own, finer one takes over.
  const bool relink = slot.borrowed >= 0;
  if (relink) release_proxy_graft(p.node);
  slot.bytes += own;
  slot.resident = true;
  ++proxies_resident_;
  stamp_proxy(p.node);
  proxy_bytes_ += own;
  if (relink) link_node(p.node, kLinkMissing);
  ++counters_.proxies_loaded;
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
  // In frames that stand in for missing pages, the decoder decodes proxies alone (the frame's
  // thread only installs them); in frames that wait for their pages, and at the cold start,
  // this thread decodes those that arrived too, until the deadline.
  if (!budgeted_ || deadline == std::chrono::steady_clock::time_point::max()) {
    const std::vector<uint32_t> arrived = pick_ready_proxies(SIZE_MAX);
    for (size_t k = 0; k < arrived.size(); ++k) {
      if (k >= kMinStandInWork && std::chrono::steady_clock::now() >= deadline) {
        std::lock_guard<std::mutex> lock(wanted_mutex_);  // the rest in a later sync()
        proxy_wanted_.insert(proxy_wanted_.end(), arrived.begin() + std::ptrdiff_t(k), arrived.end());
        break;
      }
      ProxyDecoded p;
      if (decode_proxy(arrived[k], p)) {
        any = install_proxy(p) || any;
      } else {
        requeue_proxy(arrived[k]);
      }
    }
  }
  if (any) drop_proxies_over_budget();
  return any;
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
      if (proxy_[n].resident && proxy_[n].used == used) live.emplace_back(used, n);
    }
    proxy_lru_ = decltype(proxy_lru_)(std::greater<>(), std::move(live));
  }
}

uint64_t PagedWorld::proxy_cap() const {
  const uint64_t budget = lru_.budget();
  const uint64_t floor = std::max<uint64_t>(budget / kProxyShareDivisor, 1);
  const uint64_t taken = touched_bytes_ + garbage_bytes_ + budget / 4;
  return taken < budget ? std::max(floor, budget - taken) : floor;
}

void PagedWorld::shed_proxies(uint64_t target) {
  if (proxy_bytes_ <= target) return;
  std::vector<uint32_t> donors;  // proxies borrowed by linked nodes: drawing now too
  for (const uint32_t l : linked_nodes_) {
    if (proxy_[l].borrowed >= 0) donors.push_back(uint32_t(proxy_[l].borrowed));
  }
  std::sort(donors.begin(), donors.end());
  std::vector<std::pair<uint64_t, uint32_t>> kept;
  while (proxy_bytes_ > target && !proxy_lru_.empty()) {
    const auto [used, n] = proxy_lru_.top();
    proxy_lru_.pop();
    if (!proxy_[n].resident || proxy_[n].used != used) continue;  // stale
    if (n == 0 || proxy_[n].link != kLinkNone || std::binary_search(donors.begin(), donors.end(), n)) {
      kept.emplace_back(used, n);  // the root's, or drawing now
      continue;
    }
    drop_proxy(n);
  }
  for (const auto& e : kept) proxy_lru_.push(e);
}

void PagedWorld::drop_proxies_over_budget() {
  const uint64_t cap = proxy_cap();
  while (proxy_bytes_ > cap && !proxy_lru_.empty()) {
    const auto [used, n] = proxy_lru_.top();
    proxy_lru_.pop();
    if (n == 0) {
      stamp_proxy(0);  // the root's stays
      continue;
    }
    if (!proxy_[n].resident || proxy_[n].used != used) continue;  // stale
    drop_proxy(n);  // its cells are missing again
  }
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

bool PagedWorld::graft_proxy(uint32_t node, int32_t from) {
  ProxySlot& slot = proxy_[node];
  if (slot.graft >= 0) return true;
  const uint32_t source = from >= 0 ? uint32_t(from) : node;
  ProxySlot::Data& data = *proxy_[source].data;
  Decoded d;
  d.cell = node;
  d.stand_in = int32_t(node);
  d.scene = data.scene;
  // Its own triangles' tree, built when it was decoded, goes into the graft (the triangles stay:
  // a borrowed stand-in below may clip them, a later graft rebuilds the tree); an ancestor's
  // triangles over this node's region get a tree of their own (the builder clips them to it).
  const bool own_tree = source == node && !data.tree.nodes().empty();
  if (!own_tree) d.tree = KdTree::build(d.scene, proxy_build_options(node));
  const uint64_t tree_size = tree_bytes(own_tree ? data.tree : d.tree, kPerCellOverhead);
  d.bytes = d.scene.prims.size() * (sizeof(PrimRef) + sizeof(Triangle)) + tree_size;
  if (lru_.bytes() + held_besides_cells() + d.bytes > lru_.budget()) return false;
  if (own_tree) {
    const uint64_t held = tree_bytes(data.tree, 0);
    d.tree = std::move(data.tree);
    data.tree = KdTree();
    proxy_[source].bytes -= held;
    proxy_bytes_ -= held;
  }
  const Graft g = append(d, node_ropes(node), kNoOwner);
  slot.graft = static_cast<int32_t>(live_.size());
  live_.push_back(g);
  slot.bytes += g.bytes;
  proxy_bytes_ += g.bytes;
  if (source != node) slot.borrowed = int32_t(source);
  return true;
}

bool PagedWorld::linked_below(uint32_t node) const {
  return std::any_of(linked_nodes_.begin(), linked_nodes_.end(),
                     [&](uint32_t n) { return n > node && n < subtree_end_[node]; });
}

int32_t PagedWorld::link_above(uint32_t node) const {
  for (int32_t n = int32_t(node); n >= 0; n = parent_[size_t(n)]) {
    if (proxy_[size_t(n)].link != kLinkNone) return n;
  }
  return -1;
}

bool PagedWorld::link_node(uint32_t node, uint8_t why, int32_t from) {
  ProxySlot& slot = proxy_[node];
  if (slot.link != kLinkNone) {
    slot.link = slot.last_link = why;
    return false;
  }
  if (!graft_proxy(node, from)) return false;
  // What was linked below is inside the node's region: the node's proxy draws it now.
  for (size_t k = 0; k < linked_nodes_.size();) {
    const uint32_t n = linked_nodes_[k];
    if (n > node && n < subtree_end_[node]) {
      unlink_node(n);
    } else {
      ++k;
    }
  }
  // The node becomes a link to its proxy's subtree, which covers the node's region: a ray that
  // reaches any part of it goes through the proxy until it leaves the node, and the proxy's
  // locked borders meet the neighbours' surfaces (no crack between a proxy and a page).
  KdTree::Node& n = tree_.nodes_[node];
  slot.saved = n;
  n.axis_or_leaf = 4;
  n.child = live_[size_t(slot.graft)].node0;
  slot.link = why;
  slot.last_link = why;
  // Linked for what the rays wanted: judged by the images after this one, not by rays cast
  // before it existed.
  slot.last_drawn = image_;
  stamp_proxy(node);
  linked_nodes_.push_back(node);
  ++tree_.links_;
  ++counters_.stand_ins;
  return true;
}

void PagedWorld::unlink_node(uint32_t node) {
  ProxySlot& slot = proxy_[node];
  if (slot.link == kLinkNone) return;
  tree_.nodes_[node] = slot.saved;
  slot.link = kLinkNone;
  std::erase(linked_nodes_, node);
  --tree_.links_;
  ++stand_ins_replaced_;
  if (slot.borrowed >= 0) {
    remove_proxy_graft(node);  // a borrowed subtree is made for one link: it goes with it
    slot.borrowed = -1;
  }
}

void PagedWorld::remove_proxy_graft(uint32_t node) {
  ProxySlot& slot = proxy_[node];
  const uint64_t bytes = live_[size_t(slot.graft)].bytes;
  remove_graft(slot.graft);
  slot.graft = -1;
  slot.bytes -= bytes;
  proxy_bytes_ -= bytes;
}

bool PagedWorld::complete_below(uint32_t node) const {
  const auto& nodes = model_.nodes();
  for (uint32_t n = node; n < subtree_end_[node]; ++n) {
    if (!nodes[n].is_leaf()) continue;
    const uint32_t c = nodes[n].child;
    if (model_.cells()[c].page != StoreCell::kNoPage && slot_[c] < 0 && failed_[c] == 0) return false;
  }
  return true;
}

bool PagedWorld::drawable(uint32_t node) const {
  const auto& nodes = model_.nodes();
  if (nodes[node].is_leaf()) {
    const uint32_t c = nodes[node].child;
    return model_.cells()[c].page == StoreCell::kNoPage || slot_[c] >= 0 || failed_[c] != 0;
  }
  return proxy_[node].resident || (drawable(node + 1) && drawable(nodes[node].child));
}

void PagedWorld::link_children(uint32_t node) {
  const auto& nodes = model_.nodes();
  for (const uint32_t x : {node + 1, nodes[node].child}) {
    if (nodes[x].is_leaf() || complete_below(x)) continue;
    if (proxy_[x].resident && link_node(x, kLinkMissing)) continue;
    link_children(x);
  }
}

void PagedWorld::refine(uint32_t node) {
  const auto& nodes = model_.nodes();
  // Coarse to fine: the proxies of its children and grandchildren (two levels a round trip),
  // and the pages of a subtree of a few cells.
  const auto request = [&](uint32_t x) {
    if (nodes[x].is_leaf()) return;
    std::lock_guard<std::mutex> lock(wanted_mutex_);
    request_proxy(x);
  };
  if (proxy_[node].borrowed >= 0) request(node);  // drawn by an ancestor's: its own first
  for (const uint32_t x : {node + 1, nodes[node].child}) {
    request(x);
    if (!nodes[x].is_leaf()) {
      request(x + 1);
      request(nodes[x].child);
    }
  }
  if (leaves_under_[node] <= kRefineCells) {
    for (uint32_t n = node; n < subtree_end_[node]; ++n) {
      if (!nodes[n].is_leaf()) continue;
      const uint32_t c = nodes[n].child;
      if (model_.cells()[c].page == StoreCell::kNoPage || slot_[c] >= 0 || failed_[c] != 0) continue;
      if (wanted_flag_[c].exchange(1, std::memory_order_acq_rel) != 0) continue;
      std::lock_guard<std::mutex> lock(wanted_mutex_);
      wanted_.push_back(c);
      cache_->request(model_.cells()[c].page);
    }
  }
  if (drawable(node + 1) && drawable(nodes[node].child)) {
    unlink_node(node);
    link_children(node);
  }
}

void PagedWorld::release_proxy_graft(uint32_t node) {
  unlink_node(node);
  if (proxy_[node].graft >= 0) remove_proxy_graft(node);
}

void PagedWorld::release_proxy_grafts() {
  for (size_t n = 0; n < proxy_.size(); ++n) {
    if (proxy_[n].graft >= 0 || proxy_[n].link != kLinkNone) release_proxy_graft(uint32_t(n));
  }
}

void PagedWorld::drop_proxy(uint32_t node) {
  release_proxy_graft(node);
  const std::vector<uint32_t> linked = linked_nodes_;
  for (const uint32_t n : linked) {
    if (proxy_[n].borrowed == int32_t(node)) unlink_node(n);  // drew this proxy's triangles
  }
  proxy_bytes_ -= proxy_[node].bytes;
  if (proxy_[node].resident) --proxies_resident_;
  proxy_[node] = ProxySlot();
}

bool PagedWorld::stand_in_wanted(std::chrono::steady_clock::time_point deadline) {
  (void)deadline;
  std::vector<uint32_t> wanted;
  {
    std::lock_guard<std::mutex> lock(wanted_mutex_);
    wanted = wanted_;
  }
  bool changed = false;
  std::vector<uint32_t> detail_done;
  for (const uint32_t c : wanted) {
    if (slot_[c] >= 0) continue;  // its page is grafted
    const int32_t above = link_above(leaf_node_[c]);
    if (above >= 0) {
      // Drawn by a linked node's proxy already (linked after the cell was wanted): for detail,
      // the page is not wanted; while pages are missing, it still is. Work parked on the cell
      // resumes through the link (the caster must be told: nothing else may have changed, and
      // a frame with nothing pending would end with that work parked).
      if (proxy_[size_t(above)].link == kLinkDetail) detail_done.push_back(c);
      changed = true;
      continue;
    }
    const int32_t detail = detail_node(c);
    if (detail >= 0) {
      link_node(uint32_t(detail), kLinkDetail);
      if (link_above(leaf_node_[c]) >= 0) {
        detail_done.push_back(c);
        changed = true;
      }
      continue;
    }
    // A missing cell is drawn by the finest proxy there is until its page arrives; not by one
    // that would replace finer linked proxies (linking it unlinks them: the whole region would
    // turn coarse, down to the root's proxy for a whole view). There, the nearest proxy draws
    // only the part of its region on the cell's path that holds none (a borrowed stand-in), while
    // the cell's own proxies come (request_proxies).
    if (!stand_in_missing()) continue;
    const int32_t nearest = nearest_proxy(c);
    if (nearest < 0) continue;
    if (!linked_below(uint32_t(nearest))) {
      changed |= link_node(uint32_t(nearest), kLinkMissing);
    } else if (const int32_t free = free_node_on_path(uint32_t(nearest), c); free >= 0) {
      changed |= link_node(uint32_t(free), kLinkMissing, nearest);
    }
  }
  if (!detail_done.empty()) {
    // Drawn for detail: not wanted any more; wanted again when the link goes and a ray reaches it.
    std::sort(detail_done.begin(), detail_done.end());
    std::lock_guard<std::mutex> lock(wanted_mutex_);
    std::erase_if(wanted_, [&](uint32_t c) { return std::binary_search(detail_done.begin(), detail_done.end(), c); });
    for (const uint32_t c : detail_done) wanted_flag_[c].store(0, std::memory_order_release);
  }
  return changed;
}

void PagedWorld::set_detail(const View& view, double pixel_error, bool stand_in_missing) {
  detail_view_ = view;
  set_decode_eye(view.eye);
  pixel_error_ = proxy_.empty() ? 0.0 : pixel_error;
  budgeted_ = stand_in_missing;
}

bool PagedWorld::refine_arrived() {
  // Linked nodes (for missing pages) whose children can now be drawn without them give way at
  // once, within the frame: the rays still to come see the finer proxies.
  bool changed = false;
  const std::vector<uint32_t> linked = linked_nodes_;
  for (const uint32_t n : linked) {
    if (proxy_[n].link != kLinkMissing) continue;
    const uint32_t upper = model_.nodes()[n].child;
    if (drawable(n + 1) && drawable(upper)) {
      unlink_node(n);
      link_children(n);
      changed = true;
    }
  }
  return changed;
}

uint64_t PagedWorld::note_drawn(const CellMarks& marks) {
  std::vector<uint32_t> used;  // proxies the image drew: linked nodes' own, or those they borrow
  for (const uint32_t n : linked_nodes_) {
    const ProxySlot& slot = proxy_[n];
    const Graft& g = live_[size_t(slot.graft)];
    bool drew = false;
    for (uint32_t wc = g.cell0; wc < g.cell0 + g.cells && wc < marks.size() && !drew; ++wc) drew = marks.marked(int32_t(wc));
    if (!drew) continue;
    proxy_[n].last_drawn = image_;
    used.push_back(n);
    if (slot.borrowed >= 0) used.push_back(uint32_t(slot.borrowed));
  }
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  uint64_t bytes = 0;
  for (const uint32_t n : used) {
    stamp_proxy(n);  // what the image drew is used: kept before what it did not
    bytes += proxy_[n].bytes;
  }
  return bytes;
}

void PagedWorld::review_stand_ins() {
  if (stand_in_missing() && linked_nodes_.empty() && resident_cells() == 0 && proxy_[0].resident) {
    // A cold start (nothing of the model in memory yet, e.g. the first frame): the root's proxy
    // draws the whole model at once instead of after a round trip of parked rays; it refines
    // from the next frame on like any linked node.
    if (link_node(0, kLinkMissing)) refine(0);  // asks for the next levels now
    return;
  }
  const std::vector<uint32_t> linked = linked_nodes_;
  for (const uint32_t n : linked) {
    ProxySlot& slot = proxy_[n];
    if (slot.link == kLinkNone) continue;  // unlinked by an ancestor's refinement meanwhile
    const uint64_t age = image_ - slot.last_drawn;  // 1: the last image drew it
    if (age > kLinkKeepImages) {
      // Out of view: a ray that reaches it later wants its cells again (and links it again).
      unlink_node(n);
      continue;
    }
    if (pixel_error_ > 0.0 && detail_ok(int32_t(n))) {
      slot.link = slot.last_link = kLinkDetail;  // fine enough from here: stays, whatever is missing below
      continue;
    }
    if (slot.link == kLinkDetail || !stand_in_missing()) {
      unlink_node(n);
      continue;
    }
    if (age > 1) continue;  // kept while unseen, refined when seen
    if (slot.borrowed >= 0) {
      // A finer ancestor's proxy came in since: it draws the node from now on.
      const int32_t donor = resident_above(n);
      if (donor >= 0 && donor != slot.borrowed) {
        unlink_node(n);
        if (!link_node(n, kLinkMissing, donor)) continue;  // no room: its cells wait
      }
    }
    refine(n);
  }
}

void PagedWorld::cells_under(uint32_t node, const Aabb& box, std::vector<uint32_t>& out) const {
  // The store's top tree below `node`, descended to the leaves whose regions share volume with
  // `box` (a face in common is not enough: a ray in `box` never entered such a leaf).
  const auto& nodes = model_.nodes();
  std::vector<uint32_t> stack{node};
  while (!stack.empty()) {
    const uint32_t n = stack.back();
    stack.pop_back();
    if (nodes[n].is_leaf()) {
      out.push_back(nodes[n].child);
      continue;
    }
    const int a = static_cast<int>(nodes[n].axis_or_leaf);
    if (box.lo[a] < nodes[n].split) stack.push_back(n + 1);
    if (box.hi[a] > nodes[n].split) stack.push_back(nodes[n].child);
  }
}

StandInReport PagedWorld::stand_in_report(const CellMarks& marks) const {
  // Rays that reach a linked node go on in its proxy's subtree, whose world cells have no store
  // owner: what a proxy drew is read from its marked world cells, and the store cells it drew
  // for are those under them.
  StandInReport r;
  // Every grafted proxy (one linked earlier in the frame may have given way to finer ones since),
  // in node order; found through the live grafts, not by a walk over the whole top tree.
  std::vector<uint32_t> grafted;
  for (const Graft& g : live_) {
    if (g.stand_in) grafted.push_back(g.cell);
  }
  std::sort(grafted.begin(), grafted.end());
  std::unordered_set<uint32_t> counted;
  std::vector<uint32_t> under;
  for (const uint32_t n : grafted) {
    const ProxySlot& slot = proxy_[n];
    const Graft& g = live_[size_t(slot.graft)];
    bool drew = false;
    for (uint32_t wc = g.cell0; wc < g.cell0 + g.cells && wc < marks.size(); ++wc) {
      if (!marks.marked(int32_t(wc))) continue;
      drew = true;
      under.clear();
      cells_under(n, tree_.cells()[wc].bounds, under);
      for (const uint32_t c : under) {
        if (model_.cells()[c].page == StoreCell::kNoPage || !counted.insert(c).second) continue;
        if (slot.last_link == kLinkDetail) {
          ++r.detail_cells;
        } else if (slot_[c] < 0) {
          ++r.missing_cells;
        }
      }
    }
    if (!drew) continue;
    ++r.proxy_nodes;
    if (slot.last_link == kLinkMissing) ++r.missing_nodes;
  }
  return r;
}

}  // namespace frontier
