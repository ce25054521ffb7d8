// The global quantization lattice of a model store: point(q) = origin + step * q for integer
// q in [0, 2^bits - 1] on every axis, fixed for the whole model (the `model` section holds it;
// store/FORMAT.md "The lattice"). Because every cell dequantizes through the same function, a
// vertex shared by two cells decodes to the same double in both: no cracks between cells.
//
// step is the same on all three axes (a cubic lattice sized to the largest extent), so the
// error bound is step/2 per axis, step*sqrt(3)/2 in distance. All members are pure and may be
// called from any number of threads at once.
#pragma once

#include "src/core/geometry.h"
#include "src/core/status.h"

#include <array>
#include <cstdint>
#include <string_view>

namespace frontier {

// A point's integer coordinates on a lattice.
using LatticeIndex = std::array<int64_t, 3>;

struct Lattice {
  // The most bits per axis a usable lattice has: the Draco codec predicts positions with
  // differences in int32.
  static constexpr int kMaxBits = 30;

  Vec3 origin{0.0};
  double step = 1.0;
  int bits = 16;

  // The lattice covering `bounds` with `bits` bits per axis.
  static Lattice covering(const Aabb& bounds, int bits);
  // Nearest lattice index of p, clamped to [0, 2^bits - 1].
  LatticeIndex quantize(const Vec3& p) const;
  Vec3 point(const LatticeIndex& q) const;
  // point(quantize(p)).
  Vec3 snap(const Vec3& p) const { return point(quantize(p)); }
  double max_error() const { return 0.5 * step; }  // per axis
};

// InvalidArgument "WHO: unusable lattice ..." unless bits is 1..kMaxBits and origin and step are
// finite with step > 0.
Status check_lattice(const Lattice& lattice, std::string_view who);

}  // namespace frontier
