// Bounds of a model file, read in one streaming pass (constant memory): binary (either
// endianness) and ASCII PLY, NFF (spheres, cones, polygons) and OBJ vertices.
#pragma once

#include "src/core/geometry.h"
#include "src/core/status.h"

#include <string>

namespace frontier::gen {

// InvalidArgument for an unknown extension, Corruption (naming the file) for malformed input.
Result<Aabb> scan_model_bounds(const std::string& path);

}  // namespace frontier::gen
