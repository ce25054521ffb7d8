// Byte streams that also carry geometry: the store's little-endian ByteWriter/ByteReader
// (store/byte_stream.h) plus doubles, points and boxes, for every section and page payload the
// engine writes (layouts in store/FORMAT.md).
//
// A double is its IEEE-754 bits as a little-endian u64, so every value round-trips bit for bit
// (NaN payloads and -0 included). A box is lo then hi, read back exactly as stored: the Aabb
// constructor would order them, turning an empty box (lo > hi) into a full one. Reads keep the
// ByteReader contract: never outside the span, sticky failure, zeros once failed.
#pragma once

#include "src/core/geometry.h"
#include "store/byte_stream.h"

#include <bit>
#include <cstdint>
#include <span>
#include <vector>

namespace frontier {

class GeometryWriter : public store::ByteWriter {
 public:
  using store::ByteWriter::ByteWriter;
  void f64(double v) { u64(std::bit_cast<uint64_t>(v)); }
  void vec3(const Vec3& v) {
    f64(v.x);
    f64(v.y);
    f64(v.z);
  }
  void box(const Aabb& b) {
    vec3(b.lo);
    vec3(b.hi);
  }
};

class GeometryReader : public store::ByteReader {
 public:
  using store::ByteReader::ByteReader;
  double f64() { return std::bit_cast<double>(u64()); }
  Vec3 vec3() {
    const double x = f64(), y = f64();
    return {x, y, f64()};
  }
  Aabb box() {
    Aabb b;
    b.lo = vec3();
    b.hi = vec3();
    return b;
  }
};

}  // namespace frontier
