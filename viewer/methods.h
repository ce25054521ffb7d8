// frontier-view's rendering methods for a model file, in one table. A row names a method,
// says in one line what it is and which options it reads, checks those options, makes its
// FrameRenderer (src/engine/frame_renderer.h) and prints its line on stderr after the frame.
// --method's choices and help text are the table's rows; adding a method is adding a row.
//
// Which row renders: the one --method names, except that the three ray-casting methods are the
// frustum-advance visibility class, and --visibility naming a rasterizing class (exhaustive,
// frustum-cull, occlusion-cull, portals) picks that class's row instead. The other methods
// (imr, tessellated, mesa, bsp) ignore --visibility.
#pragma once

#include "src/core/scene.h"
#include "src/core/status.h"
#include "src/core/view.h"
#include "src/engine/frame_renderer.h"
#include "src/engine/kdtree.h"
#include "viewer/options.h"

#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace frontier {

// What a method renders from: the model in memory and the frame's view.
struct MethodInput {
  const ViewerOptions& options;
  const Scene& scene;
  const KdTree& tree;
  const View& view;  // the frame's (Mesa sizes its framebuffer from it)
  double load_ms = 0.0, build_ms = 0.0;  // reading the model, building its k-d tree
};

struct ViewMethod {
  std::string_view name;
  std::string_view help;   // one line
  std::string_view reads;  // the options it reads besides --size, --threads, --png, --ids, --stats
  std::string_view option = "--method";  // the option naming it, or "--visibility"
  bool frustum_advance = false;  // a ray-casting method, replaced when --visibility names another class
  // The message for exit code 2 when the options do not fit this method, else empty (null: any
  // options fit).
  std::string (*check)(const ViewerOptions& options) = nullptr;
  // The method's renderer for `input` (which must outlive it). A failure ends the run with
  // exit code 1.
  Result<std::unique_ptr<FrameRenderer>> (*make)(const MethodInput& input) = nullptr;
  // The line frontier-view prints on stderr after the frame (with its newline).
  std::string (*summary)(const MethodInput& input, const Frame& frame) = nullptr;
};

// The rows, --method's first.
const std::vector<ViewMethod>& view_methods();
// The row that renders with `options` (see the top of this file). REQUIRES: --method and
// --visibility hold values CLI11 checked against the table.
const ViewMethod& pick_method(const ViewerOptions& options);

// --method's choices and its help text (every "--method" row with its help and options).
std::vector<std::string> method_names();
std::string method_help();

}  // namespace frontier
