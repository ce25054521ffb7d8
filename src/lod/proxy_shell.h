// Voxel shells: a closed surface around a triangle soup, for proxies the topological simplifier
// cannot bring down (src/lod/proxy.h). meshoptimizer's clustering ("sloppy") reaches any size
// but collapses every feature thinner than its grid — a building's walls, floors and roof vanish
// and a viewer shows its rooms through holes. The shell keeps them: OpenVDB samples the unsigned
// distance to the input on a grid of about `resolution` voxels along the input's longest side
// (tools::meshToUnsignedDistanceField), the voxels farther than one voxel from every triangle that
// can be reached from outside the grid are outside, everything else (walls thickened to one voxel,
// and the rooms they close off) is inside, and tools::volumeToMesh draws the boundary. So every
// surface of the input has shell within about a voxel of it on the side a distant viewer sees,
// and the closed cavities (rooms seen only from inside) cost no triangles.
//
// The shell's vertices are new points: they are moved into `region` when one is given (a viewer
// draws a node's proxy inside the node's region only, and the offset shell of a wall on the
// region's face would lie just outside it), then snapped to `lattice` when one is given (the
// Draco and meshopt codecs store lattice positions). The caller measures the proxy's bound.
#pragma once

#include "src/codec/lattice.h"
#include "src/core/geometry.h"

#include <bit>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace frontier {

// A hash of a position's exact bits, for welding vertices by exact position (here and in
// proxy.cpp); -0 and +0 hash alike, as they compare equal.
struct ExactPositionHash {
  size_t operator()(const Vec3& p) const {
    uint64_t h = 0x9e3779b97f4a7c15ull;
    for (int a = 0; a < 3; ++a) {
      h ^= std::bit_cast<uint64_t>(p[a] + 0.0);
      h *= 0xff51afd7ed558ccdull;
      h ^= h >> 32;
    }
    return static_cast<size_t>(h);
  }
};

struct VoxelShell {
  std::vector<Vec3> positions;    // distinct, every one used by a triangle
  std::vector<uint32_t> indices;  // three per triangle, outward-facing
  double voxel = 0.0;             // the grid's voxel size (also the shell's offset from the input)
};

// The shell of the triangles (indices[3 i .. 3 i + 2]) of `positions`; empty when the input has
// no extent or no triangles. REQUIRES: resolution >= 4. Thread-safe (OpenVDB's tools run on TBB).
VoxelShell voxel_shell(std::span<const Vec3> positions, std::span<const uint32_t> indices, int resolution,
                       const Aabb* region, const std::optional<Lattice>& lattice);

}  // namespace frontier
