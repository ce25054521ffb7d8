// Model files into an in-memory Scene: load_scene reads a whole file through the streaming
// readers (scene_reader.h); SceneBuilder adds input primitives one at a time, for callers that
// keep only batches in memory (frontier-build). Both keep the invariants stated at the top of
// load_scene.cpp: the i-th input primitive has source id i, degenerate primitives are dropped
// and counted in Scene::degenerate_dropped.
#pragma once

#include "src/core/scene.h"
#include "src/core/status.h"
#include "src/io/scene_reader.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace frontier {

// Reads a model file (NFF, PLY, OBJ, OFF, STL by extension) into memory through the streaming
// readers. Polygons are triangulated (concave ones correctly); zero-area triangles are dropped
// and counted in Scene::degenerate_dropped. Errors name the file and line or byte offset. A
// file with no primitives, or none left once degenerate ones are dropped, is an error too
// (no_primitives_error). The reader's warnings go to `warnings` when given, else to stderr.
Status load_scene(const std::string& path, Scene& scene, std::vector<std::string>* warnings = nullptr);

// The error for a model that holds nothing to build or draw: bad input (Corruption) for
// frontier-build and frontier-view alike. `input_primitives` is what the file holds; when it is
// not 0 they were all degenerate.
Status no_primitives_error(const std::string& path, uint64_t input_primitives);

// Adds input primitives to a Scene the way load_scene does: polygons triangulated, degenerate
// primitives dropped and counted in Scene::degenerate_dropped. The out-of-core builder uses it
// on batches of primitives.
class SceneBuilder {
 public:
  explicit SceneBuilder(Scene& scene) : scene_(scene) {}
  void add(const InputPrimitive& p, uint32_t source);

 private:
  void add_triangle(const InputPrimitive& p, uint32_t a, uint32_t b, uint32_t c, uint32_t source);
  void add_polygon(const InputPrimitive& p, uint32_t source);

  Scene& scene_;
  std::vector<std::array<uint32_t, 3>> triangles_;
};

}  // namespace frontier
