// The z-pyramid: min-reduction of the rasterizer's 1/w, refreshed per changed tile, and the
// hierarchical box test.
//
// Why the box test is conservative: a box with every corner beyond the near plane projects
// onto the convex hull of its projected corners, so a triangle inside it covers only pixel
// centres inside the corners' bounds (rounding outward absorbs the rasterizer's sub-pixel
// snapping), and at each such centre its 1/w is that of a point of the box, at most 1/w_min of
// the box's nearest point. The rasterizer clips nothing of it at the near plane: its own near
// (View::near, near_floor, or 1e-9 of a triangle's farthest w) lies before w_min.
#include "src/raster/zpyramid.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>

namespace frontier {
namespace {

// With no near plane set, corners nearer than this fraction of the box's farthest w count as
// reaching the eye plane (the rasterizer's own automatic near plane uses the same fraction).
constexpr double kAutoNearFraction = 1e-9;

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

DepthPyramidCounters& DepthPyramidCounters::operator+=(const DepthPyramidCounters& o) {
  queries += o.queries;
  hidden += o.hidden;
  outside += o.outside;
  texels_read += o.texels_read;
  updates += o.updates;
  tiles_updated += o.tiles_updated;
  update_ms += o.update_ms;
  return *this;
}

DepthPyramid::DepthPyramid(Rasterizer& rasterizer)
    : width_(rasterizer.view().width),
      height_(rasterizer.view().height),
      clip_(rasterizer.clip_transform()),
      near_(rasterizer.near_plane()),
      tile_size_(rasterizer.options().tile_size) {
  int width = width_, height = height_;
  for (;;) {
    Level level;
    level.width = width;
    level.height = height;
    level.texels.assign(static_cast<size_t>(width) * static_cast<size_t>(height), 0.0);
    levels_.push_back(std::move(level));
    if (width == 1 && height == 1) break;
    width = (width + 1) / 2;
    height = (height + 1) / 2;
  }
  rebuild(rasterizer);
}

void DepthPyramid::rebuild(Rasterizer& rasterizer) {
  assert(rasterizer.view().width == width_ && rasterizer.view().height == height_);
  const auto start = std::chrono::steady_clock::now();
  rasterizer.flush();
  seen_generation_ = rasterizer.generation();
  refresh_level0(rasterizer.inverse_depth(), 0, 0, width_ - 1, height_ - 1);
  for (int level = 1; level < levels(); ++level) refresh_level(level, 0, 0, width_ - 1, height_ - 1);
  ++counters_.updates;
  counters_.tiles_updated += static_cast<uint64_t>(rasterizer.tiles_x()) * static_cast<uint64_t>(rasterizer.tiles_y());
  counters_.update_ms += ms_since(start);
}

void DepthPyramid::update(Rasterizer& rasterizer) {
  assert(rasterizer.view().width == width_ && rasterizer.view().height == height_ &&
         rasterizer.options().tile_size == tile_size_);
  const auto start = std::chrono::steady_clock::now();
  const std::vector<int> tiles = rasterizer.tiles_changed_since(seen_generation_);
  seen_generation_ = rasterizer.generation();
  struct PixelRect {
    int x0, y0, x1, y1;
  };
  std::vector<PixelRect> changed;
  changed.reserve(tiles.size());
  for (int tile : tiles) {
    const int x0 = (tile % rasterizer.tiles_x()) * tile_size_, y0 = (tile / rasterizer.tiles_x()) * tile_size_;
    changed.push_back({x0, y0, std::min(x0 + tile_size_, width_) - 1, std::min(y0 + tile_size_, height_) - 1});
  }
  const std::vector<double>& depth = rasterizer.inverse_depth();
  for (const PixelRect& r : changed) refresh_level0(depth, r.x0, r.y0, r.x1, r.y1);
  // Level by level, so that a coarse texel shared by several changed tiles reads fresh children.
  for (int level = 1; level < levels(); ++level) {
    for (const PixelRect& r : changed) refresh_level(level, r.x0, r.y0, r.x1, r.y1);
  }
  ++counters_.updates;
  counters_.tiles_updated += tiles.size();
  counters_.update_ms += ms_since(start);
}

void DepthPyramid::refresh_level0(const std::vector<double>& depth, int x0, int y0, int x1, int y1) {
  Level& pixels = levels_.front();
  for (int y = y0; y <= y1; ++y) {
    const size_t row = static_cast<size_t>(y) * static_cast<size_t>(width_);
    std::copy(depth.begin() + static_cast<ptrdiff_t>(row + static_cast<size_t>(x0)),
              depth.begin() + static_cast<ptrdiff_t>(row + static_cast<size_t>(x1) + 1),
              pixels.texels.begin() + static_cast<ptrdiff_t>(row + static_cast<size_t>(x0)));
  }
}

void DepthPyramid::refresh_level(int level, int x0, int y0, int x1, int y1) {
  const Level& fine = levels_[static_cast<size_t>(level - 1)];
  Level& coarse = levels_[static_cast<size_t>(level)];
  for (int y = y0 >> level; y <= y1 >> level; ++y) {
    // A last odd row or column has one child: repeat it rather than read past the edge.
    const int fy0 = 2 * y, fy1 = std::min(2 * y + 1, fine.height - 1);
    for (int x = x0 >> level; x <= x1 >> level; ++x) {
      const int fx0 = 2 * x, fx1 = std::min(2 * x + 1, fine.width - 1);
      coarse.texels[static_cast<size_t>(y) * static_cast<size_t>(coarse.width) + static_cast<size_t>(x)] =
          std::min({fine.at(fx0, fy0), fine.at(fx1, fy0), fine.at(fx0, fy1), fine.at(fx1, fy1)});
    }
  }
}

BoxFootprint DepthPyramid::footprint(const Aabb& box) const {
  BoxFootprint f;
  if (box.empty()) return f;
  Vec3 corners[8];
  double w_min = kInfinity, w_max = -kInfinity;
  bool finite = true;
  for (int k = 0; k < 8; ++k) {
    const Vec3 c = clip_(Vec3(k & 1 ? box.hi.x : box.lo.x, k & 2 ? box.hi.y : box.lo.y, k & 4 ? box.hi.z : box.lo.z));
    finite = finite && std::isfinite(c.x) && std::isfinite(c.y) && std::isfinite(c.z);
    w_min = std::min(w_min, c.z);
    w_max = std::max(w_max, c.z);
    corners[k] = c;
  }
  if (!finite) {
    f.kind = BoxFootprint::Kind::kUnbounded;
    return f;
  }
  if (w_max < near_ || w_max <= 0.0) return f;  // wholly behind the near plane: culled, all of it
  const double near = near_ > 0.0 ? near_ : kAutoNearFraction * w_max;
  if (!(w_min > near)) {
    f.kind = BoxFootprint::Kind::kUnbounded;
    return f;
  }
  double x_min = kInfinity, x_max = -kInfinity, y_min = kInfinity, y_max = -kInfinity;
  for (const Vec3& c : corners) {
    x_min = std::min(x_min, c.x / c.z);
    x_max = std::max(x_max, c.x / c.z);
    y_min = std::min(y_min, c.y / c.z);
    y_max = std::max(y_max, c.y / c.z);
  }
  // Rounded outward: a centre on the boundary, or just past it by rounding, counts as covered.
  const double last_x = width_ - 1, last_y = height_ - 1;
  const double x0 = std::floor(x_min), x1 = std::ceil(x_max), y0 = std::floor(y_min), y1 = std::ceil(y_max);
  if (x1 < 0.0 || y1 < 0.0 || x0 > last_x || y0 > last_y) return f;
  f.kind = BoxFootprint::Kind::kOnScreen;
  f.x0 = static_cast<int>(std::max(x0, 0.0));
  f.y0 = static_cast<int>(std::max(y0, 0.0));
  f.x1 = static_cast<int>(std::min(x1, last_x));
  f.y1 = static_cast<int>(std::min(y1, last_y));
  f.hiding_inverse_depth = (1.0 / w_min) * (1.0 + kDepthMargin);
  return f;
}

BoxVisibility DepthPyramid::classify(const Aabb& box, DepthPyramidCounters& counters) const {
  ++counters.queries;
  const BoxFootprint f = footprint(box);
  if (f.kind == BoxFootprint::Kind::kOffScreen) {
    ++counters.outside;
    return BoxVisibility::kOutside;
  }
  if (f.kind == BoxFootprint::Kind::kUnbounded) return BoxVisibility::kMaybeVisible;
  // Start at the finest level where the rectangle spans at most 2x2 texels (the last level, a
  // single texel, always qualifies); descend only where a texel straddles the rectangle.
  int level = 0;
  while ((f.x1 >> level) - (f.x0 >> level) > 1 || (f.y1 >> level) - (f.y0 >> level) > 1) ++level;
  uint64_t texels_read = 0;
  bool hidden = true;
  for (int y = f.y0 >> level; hidden && y <= f.y1 >> level; ++y) {
    for (int x = f.x0 >> level; hidden && x <= f.x1 >> level; ++x) hidden = covers(level, x, y, f, texels_read);
  }
  counters.texels_read += texels_read;
  if (!hidden) return BoxVisibility::kMaybeVisible;
  ++counters.hidden;
  return BoxVisibility::kHidden;
}

bool DepthPyramid::covers(int level, int x, int y, const BoxFootprint& f, uint64_t& texels_read) const {
  ++texels_read;
  if (texel(level, x, y) > f.hiding_inverse_depth) return true;
  if (level == 0) return false;
  // The texel's minimum lies somewhere in its block: inside the rectangle it settles the answer.
  const int bx0 = x << level, by0 = y << level;
  const int bx1 = std::min(((x + 1) << level) - 1, width_ - 1), by1 = std::min(((y + 1) << level) - 1, height_ - 1);
  if (bx0 >= f.x0 && bx1 <= f.x1 && by0 >= f.y0 && by1 <= f.y1) return false;
  const int child = level - 1;
  const int cx0 = std::max(2 * x, f.x0 >> child), cx1 = std::min(2 * x + 1, f.x1 >> child);
  const int cy0 = std::max(2 * y, f.y0 >> child), cy1 = std::min(2 * y + 1, f.y1 >> child);
  for (int cy = cy0; cy <= cy1; ++cy) {
    for (int cx = cx0; cx <= cx1; ++cx) {
      if (!covers(child, cx, cy, f, texels_read)) return false;
    }
  }
  return true;
}

}  // namespace frontier
