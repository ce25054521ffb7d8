// Little-endian doubles, points and boxes in section payloads (store/FORMAT.md), on top of the
// store's integer helpers: one definition for every section the engine writes.
#pragma once

#include "src/core/geometry.h"
#include "store/page_format.h"

#include <bit>
#include <cstdint>
#include <vector>

namespace frontier {

inline void put_f64(std::vector<uint8_t>& out, double v) { store::put_u64(out, std::bit_cast<uint64_t>(v)); }
inline double get_f64(const uint8_t* p) { return std::bit_cast<double>(store::get_u64(p)); }
inline void put_vec(std::vector<uint8_t>& out, const Vec3& v) {
  for (int a = 0; a < 3; ++a) put_f64(out, v[a]);
}
inline Vec3 get_vec(const uint8_t* p) { return {get_f64(p), get_f64(p + 8), get_f64(p + 16)}; }
// lo and hi as stored: the Aabb constructor would order them, turning an empty box into a full one.
inline Aabb get_box(const uint8_t* p) {
  Aabb b;
  b.lo = get_vec(p);
  b.hi = get_vec(p + 24);
  return b;
}

}  // namespace frontier
