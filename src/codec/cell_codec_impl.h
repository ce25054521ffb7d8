// What every cell page codec implements (internal to src/codec; the public contract is
// cell_codec.h). Each codec is one .cpp that defines one CellCodecImpl; cell_codec.cpp checks
// the scene, then dispatches on the tag through its table of them. Adding a codec: its tag in
// CellCodec, its file, its declaration below and its entry in cell_codec.cpp's table. The shared
// payload parts a codec may use are the value streams (value_stream.h), the raw body of
// non-triangle primitives (raw_body.h) and, for codecs on the lattice, the split of a cell into
// lattice triangles and the rest (lattice_cell.h).
#pragma once

#include "src/codec/cell_codec.h"

#include <fmt/format.h>

#include <cstddef>
#include <span>
#include <string_view>

namespace frontier::cell_page {

struct CellCodecImpl {
  CellCodec tag;
  std::string_view name;  // in the model section, e.g. "draco"
  // REQUIRES: the dispatcher's check_scene(cell) passed. The payload and the cell as a reader
  // will decode it (EncodedCell::decoded); InvalidArgument for what the codec cannot hold.
  Result<EncodedCell> (*encode)(const Scene& cell, const CellCodecOptions& options);
  // Fills `out` (empty on entry) from an untrusted payload; the dispatcher empties it again on
  // failure. Safe on any bytes: Corruption for anything inconsistent.
  Status (*decode)(std::span<const uint8_t> payload, const Lattice& lattice, Scene& out);
};

extern const CellCodecImpl kRawCodec;    // raw_codec.cpp
extern const CellCodecImpl kDracoCodec;    // draco_codec.cpp
extern const CellCodecImpl kMeshoptCodec;  // meshopt_codec.cpp

// How every codec reports damage: Corruption "CODEC cell page: WHAT (at byte OFFSET)".
inline Status corrupt(std::string_view codec, size_t offset, std::string_view what) {
  return Status::corruption(fmt::format("{} cell page: {} (at byte {})", codec, what, offset));
}

}  // namespace frontier::cell_page
