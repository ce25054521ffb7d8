// The `building` model: an architectural interior written piece by piece (one piece per floor
// slot: its slab, the walls on its west and south grid edges, and its detail), plus the JSON
// sidecar that describes its cells and portals for cells-and-portals culling and walk mode.
#pragma once

#include "data_gen/building_layout.h"
#include "data_gen/furniture.h"
#include "data_gen/piece_stream.h"
#include "src/core/status.h"

#include <cstdint>
#include <string>

namespace frontier::gen {

struct BuildingParams {
  BuildingShape shape;  // floors, rooms per floor, seed
  DetailParams detail;  // furniture density, tessellation
  PlyVertexLayout layout;
};

// Limits that keep the generator's promises (closed solids, bounded pieces, 32-bit indices).
inline constexpr int kMaxFloors = 10000;
inline constexpr int kMaxRoomsPerFloor = 1000000;
inline constexpr double kMaxFurniture = 20.0;
inline constexpr int kMinSegments = 3, kMaxSegments = 128;

// InvalidArgument naming the offending option, or ok.
Status validate(const BuildingParams& p);

uint64_t building_piece_count(const BuildingLayout& layout);
// Emits (or counts) piece `index` of the building.
void building_piece(const BuildingLayout& layout, const DetailParams& detail, uint64_t index,
                    MeshBuilder& mb);
// Exact counts without writing anything.
MeshCounts count_building(const BuildingParams& p);

// Writes the sidecar (streamed: memory does not grow with the building).
Status write_building_sidecar(const BuildingParams& p, const MeshCounts& counts,
                              const std::string& model_path, const std::string& path);

// --triangles N: chooses the parameters not fixed by the user so that the model lands within
// `tolerance` (relative) of `target`, trying to get as close as it cheaply can. Fails with
// InvalidArgument (naming --triangles) when the target is out of reach.
struct FitOptions {
  bool floors_fixed = false, rooms_fixed = false, furniture_fixed = false, tessellation_fixed = false;
  double tolerance = 0.05;
};
Result<BuildingParams> fit_building(BuildingParams p, uint64_t target, const FitOptions& options);

}  // namespace frontier::gen
