// Rendering a complete frame by ray casting, for the command line, tests and benchmarks. Brute
// force and ray walking resolve every pixel per ray; frustum casting runs its job queue to
// completion (or to a budget). RayCastFrameRenderer puts all three behind the FrameRenderer
// interface (src/engine/frame_renderer.h) that every rendering method shares.
#pragma once

#include "src/core/counters.h"
#include "src/engine/frame_renderer.h"
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

// How Renderer finds each pixel's first hit. Which method of all (ray casting or another) a
// frame is rendered with is the caller's choice of FrameRenderer; this picks among the three
// ray-casting strategies inside one.
enum class Method { Brute, RayWalk, Frustum, Packet };

// "brute", "raywalk", "frustum", "packet" (4x4 pixel blocks traced as ray packets,
// src/engine/packet.h).
const char* method_name(Method method);

struct RenderOptions {
  Method method = Method::Frustum;
  int threads = 0;          // 0: all cores
  bool shade = true;        // false: visibility only (ids), no lighting work
  bool shadows = true;      // deferred shadow effect (only if the scene declares lights)
  FrameBudget budget;       // frustum casting only
  int leaf_pixels = FrustumCaster::kDefaultLeafPixels;  // frustum casting: walk-per-pixel size
  // Frustum casting and packets: rays through Embree's BVH with frontier's exact tests
  // (prim_accel.h) or through the k-d tree, whichever is faster on the scene (KernelChoice,
  // measured as they run); false: the k-d tree alone. The same hits either way.
  bool accel = true;
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
  std::unique_ptr<class PacketLayout> layout_;  // made on first use of Method::Packet
  std::unique_ptr<PrimAccel> accel_;            // made on first use of Method::Packet with accel
  KernelChoice kernel_choice_;                  // Method::Packet: Embree's BVH or the k-d tree
  struct Arena;
  std::unique_ptr<Arena> arena_;
};

// Ray casting as a FrameRenderer: a Renderer and its sample buffer kept from frame to frame.
// stats: Counters::to_json() plus method, width, height, primitives, cells and
// shadows_declared (whether the scene has lights). `scene` and `tree` must outlive it.
class RayCastFrameRenderer final : public FrameRenderer {
 public:
  RayCastFrameRenderer(const Scene& scene, const KdTree& tree, const RenderOptions& options);
  Result<Frame> render(const View& view) override;

 private:
  const Scene& scene_;
  const KdTree& tree_;
  RenderOptions options_;
  Renderer renderer_;
  SampleBuffer buffer_;
};

// One frame with a fresh Renderer.
Counters render_frame(const Scene& scene, const KdTree& tree, const View& view,
                      const RenderOptions& options, SampleBuffer& buffer);

// The id image: per pixel the source id of the first-hit primitive, kNoPrim for background or
// unsampled pixels. Row-major, top row first.
std::vector<uint32_t> id_image(const Scene& scene, const SampleBuffer& buffer);

}  // namespace frontier
