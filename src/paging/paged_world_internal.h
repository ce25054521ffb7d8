// PagedWorld's private records, shared by paged_world.cpp, paged_world_cut.cpp and paged_world_decoder.cpp.
#pragma once

#include "src/paging/paged_world.h"

#include <tbb/task_arena.h>

#include <condition_variable>
#include <memory>
#include <optional>
#include <thread>

namespace frontier {

// Per world cell: owner_ here, the caster's marks and per-cell incidence cache.
inline constexpr uint64_t kPerCellOverhead = sizeof(uint32_t) + sizeof(uint32_t) + 48;

// Bytes a k-d tree's arrays take, with `per_cell_extra` more per cell (kPerCellOverhead once it
// is grafted into the world).
inline uint64_t tree_bytes(const KdTree& t, uint64_t per_cell_extra) {
  return t.nodes().size() * sizeof(KdTree::Node) + t.cells().size() * (sizeof(KdTree::Cell) + per_cell_extra) +
         t.reference_count() * (sizeof(uint32_t) + sizeof(Aabb));
}

// Where a grafted cell's pieces live in the world's arrays (each a contiguous range: a graft
// appends to every array at once, so ranges of later grafts lie after earlier ones).
struct PagedWorld::Graft {
  uint32_t cell = 0;                     // store cell
  uint32_t node0 = 0, nodes = 0;         // tree nodes
  uint32_t cell0 = 0, cells = 0;         // world cells
  uint32_t ref0 = 0, refs = 0;           // references (and their bounds)
  uint32_t prim0 = 0, prims = 0;         // scene.prims
  std::array<uint32_t, 5> kind0{}, kinds{};  // per PrimKind array ranges
  uint64_t bytes = 0;
  bool stand_in = false;                 // a proxy's subtree: `cell` is then the top node
};

struct PagedWorld::Decoded {
  uint32_t cell = 0;
  // Not decoded: the page left the cache between ready() and try_pin(), or the deadline came
  // before its turn. Wanted again.
  bool retry = false;
  bool skipped = false;  // not decoded: it would not fit (hopeless())
  Status status;
  Scene scene;
  KdTree tree;
  uint64_t bytes = 0;
  int32_t stand_in = -1;  // a proxy subtree: the node whose proxy it is
};

// A top node's proxy decoded by the decoder thread, with the k-d tree of its triangles over the
// node's region (what graft_proxy() appends), not installed yet.
struct PagedWorld::ProxyDecoded {
  uint32_t node = 0;
  bool page_failed = false;  // the page could not be read (the cache counted the error)
  Status status;
  Scene scene;
  KdTree tree;
};

// A top node's proxy as the world holds it. One per top node, so it stays small (a 1 B-triangle
// store has millions of top nodes): a resident proxy is a graft in the world's arrays.
struct PagedWorld::ProxySlot {
  uint64_t bytes = 0;        // its graft's
  uint64_t used = 0;         // proxy_use_ stamp of the last cut that drew it
  KdTree::Node saved;        // the top node as the store has it, while linked
  int32_t graft = -1;        // its subtree's index in live_ while resident (-1: not resident)
  bool linked = false;       // the top node is a link to the graft now (in the cut)
  bool requested = false;    // asked for, not installed yet
  bool failed = false;
};

// The decoder thread's shared state (paged_world_decoder.cpp). Lock order: wanted_mutex_, then
// `mutex`.
struct PagedWorld::DecoderState {
  std::thread thread;
  tbb::task_arena arena{1, 1};
  std::mutex mutex;
  std::condition_variable cv;
  bool stop = false;
  std::vector<Decoded> done;      // decoded, not placed yet
  uint64_t done_bytes = 0;
  size_t in_flight = 0;           // taken off wanted_, being decoded
  uint64_t cap = 0;               // done_bytes stay below this
  uint64_t room = 0;              // the decoded share's free bytes at the last publish_room()
  uint64_t room_generation = 0;
  bool blocked = false;           // a decoded cell did not fit the room of this generation
  Vec3 eye{0.0};                  // the current view's eye (priority)
  bool has_eye = false;
  double ms = 0.0;                // decoding time since the last take_decoded()
  std::vector<ProxyDecoded> proxies_done;  // proxies decoded, not installed yet
  bool trim = false;              // give free heap pages back to the system when idle
  bool paused = false;            // a pegged cut's frames: the frame's threads decode (sync())
};

}  // namespace frontier
