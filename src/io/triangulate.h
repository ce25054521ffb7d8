// Polygon triangulation for the readers' polygons (load_scene.cpp's SceneBuilder): ear clipping
// that keeps the input's winding in every triangle; see triangulate.cpp for the method.
#pragma once

#include "src/core/geometry.h"

#include <array>
#include <cstdint>
#include <vector>

namespace frontier {

// Splits a simple planar polygon (possibly concave, any winding) into n-2 triangles by ear
// clipping in its dominant projection plane; writes vertex index triples. Returns false if the
// polygon is degenerate beyond repair (the caller then drops and counts it).
bool triangulate_polygon(const std::vector<Vec3>& vertices, std::vector<std::array<uint32_t, 3>>& out);

}  // namespace frontier
