// Curved primitives turned into triangles: for consumers that only take triangle soups (the
// walk-mode collision grid, triangle-only ray tracers benchmarked against frontier) and as the
// "tessellated" baseline the immediate-mode paper compares exact quadrics against.
//
// Shapes and their meshes (every vertex lies exactly on the true surface, up to rounding, so the
// mesh is inscribed: it never sticks out of the primitive's bounds):
//  * Sphere: a latitude/longitude mesh with `n` meridians and max(3, ceil(n / 2)) parallels, poles on
//    the z axis; closed (every edge shared by exactly two triangles, vertices bit-identical
//    where they meet), 2 n (max(3, ceil(n / 2)) - 1) triangles.
//  * Cone (NFF `c`, open at both ends): `n` side quads as two triangles each, one where a radius
//    is zero (a pointed end); no caps, as NFF declares.
//  * Box: 12 triangles, closed.
//  * Quadric: NOT tessellated faithfully; replaced by the surface of its bounding box (what the
//    collision grid wants: conservative). Counted in TessellateStats::quadrics_as_boxes so a
//    caller that renders can refuse or report it.
//  * Triangle: passed through unchanged (shading normals too).
// Chord error of a circle of radius r cut into n segments: r (1 - cos(pi / n)).
#pragma once

#include "src/core/primitives.h"
#include "src/core/scene.h"

#include <array>
#include <cstdint>
#include <vector>

namespace frontier {

struct TessellateOptions {
  static constexpr int kDefaultSegments = 24;  // chord error 0.86% of the radius: a sphere
                                               // 100 px across is off by under half a pixel
  // Segments around a full circle, used when max_chord_error is 0. Clamped to >= 3.
  int segments = kDefaultSegments;
  // When > 0, each primitive gets the fewest segments (within [min_segments, max_segments]) whose
  // mesh lies within this distance of the true surface: cones by their larger radius, spheres
  // with half the error per direction because their quads bulge along two curves.
  double max_chord_error = 0.0;
  int min_segments = 6;
  int max_segments = 256;
  // Scene output only: give sphere and cone triangles the true surface normals at their vertices
  // (smooth shading). Makes Scene::triangle_normals non-empty for the whole scene.
  bool smooth_normals = true;
};

struct TessellateStats {
  uint64_t triangles_in = 0;        // passed through
  uint64_t triangles_out = 0;       // in the output scene (passed through + generated)
  uint64_t quadrics_as_boxes = 0;   // quadrics replaced by their bounding box surface
  uint64_t degenerate_dropped = 0;  // zero-area triangles not emitted (flat boxes, zero radii)
};

// The segments tessellate_primitive gives a circle of radius r: options.segments, or with a
// chord error the fewest meeting it, clamped to [min_segments, max_segments].
int tessellation_segments(double radius, const TessellateOptions& options);

// Appends the triangles of scene primitive `i` to `out` and, when `normals` is not null, one
// per-vertex normal triple per triangle (the surface's true normals for spheres and cones, the
// shading normals or geometric normal otherwise). May append zero-area triangles for degenerate
// input (a flat box); appends nothing for a sphere of radius <= 0 or a cone with a zero-length
// axis or two zero radii. REQUIRES: i < scene.size().
void tessellate_primitive(std::vector<Triangle>& out, std::vector<std::array<Vec3, 3>>* normals,
                          const Scene& scene, uint32_t i, const TessellateOptions& options = {});

// A scene of triangles only: every primitive of `scene` tessellated in order, each output
// triangle keeping its input primitive's `source` and `material` (so id images stay comparable
// with the input scene's), zero-area triangles dropped. Materials, lights, camera, background
// and input_primitives are copied. `stats` may be null.
Scene tessellate(const Scene& scene, const TessellateOptions& options = {}, TessellateStats* stats = nullptr);

}  // namespace frontier
