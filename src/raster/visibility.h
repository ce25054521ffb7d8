// The visibility classes of the frustum-casting paper's §1.5 (Fig. 1) side by side, over the
// same k-d tree, the same paging and the same per-frame report (issue 7):
//
//   exhaustive      every cell and every primitive, every frame, into the z-buffer;
//   frustum-cull    hierarchical view-frustum culling of the k-d tree (Hoff §2): a node outside
//                   a frustum plane is rejected with its subtree, a node inside all of them is
//                   accepted with its subtree (no more tests below it), only straddling nodes
//                   test further; in straddling cells each primitive is tested; optional
//                   back-face culling; then rasterization;
//   occlusion-cull  the same front to back (near child first), and a node whose bounds are hidden
//                   behind what is already drawn (a CPU z-pyramid, src/raster/zpyramid.h) is skipped
//                   with its subtree;
//   frustum-advance frontier's frustum casting (src/engine/frustum.h; not rendered here);
//   portals         cells and portals (Hoff §4): the eye's room, then rooms seen through portals
//                   with the screen rectangle narrowed at each portal (src/raster/portals.h); only
//                   primitives in the rooms reached are drawn. When the eye is in no room (outside
//                   the building), frustum culling instead (counted).
//
// Every primitive kind is drawn: triangles, boxes as their 12 triangles, and curved primitives
// (spheres, cones, quadrics) as immediate-mode ray casting draws them (src/raster/imr.h, the
// same pieces): the bound's front faces (and a near-plane cap) are rasterized, each bound
// fragment that passes the depth test casts its pixel's ray at the surface, and only a hit is
// written, so a fragment that misses writes no depth (the z-pyramid stays conservative).
// All rasterizing classes are conservative: every primitive that can be seen is drawn, so the
// id image equals brute-force ray casting's except on exact ties and pixel centres exactly on
// an edge (tests/test_visibility.cpp). Back-face culling is only conservative for closed
// solids seen from outside (the generated buildings, spheres, tessellated SPD scenes); it is an
// option, and curved surfaces then drop back-facing samples (imr's back-sample culling).
//
// Paging: a cell whose page is not in memory is asked for. The order-independent classes
// (exhaustive, frustum-cull, portals) put it aside and draw it when it arrives; occlusion
// culling waits for it on the spot (what it draws first decides what it skips later). Cells
// already drawn may be evicted while the frame goes on (PagedWorld::sync_evicting), so a class
// whose working set exceeds the budget still completes its frame, reading pages again.
//
// Ids in the z-buffer are frame-local submission indices; a per-frame table maps them to the
// input primitive (source), material and geometric normal (curved primitives: their implicit
// surface, kept by the frame's SurfaceCaster), so that the image can be shaded after the cells
// it came from were evicted (flat normals for polygons, the surface's for curved hits; no
// shadows).
#pragma once

#include "src/core/counters.h"
#include "src/engine/frame_renderer.h"
#include "src/engine/kdtree.h"
#include "src/raster/imr.h"
#include "src/raster/raster.h"
#include "src/core/scene.h"
#include "src/engine/shading.h"
#include "src/core/view.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

namespace frontier {

class PortalGraph;
class DepthPyramid;

enum class Visibility { kExhaustive, kFrustumCull, kOcclusionCull, kFrustumAdvance, kPortals };
const char* visibility_name(Visibility v);
std::optional<Visibility> parse_visibility(std::string_view text);

struct CullOptions {
  Visibility visibility = Visibility::kFrustumCull;
  bool cull_back_faces = false;  // drop triangles facing away from the eye before rasterizing
                                 // (and back-facing samples of curved surfaces)
  int bound_slices = 6;          // curved primitives' bounds (ImrOptions::slices; stacks: half)
  int threads = 0;               // rasterizer threads (0: all cores)
  // Occlusion culling: triangles submitted between z-pyramid updates. Fewer updates cost less
  // but see less occlusion (the pyramid lags behind what is drawn; never wrong).
  uint32_t pyramid_batch = 1024;
};

struct CullCounters {
  uint64_t nodes_touched = 0;          // k-d tree nodes visited (interior and leaf)
  uint64_t nodes_tested = 0;           // of those, classified (frustum planes, portal regions)
  uint64_t cells_touched = 0;          // leaf cells whose primitives were examined
  uint64_t subtrees_accepted = 0;      // nodes found inside the frustum: subtree taken untested
  uint64_t subtrees_rejected = 0;      // nodes outside the frustum (or the portal regions)
  uint64_t occlusion_queries = 0;
  uint64_t subtrees_occluded = 0;      // nodes found hidden by the z-pyramid
  uint64_t primitives_touched = 0;     // primitive references examined
  uint64_t primitives_culled = 0;      // of those, outside the frustum or the portal regions
  uint64_t back_faces_culled = 0;      // triangles (box faces too) facing away
  uint64_t primitives_rasterized = 0;  // primitives submitted to the rasterizer (all kinds)
  uint64_t curved_primitives = 0;      // of those, spheres, cones and quadrics (bound + rays)
  uint64_t bound_triangles = 0;        // their bound and near-cap triangles rasterized
  uint64_t pixels_rasterized = 0;      // fragments depth-tested (bound fragments included)
  uint64_t surface_rays = 0;           // bound fragments that passed the depth test: rays cast
  uint64_t surface_hits = 0;           // of those, rays that met the surface
  uint64_t degenerate_primitives = 0;  // zero-size spheres and cones: nothing to draw (nor to hit)
  uint64_t skipped_primitives = 0;     // primitives of a kind the classes cannot draw (none known)
  uint64_t cells_waited = 0;           // missing cells this frame had to page in
  uint64_t cells_unavailable = 0;      // missing cells that could not come in (failed or too big)
  uint64_t rooms_visited = 0;          // portals: room visits
  uint64_t portals_tested = 0, portals_passed = 0;
  bool portal_fallback = false;        // portals: eye in no room, frustum culling used
  double pyramid_ms = 0.0;             // z-pyramid updates
  double raster_ms = 0.0;              // triangle setup and rasterization
  double ms = 0.0;                     // the whole frame

  nlohmann::json to_json() const;
};

// What the culling classes draw from: a k-d tree over a scene whose top cells may be missing.
// Top nodes keep their indices for the whole frame; everything else may be renumbered by
// fetch() (generation() changes).
class CullSource {
 public:
  virtual ~CullSource() = default;
  virtual const KdTree& tree() const = 0;
  virtual const Scene& scene() const = 0;
  virtual bool missing(int32_t /*cell*/) const { return false; }
  virtual void want(int32_t /*cell*/) {}
  // Waits for wanted cells and brings in what arrived. Returns false when nothing is pending
  // any more (what is still missing cannot come in).
  virtual bool fetch() { return false; }
  virtual uint64_t generation() const { return 0; }
  // The frame used world cell c (paging LRU and the store-cell count).
  virtual void used(int32_t /*cell*/) {}
};

// An in-memory tree and scene: nothing is ever missing.
class MemoryCullSource final : public CullSource {
 public:
  MemoryCullSource(const Scene& scene, const KdTree& tree) : scene_(scene), tree_(tree) {}
  const KdTree& tree() const override { return tree_; }
  const Scene& scene() const override { return scene_; }

 private:
  const Scene& scene_;
  const KdTree& tree_;
};

class CullingRenderer {
 public:
  // REQUIRES: options.visibility != kFrustumAdvance; `portals` outlives the renderer (may be
  // null: then kPortals always falls back to frustum culling).
  explicit CullingRenderer(const CullOptions& options, const PortalGraph* portals = nullptr);
  ~CullingRenderer();

  const CullOptions& options() const { return options_; }

  // Renders one complete frame of `view`, paging through `source`.
  CullCounters render(const View& view, CullSource& source);

  // The last frame. Source id per pixel (kNoPrim: background).
  std::vector<uint32_t> ids() const;
  // Ray parameter t per pixel (kInfinity: background).
  std::vector<double> depths() const;
  // Shades the last frame with `shader`'s lights and materials (flat normals for polygons, the
  // surface normal for curved primitives; no shadows).
  std::vector<Rgb> shade(const Shader& shader, Counters& counters) const;

 private:
  struct Item;
  struct Entry {
    uint32_t source = 0;
    uint32_t material = 0;
    Vec3 normal{0.0};
  };

  void traverse(Item root, bool front_to_back, std::vector<Item>* deferred);
  void draw_cell(int32_t cell, uint32_t mask);
  // Submits one triangle of primitive `ref` (back-face culling first); false when culled.
  bool draw_triangle(const Triangle& t, const PrimRef& ref);
  // Submits world primitive p's bound, its fragments casting rays at its surface.
  void draw_curved(const Scene& scene, uint32_t p, const PrimRef& ref);
  bool admit(const Aabb& box, uint32_t& mask);
  void reset_stamps();
  void update_pyramid();

  CullOptions options_;
  const PortalGraph* portals_ = nullptr;
  // Per frame.
  CullSource* source_ = nullptr;
  View view_;
  std::unique_ptr<Rasterizer> raster_;
  std::unique_ptr<DepthPyramid> pyramid_;
  std::vector<Entry> table_;
  SurfaceCaster caster_;          // curved primitives' surfaces, keyed by submission id
  double surface_near_ = 0.0;     // where their rays start (surface_near)
  std::vector<uint32_t> drawn_;   // per world primitive: frame stamp when submitted
  uint32_t stamp_ = 0;
  uint64_t generation_ = 0;
  uint64_t since_update_ = 0;     // triangles submitted since the z-pyramid was updated
  bool use_frustum_ = true, use_pyramid_ = false;
  std::vector<Aabb> regions_;     // portals: where drawn primitives must lie (empty: anywhere)
  struct Planes;
  std::unique_ptr<Planes> planes_;
  CullCounters counters_;
};

// A rasterizing visibility class over an in-memory scene and tree, as a FrameRenderer: frames
// are shaded flat (CullingRenderer::shade). stats: CullCounters::to_json() plus visibility,
// width, height, primitives and cells. REQUIRES: options.visibility is exhaustive,
// frustum-cull or occlusion-cull (portals needs a store's graph); `scene` and `tree` outlive it.
class CullingFrameRenderer final : public FrameRenderer {
 public:
  CullingFrameRenderer(const Scene& scene, const KdTree& tree, const CullOptions& options);
  Result<Frame> render(const View& view) override;

 private:
  MemoryCullSource source_;
  CullingRenderer renderer_;
  Shader shader_;
};

}  // namespace frontier
