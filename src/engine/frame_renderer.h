// One interface for every way frontier renders a complete frame of an in-memory model: a View
// in; the image, the per-pixel input ids and the method's counters out. Ray casting (brute
// force, ray walking, frustum casting: src/engine/render.h), the rasterizing visibility classes
// (src/raster/visibility.h), immediate-mode ray casting (src/raster/imr.h), the tessellated
// baseline (src/raster/gouraud.h), BSP trees (src/raster/bsp_render.h) and the Mesa baseline
// (viewer/mesa_frame_renderer.h) all implement it, so a caller (frontier-view's method table,
// tests) picks a method by name and treats every frame alike.
//
// Invariants every implementation keeps:
//  * colors and ids have view.width * view.height entries, row-major, top row first (pixel
//    (x, y) is what view.ray(x, y) sees);
//  * ids are input ids (PrimRef::source: the NFF object or mesh face before triangulation), so
//    id images of different methods compare pixel for pixel; kNoPrim marks background;
//  * stats is a JSON object of the method's own counters and settings (what frontier-view's
//    --stats writes, its keys are the method's), and ms is the frame's time as the method
//    measures it (what frontier-view prints).
#pragma once

#include "src/core/sample_buffer.h"
#include "src/core/scene.h"
#include "src/core/status.h"
#include "src/core/view.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <vector>

namespace frontier {

struct Frame {
  std::vector<Rgb> colors;
  std::vector<uint32_t> ids;  // input (source) ids; kNoPrim: background
  nlohmann::json stats = nlohmann::json::object();
  double ms = 0.0;
};

// Thread safety: one thread renders with a FrameRenderer at a time; implementations use their
// own worker threads inside render().
class FrameRenderer {
 public:
  virtual ~FrameRenderer() = default;
  // Renders `view` completely. Errors come from outside the program (a driver that fails, a
  // view the renderer cannot take: see the implementation's contract).
  virtual Result<Frame> render(const View& view) = 0;
};

// Replaces scene primitive indices (kNoPrim kept) by their input ids: the id image of a method
// whose buffer holds indices into scene.prims.
std::vector<uint32_t> source_ids(const Scene& scene, std::vector<uint32_t> prim_ids);

}  // namespace frontier
