// MesaFrameRenderer: the tessellated triangle stream through MesaRenderer's lit and id passes,
// ids mapped back from triangles to the input.
#include "viewer/mesa_frame_renderer.h"

#include <nlohmann/json.hpp>

namespace frontier {

Result<std::unique_ptr<MesaFrameRenderer>> MesaFrameRenderer::create(const Scene& scene,
                                                                     const TessellatedOptions& options,
                                                                     std::unique_ptr<MesaRenderer> mesa) {
  std::unique_ptr<MesaFrameRenderer> r(new MesaFrameRenderer(scene, options, std::move(mesa)));
  if (Status s = r->mesa_->set_scene(r->tessellated_.tessellated_scene()); !s) return s;
  return r;
}

Result<Frame> MesaFrameRenderer::render(const View& view) {
  const std::vector<uint32_t> triangle_order = tessellated_.triangle_order(view);
  MesaOptions options;
  options.cull_back_faces = tessellated_.options().cull_back_faces;
  options.id_kind = MesaIdKind::Primitive;  // triangle indices, mapped to the input below
  auto lit = mesa_->render(view, &triangle_order, options);
  if (!lit) return lit.status();
  std::vector<uint32_t> triangle_ids;
  if (Status s = mesa_->ids(view, triangle_ids, &triangle_order, options); !s) return s;

  Frame frame;
  frame.ids = std::move(triangle_ids);
  for (uint32_t& id : frame.ids) {
    if (id != kNoPrim) id = tessellated_.triangle_prim(id);
  }
  frame.ids = source_ids(scene_, std::move(frame.ids));
  frame.colors = std::move(lit->colors);
  frame.ms = lit->frame_ms;
  frame.stats = {{"renderer", mesa_->renderer()},         {"triangles_issued", lit->triangles_issued},
                 {"vertices_lit", lit->vertices_lit},     {"pixels_covered", lit->pixels_covered},
                 {"samples_passed", lit->samples_passed}, {"lights_used", lit->lights_used},
                 {"lights_dropped", lit->lights_dropped}, {"ms", lit->frame_ms}};
  tessellated_.add_stats(frame.stats, "mesa", view);
  return frame;
}

}  // namespace frontier
