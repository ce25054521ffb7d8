// Walk mode (src/walk/walker.h) against small scenes with known answers: walls stop the eye at its
// radius and let it slide, floors catch it after a fall at eye height, low steps are climbed
// and high ones block, a flat walk keeps its height exactly, and the counters count.
// Scenes are metre-scale, z up, built into 5 cm grids in memory (a few tenths of a second each).
#include "preprocess/walkable_grid.h"
#include "src/walk/collision_grid.h"
#include "src/walk/walker.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <vector>

namespace frontier {
namespace {

constexpr double kVoxel = 0.05;
constexpr double kDt = 1.0 / 60.0;
const WalkParams kParams;  // the defaults: eye 1.7, radius 0.25, step 0.35, z up
// The grid's error bound (src/walk/collision_grid.h): 0.94 voxel.
constexpr double kGridError = 0.94 * kVoxel;
// Grid values are floats: a flat floor is found to about 1e-7 of a distance of a few voxels.
constexpr double kFloatNoise = 1e-6;

void add_quad(Scene& s, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  s.add_triangle({a, b, c}, 0, 0);
  s.add_triangle({a, c, d}, 0, 0);
}

// The floor z = z0 over [x0, x1] x [y0, y1].
void add_floor(Scene& s, double x0, double x1, double y0, double y1, double z0 = 0.0) {
  add_quad(s, {x0, y0, z0}, {x1, y0, z0}, {x1, y1, z0}, {x0, y1, z0});
}

// A zero-thickness wall x = x0 over [y0, y1] x [z0, z1].
void add_thin_wall(Scene& s, double x0, double y0, double y1, double z0, double z1) {
  add_quad(s, {x0, y0, z0}, {x0, y1, z0}, {x0, y1, z1}, {x0, y0, z1});
}

void add_box(Scene& s, const Vec3& lo, const Vec3& hi) { s.add_box(Box{Aabb(lo, hi)}, 1, 0); }

CollisionGrid build_grid(const Scene& s) {
  WalkableGridBuilder builder(kVoxel, WalkableGridBuilder::band_voxels_for_radius(kParams.radius, kVoxel));
  const Status added = builder.add_partition(s, s.bounds());
  EXPECT_TRUE(added.is_ok()) << added.to_string();
  Result<SdfImage> bytes = builder.finish();
  if (!bytes.is_ok()) {
    ADD_FAILURE() << bytes.status().to_string();
    std::abort();
  }
  Result<CollisionGrid> grid = CollisionGrid::load(bytes.value());
  if (!grid.is_ok()) {
    ADD_FAILURE() << grid.status().to_string();
    std::abort();
  }
  return std::move(grid).value();
}

// Walks from `eye` by `stride` per frame for `frames` frames; calls check(eye) after each.
template <typename Check>
Vec3 walk(Walker& walker, Vec3 eye, const Vec3& stride, int frames, Check check) {
  for (int i = 0; i < frames; ++i) {
    eye = walker.step(eye, eye + stride, kDt);
    check(eye);
  }
  return eye;
}

// A floor with a wall at x = 3 facing the walker: zero-thickness, or a 30 cm box.
Scene wall_scene(bool thin) {
  Scene s;
  add_floor(s, -1.0, 5.0, -2.5, 2.5);
  if (thin) {
    add_thin_wall(s, 3.0, -2.5, 2.5, 0.0, 3.0);
  } else {
    add_box(s, {3.0, -2.5, 0.0}, {3.3, 2.5, 3.0});
  }
  return s;
}

TEST(WalkerWalls, StopAtTheRadiusAndNeverPassEvenThinOnALongStep) {
  for (bool thin : {true, false}) {
    SCOPED_TRACE(thin ? "zero-thickness wall" : "30 cm wall");
    const CollisionGrid grid = build_grid(wall_scene(thin));
    ASSERT_TRUE(Walker::check(grid, kParams).is_ok());
    const double stop = 3.0 - kParams.radius;

    // One long step aimed 5 m past the wall.
    Walker leap(grid, kParams);
    const Vec3 landed = leap.step({0.0, 0.0, 1.7}, {8.0, 0.0, 1.7}, kDt);
    EXPECT_NEAR(landed.x, stop, kGridError);
    EXPECT_LT(landed.x, 3.0);
    EXPECT_GE(grid.distance(landed), kParams.radius);
    EXPECT_NEAR(landed.z, 1.7, 1e-9);
    EXPECT_NEAR(landed.y, 0.0, 1e-9);
    // Pressing on with long steps goes nowhere.
    Vec3 pressed = landed;
    for (int i = 0; i < 20; ++i) pressed = leap.step(pressed, pressed + Vec3(4.0, 0.0, 0.0), kDt);
    EXPECT_NEAR(pressed.x, stop, kGridError);
    EXPECT_LT(pressed.x, 3.0);

    // Short steps (3 cm a frame) against it: never closer than the bound on the way.
    Walker stroll(grid, kParams);
    double max_x = -kInfinity;
    const Vec3 end = walk(stroll, {0.0, 0.0, 1.7}, {0.03, 0.0, 0.0}, 200,
                          [&](const Vec3& e) { max_x = std::max(max_x, e.x); });
    EXPECT_LE(max_x, stop + kGridError);
    EXPECT_NEAR(end.x, stop, kGridError);
    EXPECT_EQ(stroll.falls(), 0u);
  }
}

TEST(WalkerWalls, WalkingAtAnAngleSlidesAlong) {
  const CollisionGrid grid = build_grid(wall_scene(/*thin=*/true));
  Walker walker(grid, kParams);
  const Vec3 start(2.0, -1.5, 1.7);
  const Vec3 stride = 0.03 * glm::normalize(Vec3(1.0, 1.0, 0.0));
  const int frames = 100;
  double max_x = -kInfinity;
  const Vec3 end = walk(walker, start, stride, frames, [&](const Vec3& e) { max_x = std::max(max_x, e.x); });
  const double stop = 3.0 - kParams.radius;
  EXPECT_LE(max_x, stop + kGridError);
  EXPECT_NEAR(end.x, stop, kGridError);
  // The wall takes the x part of the motion; the y part (2.12 m) is kept, nearly all of it.
  EXPECT_GT(end.y - start.y, 0.95 * frames * stride.y);
  EXPECT_LE(end.y - start.y, frames * stride.y + 1e-9);
  EXPECT_NEAR(end.z, 1.7, 1e-9);
}

TEST(WalkerGravity, DroppedAboveAFloorFallsAndRestsAtEyeHeight) {
  Scene s;
  add_floor(s, -2.0, 2.0, -2.0, 2.0);
  const CollisionGrid grid = build_grid(s);
  Walker walker(grid, kParams);
  Vec3 eye(0.3, -0.2, 1.7 + 3.3);  // one storey above standing height
  int landed_at = -1;
  for (int frame = 1; frame <= 200; ++frame) {
    const Vec3 before = eye;
    eye = walker.step(eye, eye, kDt);
    ASSERT_GE(eye.z, 1.7 - kFloatNoise) << "frame " << frame;  // never below standing height
    ASSERT_LE(eye.z, before.z) << "frame " << frame;
    ASSERT_LE(before.z - eye.z, kParams.max_fall_speed * kDt + 1e-12);
    if (landed_at < 0 && walker.on_floor()) landed_at = frame;
  }
  // Semi-implicit Euler: after n frames the eye fell g dt^2 n (n + 1) / 2; 3.3 m takes 49 frames.
  EXPECT_GE(landed_at, 47);
  EXPECT_LE(landed_at, 50);
  EXPECT_NEAR(eye.z, 1.7, 1e-4);
  EXPECT_EQ(walker.falls(), 1u);
  EXPECT_EQ(walker.fall_speed(), 0.0);
  EXPECT_NEAR(eye.x, 0.3, 1e-12);
  EXPECT_NEAR(eye.y, -0.2, 1e-12);
}

TEST(WalkerGravity, LongFramesAndTheSpeedCapNeverOvershootTheFloor) {
  Scene s;
  add_floor(s, -2.0, 2.0, -2.0, 2.0);
  const CollisionGrid grid = build_grid(s);

  // Half-second frames: the second one would drop 4.9 m with 0.85 m to go.
  Walker coarse(grid, kParams);
  Vec3 eye(0.0, 0.0, 5.0);
  for (int i = 0; i < 5; ++i) {
    eye = coarse.step(eye, eye, 0.5);
    ASSERT_GE(eye.z, 1.7 - kFloatNoise);
  }
  EXPECT_NEAR(eye.z, 1.7, 1e-4);
  EXPECT_TRUE(coarse.on_floor());

  // A low speed cap: the fall speed saturates and each frame drops exactly cap * dt.
  WalkParams slow = kParams;
  slow.max_fall_speed = 2.0;
  Walker capped(grid, slow);
  eye = Vec3(0.0, 0.0, 5.0);
  double last_drop = 0.0;
  for (int i = 0; i < 60; ++i) {
    const Vec3 before = eye;
    eye = capped.step(eye, eye, kDt);
    last_drop = before.z - eye.z;
    ASSERT_LE(capped.fall_speed(), 2.0);
    ASSERT_LE(last_drop, 2.0 * kDt + 1e-12);
  }
  EXPECT_NEAR(last_drop, 2.0 * kDt, 1e-12);  // still falling, at the cap
  EXPECT_FALSE(capped.on_floor());
}

TEST(WalkerGravity, WalkingOffALedgeFallsToTheFloorBelow) {
  Scene s;
  add_floor(s, -1.0, 5.0, -1.5, 1.5);
  add_box(s, {-1.0, -1.5, 0.0}, {2.0, 1.5, 1.0});  // a 1 m platform
  const CollisionGrid grid = build_grid(s);
  Walker walker(grid, kParams);
  double min_z = kInfinity;
  const Vec3 end = walk(walker, {0.0, 0.0, 2.7}, {0.02, 0.0, 0.0}, 150,
                        [&](const Vec3& e) { min_z = std::min(min_z, e.z); });
  EXPECT_EQ(walker.falls(), 1u);
  EXPECT_NEAR(end.z, 1.7, 1e-4);
  EXPECT_GE(min_z, 1.7 - kFloatNoise);
  EXPECT_GT(end.x, 2.5);
  EXPECT_EQ(walker.steps_climbed(), 0u);
}

// Five steps like the generated buildings' (0.165 m risers, 0.28 m treads) from x = 1 up to a
// landing at 0.825 m.
constexpr int kStairSteps = 5;
constexpr double kRiser = 0.165, kTread = 0.28;
Scene stair_scene() {
  Scene s;
  add_floor(s, -1.0, 5.0, -1.5, 1.5);
  for (int i = 0; i < kStairSteps; ++i) {
    const double x1 = i + 1 == kStairSteps ? 4.5 : 1.0 + (i + 1) * kTread;
    add_box(s, {1.0 + i * kTread, -0.7, 0.0}, {x1, 0.7, (i + 1) * kRiser});
  }
  return s;
}

TEST(WalkerSteps, ClimbsAndDescendsAStairLowerThanStepHeight) {
  const CollisionGrid grid = build_grid(stair_scene());
  const double top = kStairSteps * kRiser + 1.7;
  Walker walker(grid, kParams);
  double last_z = 1.7;
  bool monotone = true;
  const Vec3 up_end = walk(walker, {0.0, 0.0, 1.7}, {0.02, 0.0, 0.0}, 175, [&](const Vec3& e) {
    monotone = monotone && e.z >= last_z - 1e-9;
    last_z = e.z;
    EXPECT_GE(grid.distance(e), kParams.radius);
  });
  EXPECT_TRUE(monotone);
  EXPECT_NEAR(up_end.x, 3.5, 1e-9);
  EXPECT_NEAR(up_end.z, top, 1e-3);
  EXPECT_EQ(walker.steps_climbed(), uint64_t(kStairSteps));
  EXPECT_EQ(walker.falls(), 0u);

  // And back down: the feet follow each step, no fall, no climb.
  monotone = true;
  const Vec3 down_end = walk(walker, up_end, {-0.02, 0.0, 0.0}, 175, [&](const Vec3& e) {
    monotone = monotone && e.z <= last_z + 1e-9;
    last_z = e.z;
  });
  EXPECT_TRUE(monotone);
  EXPECT_NEAR(down_end.z, 1.7, 1e-3);
  EXPECT_EQ(walker.falls(), 0u);
  EXPECT_EQ(walker.steps_climbed(), uint64_t(kStairSteps));

  // Headless-path strides (0.3 m a frame, each cut into pieces) climb the same stair, and
  // 0.6 m strides (three risers, more than step_height, a frame) come down it without a fall.
  Walker strider(grid, kParams);
  const Vec3 strided = walk(strider, {0.0, 0.0, 1.7}, {0.3, 0.0, 0.0}, 12, [](const Vec3&) {});
  EXPECT_NEAR(strided.z, top, 1e-3);
  EXPECT_EQ(strider.steps_climbed(), uint64_t(kStairSteps));
  EXPECT_EQ(strider.falls(), 0u);
  const Vec3 strode_down = walk(strider, strided, {-0.6, 0.0, 0.0}, 6, [](const Vec3&) {});
  EXPECT_NEAR(strode_down.z, 1.7, 1e-3);
  EXPECT_EQ(strider.falls(), 0u);
}

TEST(WalkerSteps, AStepHigherThanStepHeightBlocksLikeAWall) {
  for (int kind = 0; kind < 2; ++kind) {
    SCOPED_TRACE(kind == 0 ? "0.6 m box" : "0.6 m zero-thickness partition");
    Scene s;
    add_floor(s, -1.0, 4.0, -2.5, 2.5);
    if (kind == 0) {
      add_box(s, {1.0, -2.0, 0.0}, {2.0, 2.0, 0.6});
    } else {
      add_thin_wall(s, 1.0, -2.0, 2.0, 0.0, 0.6);
    }
    const CollisionGrid grid = build_grid(s);

    Walker stroll(grid, kParams);
    double max_x = -kInfinity;
    // Next to the obstacle the floor may read a little high (the grid's error at the crease).
    const Vec3 end = walk(stroll, {0.0, 0.0, 1.7}, {0.02, 0.0, 0.0}, 100, [&](const Vec3& e) {
      max_x = std::max(max_x, e.x);
      EXPECT_NEAR(e.z, 1.7, kGridError);
    });
    EXPECT_LT(max_x, 1.0);
    EXPECT_GT(end.x, 1.0 - stroll.foot_clearance() - 0.03);  // stopped near it, not far off
    EXPECT_EQ(stroll.steps_climbed(), 0u);

    Walker leap(grid, kParams);
    const Vec3 landed = leap.step({0.0, 0.0, 1.7}, {3.5, 0.0, 1.7}, kDt);
    EXPECT_LT(landed.x, 1.0);
    EXPECT_NEAR(landed.z, 1.7, kGridError);

    // At an angle the walker slides along it (the y part of the motion survives).
    Walker slider(grid, kParams);
    const Vec3 stride = 0.03 * glm::normalize(Vec3(1.0, 1.0, 0.0));
    const Vec3 start(0.5, -1.5, 1.7);
    const Vec3 slid = walk(slider, start, stride, 60, [](const Vec3&) {});
    EXPECT_LT(slid.x, 1.0);
    EXPECT_GT(slid.y - start.y, 0.8 * 60 * stride.y);
    EXPECT_NEAR(slid.z, 1.7, kGridError);
  }
}

TEST(WalkerSteps, AStepJustBelowStepHeightIsClimbed) {
  Scene s;
  add_floor(s, -1.0, 4.0, -1.5, 1.5);
  add_box(s, {1.0, -1.0, 0.0}, {3.0, 1.0, 0.3});
  const CollisionGrid grid = build_grid(s);
  Walker walker(grid, kParams);
  const Vec3 end = walk(walker, {0.0, 0.0, 1.7}, {0.02, 0.0, 0.0}, 100, [](const Vec3&) {});
  EXPECT_NEAR(end.x, 2.0, 1e-9);
  EXPECT_NEAR(end.z, 2.0, 1e-3);
  EXPECT_EQ(walker.steps_climbed(), 1u);
}

TEST(WalkerSteps, NoHeadRoomNoClimb) {
  Scene s;
  add_floor(s, -1.0, 4.0, -1.5, 1.5);
  add_box(s, {1.0, -1.0, 0.0}, {3.0, 1.0, 0.3});
  add_floor(s, -1.0, 4.0, -1.5, 1.5, 2.1);  // a ceiling the raised eye (2.0 + radius) would hit
  const CollisionGrid grid = build_grid(s);
  Walker walker(grid, kParams);
  double max_x = -kInfinity;
  walk(walker, {0.0, 0.0, 1.7}, {0.02, 0.0, 0.0}, 100, [&](const Vec3& e) {
    max_x = std::max(max_x, e.x);
    EXPECT_NEAR(e.z, 1.7, kGridError);
  });
  EXPECT_LT(max_x, 1.0);
  EXPECT_EQ(walker.steps_climbed(), 0u);
}

TEST(WalkerFloor, FlatWalkKeepsTheEyeHeightExactly) {
  Scene s;
  add_floor(s, -3.0, 3.0, -3.0, 3.0);
  const CollisionGrid grid = build_grid(s);
  Walker walker(grid, kParams);
  Vec3 eye(1.5, 0.0, 1.7);
  for (int i = 1; i <= 1500; ++i) {
    // Laps of a 1.5 m circle, 3 cm a frame, with uneven frame times.
    const double a = 0.02 * i;
    const Vec3 desired(1.5 * std::cos(a), 1.5 * std::sin(a), 1.7 + 0.1 * std::sin(7.0 * a));
    eye = walker.step(eye, desired, kDt * (1.0 + 0.5 * std::sin(3.0 * a)));
    ASSERT_EQ(eye.z, 1.7) << "frame " << i;  // not moved at all: no drift, no jitter
    ASSERT_NEAR(eye.x, desired.x, 1e-12);
    ASSERT_NEAR(eye.y, desired.y, 1e-12);
  }
  EXPECT_EQ(walker.falls(), 0u);
  EXPECT_EQ(walker.steps_climbed(), 0u);
  EXPECT_TRUE(walker.on_floor());
}

TEST(WalkerFloor, OtherUpAxesWork) {
  Scene s;  // a floor y = 0
  add_quad(s, {-2.0, 0.0, -2.0}, {2.0, 0.0, -2.0}, {2.0, 0.0, 2.0}, {-2.0, 0.0, 2.0});
  const CollisionGrid grid = build_grid(s);
  WalkParams y_up = kParams;
  y_up.up = Vec3(0.0, 2.0, 0.0);  // normalized by the walker
  ASSERT_TRUE(Walker::check(grid, y_up).is_ok());
  Walker walker(grid, y_up);
  Vec3 eye(0.0, 4.0, 0.0);
  for (int i = 0; i < 120; ++i) eye = walker.step(eye, eye + Vec3(0.01, 0.0, 0.005), kDt);
  EXPECT_NEAR(eye.y, 1.7, 1e-4);
  EXPECT_NEAR(eye.x, 1.2, 1e-9);
  EXPECT_NEAR(eye.z, 0.6, 1e-9);
  EXPECT_EQ(walker.falls(), 1u);
}

TEST(WalkerFloor, SpawnedOffStandingHeightSettlesInOneFrame) {
  Scene s;
  add_floor(s, -2.0, 2.0, -2.0, 2.0);
  const CollisionGrid grid = build_grid(s);
  // Too low: stands up. Up to step_height too high: steps down. Neither is a fall.
  for (double z : {1.0, 1.9, 1.7 + kParams.step_height}) {
    Walker walker(grid, kParams);
    const Vec3 eye = walker.step({0.0, 0.0, z}, {0.0, 0.0, z}, kDt);
    EXPECT_NEAR(eye.z, 1.7, kFloatNoise) << "spawned at " << z;
    EXPECT_EQ(walker.falls(), 0u) << "spawned at " << z;
    EXPECT_TRUE(walker.on_floor());
  }
  // Higher than that: a fall.
  Walker walker(grid, kParams);
  walker.step({0.0, 0.0, 2.1}, {0.0, 0.0, 2.1}, kDt);
  EXPECT_EQ(walker.falls(), 1u);
  EXPECT_FALSE(walker.on_floor());
}

TEST(WalkerCounters, QueriesGrowWithStepsAndMatchTheGrid) {
  const CollisionGrid grid = build_grid(stair_scene());
  Walker walker(grid, kParams);
  EXPECT_EQ(walker.queries(), 0u);
  const uint64_t grid_before = grid.queries();
  Vec3 eye(0.0, 0.0, 1.7);
  uint64_t last = 0;
  for (int i = 0; i < 40; ++i) {
    eye = walker.step(eye, eye + Vec3(0.05, 0.0, 0.0), kDt);
    EXPECT_GT(walker.queries(), last) << "step " << i;
    last = walker.queries();
  }
  EXPECT_EQ(grid.queries() - grid_before, walker.queries());
  // Standing still on a flat floor is cheap: a resolve-free probe of a few samples.
  Walker idle(grid, kParams);
  const Vec3 spot(0.0, 0.0, 1.7);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(idle.step(spot, spot, kDt), spot);
  EXPECT_GT(idle.queries(), 0u);
  EXPECT_LE(idle.queries(), 10u * 16u);
}

TEST(WalkerCheck, RejectsParametersTheGridOrTheBodyCannotHonour) {
  Scene s;
  add_floor(s, -1.0, 1.0, -1.0, 1.0);
  const CollisionGrid grid = build_grid(s);
  EXPECT_TRUE(Walker::check(grid, kParams).is_ok());
  const auto rejects = [&](auto edit) {
    WalkParams p = kParams;
    edit(p);
    return Walker::check(grid, p).code() == Status::Code::InvalidArgument;
  };
  EXPECT_TRUE(rejects([](WalkParams& p) { p.radius = 0.09; }));   // under two voxels
  EXPECT_TRUE(rejects([](WalkParams& p) { p.radius = 0.35; }));   // not inside the band (0.3)
  EXPECT_TRUE(rejects([](WalkParams& p) { p.radius = std::nan(""); }));
  EXPECT_TRUE(rejects([](WalkParams& p) { p.eye_height = 0.6; }));  // eye sphere hits the steps
  EXPECT_TRUE(rejects([](WalkParams& p) { p.step_height = -0.1; }));
  EXPECT_TRUE(rejects([](WalkParams& p) { p.gravity = -9.81; }));
  EXPECT_TRUE(rejects([](WalkParams& p) { p.max_fall_speed = 0.0; }));
  EXPECT_TRUE(rejects([](WalkParams& p) { p.up = Vec3(0.0); }));
  EXPECT_TRUE(rejects([](WalkParams& p) { p.up = Vec3(0.0, 0.0, kInfinity); }));
  EXPECT_FALSE(rejects([](WalkParams& p) { p.radius = 0.1; }));
}

TEST(WalkerInput, NonFiniteInputLeavesTheEyeAlone) {
  Scene s;
  add_floor(s, -2.0, 2.0, -2.0, 2.0);
  const CollisionGrid grid = build_grid(s);
  Walker walker(grid, kParams);
  const Vec3 eye(0.0, 0.0, 1.7);
  EXPECT_EQ(walker.step(eye, {std::nan(""), 0.0, 1.7}, kDt), eye);
  EXPECT_EQ(walker.step(eye, {1.0, 0.0, 1.7}, std::nan("")), Vec3(1.0, 0.0, 1.7));
  const Vec3 lost = walker.step({std::nan(""), 0.0, 1.7}, eye, kDt);
  EXPECT_TRUE(std::isnan(lost.x));
  // Far in the air and no dt: nothing moves, but the feet are off the floor.
  EXPECT_EQ(walker.step({0.0, 0.0, 9.0}, {0.0, 0.0, 9.0}, -1.0), Vec3(0.0, 0.0, 9.0));
  EXPECT_FALSE(walker.on_floor());
}

}  // namespace
}  // namespace frontier
