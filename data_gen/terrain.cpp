// Height-field tiles (see header). Noise: 2-D gradient noise with quintic fade; gradients come
// from a hash of (seed, octave, lattice point) and are cached per tile and octave, so a vertex
// costs a few multiply-adds per octave.
#include "data_gen/terrain.h"

#include "data_gen/mesh_builder.h"
#include "data_gen/rng.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace frontier::gen {
namespace {

double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

// Gradients of one octave's lattice over a rectangle of lattice points.
class GradientPatch {
 public:
  GradientPatch(uint64_t key, int64_t ix0, int64_t iy0, int64_t ix1, int64_t iy1)
      : ix0_(ix0), iy0_(iy0), w_(ix1 - ix0 + 1) {
    grads_.resize(static_cast<size_t>(w_ * (iy1 - iy0 + 1)));
    for (int64_t iy = iy0; iy <= iy1; ++iy)
      for (int64_t ix = ix0; ix <= ix1; ++ix) {
        const uint64_t h = mix64(key ^ (static_cast<uint64_t>(ix) * 0x9e3779b97f4a7c15ull) ^
                                 (static_cast<uint64_t>(iy) * 0xc2b2ae3d27d4eb4full));
        const double a = static_cast<double>(h >> 11) * 0x1.0p-53 * 2.0 * std::numbers::pi;
        grads_[static_cast<size_t>((iy - iy0) * w_ + (ix - ix0))] = {std::cos(a), std::sin(a)};
      }
  }
  // Adds amp * noise over a grid of sample coordinates u[x] (columns) and v[y] (rows), into
  // out[y * nx + x]. Row and column terms (lattice cell, offsets, fades) are computed once.
  void accumulate(const std::vector<double>& u, const std::vector<double>& v, double amp,
                  std::vector<double>& out) const {
    const size_t nx = u.size(), ny = v.size();
    cols_.resize(nx);
    for (size_t x = 0; x < nx; ++x) {
      const double f = std::floor(u[x]), d = u[x] - f;
      cols_[x] = {static_cast<int64_t>(f) - ix0_, d, fade(d)};
    }
    for (size_t y = 0; y < ny; ++y) {
      const double f = std::floor(v[y]), dv = v[y] - f, sv = fade(dv);
      const int64_t row = static_cast<int64_t>(f) - iy0_;
      const std::array<double, 2>* g0 = &grads_[static_cast<size_t>(row * w_)];
      const std::array<double, 2>* g1 = g0 + w_;
      double* o = &out[y * nx];
      for (size_t x = 0; x < nx; ++x) {
        const Column& c = cols_[x];
        const auto& g00 = g0[c.ix];
        const auto& g10 = g0[c.ix + 1];
        const auto& g01 = g1[c.ix];
        const auto& g11 = g1[c.ix + 1];
        const double du = c.d;
        const double n00 = g00[0] * du + g00[1] * dv;
        const double n10 = g10[0] * (du - 1) + g10[1] * dv;
        const double n01 = g01[0] * du + g01[1] * (dv - 1);
        const double n11 = g11[0] * (du - 1) + g11[1] * (dv - 1);
        const double a = n00 + c.s * (n10 - n00), b = n01 + c.s * (n11 - n01);
        o[x] += amp * (a + sv * (b - a));
      }
    }
  }

 private:
  struct Column {
    int64_t ix;
    double d, s;
  };
  int64_t ix0_, iy0_, w_;
  std::vector<std::array<double, 2>> grads_;
  mutable std::vector<Column> cols_;
};

Rgb terrain_color(double t, double steep) {
  // t: height in [-1, 1] of the relief; steep: 1 - n.z.
  if (steep > 0.35) return {120, 110, 100};
  if (t < -0.35) return {194, 178, 128};
  if (t < 0.25) return {80, 130, 60};
  if (t < 0.55) return {110, 100, 80};
  return {235, 235, 240};
}

}  // namespace

Status validate(const TerrainParams& p) {
  if (p.nx < 1 || p.ny < 1 || p.nx > kMaxTerrainQuadsPerSide || p.ny > kMaxTerrainQuadsPerSide)
    return Status::invalid_argument(fmt::format("--grid: {} x {} quads is not in [1, {}] per side",
                                                p.nx, p.ny, kMaxTerrainQuadsPerSide));
  if (!(p.spacing > 1e-4 && p.spacing < 1e4))
    return Status::invalid_argument(fmt::format("--spacing {} is not in (0.0001, 10000)", p.spacing));
  if (!(p.relief >= 0.0 && p.relief <= 10.0))
    return Status::invalid_argument(fmt::format("--relief {} is not in [0, 10]", p.relief));
  if (p.octaves < 1 || p.octaves > 24)
    return Status::invalid_argument(fmt::format("--octaves {} is not in [1, 24]", p.octaves));
  if (p.tile < 1 || p.tile > 1024)
    return Status::invalid_argument(fmt::format("--tile {} is not in [1, 1024]", p.tile));
  return Status::ok();
}

uint64_t terrain_piece_count(const TerrainParams& p) {
  const uint64_t t = static_cast<uint64_t>(p.tile);
  return ((p.nx + t - 1) / t) * ((p.ny + t - 1) / t);
}

MeshCounts terrain_counts(const TerrainParams& p) {
  const uint64_t t = static_cast<uint64_t>(p.tile), tx = (p.nx + t - 1) / t, ty = (p.ny + t - 1) / t;
  // Tiles hold (w + 1)(h + 1) vertices; summing widths and heights separately keeps it exact.
  uint64_t sum_w1 = 0, sum_h1 = 0;
  for (uint64_t i = 0; i < tx; ++i) sum_w1 += std::min(t, p.nx - i * t) + 1;
  for (uint64_t j = 0; j < ty; ++j) sum_h1 += std::min(t, p.ny - j * t) + 1;
  return {sum_w1 * sum_h1, 2 * p.nx * p.ny};
}

void fit_terrain(TerrainParams& p, uint64_t target) {
  const uint64_t n = std::max<uint64_t>(1, static_cast<uint64_t>(std::llround(std::sqrt(target / 2.0))));
  p.nx = p.ny = n;
}

void terrain_piece(const TerrainParams& p, uint64_t index, MeshBuilder& mb) {
  const uint64_t t = static_cast<uint64_t>(p.tile), tiles_x = (p.nx + t - 1) / t;
  const uint64_t i0 = (index % tiles_x) * t, j0 = (index / tiles_x) * t;
  const uint64_t w = std::min(t, p.nx - i0), h = std::min(t, p.ny - j0);
  const uint64_t vw = w + 1, vh = h + 1;
  if (mb.counting()) {
    mb.add_counts(vw * vh, 2 * w * h);
    return;
  }
  const double s = p.spacing;
  const double half_x = 0.5 * static_cast<double>(p.nx) * s, half_y = 0.5 * static_cast<double>(p.ny) * s;
  const double extent = std::max(p.nx, p.ny) * s;
  const double amplitude = p.relief * extent;

  // Heights on the tile plus a one-point border (for normals by central differences).
  const int64_t bi0 = static_cast<int64_t>(i0) - 1, bj0 = static_cast<int64_t>(j0) - 1;
  const int64_t bw = static_cast<int64_t>(vw) + 2, bh = static_cast<int64_t>(vh) + 2;
  std::vector<double> height(static_cast<size_t>(bw * bh), 0.0);
  // Octaves finer than four grid steps would only alias into noise: drop them.
  const int octaves = std::clamp(static_cast<int>(std::floor(std::log2(extent / (8.0 * s)))) + 1, 1, p.octaves);
  double wavelength = extent / 2.0, amp = 1.0;
  for (int k = 0; k < octaves; ++k, wavelength *= 0.5, amp *= 0.5) {
    const double f = s / wavelength;  // lattice units per grid step
    const int64_t ix0 = static_cast<int64_t>(std::floor(bi0 * f)) - 1;
    const int64_t iy0 = static_cast<int64_t>(std::floor(bj0 * f)) - 1;
    const int64_t ix1 = static_cast<int64_t>(std::floor((bi0 + bw) * f)) + 2;
    const int64_t iy1 = static_cast<int64_t>(std::floor((bj0 + bh) * f)) + 2;
    const GradientPatch patch(stream_key(p.seed, uint64_t(Stream::Terrain), k), ix0, iy0, ix1, iy1);
    std::vector<double> u(static_cast<size_t>(bw)), v(static_cast<size_t>(bh));
    for (int64_t x = 0; x < bw; ++x) u[static_cast<size_t>(x)] = (bi0 + x) * f;
    for (int64_t y = 0; y < bh; ++y) v[static_cast<size_t>(y)] = (bj0 + y) * f;
    patch.accumulate(u, v, amp, height);
  }
  for (int64_t y = 0; y < bh; ++y)
    for (int64_t x = 0; x < bw; ++x) {
      // Scan jitter: 2% of the spacing, from the grid point's own hash.
      const uint64_t hj = stream_key(p.seed, uint64_t(Stream::Terrain), 1000, bi0 + x, bj0 + y);
      const double jitter = (static_cast<double>(hj >> 11) * 0x1.0p-53 - 0.5) * 0.04 * s;
      double& z = height[static_cast<size_t>(y * bw + x)];
      z = amplitude * z + jitter;
    }

  MeshPiece& out = *mb.piece();
  const size_t base = out.vertex_count();
  out.positions.reserve(out.positions.size() + 3 * vw * vh);
  if (p.layout.normals) out.normals.reserve(out.normals.size() + 3 * vw * vh);
  if (p.layout.colors) out.colors.reserve(out.colors.size() + 3 * vw * vh);
  for (uint64_t y = 0; y < vh; ++y)
    for (uint64_t x = 0; x < vw; ++x) {
      const int64_t bx = static_cast<int64_t>(x) + 1, by = static_cast<int64_t>(y) + 1;
      const double z = height[static_cast<size_t>(by * bw + bx)];
      const double px = static_cast<double>(i0 + x) * s - half_x, py = static_cast<double>(j0 + y) * s - half_y;
      const double dzdx = (height[static_cast<size_t>(by * bw + bx + 1)] - height[static_cast<size_t>(by * bw + bx - 1)]) / (2 * s);
      const double dzdy = (height[static_cast<size_t>((by + 1) * bw + bx)] - height[static_cast<size_t>((by - 1) * bw + bx)]) / (2 * s);
      const Vec3 n = glm::normalize(Vec3(-dzdx, -dzdy, 1.0));
      const Rgb c = terrain_color(amplitude > 0 ? z / amplitude : 0.0, 1.0 - n.z);
      mb.raw_vertex(Vec3(px, py, z), n, c);
    }
  for (uint64_t y = 0; y < h; ++y)
    for (uint64_t x = 0; x < w; ++x) {
      const uint32_t a = static_cast<uint32_t>(base + y * vw + x), b = a + 1;
      const uint32_t c = static_cast<uint32_t>(a + vw), d = c + 1;
      mb.raw_triangle(a, b, d);
      mb.raw_triangle(a, d, c);
    }
}

}  // namespace frontier::gen
