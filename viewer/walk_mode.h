// Walk mode for frontier-view (a window or a headless walk): the store's collision grid and the
// walker that moves the eye over it with gravity and collision. Only stores built with
// frontier-build --walkable carry the grid.
#pragma once

#include "src/paging/store_model.h"
#include "src/walk/collision_grid.h"
#include "src/walk/walker.h"
#include "viewer/options.h"

#include <memory>

namespace frontier {

struct WalkMode {
  std::unique_ptr<CollisionGrid> grid;
  std::unique_ptr<Walker> walker;  // moves over *grid
};

// Opens `model`'s grid (budget: --collision-cache) and a walker with --eye-height and --radius
// (else the store's radius). Returns 0 when ready; else prints why and returns 1 (the store has
// no usable grid) or 2 (the walk options do not fit the grid).
int open_walk_mode(const ViewerOptions& o, const StoreModel& model, WalkMode& mode);

}  // namespace frontier
