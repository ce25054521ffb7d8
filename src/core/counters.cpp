// Counters arithmetic and JSON form.
#include "src/core/counters.h"

#include <nlohmann/json.hpp>

namespace frontier {

namespace {

// Every integer counter with its JSON name: one list, so that a counter cannot be summed but
// not reported, or the reverse.
struct Field {
  const char* name;
  uint64_t Counters::*member;
};
constexpr Field kFields[] = {
    {"rays", &Counters::rays},                       {"rays_walked", &Counters::rays_walked},
    {"samples", &Counters::samples},                 {"cells_touched", &Counters::cells_touched},
    {"cell_visits", &Counters::cell_visits},         {"frusta", &Counters::frusta},
    {"frustum_fills", &Counters::frustum_fills},     {"frustum_lookaheads", &Counters::frustum_lookaheads},
    {"plane_tests", &Counters::plane_tests},         {"primitives_tested", &Counters::primitives_tested},
    {"ray_primitive_tests", &Counters::ray_primitive_tests}, {"hits", &Counters::hits},
    {"shading_ops", &Counters::shading_ops},         {"specular_ops", &Counters::specular_ops},
    {"shadow_rays", &Counters::shadow_rays},         {"parks", &Counters::parks},
    {"packet_rays", &Counters::packet_rays},         {"packet_filter_tests", &Counters::packet_filter_tests},
    {"packet_leaves", &Counters::packet_leaves},     {"accel_rays", &Counters::accel_rays},
};

}  // namespace

Counters& Counters::operator+=(const Counters& o) {
  for (const Field& f : kFields) this->*f.member += o.*f.member;
  ms += o.ms;
  return *this;
}

nlohmann::json Counters::to_json() const {
  nlohmann::json j = nlohmann::json::object();
  for (const Field& f : kFields) j[f.name] = this->*f.member;
  j["ms"] = ms;
  return j;
}

}  // namespace frontier
