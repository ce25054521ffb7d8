// What the two lattice codecs (Draco, draco_codec.cpp; meshopt, meshopt_codec.cpp) share: how a
// cell splits into triangles on the global lattice (as distinct-vertex ids, in primitive order)
// and everything else (a raw body), the page fields that place the cell on the lattice (its
// bits and per-cell integer base), and the per-triangle sources and materials stored beside the
// mesh (store/FORMAT.md "Cell pages").
//
// Invariants: a triangle with two corners on one lattice point is dropped (neither codec can
// hold it); other zero-area triangles are kept. Vertex ids number distinct lattice points in the
// order they are first seen. The readers are safe on untrusted bytes: Corruption naming the
// codec and byte offset.
#pragma once

#include "src/codec/dense_ids.h"
#include "src/codec/lattice.h"
#include "src/core/byte_io.h"
#include "src/core/scene.h"
#include "src/core/status.h"

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

namespace frontier::cell_page {

// Lattice indices fit in 32 bits (bits <= 30): the key of a vertex.
using VertexKey = std::array<int32_t, 3>;

inline VertexKey vertex_key(const LatticeIndex& q) {
  return {static_cast<int32_t>(q[0]), static_cast<int32_t>(q[1]), static_cast<int32_t>(q[2])};
}

// One triangle of the cell on the lattice: its distinct-vertex ids, its index in the input's
// triangle array (for its normals) and what the page keeps beside it.
struct LatticeFace {
  std::array<uint32_t, 3> vertex;
  uint32_t triangle, source, material;
};

struct LatticeCell {
  explicit LatticeCell(size_t triangles) : vertex_ids(triangles) { faces.reserve(triangles); }
  std::vector<LatticeFace> faces;  // in primitive order
  DenseIds<VertexKey> vertex_ids;  // absolute lattice indices
  Scene others;                    // every non-triangle primitive, in primitive order
  LatticeIndex base{0, 0, 0};      // the smallest index of a vertex on each axis (0 without faces)
  LatticeIndex span{0, 0, 0};      // the largest index minus base, per axis
};

// Splits `cell` (which passed the dispatcher's check_scene) and sets out.base and out.span.
// InvalidArgument naming the primitive for a triangle vertex not on `lattice` (Lattice::snap).
Status split_lattice_cell(const Scene& cell, const Lattice& lattice, LatticeCell& out);

// The lattice bits and the cell's base, as the page stores them.
void write_lattice_base(GeometryWriter& w, int bits, const LatticeIndex& base);
// Reads what write_lattice_base wrote; Corruption unless the bits equal the model lattice's and
// the base lies on it. `extent`: the largest offset from the base each axis allows.
Status read_lattice_base(GeometryReader& r, std::string_view codec, const Lattice& lattice, LatticeIndex& base,
                         LatticeIndex& extent);

// Per-triangle sources, then materials (value streams), in the page's triangle order.
void write_triangle_ids(GeometryWriter& w, const std::vector<uint32_t>& sources,
                        const std::vector<uint32_t>& materials);
// REQUIRES: `triangles` was capped against the bytes left.
Status read_triangle_ids(GeometryReader& r, std::string_view codec, size_t triangles, std::vector<uint32_t>& sources,
                         std::vector<uint32_t>& materials);

}  // namespace frontier::cell_page
