// The Draco edgebreaker stream inside a Draco cell page, at the boundary of the Draco library:
// encoding a cell's triangles given as integer lattice offsets (and optional float normals),
// checking a stream's header against the page before Draco reads it, running Draco's decoder,
// and reading the decoded mesh back range-checked.
//
// Draco is not hardened against arbitrary input: it sizes its tables from counts at the start
// of the stream. So a stream reaches run_draco_decoder only after check_draco_stream has bounded
// those counts by the page's own face count and the stream's length, and nothing Draco hands
// back is used before read_draco_mesh has range-checked it. Nothing here throws; every function
// is pure and may run on several threads at once.
#pragma once

#include "src/codec/lattice.h"
#include "src/core/geometry.h"
#include "src/core/status.h"

#include <draco/mesh/mesh.h>

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace frontier::cell_page {

// A cell's triangles as Draco gets them. Faces refer to points: without normals a point is a
// vertex; with normals it is a distinct (vertex, float normal) pair.
struct DracoInput {
  bool normals = false;
  std::vector<std::array<int32_t, 3>> positions;    // per vertex: lattice offset from the cell's base
  std::vector<uint32_t> point_vertex;               // with normals: per point, its vertex
  std::vector<std::array<float, 3>> point_normals;  // with normals: per point, its normal
  std::vector<std::array<uint32_t, 3>> faces;       // per face: its three points
};

// The stream, always the standard edgebreaker traversal (check_draco_stream relies on it).
// REQUIRES: at least one face; speed 0..10, normal_bits 2..30. InvalidArgument when Draco fails.
Result<std::vector<uint8_t>> encode_draco_stream(const DracoInput& input, int speed, int normal_bits);

// Corruption unless `blob` starts as a Draco 2.2 standard edgebreaker mesh stream with exactly
// `faces` faces, attribute data for positions (and normals), and counts that a stream of its
// length can hold: what bounds everything Draco's decoder allocates by a constant times the
// page size.
Status check_draco_stream(std::span<const uint8_t> blob, uint64_t faces, bool normals);

// Runs Draco's decoder on a stream that passed check_draco_stream. Its failures (a Status, or
// an exception from an allocation) become Corruption.
Result<std::unique_ptr<draco::Mesh>> run_draco_decoder(std::span<const uint8_t> blob);

// A decoded Draco mesh, range-checked: per point its lattice offset from the page's base and
// its normal (when the page has normals), and per face its three points, in Draco's order.
struct DracoMesh {
  std::vector<LatticeIndex> offsets;
  std::vector<Vec3> normals;
  std::vector<std::array<uint32_t, 3>> faces;
};

// Checks a decoded mesh against the page header (`faces`, `points`, `normals`) and reads it.
// `extent` is the largest offset allowed per axis (base + offset must stay on the lattice).
Result<DracoMesh> read_draco_mesh(const draco::Mesh& mesh, uint64_t faces, uint64_t points, bool normals,
                                  const LatticeIndex& extent);

}  // namespace frontier::cell_page
