// The depth pyramid against simple references: every texel is the brute-force minimum of its
// pixel block, after a full build and after incremental updates (non-power-of-two images, two
// tile sizes); the rasterizer reports exactly the tiles whose pixels changed; a box found hidden
// really is (drawing it, with ids that win ties, changes no pixel); the hierarchical test agrees
// with a per-pixel test of the same rectangle; and the wall cases (behind, beside, straddling
// the eye plane, behind a wall with a hole near or over it).
#include "src/raster/zpyramid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <set>
#include <string>

namespace frontier {
namespace {

// Scene triangles get ids from here up; probes drawn into the same framebuffer use lower ids,
// so they win every tie.
constexpr uint32_t kSceneIds = 1000;

// Looking down -z from the origin, y up.
View view_down_z(int width, int height, double fov, double near = 0.0) {
  Camera c;
  c.eye = Vec3(0.0);
  c.look_at = Vec3(0.0, 0.0, -1.0);
  c.up = Vec3(0.0, 1.0, 0.0);
  c.vfov_deg = fov;
  c.near = near;
  return View(c, width, height);
}

RasterOptions options_with_tile(int tile) {
  RasterOptions options;
  options.threads = 2;
  options.tile_size = tile;
  return options;
}

// A rectangle facing the camera at z (two triangles).
std::vector<Triangle> quad(double x0, double y0, double x1, double y1, double z) {
  return {{Vec3(x0, y0, z), Vec3(x1, y0, z), Vec3(x1, y1, z)}, {Vec3(x0, y0, z), Vec3(x1, y1, z), Vec3(x0, y1, z)}};
}

// The 12 triangles of a box's faces.
std::vector<Triangle> box_triangles(const Aabb& b) {
  auto corner = [&](int k) { return Vec3(k & 1 ? b.hi.x : b.lo.x, k & 2 ? b.hi.y : b.lo.y, k & 4 ? b.hi.z : b.lo.z); };
  static constexpr int kFaces[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
  std::vector<Triangle> triangles;
  for (const auto& f : kFaces) {
    triangles.push_back({corner(f[0]), corner(f[1]), corner(f[2])});
    triangles.push_back({corner(f[0]), corner(f[2]), corner(f[3])});
  }
  return triangles;
}

// Random triangles in front of the camera at depths 1..20, some large, plus `occluders` big
// camera-facing rectangles at depths 2..10: the scenes boxes hide behind.
std::vector<Triangle> random_scene(std::mt19937_64& rng, int triangles, int occluders) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(1.0, 20.0), wall_depth(2.0, 10.0), size(0.05, 0.6);
  std::uniform_int_distribution<int> large(0, 9);
  std::vector<Triangle> scene;
  for (int i = 0; i < triangles; ++i) {
    const double d = depth(rng);
    const Vec3 c(0.6 * d * u(rng), 0.4 * d * u(rng), -d);
    const double s = (large(rng) == 0 ? 3.0 : size(rng)) * 0.3 * d;
    scene.push_back({c, c + s * Vec3(u(rng), u(rng), u(rng)), c + s * Vec3(u(rng), u(rng), u(rng))});
  }
  for (int i = 0; i < occluders; ++i) {
    const double d = wall_depth(rng);
    const double x = 0.5 * d * u(rng), y = 0.3 * d * u(rng), hw = 0.4 * d * (1.2 + u(rng)), hh = 0.3 * d * (1.2 + u(rng));
    for (const Triangle& t : quad(x - hw, y - hh, x + hw, y + hh, -d)) scene.push_back(t);
  }
  return scene;
}

void submit_scene(Rasterizer& r, const std::vector<Triangle>& scene) {
  for (size_t i = 0; i < scene.size(); ++i) r.submit(scene[i], kSceneIds + static_cast<uint32_t>(i));
  r.flush();
}

// Random boxes in and around the view frustum at depths -3..25 (behind the eye too), sizes up
// to 0.3 of their distance: some reach the eye or near plane, some lie off screen.
Aabb random_box(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(-3.0, 25.0), size(0.005, 0.3);
  const double d = depth(rng);
  const Vec3 c(1.5 * d * u(rng), 1.0 * d * u(rng), -d);
  const Vec3 half = std::max(std::abs(d), 0.3) * Vec3(size(rng), size(rng), size(rng));
  return Aabb(c - half, c + half);
}

// The brute-force pyramid check: level sizes, and every texel equal to the minimum 1/w over its
// pixel block (clipped to the image).
void expect_pyramid_is_block_minima(const DepthPyramid& p, const std::vector<double>& depth, int width, int height,
                                    const std::string& what) {
  int expected_levels = 1;
  while ((width - 1) >> (expected_levels - 1) > 0 || (height - 1) >> (expected_levels - 1) > 0) ++expected_levels;
  ASSERT_EQ(p.levels(), expected_levels) << what;
  size_t wrong = 0;
  std::string first;
  for (int level = 0; level < p.levels(); ++level) {
    ASSERT_EQ(p.level_width(level), ((width - 1) >> level) + 1) << what;
    ASSERT_EQ(p.level_height(level), ((height - 1) >> level) + 1) << what;
    for (int ty = 0; ty < p.level_height(level); ++ty) {
      for (int tx = 0; tx < p.level_width(level); ++tx) {
        double minimum = kInfinity;
        for (int y = ty << level; y < std::min((ty + 1) << level, height); ++y) {
          for (int x = tx << level; x < std::min((tx + 1) << level, width); ++x) {
            minimum = std::min(minimum, depth[static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)]);
          }
        }
        if (p.texel(level, tx, ty) != minimum && wrong++ == 0) {
          first = "level " + std::to_string(level) + " texel (" + std::to_string(tx) + ", " + std::to_string(ty) + ")";
        }
      }
    }
  }
  EXPECT_EQ(p.level_width(p.levels() - 1) * p.level_height(p.levels() - 1), 1) << what;
  EXPECT_EQ(wrong, 0u) << what << ", first at " << first;
}

// The per-pixel reference of classify() on footprint(box)'s rectangle.
bool rectangle_hidden_per_pixel(const BoxFootprint& f, const std::vector<double>& depth, int width) {
  for (int y = f.y0; y <= f.y1; ++y) {
    for (int x = f.x0; x <= f.x1; ++x) {
      if (!(depth[static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)] > f.hiding_inverse_depth)) {
        return false;
      }
    }
  }
  return true;
}

// Draws the box's faces and `inside` random triangles within it (ids below the scene's, so they
// win ties) into `r`; returns how many pixels changed. `r` is left with them drawn.
size_t pixels_changed_by_drawing(Rasterizer& r, const Aabb& box, int inside, std::mt19937_64& rng) {
  const std::vector<uint32_t> ids_before = r.ids();
  const std::vector<double> depth_before = r.inverse_depth();
  uint32_t id = 0;
  for (const Triangle& t : box_triangles(box)) r.submit(t, id++);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  auto point = [&] { return box.lo + Vec3(u(rng), u(rng), u(rng)) * box.extent(); };
  for (int i = 0; i < inside; ++i) r.submit({point(), point(), point()}, id++);
  const std::vector<uint32_t>& ids = r.ids();
  const std::vector<double>& depth = r.inverse_depth();
  size_t changed = 0;
  for (size_t i = 0; i < ids.size(); ++i) changed += ids[i] != ids_before[i] || depth[i] != depth_before[i];
  return changed;
}

TEST(DepthPyramid, RasterizerReportsExactlyTheChangedTiles) {
  std::mt19937_64 rng(3);
  const View view = view_down_z(333, 201, 60.0);
  for (int tile : {16, 64}) {
    Rasterizer r(view, options_with_tile(tile));
    const int tiles = r.tiles_x() * r.tiles_y();
    EXPECT_EQ(r.tiles_x(), (333 + tile - 1) / tile);
    EXPECT_EQ(r.tiles_y(), (201 + tile - 1) / tile);
    uint64_t seen = 0;
    EXPECT_EQ(r.tiles_changed_since(seen).size(), size_t(tiles)) << "a new framebuffer is all new";
    seen = r.generation();
    for (int round = 0; round < 8; ++round) {
      const std::vector<uint32_t> ids = r.ids();
      const std::vector<double> depth = r.inverse_depth();
      // Few small triangles: most tiles stay untouched.
      const std::vector<Triangle> batch = random_scene(rng, 1 + round, round % 3 == 0 ? 1 : 0);
      for (size_t i = 0; i < batch.size(); ++i) r.submit(batch[i], kSceneIds + uint32_t(100 * round + i));
      std::set<int> expected;
      for (int y = 0; y < view.height; ++y) {
        for (int x = 0; x < view.width; ++x) {
          const size_t i = size_t(y) * size_t(view.width) + size_t(x);
          if (r.ids()[i] != ids[i] || r.inverse_depth()[i] != depth[i]) expected.insert((y / tile) * r.tiles_x() + x / tile);
        }
      }
      const std::vector<int> changed = r.tiles_changed_since(seen);
      seen = r.generation();
      EXPECT_EQ(std::set<int>(changed.begin(), changed.end()), expected) << "tile " << tile << ", round " << round;
      EXPECT_TRUE(std::is_sorted(changed.begin(), changed.end()));
    }
    // Nothing queued: nothing new. Clearing changes every tile.
    r.flush();
    EXPECT_EQ(r.generation(), seen);
    EXPECT_TRUE(r.tiles_changed_since(seen).empty());
    r.clear();
    EXPECT_EQ(r.tiles_changed_since(seen).size(), size_t(tiles));
  }
}

TEST(DepthPyramid, TexelsAreMinimaOfTheirBlocksAfterBuildAndUpdates) {
  std::mt19937_64 rng(5);
  for (const auto& [width, height] : {std::pair{333, 201}, std::pair{256, 128}, std::pair{1, 37}}) {
    const View view = view_down_z(width, height, 60.0);
    for (int tile : {16, 64}) {
      const std::string what = std::to_string(width) + "x" + std::to_string(height) + ", tile " + std::to_string(tile);
      Rasterizer r(view, options_with_tile(tile));
      const uint64_t tiles = uint64_t(r.tiles_x()) * uint64_t(r.tiles_y());
      DepthPyramid pyramid(r);
      expect_pyramid_is_block_minima(pyramid, r.inverse_depth(), width, height, what + ", empty");
      for (int level = 0; level < pyramid.levels(); ++level) EXPECT_EQ(pyramid.texel(level, 0, 0), 0.0);
      EXPECT_EQ(pyramid.counters().tiles_updated, tiles);

      // Several flushes between updates, some rounds with only a few small triangles.
      bool partial = false;
      for (int round = 0; round < 6; ++round) {
        const uint64_t before = pyramid.counters().tiles_updated;
        const bool small = round % 2 == 0;
        for (int flush = 0; flush < (small ? 1 : 3); ++flush) {
          const std::vector<Triangle> batch = random_scene(rng, small ? 1 : 40, round == 3 ? 1 : 0);
          for (size_t i = 0; i < batch.size(); ++i) r.submit(batch[i], kSceneIds + uint32_t(1000 * round + 100 * flush + i));
          r.flush();
        }
        pyramid.update(r);
        expect_pyramid_is_block_minima(pyramid, r.inverse_depth(), width, height, what + ", round " + std::to_string(round));
        partial = partial || pyramid.counters().tiles_updated - before < tiles;
      }
      EXPECT_TRUE(partial || tiles <= 4) << what << ": some update should have skipped unchanged tiles";

      // Updating twice recomputes nothing; clearing resets every texel to background.
      const uint64_t before = pyramid.counters().tiles_updated;
      pyramid.update(r);
      EXPECT_EQ(pyramid.counters().tiles_updated, before);
      r.clear();
      pyramid.update(r);
      expect_pyramid_is_block_minima(pyramid, r.inverse_depth(), width, height, what + ", cleared");
      EXPECT_EQ(pyramid.texel(pyramid.levels() - 1, 0, 0), 0.0);

      // rebuild() agrees with the incremental path.
      submit_scene(r, random_scene(rng, 50, 2));
      pyramid.rebuild(r);
      expect_pyramid_is_block_minima(pyramid, r.inverse_depth(), width, height, what + ", rebuilt");
      EXPECT_EQ(pyramid.counters().updates, 10u);
      EXPECT_GE(pyramid.counters().update_ms, 0.0);
    }
  }
}

// For random boxes in random scenes: classify() agrees with the per-pixel test of footprint()'s
// rectangle, and drawing a box found hidden or outside changes no pixel.
TEST(DepthPyramid, HiddenBoxesDrawNothingAndDescentIsExact) {
  std::mt19937_64 rng(11);
  size_t boxes = 0, outside = 0, unbounded = 0, hidden = 0, faces_hidden = 0, rect_pixels = 0, on_screen = 0;
  uint64_t texels_read = 0;
  for (int scene_index = 0; scene_index < 6; ++scene_index) {
    const double near = scene_index % 2 == 0 ? 0.0 : 0.5;
    const View view = view_down_z(333, 201, 70.0, near);
    const RasterOptions options = options_with_tile(scene_index % 3 == 0 ? 64 : 16);
    Rasterizer r(view, options), probe(view, options);
    const std::vector<Triangle> scene = random_scene(rng, 300, 3 + scene_index);
    submit_scene(r, scene);
    DepthPyramid pyramid(r);
    for (int b = 0; b < 400; ++b) {
      const Aabb box = random_box(rng);
      const uint64_t reads_before = pyramid.counters().texels_read;
      const BoxVisibility visibility = pyramid.classify(box);
      const BoxFootprint f = pyramid.footprint(box);
      ++boxes;
      switch (f.kind) {
        case BoxFootprint::Kind::kOffScreen:
          EXPECT_EQ(visibility, BoxVisibility::kOutside);
          ++outside;
          break;
        case BoxFootprint::Kind::kUnbounded:
          EXPECT_EQ(visibility, BoxVisibility::kMaybeVisible);
          ++unbounded;
          break;
        case BoxFootprint::Kind::kOnScreen: {
          EXPECT_NE(visibility, BoxVisibility::kOutside);
          EXPECT_EQ(visibility == BoxVisibility::kHidden, rectangle_hidden_per_pixel(f, r.inverse_depth(), view.width))
              << "scene " << scene_index << ", box " << b;
          ++on_screen;
          rect_pixels += size_t(f.x1 - f.x0 + 1) * size_t(f.y1 - f.y0 + 1);
          texels_read += pyramid.counters().texels_read - reads_before;
          // How much the box's own outline would allow: its faces drawn alone, compared pixel by
          // pixel with the scene (a box's contents lie behind its faces).
          probe.clear();
          uint32_t id = 0;
          for (const Triangle& t : box_triangles(box)) probe.submit(t, id++);
          const std::vector<uint32_t>& box_ids = probe.ids();
          const std::vector<double>& box_depth = probe.inverse_depth();
          const std::vector<double>& scene_depth = r.inverse_depth();
          bool all_behind = true;
          for (size_t i = 0; i < view.pixels() && all_behind; ++i) {
            all_behind = box_ids[i] == kNoPrim || scene_depth[i] > box_depth[i];
          }
          faces_hidden += all_behind;
          break;
        }
      }
      hidden += visibility == BoxVisibility::kHidden;
      if (visibility == BoxVisibility::kMaybeVisible) continue;
      // Conservative: nothing inside a hidden or outside box can change the frame.
      const size_t changed = pixels_changed_by_drawing(r, box, 8, rng);
      EXPECT_EQ(changed, 0u) << "scene " << scene_index << ", box " << b << " was "
                             << (visibility == BoxVisibility::kHidden ? "hidden" : "outside");
      if (changed != 0) {  // put the scene back for the next boxes
        r.clear();
        submit_scene(r, scene);
        pyramid.rebuild(r);
      }
    }
    EXPECT_EQ(pyramid.counters().queries, 400u);
  }
  std::printf("[ info ] %zu boxes: %zu outside, %zu reach the near plane, %zu on screen; hidden: pyramid %zu "
              "(= per-pixel test of the same rectangle), faces behind the scene at every pixel %zu; "
              "%.1f texels read per on-screen query for %.1f rectangle pixels\n",
              boxes, outside, unbounded, on_screen, hidden, faces_hidden, double(texels_read) / double(on_screen),
              double(rect_pixels) / double(on_screen));
  // The test means something only if many boxes are hidden, and some are not.
  EXPECT_GT(hidden, boxes / 10);
  EXPECT_LT(hidden, on_screen);
  EXPECT_GT(outside, 0u);
  EXPECT_GT(unbounded, 0u);
  EXPECT_LE(hidden, faces_hidden);
}

// A 256x256 view down -z, 60 degrees, with a wall at z = -5 over [-2, 2]^2 (the screen shows
// about +-2.9 there) pierced by a small hole at x in [0.2, 0.4], y in [-0.1, 0.1].
class WallScene {
 public:
  explicit WallScene(double near = 0.0) : view_(view_down_z(256, 256, 60.0, near)), raster_(view_, options_with_tile(16)) {
    for (const auto& part : {quad(-2.0, -2.0, 0.2, 2.0, -5.0), quad(0.4, -2.0, 2.0, 2.0, -5.0),
                             quad(0.2, -2.0, 0.4, -0.1, -5.0), quad(0.2, 0.1, 0.4, 2.0, -5.0)}) {
      wall_.insert(wall_.end(), part.begin(), part.end());
    }
    submit_scene(raster_, wall_);
    pyramid_ = std::make_unique<DepthPyramid>(raster_);
  }

  BoxVisibility classify(const Aabb& box, uint64_t* texels_read = nullptr) {
    const uint64_t before = pyramid_->counters().texels_read;
    const BoxVisibility v = pyramid_->classify(box);
    if (texels_read) *texels_read = pyramid_->counters().texels_read - before;
    return v;
  }
  // Pixels the box's faces and contents would change (then restores the wall).
  size_t drawing_changes(const Aabb& box) {
    std::mt19937_64 rng(1);
    const size_t changed = pixels_changed_by_drawing(raster_, box, 8, rng);
    raster_.clear();
    submit_scene(raster_, wall_);
    return changed;
  }

 private:
  View view_;
  std::vector<Triangle> wall_;
  Rasterizer raster_;
  std::unique_ptr<DepthPyramid> pyramid_;
};

TEST(DepthPyramid, BoxesAroundAWallWithAHole) {
  WallScene wall;
  // Right behind the wall, away from the hole: hidden, and drawing it indeed changes nothing.
  const Aabb behind(Vec3(-1.5, -0.5, -7.0), Vec3(-0.5, 0.5, -6.0));
  EXPECT_EQ(wall.classify(behind), BoxVisibility::kHidden);
  EXPECT_EQ(wall.drawing_changes(behind), 0u);
  // A hair behind the wall plane: still hidden. Touching it: equal depth is not hidden.
  EXPECT_EQ(wall.classify(Aabb(Vec3(-1.5, -0.5, -6.0), Vec3(-0.5, 0.5, -5.0 - 1e-6))), BoxVisibility::kHidden);
  const Aabb touching(Vec3(-1.5, -0.5, -6.0), Vec3(-0.5, 0.5, -5.0));
  EXPECT_EQ(wall.classify(touching), BoxVisibility::kMaybeVisible);
  EXPECT_GT(wall.drawing_changes(touching), 0u);
  // In front of the wall.
  EXPECT_EQ(wall.classify(Aabb(Vec3(-1.5, -0.5, -4.5), Vec3(-0.5, 0.5, -4.0))), BoxVisibility::kMaybeVisible);
  // Behind the wall next to the hole, which lies outside its rectangle but inside the coarse
  // texels covering it: found hidden by descending.
  uint64_t texels_read = 0;
  const Aabb near_hole(Vec3(-0.5, -0.3, -6.5), Vec3(0.1, 0.3, -6.0));
  EXPECT_EQ(wall.classify(near_hole, &texels_read), BoxVisibility::kHidden);
  EXPECT_GT(texels_read, 4u) << "the coarse texels include the hole: the test must descend";
  EXPECT_EQ(wall.drawing_changes(near_hole), 0u);
  // The hole over part of its projection: not hidden, and really visible through the hole.
  const Aabb through_hole(Vec3(0.1, -0.3, -6.5), Vec3(0.6, 0.3, -6.0));
  EXPECT_EQ(wall.classify(through_hole), BoxVisibility::kMaybeVisible);
  EXPECT_GT(wall.drawing_changes(through_hole), 0u);
  // Beside the wall (beyond its edge at x = 2): visible past the edge.
  const Aabb beside(Vec3(2.1, -0.5, -7.0), Vec3(2.6, 0.5, -6.0));
  EXPECT_EQ(wall.classify(beside), BoxVisibility::kMaybeVisible);
  EXPECT_GT(wall.drawing_changes(beside), 0u);
  // Straddling the eye plane, and reaching the eye from behind the wall.
  EXPECT_EQ(wall.classify(Aabb(Vec3(-0.5, -0.5, -6.0), Vec3(0.5, 0.5, 0.5))), BoxVisibility::kMaybeVisible);
  EXPECT_EQ(wall.classify(Aabb(Vec3(-1.5, -0.5, -7.0), Vec3(-0.5, 0.5, 0.0))), BoxVisibility::kMaybeVisible);
  // Behind the eye, and off to the side: outside.
  EXPECT_EQ(wall.classify(Aabb(Vec3(-0.5, -0.5, 1.0), Vec3(0.5, 0.5, 2.0))), BoxVisibility::kOutside);
  EXPECT_EQ(wall.classify(Aabb(Vec3(20.0, -0.5, -7.0), Vec3(21.0, 0.5, -6.0))), BoxVisibility::kOutside);
  EXPECT_EQ(wall.classify(Aabb()), BoxVisibility::kOutside) << "an empty box";
  EXPECT_EQ(wall.classify(Aabb(Vec3(-1.0, -1.0, -kInfinity), Vec3(1.0, 1.0, -6.0))), BoxVisibility::kMaybeVisible)
      << "an unbounded box";
}

TEST(DepthPyramid, NearPlaneDecidesWhatReachesTheEye) {
  WallScene wall(0.5);
  // Nearer than the near plane: clipped away whole, so outside; drawing it changes nothing.
  const Aabb before_near(Vec3(-0.1, -0.1, -0.4), Vec3(0.1, 0.1, -0.1));
  EXPECT_EQ(wall.classify(before_near), BoxVisibility::kOutside);
  EXPECT_EQ(wall.drawing_changes(before_near), 0u);
  // Crossing it: no bounded projection, so maybe visible.
  EXPECT_EQ(wall.classify(Aabb(Vec3(-1.5, -0.5, -7.0), Vec3(-0.5, 0.5, -0.3))), BoxVisibility::kMaybeVisible);
  // Beyond it and behind the wall: hidden as without a near plane.
  EXPECT_EQ(wall.classify(Aabb(Vec3(-1.5, -0.5, -7.0), Vec3(-0.5, 0.5, -6.0))), BoxVisibility::kHidden);
}

}  // namespace
}  // namespace frontier
