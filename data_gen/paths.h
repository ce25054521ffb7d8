// Camera paths a walkthrough user would take.
//
//   walk   through a building, using its sidecar: a seeded tour over the portal graph (room ->
//          door -> corridor -> ... , up and down stairs), at eye height, at a constant step per
//          frame, corners rounded, looking ahead along the path. Inside a cell the walker goes
//          portal approach -> the cell's walk line -> next portal approach; these segments are
//          the ones the generator keeps clear of furniture, so the path stays in free space.
//   orbit  a circle around the model's bounds centre, 25 degrees above it, looking at it.
//   fly    a smooth closed spline through seeded points of the bounding box above the model's
//          mid-height, looking ahead, lifted where it would come closer than the clearance to
//          the ground (data_gen/ground.h). Guarantee: every eye is at least `clearance` above
//          the highest geometry within `clearance` horizontally of it; the lift is widened and
//          smoothed along the path (a running maximum, then two running means) so the eye
//          climbs before a rise and does not jitter.
#pragma once

#include "data_gen/ground.h"
#include "src/core/geometry.h"
#include "src/core/scene.h"
#include "src/core/status.h"

#include <cstdint>
#include <string>
#include <vector>

namespace frontier::gen {

// What walk mode needs from a building sidecar, kept compact (a sidecar of a billion-triangle
// building is read in a streaming parse without building a JSON tree of it).
struct WalkCell {
  int floor = 0;
  bool room = false;
  Aabb bounds;
  glm::dvec2 line[2];
};
struct WalkPortal {
  int64_t cells[2] = {-1, -1};
  Vec3 approach[2];
  std::vector<Vec3> route;  // from approach[0] to approach[1]
};
struct WalkModel {
  bool walkable = false;
  double eye_height = 1.7;
  Aabb bounds;
  std::vector<WalkCell> cells;  // index = cell id
  std::vector<WalkPortal> portals;
};

// Reads a building sidecar. Corruption naming the file for malformed content.
Result<WalkModel> read_walk_sidecar(const std::string& path);
// Only the "bounds" of a sidecar (cheap, same streaming parse).
Result<Aabb> read_sidecar_bounds(const std::string& path);

struct PathOptions {
  int frames = 300;
  uint64_t seed = 1;
  double step = 0.05;   // walk: metres per frame
  double vfov_deg = 60.0;
  double clearance = 0.0;  // fly: metres above the ground; 0: default_clearance(bounds)
  // orbit, fly: metres the eye moves per frame (along the orbit's circle, along the fly's loop,
  // going round again as often as the frames need); 0: one loop spread over the frames.
  double speed = 0.0;
};

// The fly path's default clearance: 1% of the bounds' larger horizontal side (of the diagonal
// when the bounds are flat in x and y).
double default_clearance(const Aabb& bounds);

Result<std::vector<Camera>> walk_path(const WalkModel& model, const PathOptions& options);
Result<std::vector<Camera>> orbit_path(const Aabb& bounds, const PathOptions& options);
// `ground` covers the model (scan_ground over `bounds`).
Result<std::vector<Camera>> fly_path(const Aabb& bounds, const GroundMap& ground, const PathOptions& options);

}  // namespace frontier::gen
