// The global lattice (contract: lattice.h). Quantizing must give the same index for the same
// double on every machine and in every cell, hence the explicit rounding below.
#include "src/codec/lattice.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace frontier {

Lattice Lattice::covering(const Aabb& bounds, int bits) {
  Lattice lattice;
  lattice.bits = bits;
  if (bounds.empty() || bits < 1) return lattice;
  lattice.origin = bounds.lo;
  const Vec3 e = bounds.extent();
  const double extent = std::max({e.x, e.y, e.z});
  const double last = std::ldexp(1.0, bits) - 1.0;
  if (!(extent > 0.0)) return lattice;  // a single point (or non-finite bounds: caught later)
  lattice.step = extent / last;
  // Division rounding may leave the last lattice point a hair short of bounds.hi; widen the step
  // by ulps until it covers, so that max_error() holds everywhere inside `bounds`.
  for (int a = 0; a < 3 && std::isfinite(lattice.step); ++a) {
    while (lattice.origin[a] + lattice.step * last < bounds.hi[a]) {
      lattice.step = std::nextafter(lattice.step, kInfinity);
    }
  }
  return lattice;
}

namespace {

// std::round (halves away from zero) without the library call, bit for bit: adding and
// removing 1.5 * 2^52 rounds to the nearest integer (ties to even) for |x| < 2^51, and a tie
// is then moved away from zero. Anything else (huge, infinite, NaN) goes to std::round.
inline double round_half_away(double x) {
  if (!(std::abs(x) < 0x1p51)) return std::round(x);
  double r = (x + 0x1.8p52) - 0x1.8p52;  // IEEE arithmetic: not reassociated without -ffast-math
  if (std::abs(x - r) == 0.5) r = x + std::copysign(0.5, x);
  return std::copysign(r, x);  // -0.4 rounds to -0, as std::round does
}

}  // namespace

LatticeIndex Lattice::quantize(const Vec3& p) const {
  const double last = bits >= 1 && bits <= 62 ? static_cast<double>((int64_t{1} << bits) - 1) : std::ldexp(1.0, bits) - 1.0;
  LatticeIndex q{};
  for (int a = 0; a < 3; ++a) {
    const double t = round_half_away((p[a] - origin[a]) / step);
    // !(t > 0) also sends NaN to 0; clamping before the conversion keeps it defined.
    q[a] = !(t > 0.0) ? 0 : t >= last ? static_cast<int64_t>(last) : static_cast<int64_t>(t);
  }
  return q;
}

// Out of line on purpose: every decoder dequantizes through this one function, so a vertex
// shared by two cells gets bit-identical doubles in both.
Vec3 Lattice::point(const LatticeIndex& q) const {
  return {origin.x + step * static_cast<double>(q[0]), origin.y + step * static_cast<double>(q[1]),
          origin.z + step * static_cast<double>(q[2])};
}

Status check_lattice(const Lattice& lattice, std::string_view who) {
  if (lattice.bits < 1 || lattice.bits > Lattice::kMaxBits || !(lattice.step > 0.0) ||
      !std::isfinite(lattice.step) || !std::isfinite(lattice.origin.x) || !std::isfinite(lattice.origin.y) ||
      !std::isfinite(lattice.origin.z)) {
    return Status::invalid_argument(fmt::format("{}: unusable lattice (bits {}, step {}; bits must be 1..{})", who,
                                                lattice.bits, lattice.step, Lattice::kMaxBits));
  }
  return Status::ok();
}

}  // namespace frontier
