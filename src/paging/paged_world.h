// PagedWorld: the part of a store that is in memory right now, held as one Scene and one KdTree
// that the in-memory engine (frustum casting, shading) renders directly.
//
// The store's top tree is resident for the whole session; its cell indices are the store's.
// Each top cell is, at any moment, in one of four states:
//   empty     no page: an ordinary empty cell, never wanted;
//   missing   its page is not in memory: the cell is a placeholder without references, and
//             missing() says so, so the frustum caster parks work that reaches it and want()s it;
//   resident  its page read (through the store's PageCache), decoded, checked and refined by the
//             SAH builder into a subtree inside the cell's exact region, and *grafted*: the top
//             leaf becomes a link node to the subtree root, the subtree's nodes, cells, references
//             and primitives are appended to the world's arrays, and its ropes that left the
//             subtree are replaced by the placeholder's ropes into the top tree;
//   failed    its page could not be read or decoded (checksum, codec, invariants): the cell stays
//             empty for the rest of the session ("drawn as missing"), counted in page_errors.
//
// Memory, one budget for everything paged: the compressed pages the PageCache holds (an eighth
// of the budget, at least 1 MiB) plus the decoded, grafted cells (the rest). resident_bytes()
// is their sum and stays within the budget: before a cell is grafted, cells no frame touched
// since the oldest are unlinked (LRU by the frame that last touched them; among one frame's,
// the smallest on screen from the next frame's eye first, the decoder's priority the other way
// round; ties by store cell: CellLru, cell_lru.h); cells touched in the current frame are never evicted, so when the
// current view alone needs more than the budget the newcomer is dropped (it stays missing; the
// frame degrades to fewer samples) instead.
// Unlinked subtrees leave garbage in the arrays; compact() at a frame boundary reclaims it.
//
// A frame whose own cells do not fit is rendered in passes (Walkthrough): release_pass()
// between two passes unlinks every cell, the current frame's included, and compacts. An image
// (begin_frame() to end_frame()) may so span several LRU frames; what it touched in all of
// them is its working set (image_cells(), working_set_bytes()), and a cell grafted twice in
// one image counts as re-read (PagingCounters::cells_reread).
//
// Level of detail: one cut per frame (DESIGN.md "Level of detail: one cut per frame"; the
// store's `proxies` section). An interior node of the top tree may be drawn by its PROXY instead
// of what lies below it: the node becomes a link to a subtree built over the proxy's triangles in
// the node's region, so every ray that reaches the region goes through the proxy until it leaves
// the node. A resident proxy is grafted (its subtree appended to the world's arrays) when it is
// installed; linking and unlinking it only swap the node. A whole node, never part of one:
// meshoptimizer kept the proxy's borders, so it meets its neighbours' surfaces without cracks.
// The cut is chosen at begin_frame(), before the first ray, and the traced tree does not change
// until the next begin_frame() in the frames that draw it:
//   pegged   (pixel error T > 0 and a budget, set_detail()): from the root, a node whose error
//            bound projects below T pixels (at the point of its region nearest the eye), or that
//            lies outside the view, or whose children cannot all be drawn, is in the cut, drawn by
//            its proxy (or, a leaf, by its cell); otherwise its children are considered. A child
//            can be drawn when it is a resident, empty or failed cell, or a node with a resident
//            proxy, or a node all of whose children can. The root's proxy is always resident, so
//            the cut never leaves a hole and no ray of such a frame parks (the top levels below
//            it are read at the opening too: preload_top()). After the frame
//            (end_frame()), each cut node its rays entered whose bound projects to T or more asks
//            for what lies below it, down to where the bounds project below T (a few levels at
//            most): proxies, then pages, largest projected error first. Nothing is asked for
//            where no ray went. What arrived is installed by sync(): in the next frame's paging
//            share before its rays, and (the Walkthrough's use_slack()) in what is left of a frame
//            whose image finished before its peg; the next begin_frame() draws it.
//   waited   (T > 0, frames that run to completion, e.g. --sync-paging): the nodes in view whose
//            bounds project below T are drawn by their proxies, read at begin_frame() if they are
//            not resident; below the others, rays park on missing cells as in the exact path.
//   exact    (T = 0): nothing is linked; rays park on missing cells and resume (the exact path).
// Residency: decoded cells and grafted proxies share the decoded budget; what the current cut
// draws (linked proxies, the cells its rays entered) is never evicted; other proxies go least
// recently drawn first, cells as described above. When the cut's own proxies and cells fill
// most of the budget, the cut stops asking for more (it stays coarser instead of thrashing).
// Decoding ahead. A decoder thread takes wanted cells whose pages have arrived, the one that
// spans the most pixels from the current eye first (cell size over distance), decodes and
// refines them off the frame, and leaves them for sync(), which only grafts them (O(cell)).
// What it holds decoded stays below a sixteenth of the decoded share and below the room the
// world had at the last sync(); a decode that does not fit is dropped and its cell wanted
// again. sync() also decodes ready pages itself, in parallel, until its deadline.
//
// Threads: missing() and want() are called by render workers while a frame slice runs; every
// other call is made by the owner between slices (no slice running). I/O runs on the cache's
// loader thread; the decoder thread shares only wanted_ (wanted_mutex_) and its own state.
#pragma once

#include "src/engine/cell_gate.h"
#include "src/engine/frustum.h"
#include "src/engine/kdtree.h"
#include "src/core/sample_buffer.h"
#include "src/core/scene.h"
#include "src/core/view.h"
#include "src/paging/cell_lru.h"
#include "src/paging/store_model.h"
#include "store/page_cache.h"
#include "store/store_page_source.h"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <iterator>
#include <memory>
#include <mutex>
#include <queue>
#include <utility>
#include <vector>

namespace frontier {

struct PagedWorldOptions {
  uint64_t budget_bytes = 512ull << 20;  // compressed + decoded
  int io_threads = 1;                    // PageCache loader threads
  KdBuildOptions cell_build;             // how a paged-in cell is refined (max/min cell size)
};

// What paging did since the last take_counters().
struct PagingCounters {
  uint64_t cells_paged_in = 0;  // cells grafted
  uint64_t cells_evicted = 0;   // cells unlinked to make room
  uint64_t cells_dropped = 0;   // decoded cells that did not fit (everything else touched this frame)
  uint64_t page_errors = 0;     // pages that failed (each at most once)
  uint64_t primitives_paged_in = 0;
  uint64_t cells_reread = 0;    // cells grafted again in the same image (released in between)
  uint64_t stand_ins = 0;       // nodes linked to their proxies (see "Level of detail")
  uint64_t proxies_loaded = 0;  // proxy pages decoded
  double decode_ms = 0.0;       // wall time of sync() (on the frame's thread): placing, decoding, grafting
  double decode_ahead_ms = 0.0; // decoder thread time spent decoding cells sync() placed since
};

// What the cut drew for an image (PagedWorld::stand_in_report).
struct StandInReport {
  uint64_t cut_nodes = 0;    // interior nodes drawn by their proxies (linked now)
  uint64_t proxy_nodes = 0;  // of those, the nodes the image's rays entered
  uint64_t proxy_cells = 0;  // store cells (with pages) below the nodes the rays entered
  uint64_t requests = 0;     // proxies and pages asked for, not in yet
  // The largest error bound, projected to pixels, of a node the rays entered that is drawn by
  // its proxy (0: none; kEyeInside when the eye is inside such a node): how far the image is
  // from the cut's pixel error where rays went.
  static constexpr double kEyeInside = 1e6;
  double cut_error = 0.0;
};

class PagedWorld final : public CellGate {
 public:
  // REQUIRES: `model` outlives the world.
  PagedWorld(const StoreModel& model, const PagedWorldOptions& options);
  ~PagedWorld() override;
  PagedWorld(const PagedWorld&) = delete;
  PagedWorld& operator=(const PagedWorld&) = delete;

  const Scene& scene() const { return scene_; }
  // How paged-in cells are refined (PagedWorldOptions::cell_build): a page's stored tree is used
  // when it was built with these options.
  const KdBuildOptions& cell_build() const { return cell_build_; }
  const KdTree& tree() const { return tree_; }
  const StoreModel& model() const { return model_; }

  // CellGate (render workers).
  // Only top cells can be missing; grafted cells are numbered after them.
  bool missing(int32_t cell) const override { return size_t(cell) < missing_.size() && missing_[size_t(cell)] != 0; }
  void want(int32_t cell) override;

  // Number of cells wanted whose pages have not been grafted, failed or dropped yet.
  size_t pending() const;
  // Grafts what has arrived: wanted cells whose pages the cache holds (or that failed) are
  // decoded and refined in parallel, then grafted, evicting as described above. Stops starting
  // new decodes at `deadline`. Returns true when the tree changed (the caster must be told).
  bool sync(std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max());
  // sync() for the culling classes (src/raster/visibility.h), which hold no world cell between calls:
  // when a decoded cell does not fit, cells grafted before this call — least recently touched
  // first, this frame's included — are unlinked (and the arrays compacted) to make room. Only a
  // cell larger than the whole decoded share is dropped. Compaction renumbers world cells,
  // primitives and subtree nodes (top nodes keep theirs): generation() counts it.
  bool sync_evicting();
  uint64_t generation() const { return generation_; }
  // Records that the current frame used store cell `c` (LRU), for renderers without CellMarks.
  void touch(uint32_t store_cell) {
    if (store_cell < top_cells_) lru_.touch(store_cell);
  }
  // Bytes store cell c took decoded and refined when it was last paged in (0: never was).
  uint64_t decoded_size(uint32_t store_cell) const { return decoded_size_[store_cell]; }
  // Store cells touched (or paged in) since the last begin_frame().
  std::vector<uint32_t> touched_this_frame() const;
  // Blocks until at least one wanted page is readable or failed (or nothing is pending), or
  // until `deadline`. Returns the milliseconds waited (stall time).
  double wait_for_pages(std::chrono::steady_clock::time_point deadline);

  // Frame bookkeeping: call begin_frame() before the caster's begin() (it may compact, which
  // renumbers cells; `marks` must be the caster's marks, they are resized), and end_frame()
  // after the frame's last slice: it records which top cells the frame touched (for the LRU)
  // and returns how many distinct store cells that is.
  void begin_frame(CellMarks& marks);
  // When the current image cannot finish because what it needs does not fit beside what is
  // resident: unlinks every cell the image has not touched and compacts. Returns false (and
  // changes nothing) when there is nothing to reclaim; otherwise cells are renumbered and the
  // caller must restart the image.
  bool reclaim_untouched(CellMarks& marks);
  // Between two passes of an image whose own cells do not fit: records what the pass touched
  // (for the image's working set), unlinks every cell and compacts, and forgets the cells
  // dropped. Cells are renumbered: the caller must tell the caster (FrustumCaster::renumbered).
  // Returns the pass's demand: decoded bytes of the cells it touched and of those it dropped.
  uint64_t release_pass(CellMarks& marks);
  uint64_t end_frame(const CellMarks& marks);
  // Store cells the current image touched: in its earlier passes, paged in or touched in this
  // pass, and marked in `marks` (each grafted subtree counts as its store cell). Ascending.
  std::vector<uint32_t> image_cells(const CellMarks& marks) const;
  // Decoded bytes of the image's cells as of the last end_frame() (cells never decoded: 0), and
  // of the proxies it drew.
  uint64_t working_set_bytes() const { return working_set_bytes_; }
  // The smallest budget_bytes whose decoded share holds `decoded_bytes` (the inverse of the
  // split between compressed pages and decoded cells), rounded up to a MiB.
  static uint64_t budget_for(uint64_t decoded_bytes);
  // The store cell a world cell belongs to (kNoOwner: a proxy's subtree).
  static constexpr uint32_t kNoOwner = UINT32_MAX;
  uint32_t store_cell(int32_t world_cell) const { return owner_[size_t(world_cell)]; }
  bool resident(uint32_t store_cell) const { return slot_[store_cell] >= 0; }
  // Asked for (by want()) and not grafted, failed or dropped since.
  bool wanted(uint32_t store_cell) const {
    return wanted_flag_[store_cell].load(std::memory_order_acquire) != 0 && slot_[store_cell] < 0 &&
           failed_[store_cell] == 0;
  }

  // The cut of the next image (call before begin_frame(), which chooses it; see "Level of
  // detail"): the view, the pixel error T (0: the exact path, nothing is linked) and whether
  // frames may end before every page is in (pegged: the cut draws only what is resident, and the
  // decoder thread decodes alone).
  void set_detail(const View& view, double pixel_error, bool pegged);
  bool has_proxies() const { return !proxy_.empty(); }
  // The current image's cut is the pegged kind: no ray of it parks.
  bool pegged_cut() const { return cut_ == CutKind::kPegged; }
  // World primitive `p` belongs to a proxy (now or when it was confirmed: dropped proxies'
  // primitives keep their flag until compact()).
  bool stand_in_prim(uint32_t p) const { return p < stand_in_prim_.size() && stand_in_prim_[p] != 0; }
  // Store cell `c` is drawn by an ancestor's proxy now.
  bool stood_in(uint32_t c) const { return !proxy_.empty() && link_above(leaf_node_[c]) >= 0; }
  // Top nodes drawn by their proxies now (the cut's interior nodes).
  const std::vector<uint32_t>& linked_nodes() const { return linked_nodes_; }
  // Times a chosen cut differed from the one before: an image drawn with proxies is out of date
  // once this grows.
  uint64_t cut_changes() const { return cut_changes_; }
  // Some cell the cut asked for has its page in, not yet decoded.
  bool cells_ready() const;
  // Proxies installed now (the root's and the top levels' from the store's opening on).
  size_t proxies_resident() const { return proxies_resident_; }
  // Cells grafted and proxies installed so far (it only grows).
  uint64_t installs() const { return installs_; }
  // Proxies and pages the cut asked for that are not in yet.
  size_t requests_outstanding() const;
  // What the image's rays reached of the cut, as of the last end_frame().
  StandInReport stand_in_report() const;
  // Grafted proxies' bytes (within the decoded share).
  uint64_t proxy_bytes() const { return proxy_bytes_; }

  PagingCounters take_counters();
  uint64_t budget_bytes() const { return budget_; }
  uint64_t decoded_bytes() const { return lru_.bytes(); }
  uint64_t decoded_budget() const { return lru_.budget(); }  // the decoded cells' share
  // Decoded bytes of the cells the frame touched, as of the last end_frame().
  uint64_t touched_bytes() const { return touched_bytes_; }
  // Compressed pages held by the cache plus decoded cells: never above budget_bytes() after
  // sync() returns (the cache's own rule: see store/page_cache.h).
  uint64_t resident_bytes() const { return cache_->resident_bytes() + lru_.bytes() + proxy_bytes_; }
  uint64_t pinned_bytes() const { return cache_->pinned_bytes(); }
  store::PageCacheStats cache_stats() const { return cache_->stats(); }
  size_t resident_cells() const;
  // Rebuilds the arrays without garbage. Renumbers world cells: only between frames.
  void compact();

 private:
  struct Graft;
  struct Decoded;
  struct SyncPass;
  struct ProxySlot;
  struct ProxyDecoded;
  struct DecoderState;
  void decode(uint32_t cell, Decoded& out) const;
  bool sync_impl(std::chrono::steady_clock::time_point deadline, bool evict);
  // Takes the wanted cells whose pages arrived (or failed) off the list (`take`; else leaves
  // them) and asks again for the pages of the others (no-op while queued or loading).
  std::vector<uint32_t> take_ready(bool take = true);
  bool hopeless(uint32_t cell) const;
  void place(Decoded& d, bool evict, SyncPass& pass);
  // `bytes` more fit in the decoded share, once proxies nothing draws now made room.
  bool fits(uint64_t bytes);
  // Unlinks live cells other than `keep` (LRU first) and compacts until `bytes` more fit.
  bool evict_for(uint64_t bytes, const std::vector<uint32_t>& keep);
  // Unlinks cells not touched in this frame, LRU first, until at most `target` decoded bytes
  // are live. False when the cells left (all touched in this frame) still take more.
  bool unlink_oldest(uint64_t target);
  void graft(Decoded& d);
  // Appends a decoded subtree to the world's arrays; its faces on the root's boundary get
  // `ropes`, its world cells the owner `owner`.
  Graft append(const Decoded& d, const std::array<int32_t, 6>& ropes, uint32_t owner);
  void remove_graft(int32_t slot);
  void unlink(uint32_t cell);
  void note_touched(const CellMarks& marks);
  void forget_dropped();
  // Decoded bytes held in the decoded share besides live cells: garbage and proxies.
  uint64_t held_besides_cells() const { return garbage_bytes_ + proxy_bytes_; }

  // Decoding ahead (paged_world_decoder.cpp).
  static constexpr uint64_t kDecodeAheadShareDivisor = 16;
  void start_decoder();
  void stop_decoder();
  void decoder_loop();
  // Store cell `cell`'s size over its distance from `eye`: its size on screen, up to a constant.
  // The decoder serves the largest first; among one frame's cells, the smallest is evicted first.
  double screen_size(uint32_t cell, const Vec3& eye) const;
  // Takes up to `count` proxies whose pages arrived (or failed) off proxy_wanted_.
  std::vector<uint32_t> pick_ready_proxies(size_t count);
  // Puts `node` back on proxy_wanted_ and asks for its page again (it left the cache).
  void requeue_proxy(uint32_t node);
  // How a proxy's triangles get their tree over node `node`'s region: the cells' refine options
  // with leaves of up to kProxyCellPrims (cell_tree.h proxy_tree_options).
  KdBuildOptions proxy_build_options(uint32_t node) const;
  // Decodes node `node`'s proxy page and loads its tree from the page, or builds it when the
  // page carries none built with proxy_build_options (any thread: reads the model only).
  // False when the page left the cache meanwhile.
  bool decode_proxy(uint32_t node, ProxyDecoded& out) const;
  // Whether the frame's threads decode what arrived (in sync, within its deadline): in frames
  // that wait for their pages, and before a pegged cut's rays (its decoder thread pauses).
  bool frame_decodes() const;
  // Takes up to `count` ready cells off wanted_, those to decode first.
  std::vector<uint32_t> pick_ready(const Vec3& eye, bool has_eye, size_t count);
  static constexpr size_t kDecodeBatch = 4;
  // Tells the decoder how much room the decoded share has now.
  void publish_room();
  void set_decode_eye(const Vec3& eye);
  // The decoder waits for room the last sync() did not publish: the frame's thread decodes.
  bool decoder_blocked() const;
  std::vector<Decoded> take_decoded();
  // Gives back decoded cells sync() had no time to place.
  void keep_decoded(std::move_iterator<std::vector<Decoded>::iterator> first,
                    std::move_iterator<std::vector<Decoded>::iterator> last);

  // Level of detail (paged_world_cut.cpp).
  enum class CutKind : uint8_t { kExact, kPegged, kWaited };
  void open_proxies();
  // Asks for top node `node`'s proxy page unless it is resident, asked for or failed
  // (wanted_mutex_ held).
  void request_proxy(uint32_t node);
  // Pixels node `node`'s error bound spans at the point of its region nearest the eye (infinite
  // without a proxy, or with the eye inside the region).
  double pixels_of(uint32_t node) const;
  // Node `node`'s region may be seen from the view (its projection meets the screen).
  bool in_view(uint32_t node) const;
  // Makes a decoded proxy resident (grafted) or marks it failed; true when it became resident.
  bool install_proxy(ProxyDecoded& p);
  // Installs the proxies the decoder finished (and, in frames that wait for their pages, decodes
  // those that arrived here); true when one became resident.
  bool load_proxies(std::chrono::steady_clock::time_point deadline);
  // Stamps a resident proxy as just used (its place in the proxy LRU).
  void stamp_proxy(uint32_t node);
  // Drops resident proxies no node is linked to (least recently used first, never the root's)
  // until proxies take at most `target` bytes or only linked ones are left.
  void shed_proxies(uint64_t target);
  // Links top node `node` to its proxy's subtree (REQUIRES: grafted, no linked node above or
  // below it) / restores the node.
  void link_node(uint32_t node);
  void unlink_node(uint32_t node);
  // The linked node at or above top node `node` (-1: none).
  int32_t link_above(uint32_t node) const;
  // `node` can be drawn from what is resident (see "Level of detail").
  bool drawable(uint32_t node) const;
  // Chooses the cut for the image begin_frame() starts and links it; true when it changed.
  bool choose_cut();
  // The waited cut's proxies that are not resident: read and installed now.
  void load_now(const std::vector<uint32_t>& nodes);
  // At open: the proxies of the top levels below the root, whole levels, at most
  // kPreloadTriangles triangles and 1/kPreloadBudgetShare of the decoded budget.
  void preload_top();
  // After a pegged frame: the cut nodes its rays entered (note_drawn()) ask for what lies below.
  void request_refinements();
  // Records which linked nodes the image's rays reached (end_frame(): drawn_nodes_); returns the
  // bytes of the proxies they drew (part of the image's working set).
  uint64_t note_drawn(const CellMarks& marks);
  // Grafts node `node`'s proxy as a subtree over its region; false when it does not fit.
  bool graft_proxy(uint32_t node, ProxyDecoded& p);
  std::array<int32_t, 6> node_ropes(uint32_t node) const;
  // Unlinks the node and removes its proxy (subtree and bytes); it is no longer resident.
  void drop_proxy(uint32_t node);
  // Wanted cells the current cut did not ask for again go off the list (pegged cut).
  void forget_unasked(const std::vector<uint32_t>& cells, const std::vector<uint32_t>& proxies);
  // The cut asks for at most this many proxies and pages after a frame, largest error first.
  static constexpr size_t kMaxProxyRequests = 512, kMaxPageRequests = 256;
  // Below a cut node its rays entered, what is asked for goes at most this many levels down.
  static constexpr int kRequestLevels = 4;
  static constexpr uint64_t kPreloadTriangles = 1u << 17, kPreloadBudgetShare = 32;
  static constexpr uint64_t kDecodedBytesPerProxyTriangle = 256;  // triangle, reference, tree: rough
  // The cut stops asking for more once what it draws takes this share of the decoded budget.
  static constexpr double kCutFullShare = 0.75;

  const StoreModel& model_;
  uint64_t installs_ = 0;  // installs()
  std::unique_ptr<store::StorePageSource> source_;
  std::unique_ptr<store::PageCache> cache_;
  KdBuildOptions cell_build_;
  uint64_t budget_ = 0;         // total
  CellLru lru_;                 // the live cells' bytes within the decoded share, order of use
  uint64_t garbage_bytes_ = 0;
  uint64_t touched_bytes_ = 0;
  uint64_t working_set_bytes_ = 0;
  std::vector<uint32_t> dropped_;        // store cells dropped for lack of room this frame
  uint64_t image_ = 1;                   // images begun so far (begin_frame)
  std::vector<uint64_t> passed_image_;   // store cell -> last image whose earlier pass touched it
  std::vector<uint32_t> earlier_cells_;  // store cells touched in earlier passes of this image
  std::vector<uint64_t> grafted_image_;  // store cell -> last image that grafted it

  Scene scene_;
  KdTree tree_;
  size_t top_nodes_ = 0;
  size_t top_cells_ = 0;
  std::vector<uint32_t> leaf_node_;      // store cell -> its top leaf node
  std::vector<uint8_t> missing_;         // per top cell
  std::vector<uint32_t> owner_;          // world cell -> store cell
  std::vector<int32_t> slot_;            // store cell -> index in live_, or -1
  std::vector<Graft> live_;
  std::vector<uint8_t> failed_;          // store cell
  std::vector<uint64_t> decoded_size_;   // store cell -> bytes when last grafted
  uint64_t generation_ = 0;              // compactions so far

  // Level of detail.
  std::vector<ProxySlot> proxy_;         // per top node; empty when the store has no proxies
  std::vector<int32_t> parent_;          // per top node (-1: the root)
  std::vector<uint32_t> linked_nodes_;   // top nodes that are links to their proxies now
  std::vector<uint32_t> drawn_nodes_;    // of those, the ones the last image's rays entered
  std::vector<uint32_t> page_cells_under_;  // per top node: cells with pages in its subtree
  std::vector<uint8_t> stand_in_prim_;   // world primitive -> belongs to a proxy
  std::vector<uint32_t> proxy_wanted_;   // nodes whose proxy pages were requested, not decoded
  uint64_t proxy_bytes_ = 0;
  uint64_t proxy_use_ = 0;               // stamps for proxy LRU
  // Resident proxies by their stamp, oldest on top; entries whose stamp changed since are stale
  // (skipped when popped, dropped when the heap outgrows the resident proxies).
  std::priority_queue<std::pair<uint64_t, uint32_t>, std::vector<std::pair<uint64_t, uint32_t>>,
                      std::greater<>> proxy_lru_;
  size_t proxies_resident_ = 0;
  uint64_t cut_changes_ = 0;
  uint64_t cut_bytes_ = 0;               // decoded bytes the current cut draws (proxies and cells)
  View detail_view_;
  double pixel_error_ = 0.0;
  CutKind cut_ = CutKind::kExact;
  // Frames may end before every page is in (pegged): the decoder thread decodes alone, the
  // frame's thread only places what it finished (set_detail()).
  bool budgeted_ = false;

  // The world's scene has shading normals (a proxy brought them): every triangle is charged for
  // them (charge_of), the cells' flat ones included. Read by the decoder thread.
  std::atomic<bool> normals_{false};
  std::unique_ptr<std::atomic<uint8_t>[]> wanted_flag_;  // store cell: in wanted_ already
  mutable std::mutex wanted_mutex_;
  std::vector<uint32_t> wanted_;

  // Frames between two returns of free heap memory to the system (by the decoder thread).
  static constexpr uint32_t kTrimFrames = 8;
  uint32_t frames_since_trim_ = 0;

  PagingCounters counters_;
  std::unique_ptr<DecoderState> decoder_;  // last: its thread stops first
};

}  // namespace frontier
