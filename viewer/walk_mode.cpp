// Walk mode's set-up: the grid from the store, the walker's parameters from the options.
#include "viewer/walk_mode.h"

#include "viewer/outputs.h"

namespace frontier {
namespace {

// Walk mode: the store must carry a distance grid (frontier-build --walkable).
Result<std::unique_ptr<CollisionGrid>> load_grid(const StoreModel& model, uint64_t budget) {
  if (!model.info().walkable) {
    return Status::invalid_argument(model.reader().name() +
                                    ": the store declares no walk mode (build it with --walkable)");
  }
  return open_collision_grid(model.reader(), budget);
}

WalkParams walk_params(const ViewerOptions& o, const StoreModel& model) {
  WalkParams p;
  if (o.eye_height > 0.0) p.eye_height = o.eye_height;
  if (o.radius > 0.0) {
    p.radius = o.radius;
  } else if (model.info().walk_radius > 0.0) {
    p.radius = model.info().walk_radius;
  }
  return p;
}

}  // namespace

int open_walk_mode(const ViewerOptions& o, const StoreModel& model, WalkMode& mode) {
  auto grid = load_grid(model, o.collision_cache);
  if (!grid) return fail(grid.status());
  mode.grid = std::move(*grid);
  const WalkParams params = walk_params(o, model);
  if (Status s = Walker::check(*mode.grid, params); !s) return bad_option("walk mode: " + s.message());
  mode.walker = std::make_unique<Walker>(*mode.grid, params);
  return 0;
}

}  // namespace frontier
