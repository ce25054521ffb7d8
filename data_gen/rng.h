// The generator's only source of randomness: splitmix64 streams keyed by (seed, what, where).
//
// Every piece of a model (a room, a terrain tile) draws from its own stream, keyed by the seed
// and the piece's coordinates, so pieces can be generated in any order or in parallel and the
// output stays byte-identical. Conversions to doubles and integer ranges are written out here
// (never std::uniform_*_distribution, whose results differ between standard libraries).
#pragma once

#include <cstdint>

namespace frontier::gen {

inline constexpr uint64_t mix64(uint64_t z) {
  z += 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// Hash of a seed and any number of integer coordinates, order-sensitive.
template <typename... Parts>
constexpr uint64_t stream_key(uint64_t seed, Parts... parts) {
  uint64_t h = mix64(seed ^ 0x5eed5eed5eed5eedull);
  ((h = mix64(h ^ static_cast<uint64_t>(parts))), ...);
  return h;
}

// Distinct purposes get distinct streams even at equal coordinates.
enum class Stream : uint64_t { Room = 1, Door, Corridor, Stair, Terrain, Spheres, Path, Fit };

class Rng {
 public:
  explicit Rng(uint64_t key) : state_(key) {}
  template <typename... Parts>
  Rng(uint64_t seed, Stream s, Parts... parts)
      : state_(stream_key(seed, static_cast<uint64_t>(s), parts...)) {}

  uint64_t next() {
    state_ += 0x9e3779b97f4a7c15ull;
    uint64_t z = state_;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  // Uniform integer in [0, n), n > 0 (multiply-shift; the bias is below 2^-32).
  uint32_t below(uint32_t n) {
    return static_cast<uint32_t>((static_cast<uint64_t>(static_cast<uint32_t>(next() >> 32)) * n) >> 32);
  }
  bool chance(double p) { return uniform() < p; }
  // floor(x + u) with u uniform: an integer whose expectation is x (x >= 0).
  int stochastic_round(double x) { return static_cast<int>(x + uniform()); }

 private:
  uint64_t state_;
};

}  // namespace frontier::gen
