// The scan-conversion baseline of the immediate-mode ray-casting paper, on frontier's own
// rasterizer: every curved primitive tessellated (src/core/tessellate.h), every vertex of every
// issued triangle lit (per-vertex lighting, as fixed-function OpenGL), colours interpolated
// across the winning triangle (perspective-correct Gouraud). Its counters are the paper's
// Mesa columns: triangles issued, vertices lit, pixels covered.
#pragma once

#include "src/engine/frame_renderer.h"
#include "src/raster/imr.h"
#include "src/engine/kdtree.h"
#include "src/raster/raster.h"
#include "src/core/scene.h"
#include "src/engine/shading.h"
#include "src/core/tessellate.h"
#include "src/core/view.h"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace frontier {

struct TessellatedOptions {
  int segments = 8;  // around a full circle (TessellateOptions::segments)
  IssueOrder order = IssueOrder::kInput;
  uint64_t seed = 1;
  bool cull_back_faces = false;  // NFF cones are open: culling would hide their insides
  int threads = 0;
};

struct TessellatedCounters {
  uint64_t triangles_issued = 0;
  uint64_t vertices_lit = 0;     // 3 per triangle issued (non-indexed, as glDrawArrays)
  uint64_t shading_ops = 0;      // lighting evaluations (per vertex and light)
  uint64_t pixels_covered = 0;   // fragments rasterized
  uint64_t depth_passes = 0;     // fragments written
  double order_ms = 0.0, light_ms = 0.0, raster_ms = 0.0, interpolate_ms = 0.0;
  double ms = 0.0;

  nlohmann::json to_json() const;
};

class TessellatedRenderer {
 public:
  TessellatedRenderer(const Scene& scene, const TessellatedOptions& options = {});
  ~TessellatedRenderer();

  const TessellatedOptions& options() const { return options_; }
  size_t triangles() const { return triangles_.size(); }
  // Scene primitive i's triangles: [first, last) in tessellated_scene() and in ids().
  std::pair<uint32_t, uint32_t> triangle_range(uint32_t i) const { return {first_[i], first_[i + 1]}; }
  // The scene primitive triangle k of the tessellation belongs to.
  uint32_t triangle_prim(uint32_t k) const { return triangle_prim_[k]; }
  // The triangle order a frame issues for `view` (the options' object order, each object's
  // triangles together): what another renderer is given to draw the same stream.
  std::vector<uint32_t> triangle_order(const View& view) const;

  TessellatedCounters render(const View& view);
  // The last frame: ids() are indices into the tessellation (see prim_ids()), colors() lit.
  Rasterizer& rasterizer() { return *raster_; }
  // The last frame's id image as scene primitive indices (kNoPrim: background).
  std::vector<uint32_t> prim_ids();
  // A triangles-only scene of the same tessellation (for other renderers: Mesa), each
  // triangle keeping its primitive's source and material.
  Scene tessellated_scene() const;
  // What the stats of a method drawing this tessellation name besides its counters:
  // add_issue_stats' keys, tessellation (segments around a circle) and triangles.
  void add_stats(nlohmann::json& stats, const char* method, const View& view) const;

 private:
  const Scene& scene_;
  TessellatedOptions options_;
  KdTree tree_;
  std::unique_ptr<Shader> shader_;
  std::vector<Triangle> triangles_;
  std::vector<std::array<Vec3, 3>> normals_;
  std::vector<uint32_t> triangle_prim_;  // per triangle: its scene primitive
  std::vector<uint32_t> first_;          // per primitive: its first triangle (size + 1 entries)
  std::vector<std::array<Rgb, 3>> vertex_colors_;
  std::unique_ptr<Rasterizer> raster_;
};

// The tessellated baseline as a FrameRenderer. stats: TessellatedCounters::to_json() plus
// TessellatedRenderer::add_stats' keys (method "tessellated"). `scene` must outlive it.
class TessellatedFrameRenderer final : public FrameRenderer {
 public:
  TessellatedFrameRenderer(const Scene& scene, const TessellatedOptions& options)
      : scene_(scene), tessellated_(scene, options) {}
  Result<Frame> render(const View& view) override;

 private:
  const Scene& scene_;
  TessellatedRenderer tessellated_;
};

}  // namespace frontier
