// One call to render a complete frame with any method, for the command line, tests and
// benchmarks. Brute force and ray walking resolve every pixel per ray; frustum casting runs
// its job queue to completion (or to a budget).
#pragma once

#include "src/core/counters.h"
#include "src/engine/frustum.h"
#include "src/engine/kdtree.h"
#include "src/core/sample_buffer.h"
#include "src/core/scene.h"
#include "src/engine/shading.h"
#include "src/core/view.h"

#include <memory>
#include <string>
#include <vector>

namespace frontier {

enum class Method { Brute, RayWalk, Frustum };

// Parses "brute", "raywalk", "frustum".
bool parse_method(const std::string& name, Method& method);
const char* method_name(Method method);

struct RenderOptions {
  Method method = Method::Frustum;
  int threads = 0;          // 0: all cores
  bool shade = true;        // false: visibility only (ids), no lighting work
  bool shadows = true;      // deferred shadow effect (only if the scene declares lights)
  FrameBudget budget;       // frustum casting only
  int leaf_pixels = FrustumCaster::kDefaultLeafPixels;  // frustum casting: walk-per-pixel size
};

// Renders frames of one scene and tree, keeping what a viewer keeps between frames (the
// frustum caster with its per-cell lists and pixel stamps, cell marks, the thread arena), so
// each frame pays for its own work only. The first frame allocates per-cell state (for a
// million-triangle tree that is several times the cost of the frame itself).
class Renderer {
 public:
  // `threads` render threads (0: all cores).
  Renderer(const Scene& scene, const KdTree& tree, int threads);
  ~Renderer();
  // Renders `view` into `buffer` (which keeps per-pixel first-hit primitive, t and colour) and
  // reconstructs unsampled pixels. options.threads is the constructor's. Returns the counters.
  Counters render(const View& view, const RenderOptions& options, SampleBuffer& buffer);

 private:
  const Scene& scene_;
  const KdTree& tree_;
  int threads_;
  Shader shader_;
  CellMarks marks_;
  std::unique_ptr<FrustumCaster> caster_;  // made on first use
  struct Arena;
  std::unique_ptr<Arena> arena_;
};

// One frame with a fresh Renderer.
Counters render_frame(const Scene& scene, const KdTree& tree, const View& view,
                      const RenderOptions& options, SampleBuffer& buffer);

// The id image: per pixel the source id of the first-hit primitive, kNoPrim for background or
// unsampled pixels. Row-major, top row first.
std::vector<uint32_t> id_image(const Scene& scene, const SampleBuffer& buffer);

}  // namespace frontier
