// Writing a model piece by piece: pieces are generated in parallel (TBB pipeline) and handed
// to the PLY writer strictly in index order, so the file does not depend on thread timing.
// Memory is bounded by the pieces in flight (a few per thread), never by the model.
#pragma once

#include "data_gen/mesh_builder.h"
#include "src/core/progress.h"
#include "src/io/ply_writer.h"
#include "src/core/status.h"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace frontier::gen {

// Builds piece `index` with the builder (counting or emitting). Must be deterministic and
// safe to call concurrently for different indices.
using PieceFunction = std::function<void(uint64_t index, MeshBuilder& builder)>;

struct MeshCounts {
  uint64_t vertices = 0, triangles = 0;
};

// Counting pass: runs every piece with a counting builder (in parallel; the sum is exact).
MeshCounts count_pieces(uint64_t piece_count, const PieceFunction& piece,
                        const PlyVertexLayout& layout);

struct StreamOptions {
  std::string path;
  PlyVertexLayout layout;
  std::vector<std::string> comments;
  bool quiet = false;
  std::string label = "writing";
};

// Counts, then writes every piece to a PLY file. Returns the counts written.
Result<MeshCounts> write_pieces(uint64_t piece_count, const PieceFunction& piece,
                                const StreamOptions& options);

}  // namespace frontier::gen
