// The `terrain` model: a fractal height field (fBm of seeded gradient noise plus a little
// per-vertex scan jitter) over a regular grid, written tile by tile. Z is up; the grid is
// centred on the origin; triangles are counter-clockwise seen from above (+z).
//
// A grid point's height is a pure function of (seed, i, j), so tiles agree exactly on their
// shared edges (each tile writes its own copy of the edge vertices: dedup is per tile).
#pragma once

#include "data_gen/piece_stream.h"
#include "src/core/status.h"

#include <cstdint>

namespace frontier::gen {

struct TerrainParams {
  uint64_t nx = 256, ny = 256;  // quads along x and y: 2 * nx * ny triangles
  double spacing = 0.25;        // metres between grid points
  double relief = 0.08;         // height amplitude as a fraction of the larger extent
  int octaves = 8;              // at most; octaves finer than 4 grid steps are dropped
  int tile = 128;               // quads per tile side
  uint64_t seed = 1;
  PlyVertexLayout layout;
};

inline constexpr uint64_t kMaxTerrainQuadsPerSide = 1u << 20;

Status validate(const TerrainParams& p);
uint64_t terrain_piece_count(const TerrainParams& p);
void terrain_piece(const TerrainParams& p, uint64_t index, MeshBuilder& mb);
MeshCounts terrain_counts(const TerrainParams& p);
// Square grid closest to `target` triangles.
void fit_terrain(TerrainParams& p, uint64_t target);

}  // namespace frontier::gen
