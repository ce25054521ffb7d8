// Per-frame counters. Each worker thread owns one Counters; a frame's total is their sum.
// They are what --stats writes and what proves that unrequested effects cost nothing.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <cstdint>

namespace frontier {

struct Counters {
  uint64_t rays = 0;                 // primary rays resolved (pixels given a first hit or none)
  uint64_t rays_walked = 0;          // primary rays walked individually through cells
  uint64_t packet_rays = 0;          // primary rays traced in packets (src/engine/packet.h)
  uint64_t packet_filter_tests = 0;  // lane x triangle edge tests of packets (before the exact test)
  uint64_t packet_leaves = 0;        // leaves packets entered (their lanes count in cell_visits)
  uint64_t accel_rays = 0;           // packet rays (meeting the scene's bounds) traced through Embree's BVH (prim_accel.h)
  uint64_t samples = 0;              // pixels confirmed this frame
  uint64_t cells_touched = 0;        // distinct cells a frustum or ray entered
  uint64_t cell_visits = 0;          // cell entries counted with repetition
  uint64_t frusta = 0;               // frustum jobs processed
  uint64_t frustum_fills = 0;        // frusta resolved by the one-element fill
  uint64_t frustum_lookaheads = 0;   // frusta resolved against the few elements found ahead
  uint64_t plane_tests = 0;          // element bounds classified against a frustum plane
  uint64_t primitives_tested = 0;    // distinct (element, frustum-or-ray) incidences examined
  uint64_t ray_primitive_tests = 0;  // ray/primitive intersection tests
  uint64_t hits = 0;                 // ray/primitive tests that hit
  uint64_t shading_ops = 0;          // lighting evaluations (one per sample and light)
  uint64_t specular_ops = 0;         // specular terms evaluated
  uint64_t shadow_rays = 0;
  uint64_t parks = 0;                // frusta and pixels parked on a missing cell (each time)
  double ms = 0.0;

  Counters& operator+=(const Counters& o);
  nlohmann::json to_json() const;
};

}  // namespace frontier
