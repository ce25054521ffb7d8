// The out-of-core store build behind frontier-build.
//
//   1. ingest   every input is pulled through its streaming reader (src/io/scene_reader.h),
//               triangulated and appended to one spill file; bounds and a reservoir sample of
//               primitive centres are kept, nothing else. When every input is binary PLY
//               there is no spill file: stage 3 (or stage 4, if everything fits) parses the
//               inputs again, which costs less than writing and reading back all primitives,
//               and fails the build if they changed in between.
//   2. plan     the lattice is fixed from the bounds (Draco codec); the sample is split by
//               median planes (longest axis) until every part's estimated in-core size fits
//               the memory budget: the upper levels of the k-d tree.
//   3. spill    one pass over the ingest file (or the inputs) snaps triangles to the lattice
//               and writes every primitive to each part whose region its bounds overlap
//               (triangles as lattice indices, shared vertices once: spill.h).
//   4. build    each part in turn: loaded, built in core by the SAH builder inside its region
//               (cells of at most --cell-prims references), every cell encoded (in parallel)
//               and written as one page. A part that turns out larger than planned is split
//               again on disk the same way before it is built.
//               With proxies (--proxy-triangles N > 0), the part's tree then gets a proxy page
//               at every interior node, bottom-up (src/lod/proxy.h), and the part's root mesh
//               waits on a stack until its sibling is done; the plan's nodes above the parts
//               merge and simplify those pending meshes as their second child finishes. The
//               stack holds at most one mesh of about N triangles per level of the plan.
//   5. finish   the sections model, tree, cells (sdf with --walkable, portals with a building
//               sidecar, proxies) and the footer; StoreWriter's NAME.tmp + fsync + rename makes the
//               store appear atomically.
//
// The sidecar of a single input (MODEL.json beside MODEL, written by frontier-gen building) is
// read before anything else, so a bad one fails the build at once; only its cells-and-portals
// graph is kept (src/raster/portals.h).
//
// Threads: the serial stages run as two halves on two threads: in ingest one thread parses
// while the other keeps bounds and sample and writes the spill file; in the spill pass and
// when a part is loaded one reads (and snaps) batches while the other sorts or gathers them.
// At most four batches of 4096 primitives are in flight between the two.
//
// Temporaries (preprocess/temp_dir.h): a directory ".NAME.build-XXXXXX" in --tmp-dir or beside
// the output, and OUT.tmp beside the output, each locked for the build's life and removed at
// the end and on failure. A killed build leaves them behind; the next build that looks there
// removes those no live build holds, and says so on stderr.
//
// Memory (--memory; the bound is peak RSS <= memory + kBuildMemoryOverhead): one part in core
// (estimated at kBytesPerPrimitive per primitive), or a partition pass's part buffers (a quarter
// of the budget) and samples (an eighth), beside the store's tree, cell table and page handles,
// which grow with the model and leave parts less room as they do.
#pragma once

#include "src/codec/cell_codec.h"
#include "src/core/status.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace frontier {

// --proxy-triangles' default (README "Proxies": measured on the terrain and the building).
// On: frontier-view draws far and missing subtrees with them (0: none, a smaller, faster build
// whose walks show nothing where cells are not yet in).
inline constexpr uint32_t kDefaultProxyTriangles = 128;

struct BuildOptions {
  std::vector<std::string> inputs;
  std::string output;
  // Where the temporary directory goes (an existing, writable directory); empty: beside output.
  std::string tmp_dir;
  uint64_t memory = uint64_t{1} << 30;  // bytes
  CellCodec codec = CellCodec::Draco;
  int quant_bits = 16;
  uint32_t cell_prims = 1024;           // at most this many references per cell (SAH may stop earlier)
  int threads = 0;                      // 0: all cores
  bool walkable = false;
  double sdf_voxel = 0.0;               // 0: chosen from the model's extent
  double walk_radius = 0.25;            // the walker's clearance; the grid's band is wider
  // With exactly one input whose sidecar (MODEL.json beside MODEL) lists rooms and portals, store
  // them as section "portals". A missing sidecar, or one without rooms and portals, adds
  // nothing; a malformed one fails the build.
  bool portals = true;
  // When > 0, spheres, cones and boxes are tessellated into closed triangle meshes with this
  // many segments around a circle (src/core/tessellate.h) as they are read: a store of triangles
  // only, which the rasterizing visibility classes draw (they skip other primitives).
  int tessellate = 0;
  bool quiet = false;
  // Most primitives built in core at once; 0 derives it from `memory` (kBytesPerPrimitive).
  // Tests set it to force the out-of-core path on small models.
  uint64_t part_primitives = 0;
  // When every input is binary PLY, the first partition pass parses the inputs again instead
  // of writing all primitives to a temporary file first (cheaper than the file's write and
  // read). Tests turn it off to cover the spill path with PLY inputs.
  bool reparse_binary_ply = true;
  // Triangles a proxy page of an interior node aims at (src/lod/proxy.h; at most twice as many
  // where meshoptimizer's locked borders stop it, fewer for a subtree with fewer); 0: no proxies.
  // 0 here (none: the library's callers, tests and benchmarks of cells alone, opt in);
  // frontier-build's --proxy-triangles defaults to kDefaultProxyTriangles.
  uint32_t proxy_triangles = 0;
  // The codec of proxy pages; unset: meshopt when `codec` is Draco, else `codec`. A proxy of
  // ~130 triangles decodes about 4x faster with meshopt (Draco's per-mesh setup dominates so
  // small a mesh) for 9-13 % more proxy bytes on terrains (fewer on a building), and a walk
  // decodes proxies in its frames. Draco and meshopt put the same lattice points in a page, so
  // the proxies and their bounds are the same either way.
  // REQUIRES: a lattice codec (draco, meshopt) only with a lattice `codec`.
  std::optional<CellCodec> proxy_codec;
  // Store each cell page's in-cell tree (src/codec/cell_tree.h): the tree frontier-view builds
  // when it pages the cell in with its default options, so page-in does not run the SAH builder;
  // proxy pages carry theirs too.
  bool cell_trees = true;
};

struct BuildReport {
  uint64_t input_primitives = 0;
  uint64_t primitives = 0;
  uint64_t triangles = 0;
  uint64_t references = 0;
  uint64_t degenerate_dropped = 0;
  uint64_t cells = 0;
  uint64_t pages = 0;
  uint64_t parts = 0;                   // in-core partitions built
  uint32_t depth = 0;
  uint64_t input_bytes = 0;
  uint64_t store_bytes = 0;
  uint64_t spill_bytes = 0;             // written to temporary files
  uint64_t spill_peak_bytes = 0;        // the most of them on disk at once
  uint64_t page_bytes = 0;              // payloads of all pages
  uint64_t cell_tree_pages = 0;         // cell pages carrying an in-cell tree
  uint64_t cell_tree_bytes = 0;         // those trees' bytes (in page_bytes)
  uint64_t proxy_tree_pages = 0;        // proxy pages carrying their tree
  uint64_t proxy_tree_bytes = 0;        // those trees' bytes (in proxy_bytes)
  uint64_t sdf_bytes = 0;               // the collision grid: its section and brick pages (--walkable)
  uint64_t sdf_bricks = 0;              // brick pages of the collision grid
  uint64_t sdf_memory = 0;              // most memory the grid held across partitions (index + a brick)
  uint64_t sdf_spill_bytes = 0;         // the grid's temporary spill file
  std::string portals_sidecar;          // the sidecar the portals section came from (empty: none)
  uint64_t portal_rooms = 0;
  uint64_t portals = 0;
  uint64_t proxy_pages = 0;             // proxies of interior nodes (--proxy-triangles > 0)
  uint64_t proxy_bytes = 0;             // their pages, trailers included
  uint64_t proxy_triangles = 0;         // in all proxy pages
  uint64_t proxy_shells = 0;            // proxies that are voxel shells (unlocked simplification could not)
  uint64_t proxy_sloppy = 0;            // proxies meshopt_simplifySloppy made (no shell either)
  double proxy_root_error = 0.0;        // the root's error bound (0: the root is a leaf)
  double proxy_seconds = 0.0;           // merging, simplifying, measuring and encoding proxies
  std::vector<std::string> warnings;    // what the readers read past (also printed on stderr)
  double seconds = 0.0;
  double ingest_seconds = 0.0, spill_seconds = 0.0, build_seconds = 0.0, encode_seconds = 0.0;
};

// Estimated in-core bytes per primitive reference while a part is built (scene arrays, builder
// items, references and clipped bounds), measured with getrusage on the building model.
inline constexpr uint64_t kBytesPerPrimitive = 400;

// What a build's peak RSS may exceed --memory by, for any --memory of 32M or more (README): the
// program's code and libraries (about 30 MiB resident), the window of a mapped binary PLY's
// vertices, the fixed buffers between the reader thread and the main one, and what the
// threads' malloc arenas keep beyond what is in use.
inline constexpr uint64_t kBuildMemoryOverhead = uint64_t{64} << 20;

// Builds the store, reporting progress (rate, ETA) on stderr unless options.quiet. On failure nothing exists at options.output that was not there before
// (an existing store is replaced only by a complete one).
Result<BuildReport> build_store(const BuildOptions& options);

// The codec proxy pages get under `options` (BuildOptions::proxy_codec).
CellCodec proxy_codec(const BuildOptions& options);

// Keeps memory the build frees in the process (glibc: no trimming, heap grown 256 MiB at a time,
// the mmap threshold fixed at 32 MiB) instead of returning it to the kernel and faulting it in
// again for the next part: a 20 M-triangle build took 1.7 M page faults and 5 s of system time
// before, 0.28 M and 2.5 s after. Peak RSS is unchanged (pages are reused, not added; the heap's
// padding is address space until touched). glibc keeps its arena per thread: one arena for all
// would save about 10 MiB of peak RSS (the threads' high-water marks add up) but costs 20 % of
// the build time in lock contention. Process-wide: frontier-build and bench_build call it first thing in main.
void tune_allocator_for_build();

}  // namespace frontier
