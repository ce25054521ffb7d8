// The PLY header and PLY's scalar types: parsed once, here, for the scene reader (read_ply.cpp)
// and frontier-gen's bounds scan (data_gen/model_bounds.cpp), so both accept the same files.
//
// The header is what real exporters write: `comment` and `obj_info` lines are skipped, and so is
// any other line whose keyword PLY does not define (Blender writes "Created by Blender ..."
// without `comment`), with a warning naming the file and line, as other PLY readers do. Lines
// PLY defines (format, element, property, end_header) are checked strictly: errors name the line.
#pragma once

#include "src/core/status.h"
#include "src/io/binary_stream.h"
#include "src/io/text_tokenizer.h"

#include <bit>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace frontier {

enum class PlyType : uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

// "char", "int8", "float32", ... -> the type; false for a name PLY does not define.
bool parse_ply_type(std::string_view s, PlyType& t);

constexpr size_t ply_type_size(PlyType t) {
  switch (t) {
    case PlyType::Int8: case PlyType::UInt8: return 1;
    case PlyType::Int16: case PlyType::UInt16: return 2;
    case PlyType::Int32: case PlyType::UInt32: case PlyType::Float32: return 4;
    case PlyType::Float64: return 8;
  }
  return 1;
}

constexpr bool ply_is_integer(PlyType t) { return t != PlyType::Float32 && t != PlyType::Float64; }

// Calls f(T{}) with T the C++ type of PLY type t: the one switch over types that the decoders
// share.
template <typename F>
inline decltype(auto) with_ply_type(PlyType t, F&& f) {
  switch (t) {
    case PlyType::Int8: return f(int8_t{});
    case PlyType::UInt8: return f(uint8_t{});
    case PlyType::Int16: return f(int16_t{});
    case PlyType::UInt16: return f(uint16_t{});
    case PlyType::Int32: return f(int32_t{});
    case PlyType::UInt32: return f(uint32_t{});
    case PlyType::Float32: return f(float{});
    case PlyType::Float64: break;
  }
  return f(double{});
}

inline double ply_decode_double(const uint8_t* p, PlyType t, bool swap) {
  return with_ply_type(t, [&](auto type) -> double { return load_scalar<decltype(type)>(p, swap); });
}

// Integer types only (0 for the others).
inline int64_t ply_decode_int(const uint8_t* p, PlyType t, bool swap) {
  return with_ply_type(t, [&](auto type) -> int64_t {
    using T = decltype(type);
    if constexpr (std::is_integral_v<T>) {
      return load_scalar<T>(p, swap);
    } else {
      return 0;
    }
  });
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::Float32;  // item type for lists
  bool is_list = false;
  PlyType count_type = PlyType::UInt8;
};

struct PlyElement {
  std::string name;
  int64_t count = 0;
  int64_t line = 0;  // header line, for errors about the declaration
  std::vector<PlyProperty> props;

  // Bytes of one binary record, or -1 when it holds a list.
  int64_t fixed_size() const;
  // Fewest bytes one binary record can take (lists empty).
  int64_t min_size() const;
  // Index of the property called `name`, or -1.
  int find(std::string_view name) const;
};

struct PlyHeader {
  bool ascii = true;
  bool swap = false;  // binary, in the byte order the host does not use
  std::vector<PlyElement> elements;
  uint64_t body_offset = 0;           // first byte after end_header's line
  std::vector<std::string> warnings;  // "path: line N: ..." for each unknown line skipped
};

// Reads the header from `tok`, just opened on the file with hash_comments off, up to and
// including the end_header line; tok is then at header.body_offset. Errors (Corruption, or
// the tokenizer's read error) name the file and line. Counts are not checked against the file
// size here: the caller knows what a record costs.
Status read_ply_header(TextTokenizer& tok, PlyHeader& header);

}  // namespace frontier
