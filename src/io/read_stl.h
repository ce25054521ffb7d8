// STL (stereolithography) files, binary and ASCII: the layout and how a file is told to be one
// or the other. The reader itself is behind open_scene_reader (read_stl.cpp).
//
// Binary: an 80-byte header (free text, which may itself start with "solid"), a little-endian
// uint32 triangle count, then per triangle 50 bytes: a facet normal and three vertices as
// little-endian float32 x y z, and a uint16 "attribute byte count".
// ASCII: "solid NAME", then facets "facet normal nx ny nz / outer loop / vertex x y z (three
// times) / endloop / endfacet", then "endsolid NAME"; a file may hold several solids.
//
// Facet normals are ignored (frontier takes a triangle's orientation from its vertex order, as
// the STL format defines it), and so is the attribute word. Vertices are not merged: each facet
// is its own triangle, with the source id of its place in the file.
#pragma once

#include <cstdint>
#include <string_view>

namespace frontier {

inline constexpr uint64_t kStlHeaderBytes = 80;
inline constexpr uint64_t kStlPrefixBytes = 84;  // header + triangle count
inline constexpr uint64_t kStlTriangleBytes = 50;

enum class StlKind { Binary, Ascii };

// How a file of `file_size` bytes that begins with `head` (its first kStlPrefixBytes bytes, or
// the whole file when shorter) is read: binary when its size is exactly 84 + 50 * the count in
// bytes 80..83 (binary files may start with "solid" too); otherwise ASCII when it starts with
// "solid" (after blanks, any case); otherwise binary, whose size the reader then reports as
// truncated or followed by trailing data.
StlKind detect_stl_kind(std::string_view head, uint64_t file_size);

}  // namespace frontier
