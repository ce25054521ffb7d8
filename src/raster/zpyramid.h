// A hierarchical depth buffer (z-pyramid) over a Rasterizer's framebuffer, for occlusion
// culling: "would anything inside this box still win a depth test?" answered with a few texel
// reads instead of one per pixel.
//
// Invariants:
//  * Level 0 is a copy of Rasterizer::inverse_depth() as of the last update()/rebuild(): 1/w
//    per pixel, w the distance along the view axis, 0 for background (infinitely far).
//    Level k has ceil(width / 2^k) x ceil(height / 2^k) texels; texel (x, y) of level k is the
//    MINIMUM 1/w (the farthest surface) over the pixels [x 2^k, (x+1) 2^k) x [y 2^k, (y+1) 2^k)
//    inside the image, i.e. over its up to 2x2 children. The last level has one texel.
//    Minima are exact in floating point, so a texel equals the brute-force minimum bit for bit.
//  * update() recomputes only the texels whose pixel block meets a tile the rasterizer reports
//    changed (Rasterizer::tiles_changed_since); rebuild() recomputes everything. Either leaves
//    the pyramid equal to one built from scratch.
//  * classify() is conservative with respect to the rasterizer: when it says kHidden (or
//    kOutside), submitting any triangles that lie inside the box, with any ids, changes no pixel
//    of the framebuffer the pyramid was last updated from. (Up to kDepthMargin: a triangle's
//    1/w at a pixel is its plane equation at a centre covered after 2^-32-pixel snapping, within
//    1e-9 of the box's range unless the triangle is seen almost exactly edge-on.)
//  * The hierarchical descent is exact: kHidden is returned iff every pixel of
//    footprint(box)'s rectangle holds a 1/w above its threshold.
//
// Thread safety: update() and rebuild() need exclusive access; classify(box, counters) and the
// other const members may run concurrently (each thread with its own counters).
#pragma once

#include "src/core/geometry.h"
#include "src/raster/raster.h"

#include <cstdint>
#include <vector>

namespace frontier {

enum class BoxVisibility {
  kOutside,       // covers no pixel centre of the image, or lies wholly behind the near plane
  kHidden,        // every pixel it could cover holds a surface strictly nearer than all of it
  kMaybeVisible,  // neither could be shown (includes boxes reaching the near plane)
};

struct DepthPyramidCounters {
  uint64_t queries = 0;        // classify() calls
  uint64_t hidden = 0;         // answered kHidden
  uint64_t outside = 0;        // answered kOutside
  uint64_t texels_read = 0;    // pyramid texels read by the queries, all levels
  uint64_t updates = 0;        // update() and rebuild() calls
  uint64_t tiles_updated = 0;  // rasterizer tiles whose texels were recomputed
  double update_ms = 0.0;      // time in update() and rebuild(), flushing the rasterizer included

  DepthPyramidCounters& operator+=(const DepthPyramidCounters& o);
};

// Where a box can draw, worked out before any depth is read.
struct BoxFootprint {
  enum class Kind {
    kOffScreen,  // covers no pixel centre, or lies wholly behind the near plane
    kUnbounded,  // a corner at or before the near plane (or not finite): no screen bounds
    kOnScreen,   // the fields below apply
  };
  Kind kind = Kind::kOffScreen;
  // Inclusive pixel rectangle inside the image holding every pixel centre the box's projection
  // could cover (the projected corners' bounds rounded outward to pixel centres).
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;
  // A pixel hides the box when its 1/w is above this: the 1/w of the box's nearest point,
  // raised by kDepthMargin (relative) against rounding of the per-pixel plane equations.
  double hiding_inverse_depth = 0.0;
};

class DepthPyramid {
 public:
  // Relative margin on the box's nearest 1/w. Equal depth is never hidden either way: the
  // rasterizer gives ties to the lower id, which the box's contents may have.
  static constexpr double kDepthMargin = 1e-9;

  // Builds the pyramid over the rasterizer's framebuffer (flushing it). Copies the projection;
  // the rasterizer need not outlive the pyramid.
  explicit DepthPyramid(Rasterizer& rasterizer);

  // Flushes `rasterizer` and brings the pyramid up to date with it, recomputing only the tiles
  // changed since this pyramid last looked. REQUIRES: the rasterizer it was built over.
  void update(Rasterizer& rasterizer);
  // Recomputes every texel from `rasterizer`. REQUIRES: the rasterizer it was built over.
  void rebuild(Rasterizer& rasterizer);

  // The box (world space) against the pyramid as of the last update. An empty box is kOutside.
  BoxVisibility classify(const Aabb& box, DepthPyramidCounters& counters) const;
  BoxVisibility classify(const Aabb& box) { return classify(box, counters_); }
  bool hidden(const Aabb& box) { return classify(box) == BoxVisibility::kHidden; }
  // The screen rectangle and depth classify() tests, for callers and tests that want them.
  BoxFootprint footprint(const Aabb& box) const;

  // Counters of update(), rebuild() and the classify() calls that use the pyramid's own.
  const DepthPyramidCounters& counters() const { return counters_; }
  void reset_counters() { counters_ = {}; }

  // The texels. REQUIRES: 0 <= level < levels(), (x, y) inside that level.
  int levels() const { return static_cast<int>(levels_.size()); }
  int level_width(int level) const { return levels_[static_cast<size_t>(level)].width; }
  int level_height(int level) const { return levels_[static_cast<size_t>(level)].height; }
  double texel(int level, int x, int y) const { return levels_[static_cast<size_t>(level)].at(x, y); }

 private:
  struct Level {
    int width = 0, height = 0;
    std::vector<double> texels;  // row-major
    double at(int x, int y) const {
      return texels[static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)];
    }
  };

  // Recompute the texels of one level whose pixel blocks meet pixels [x0, x1] x [y0, y1]: level 0
  // copies the rasterizer's inverse_depth(), a coarser level reduces the (fresh) level below.
  void refresh_level0(const std::vector<double>& depth, int x0, int y0, int x1, int y1);
  void refresh_level(int level, int x0, int y0, int x1, int y1);
  // True when every pixel of `footprint`'s rectangle under texel (x, y) of `level` holds a 1/w
  // above its threshold; descends only into texels that straddle the rectangle's border.
  bool covers(int level, int x, int y, const BoxFootprint& footprint, uint64_t& texels_read) const;

  int width_ = 0, height_ = 0;
  ClipTransform clip_;  // the rasterizer's projection
  double near_ = 0.0;   // the rasterizer's near_plane()
  int tile_size_ = 0;
  uint64_t seen_generation_ = 0;  // rasterizer generation the texels reflect
  std::vector<Level> levels_;
  DepthPyramidCounters counters_;
};

}  // namespace frontier
