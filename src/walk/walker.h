// Walk mode: the camera physics of frontier-view for stores that carry a collision grid (the
// "sdf" section, src/walk/collision_grid.h). Each frame the caller asks for a *desired* eye (WASD
// and mouse in the window, the next path frame headless) and gets back where the eye may go:
// moved horizontally with collision, up low steps, down stairs, and under gravity. Stores
// without an sdf section have no walk mode; the viewer flies there and constructs no Walker,
// so it reports zero collision queries.
//
// The body, as modelled here (all lengths in model units, "up" is WalkParams::up):
//  * The eye is a sphere of `radius`. Every move of the eye, horizontal or vertical, goes
//    through CollisionGrid::resolve, so it slides along what it touches and never passes
//    through a surface, not even a zero-thickness wall on a long step.
//  * The feet are eye_height below the eye. The *floor* under a point is found by the foot
//    probe: a point descending the vertical line below the eye until the grid reads
//    foot_clearance() = radius / 2 (>= one voxel, so that the field is linear there above a
//    flat floor); the floor is that contact point minus the distance read there. Over a flat
//    floor this is the floor itself (to the grid's float precision); near an edge it is the top of a sphere of radius
//    foot_clearance() rolled over the edge, so the eye rises smoothly onto a step and obstacles
//    are seen a little before the column reaches them. Within foot_clearance() + 1 voxel of
//    other geometry (wall-floor creases) it may read up to 0.94 voxel high (the grid's error).
//  * Anything the probe reports higher than the feet by at most step_height is climbed (the
//    eye is raised onto it if the head has room); anything higher blocks like a wall.
//
// Thread safety: a Walker holds per-walk state (fall speed, counters) and belongs to one thread;
// the CollisionGrid it reads may be shared (its const members are thread-safe). The grid must
// outlive the Walker.
#pragma once

#include "src/walk/collision_grid.h"
#include "src/core/geometry.h"
#include "src/core/status.h"

#include <cstdint>

namespace frontier {

// Defaults fit metre-scale models and the generated buildings (data_gen/building_layout.h: z up,
// 0.165 m risers on 0.28 m treads, 1.0 m doors, 3.0 m ceilings, paths at kEyeHeight = 1.7 m),
// and the preprocessor's default --walk-radius (0.25).
struct WalkParams {
  double eye_height = 1.7;      // feet to eye; the height the generated paths walk at
  double radius = 0.25;         // the eye's clearance from every surface
  double step_height = 0.35;    // highest rise climbed (two of the generated 0.165 m risers)
  double gravity = 9.81;        // units / s^2
  double max_fall_speed = 20.0; // units / s (a fall from 20 m, about; keeps frames short)
  Vec3 up{0.0, 0.0, 1.0};       // any non-zero vector; normalized by the Walker
};

class Walker {
 public:
  // InvalidArgument naming the field unless: every field is finite; up is non-zero;
  // grid.check_radius(radius) is ok and radius >= 2 voxels (the foot probe, radius / 2, needs a
  // voxel; see the top of this file); 0 <= step_height; eye_height - step_height >= radius + one
  // voxel (the eye sphere must clear whatever the feet may climb); gravity >= 0;
  // max_fall_speed > 0.
  static Status check(const CollisionGrid& grid, const WalkParams& params);

  // REQUIRES: check(grid, params) is ok (asserted); `grid` outlives the Walker.
  // The walker starts standing (see step()) and not falling.
  Walker(const CollisionGrid& grid, const WalkParams& params);

  // Moves the eye from `eye` towards `desired_eye` for a frame of `dt` seconds and returns
  // where it ends. Only the horizontal part (perpendicular to up) of desired_eye - eye is used;
  // height is gravity's and the floor's. Guarantees, with d = grid.distance() and h its voxel:
  //  * Clearance: if d(eye) >= radius then d(result) >= radius (true clearance >= radius -
  //    0.94 h), and the eye never crossed a surface on the way, however long the step. Walking
  //    into a wall stops where d = radius; at an angle it slides along.
  //  * Steps: the horizontal move is taken in pieces no longer than foot_clearance(); a piece is
  //    kept only if the floor at its end is at most step_height (+ 1e-3 h) above the feet
  //    (eye_height below the eye) and, when higher than the feet, the eye can be raised onto it
  //    (head room). A blocked piece is retried once slid along the obstacle (the grid's gradient
  //    at the foot contact), then the move ends. So an obstacle is never crossed when its top is
  //    more than step_height + (1 - sqrt(3)/2) foot_clearance() + 0.94 h above the feet,
  //    whatever its thickness (some piece end comes within foot_clearance() / 2 of it).
  //  * Floor: standing (see on_floor()), the eye is eye_height above the probed floor to within
  //    1e-3 h: it is moved only when the floor changes by more than that, and then placed
  //    eye_height above it (to the grid's float precision, about 1e-7 h). So a walk over a flat
  //    floor keeps one height exactly (no drift, no jitter). Down steps of at most step_height
  //    are followed piece by piece without a fall; walking off a deeper edge ends the frame's
  //    horizontal move there, and the eye falls.
  //  * Gravity: with no floor within step_height below the feet (or when already falling), the
  //    fall speed v grows by gravity * dt, capped at max_fall_speed, and the eye drops v * dt,
  //    but never below the floor the probe finds: it lands exactly eye_height above it and
  //    stands. If the eye sphere meets something before that, it rests there (v = 0).
  //  * An eye below standing height (spawned low) is raised to it, as far as the head has room.
  //  * A non-finite eye returns eye; a non-finite desired_eye is treated as eye; a non-finite or
  //    negative dt as 0. Outside the grid there is no floor: the eye falls without end (the
  //    caller decides when to reset()).
  Vec3 step(const Vec3& eye, const Vec3& desired_eye, double dt);

  // Forget the fall speed and stand (after a teleport, e.g. a path restart).
  void reset();

  const WalkParams& params() const { return params_; }
  // The foot probe's clearance: radius / 2.
  double foot_clearance() const { return foot_; }
  // True when the last step ended with the feet on a floor (standing or following stairs).
  bool on_floor() const { return on_floor_; }
  // Current fall speed (>= 0, along -up).
  double fall_speed() const { return fall_speed_; }

  // Counters since construction (reset() keeps them):
  // grid calls (distance, resolve, gradient) made by this walker; each counts one in
  // CollisionGrid::queries() too.
  uint64_t queries() const { return queries_; }
  // The grid it walks on (its brick cache counters go into the viewer's working-set report).
  const CollisionGrid& grid() const { return grid_; }
  // Times the feet left the floor (a drop deeper than step_height, or a fall on the first step).
  uint64_t falls() const { return falls_; }
  // Climbs: runs of consecutive pieces of horizontal motion, each rising at least 1 in 4, that
  // raised the eye by at least one voxel in total: one per riser when walking up a stair (treads
  // longer than foot_clearance() + a voxel or so), one for a whole ramp steeper than 1 in 4,
  // none for a gentler ramp or for walking down.
  uint64_t steps_climbed() const { return steps_climbed_; }

 private:
  // The grid's queries, counted.
  double distance(const Vec3& p);
  Vec3 gradient(const Vec3& p);
  Vec3 resolve(const Vec3& from, const Vec3& to);
  // Distance from `eye` down to the floor below it (the foot probe), or kInfinity when there is
  // none within max_gap.
  double floor_gap(const Vec3& eye, double max_gap);
  // One piece of horizontal motion from `pos` by `piece`; returns false when blocked (pos kept).
  bool move_piece(Vec3& pos, const Vec3& piece);
  // Tries the piece, ending with the feet-on-floor rules; false when the floor at its end is
  // too high or the head has no room.
  // `rise` is the floor at the end above the feet; `contact` where the probe met what blocked
  // (non-finite when nothing did).
  bool try_piece(const Vec3& pos, const Vec3& piece, Vec3& out, double& rise, Vec3& contact);
  void settle(Vec3& pos, double dt);

  const CollisionGrid& grid_;
  WalkParams params_;
  double voxel_ = 0.0;
  double foot_ = 0.0;
  double level_tolerance_ = 0.0;  // floor changes below this leave the eye where it is

  bool on_floor_ = true;
  double fall_speed_ = 0.0;
  double climb_run_ = 0.0;  // rise of the current run of rising pieces
  bool climb_counted_ = false;

  uint64_t queries_ = 0;
  uint64_t falls_ = 0;
  uint64_t steps_climbed_ = 0;
};

}  // namespace frontier
