// Quadric scenes of high depth complexity in the spirit of the SPD databases, written as NFF
// by frontier's own generators (not ports of the published ones), Z up:
//
//   rings   K^3 rings on a cubic lattice, each 12 spheres joined by 12 cylinders; neighbouring
//           rings turn to different planes so they interlock like chain mail.
//   tree    a seeded branching tree, depth K: 2^(K+1) - 1 truncated cones with a sphere at
//           every joint and leaf.
//   flake   a sphere-flake, depth K: every sphere carries 9 spheres of a third of its radius
//           spread over its outer hemisphere; (9^(K+1) - 1) / 8 spheres.
//   shells  a conical shell spiral of 200 K^2 overlapping spheres.
//
// Every file has a camera (`v`), a background, lights and a ground polygon.
#pragma once

#include "src/core/status.h"

#include <cstdint>
#include <string>

namespace frontier::gen {

enum class SphereFamily { Rings, Tree, Flake, Shells };

struct SpheresParams {
  SphereFamily family = SphereFamily::Rings;
  int size = 3;
  uint64_t seed = 1;
};

inline constexpr uint64_t kMaxQuadrics = 500'000'000;

// Primitive count (spheres + cones + polygons) of a scene, saturating on overflow.
uint64_t spheres_primitive_count(const SpheresParams& p);
Status validate(const SpheresParams& p);
Status write_spheres(const SpheresParams& p, const std::string& path, bool quiet);

}  // namespace frontier::gen
