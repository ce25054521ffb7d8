// Counters arithmetic and JSON form.
#include "src/core/counters.h"

#include <nlohmann/json.hpp>

namespace frontier {

Counters& Counters::operator+=(const Counters& o) {
  rays += o.rays;
  rays_walked += o.rays_walked;
  samples += o.samples;
  cells_touched += o.cells_touched;
  cell_visits += o.cell_visits;
  frusta += o.frusta;
  frustum_fills += o.frustum_fills;
  frustum_lookaheads += o.frustum_lookaheads;
  plane_tests += o.plane_tests;
  primitives_tested += o.primitives_tested;
  ray_primitive_tests += o.ray_primitive_tests;
  hits += o.hits;
  shading_ops += o.shading_ops;
  specular_ops += o.specular_ops;
  shadow_rays += o.shadow_rays;
  ms += o.ms;
  return *this;
}

nlohmann::json Counters::to_json() const {
  return {{"rays", rays},
          {"rays_walked", rays_walked},
          {"samples", samples},
          {"cells_touched", cells_touched},
          {"cell_visits", cell_visits},
          {"frusta", frusta},
          {"frustum_fills", frustum_fills},
          {"frustum_lookaheads", frustum_lookaheads},
          {"plane_tests", plane_tests},
          {"primitives_tested", primitives_tested},
          {"ray_primitive_tests", ray_primitive_tests},
          {"hits", hits},
          {"shading_ops", shading_ops},
          {"specular_ops", specular_ops},
          {"shadow_rays", shadow_rays},
          {"ms", ms}};
}

}  // namespace frontier
