// The Mesa baseline as a FrameRenderer: the scene tessellated exactly as the tessellated method
// does it (src/raster/gouraud.h: same segments, same object order, same triangle stream), drawn
// through real OpenGL by a MesaRenderer (viewer/mesa_renderer.h), with a lit pass for the image
// and an id pass for the ids. Comparing it with the tessellated method compares two rasterizers
// on one input.
#pragma once

#include "src/engine/frame_renderer.h"
#include "src/raster/gouraud.h"
#include "viewer/mesa_renderer.h"

#include <memory>

namespace frontier {

class MesaFrameRenderer final : public FrameRenderer {
 public:
  // Tessellates `scene` with `options` and hands the triangles to `mesa` (set_scene). Returns
  // set_scene's error when it fails. `scene` must outlive the renderer.
  static Result<std::unique_ptr<MesaFrameRenderer>> create(const Scene& scene, const TessellatedOptions& options,
                                                           std::unique_ptr<MesaRenderer> mesa);

  // stats: the MesaFrame's counters (renderer, triangles_issued, vertices_lit, pixels_covered,
  // samples_passed, lights_used, lights_dropped, ms) plus TessellatedRenderer::add_stats' keys
  // (method "mesa"). Errors: the view's size is not the MesaRenderer's, or a GL error.
  Result<Frame> render(const View& view) override;

 private:
  MesaFrameRenderer(const Scene& scene, const TessellatedOptions& options, std::unique_ptr<MesaRenderer> mesa)
      : scene_(scene), tessellated_(scene, options), mesa_(std::move(mesa)) {}

  const Scene& scene_;
  TessellatedRenderer tessellated_;
  std::unique_ptr<MesaRenderer> mesa_;
};

}  // namespace frontier
