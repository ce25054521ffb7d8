// Cell page codecs: how one k-d tree cell's primitives become the payload of a store page and
// back. The store itself only carries bytes and a codec tag (store/FORMAT.md); the geometry
// layout of a cell payload is documented in store/FORMAT.md under "Cell pages".
//
// Positions live on one global lattice (lattice.h) fixed for the whole model, so a vertex
// shared by two cells decodes to the same double in both: no cracks. The two lattice codecs,
// Draco and meshopt, store lattice integers relative to a per-cell integer base and dequantize
// in double precision (Draco's own float32 dequantization would lose far-from-origin
// coordinates). The raw codec stores every primitive bit-exactly (doubles), on or off a lattice.
//
// Spheres, boxes, cones and quadrics are stored as raw doubles by every codec. Draco reorders
// triangles, meshopt reorders them for its vertex cache; the page stores every triangle's source
// and material in the decoded order. Every function here is pure: safe to call from several
// threads at once. Each codec lives in its own file (raw_codec.cpp, draco_codec.cpp,
// meshopt_codec.cpp; the interface is cell_codec_impl.h) and cell_codec.cpp dispatches on the tag.
#pragma once

#include "src/codec/lattice.h"
#include "src/core/geometry.h"
#include "src/core/scene.h"
#include "src/core/status.h"

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace frontier {

// Codec tags as written in a page's codec byte (store/FORMAT.md). 0 is the store's raw tag.
enum class CellCodec : uint8_t { Raw = 0, Draco = 1, Meshopt = 2 };

// Whether `tag` is a page codec byte this build can decode.
bool is_cell_codec(uint8_t tag);
// The codec's name in the model section and on command lines ("raw", "draco", "meshopt"), and
// back (nullopt for a name no codec has).
std::string_view cell_codec_name(CellCodec codec);
std::optional<CellCodec> cell_codec_named(std::string_view name);
// Whether the codec stores triangles on the model's lattice (Draco, meshopt): a builder snaps
// triangle vertices to it first, and decoded triangles may sit up to a step off the input.
bool cell_codec_on_lattice(CellCodec codec);

struct CellCodecOptions {
  CellCodec codec = CellCodec::Draco;
  Lattice lattice;             // lattice codecs require triangle vertices already on it (snap)
  int draco_speed = 5;         // Draco encoding/decoding speed 0 (best compression) .. 10; at
                               // 8 and up Draco predicts positions by plain deltas (+30% size)
  int normal_bits = 10;        // octahedral quantization of per-vertex shading normals (Draco
                               // 2..30, meshopt 2..16); they decode approximately, positions exactly
};

struct EncodedCell {
  CellCodec codec = CellCodec::Raw;
  std::vector<uint8_t> payload;
  // The cell as a reader will decode it, in decoded primitive order (Draco reorders
  // triangles; every triangle keeps its source and material). Anything stored beside the
  // geometry that refers to primitive order must use this order.
  Scene decoded;
};

// Encodes the primitives of `cell` (a Scene holding only one cell's primitives; materials,
// lights and camera are ignored — they live in the store's model section).
//
// Raw: `decoded` is `cell` bit for bit (primitives, arrays and normals in input order; unused
// quadric clip-plane slots come back as zero).
// Draco: `decoded` holds the triangles in Draco's order (a face's corners may be rotated, its
// orientation is kept), each with its source, material and (approximate) normals, then the
// other primitives in input order. Triangles with two corners on the same lattice point are
// dropped (Draco cannot hold them); other zero-area triangles are kept (the caller drops
// those before, if it wants).
//
// Meshopt: `decoded` holds the triangles reordered for meshoptimizer's vertex cache (corners
// may be rotated, orientation kept), each with its source, material and (approximate: octahedral,
// normal_bits) normals, then the other primitives in input order; lattice-degenerate triangles
// are dropped as with Draco.
//
// InvalidArgument, naming the primitive, for a lattice codec's triangle vertex not on
// options.lattice (Lattice::snap), a lattice that does not fit (bits outside 1..30, non-finite
// origin or step), a Draco cell spanning 2^24 or more lattice steps on an axis (Draco's encoder
// needs memory in proportion), bad speed or normal bits, or a Scene whose primitives refer past
// their arrays.
Result<EncodedCell> encode_cell(const Scene& cell, const CellCodecOptions& options);

// Decodes a payload written by encode_cell into `out` (replacing what it held; left empty on
// failure). Never crashes or over-allocates on damaged input — memory stays within a constant
// times the payload size: Corruption with a message for anything inconsistent. `lattice` must
// be the model's lattice (InvalidArgument if unusable; Corruption if its bits differ from the
// page's); the raw codec ignores it. Any codec tag
// is accepted: an unknown one is Corruption.
Status decode_cell(std::span<const uint8_t> payload, CellCodec codec, const Lattice& lattice,
                   Scene& out);

}  // namespace frontier
