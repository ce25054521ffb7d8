// The out-of-core store build behind frontier-build.
//
//   1. ingest   every input is pulled through its streaming reader (src/scene_reader.h),
//               triangulated and appended to one spill file; bounds and a reservoir sample of
//               primitive centres are kept, nothing else.
//   2. plan     the lattice is fixed from the bounds (Draco codec); the sample is split by
//               median planes (longest axis) until every part's estimated in-core size fits
//               the memory budget: the upper levels of the k-d tree.
//   3. spill    one pass over the ingest file snaps triangles to the lattice and writes every
//               primitive to each part whose region its bounds overlap.
//   4. build    each part in turn: loaded, built in core by the SAH builder inside its region
//               (cells of at most --cell-prims references), every cell encoded (in parallel)
//               and written as one page. A part that turns out larger than planned is split
//               again on disk the same way before it is built.
//   5. finish   the sections model, tree, cells (and sdf with --walkable) and the footer;
//               StoreWriter's NAME.tmp + fsync + rename makes the store appear atomically.
//
// Memory: the spill buffers, one part in core (estimated at kBytesPerPrimitive per primitive)
// and the pages being encoded. Temporary files live in a directory beside the output
// (".NAME.build-XXXXXX"), removed at the end and on failure; a killed build may leave it
// behind, and the next build of the same output removes such leftovers.
#pragma once

#include "src/cell_codec.h"
#include "src/status.h"

#include <cstdint>
#include <string>
#include <vector>

namespace frontier {

struct BuildOptions {
  std::vector<std::string> inputs;
  std::string output;
  uint64_t memory = uint64_t{1} << 30;  // bytes
  CellCodec codec = CellCodec::Draco;
  int quant_bits = 16;
  uint32_t cell_prims = 1024;           // at most this many references per cell (SAH may stop earlier)
  int threads = 0;                      // 0: all cores
  bool walkable = false;
  double sdf_voxel = 0.0;               // 0: chosen from the model's extent
  double walk_radius = 0.25;            // the walker's clearance; the grid's band is wider
  bool quiet = false;
  // Most primitives built in core at once; 0 derives it from `memory` (kBytesPerPrimitive).
  // Tests set it to force the out-of-core path on small models.
  uint64_t part_primitives = 0;
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
  uint64_t page_bytes = 0;              // payloads of all pages
  uint64_t sdf_bytes = 0;               // the collision grid section (--walkable)
  uint64_t sdf_memory = 0;              // memory the grid held at the end of the build
  double seconds = 0.0;
  double ingest_seconds = 0.0, spill_seconds = 0.0, build_seconds = 0.0, encode_seconds = 0.0;
};

// Estimated in-core bytes per primitive reference while a part is built (scene arrays, builder
// items, references and clipped bounds), measured with getrusage on the building model.
inline constexpr uint64_t kBytesPerPrimitive = 400;

// Builds the store, reporting progress (rate, ETA) on stderr unless options.quiet. On failure nothing exists at options.output that was not there before
// (an existing store is replaced only by a complete one).
Result<BuildReport> build_store(const BuildOptions& options);

}  // namespace frontier
