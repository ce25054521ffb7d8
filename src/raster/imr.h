// Immediate-mode ray casting (Alex & Teller 1999): curved primitives are issued to the z-buffer
// rasterizer as a conservative tessellated bounding polyhedron plus an implicit (quadric)
// surface; every bound fragment that passes the depth test casts one ray at the surface, and
// only the hit is written (§2). Polygons are rasterized as usual.
//
// Pieces, each usable alone:
//  * ImplicitSurface: a quadric (10 coefficients, §3.4) in a local frame (origin subtracted, so
//    far-from-origin objects keep their precision), up to 12 clip planes, optional texture
//    coordinates generated from two planes, and an optional capped-solid mode (§3.5).
//  * cast_surface(): the per-fragment ray test, with back-sample culling (§3.5).
//  * BoundingPolyhedron: slices/stacks as gluSphere/gluCylinder (§4.9), scaled so its faces
//    lie outside the surface (the closest face plane is at the surface's radius), closed.
//  * near_cap(): the polygon where the near plane cuts a bound (§3.2, the first method), so a
//    camera inside a bound still casts rays at its surface.
//  * ImrRenderer: a frame of a Scene, unordered or front to back along the k-d tree, with the
//    paper's counters (triangles issued, pixels covered, ray-object tests, hits, lighting).
//
// Sphere, cone (NFF `c`, open) and Quadric primitives are ray cast; triangles are rasterized;
// boxes are rasterized as their 12 triangles. Ids are scene primitive indices, so id images
// compare with ray casting's pixel for pixel.
#pragma once

#include "src/core/counters.h"
#include "src/engine/frame_renderer.h"
#include "src/engine/kdtree.h"
#include "src/core/primitives.h"
#include "src/raster/raster.h"
#include "src/core/scene.h"
#include "src/engine/shading.h"
#include "src/core/view.h"

#include <tbb/task_arena.h>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace frontier {

struct ImplicitSurface {
  static constexpr int kMaxClipPlanes = Quadric::kMaxClipPlanes;
  // World point p is local point p - origin.
  Vec3 origin{0.0};
  // A x² + B y² + C z² + D xy + E yz + F xz + G x + H y + I z + J in local coordinates;
  // f < 0 is the inside of the solid (for capping and back-sample classification).
  std::array<double, 10> coeff{};
  // Local planes; a point is kept when dot(plane.xyz, p) + plane.w <= 0 for every one.
  std::array<Vec4, kMaxClipPlanes> clip{};
  int clip_count = 0;
  // Capped clipped solid (§3.5): the solid {f <= 0} cut by the clip planes is closed by the
  // planes, so a ray entering through a plane hits the cap (normal: the plane's).
  bool capped = false;
  // Texture coordinates u = dot(texgen[0].xyz, p) + texgen[0].w, v likewise (local p).
  std::array<Vec4, 2> texgen{};
  bool textured = false;
  // Local box enclosing the kept surface (the ray is only tested inside it).
  Aabb bounds;
  uint32_t prim = 0;  // scene primitive index

  // f and its gradient at local point p.
  double value(const Vec3& p) const;
  Vec3 gradient(const Vec3& p) const;
  // Distance scale of the surface (for tolerances): the bounds' magnitude.
  double scale() const { return std::max(bounds.magnitude(), 1e-300); }
};

// A nearest ray sample on an implicit surface.
struct SurfaceSample {
  double t = kInfinity;  // along the world ray
  Vec3 normal{0.0};      // unit, outward (the gradient's direction, or the cap plane's)
  bool back = false;     // the ray leaves the solid here (normal faces along the ray)
  bool cap = false;      // on a clip plane of a capped solid
  bool culled = false;   // (no sample found) a back-facing sample was discarded
};

// Nearest sample of `surface` along `ray` with tmin <= t <= tmax. With back_sample_culling,
// back-facing samples are discarded (the next sample along the ray may still be taken).
// Counts nothing; the caller counts one ray-object test per call.
bool cast_surface(const ImplicitSurface& surface, const Ray& ray, double tmin, double tmax, bool back_sample_culling,
                  SurfaceSample& sample);

// The implicit surface of scene primitive i: spheres and cones exactly (a cone's two clip
// planes are its end discs; NFF cones are open, not capped), quadrics re-expressed about the
// centre of their bounds. Returns false for triangles and boxes.
bool implicit_surface_of(const Scene& scene, uint32_t i, ImplicitSurface& surface);

// Texture coordinates of world point p on `surface` (REQUIRES: surface.textured).
std::array<double, 2> texture_coordinates(const ImplicitSurface& surface, const Vec3& p);

// A closed convex polyhedron in a surface's local frame: triangles wound counter-clockwise seen
// from outside, and the outward face planes (dot(n, p) + w <= 0 inside, n unit).
struct BoundingPolyhedron {
  std::vector<Vec3> vertices;
  std::vector<std::array<uint32_t, 3>> faces;
  std::vector<Vec4> planes;

  size_t triangles() const { return faces.size(); }
  bool contains(const Vec3& local, double tolerance = 0.0) const;
};

// The bound of scene primitive i (REQUIRES: implicit_surface_of(scene, i) is true), in the
// local frame of its ImplicitSurface. Spheres: `slices` meridians and `stacks` parallels
// (gluSphere's layout, poles on z), vertices pushed out until every face plane is at least the
// radius from the centre. Cones: a `slices`-sided frustum whose sides touch the cone from
// outside, closed by its end polygons (fans). Quadrics: their bounding box. slices >= 3,
// stacks >= 2.
BoundingPolyhedron bounding_polyhedron(const Scene& scene, uint32_t i, int slices, int stacks);

// A box as 12 triangles, wound counter-clockwise seen from outside (how boxes are rasterized).
std::array<Triangle, 12> box_triangles(const Aabb& box);

// The polygon where the near plane {p : dot(p - eye, forward) = near} cuts `bound` (placed
// at `origin`), wound to face the eye; empty when the plane misses the bound.
std::vector<Vec3> near_cap(const BoundingPolyhedron& bound, const Vec3& origin, const View& view, double near);

// A curved primitive's bound as the rasterizer is given it: the polyhedron (local frame), where
// that frame sits in the world, and a world sphere around the polyhedron (the near-plane test).
struct CurvedBound {
  BoundingPolyhedron polyhedron;
  Vec3 origin{0.0};  // the ImplicitSurface's
  Vec3 centre{0.0};  // world
  double radius = 0.0;
};
// The bound of scene primitive i, whose surface is `surface` (implicit_surface_of(scene, i)).
CurvedBound curved_bound(const Scene& scene, uint32_t i, const ImplicitSurface& surface, int slices, int stacks);

// What issuing bounds cost.
struct BoundIssueCounters {
  uint64_t triangles = 0;   // bound and cap triangles issued (culled back faces included)
  uint64_t back_faces = 0;  // of those, bound faces facing away (not sent to the rasterizer)
  uint64_t near_caps = 0;   // bounds the near plane cut (a cap was sent)
};

// The near plane bound fragments cast their rays from: view.near, or, without one, 1e-7 of
// the scene's magnitude (nearer hits are lost).
double surface_near(const View& view, const Aabb& scene_bounds);

// Sends `bound` to `raster` as surface-bound triangles with `id` (Rasterizer::submit_bound):
// its faces that face the eye (the bound is closed and convex, so the others are hidden by
// them) and, where the near plane `near` cuts it, a cap just beyond that plane, so that a
// camera inside the bound still casts rays at its surface (§3.2). The rasterizer's surface
// program must know surface `id` before the next flush.
void issue_curved(Rasterizer& raster, const CurvedBound& bound, const View& view, double near, uint32_t id,
                  BoundIssueCounters& counters);

// The unit normal a sample at world point p of `surface` is lit with: the gradient's direction
// (`fallback` where it vanishes), or on a capped solid's clip plane, the plane's.
Vec3 surface_normal(const ImplicitSurface& surface, const Vec3& p, const Vec3& fallback);

// The per-fragment ray cast of immediate-mode ray casting for implicit surfaces keyed by the
// rasterizer id their bounds are submitted with: a fragment of id k casts view.ray(x, y) at
// surface k from the near plane on. Ids may be sparse (scene primitive indices) or dense
// (a frame's submission indices). Precomputes per surface what all its fragments share.
// Thread safety: cast() runs concurrently in the rasterizer's workers; the other members only
// between flushes.
class SurfaceCaster final : public SurfaceProgram {
 public:
  // The frame's view and near plane (surface_near), and whether back-facing samples are
  // discarded (§3.5); recomputes the shared terms of every surface held.
  void begin_frame(const View& view, double near, bool back_sample_culling);
  // Surface `id` is `surface` (replacing any), for the frame begun.
  void set(uint32_t id, const ImplicitSurface& surface);
  // Forgets every surface.
  void clear();
  // The surface of id, or null. A caller may change a surface between frames (capping, texture
  // planes): begin_frame() takes it into account.
  const ImplicitSurface* surface(uint32_t id) const;
  ImplicitSurface* surface(uint32_t id) {
    return const_cast<ImplicitSurface*>(static_cast<const SurfaceCaster*>(this)->surface(id));
  }
  // Surfaces held.
  size_t size() const { return surfaces_.size(); }

  SurfaceHit cast(uint32_t id, int x, int y, double& inv_w) const override;

 private:
  struct Local {
    Vec3 eye{0.0};       // the eye in the surface's local frame
    Aabb box;            // the bounds grown by the cast tolerance
    double radius2 = 0;  // > 0: a whole sphere about the local origin
    double eye_c = 0;    // |eye|² - radius2
  };
  Local local(const ImplicitSurface& surface) const;

  View view_;
  double near_ = 0.0;
  bool back_sample_culling_ = false;
  std::vector<int32_t> slot_;  // per id: into surfaces_ and frame_, or -1
  std::vector<ImplicitSurface> surfaces_;
  std::vector<Local> frame_;
};

// The order objects are issued in: the scene's, a seeded random permutation (the paper's
// "unordered"), front to back along the k-d tree (each primitive at its first cell), or sorted
// by the distance from the eye to the primitive (nearest first, no tree).
enum class IssueOrder { kInput, kRandom, kFrontToBack, kNearestFirst };
IssueOrder parse_issue_order(const std::string& name, bool& ok);
const char* issue_order_name(IssueOrder order);
// Every primitive of `scene` once, in `order` (front to back: depth first through `tree`, the
// child on the eye's side first, each primitive at the first cell that references it, a cell's
// new primitives sorted by the distance from the eye to their bounds; then any primitive no
// cell references). Adds the k-d nodes visited to *nodes_visited when not null.
std::vector<uint32_t> issue_order(const Scene& scene, const KdTree& tree, const Vec3& eye, IssueOrder order,
                                  uint64_t seed, uint64_t* nodes_visited = nullptr);

// What the stats of a method issuing objects in `order` name besides its counters: method,
// order, width, height and primitives (the scene's).
void add_issue_stats(nlohmann::json& stats, const char* method, IssueOrder order, const View& view,
                     size_t primitives);

struct ImrOptions {
  // Bound meridians / sides (the paper's "tessellation value"). 6 (with 3 stacks): 24
  // triangles per sphere, 20 per cone, silhouettes ~90% tight (bench_imr, Tables 9–10).
  int slices = 6;
  int stacks = 0;                    // sphere parallels; 0: max(2, slices / 2)
  IssueOrder order = IssueOrder::kInput;
  uint64_t seed = 1;                 // for IssueOrder::kRandom
  bool back_sample_culling = false;  // §3.5; off: rays see the inside of open surfaces, as RC
  bool cull_back_faces = false;      // polygons (bounds are closed: their back faces are always culled)
  bool shadows = false;              // the deferred shadow effect (only if the scene has lights)
  int threads = 0;                   // 0: all cores
};

struct ImrCounters {
  uint64_t objects = 0;            // implicit surfaces issued
  uint64_t polygons = 0;           // scene triangles (and box faces) issued
  uint64_t triangles_issued = 0;   // bound + cap + polygon triangles sent to the rasterizer
  uint64_t bound_back_faces = 0;   // of those, bound faces culled as facing away (not rasterized)
  uint64_t near_caps = 0;          // bounds the near plane cut (a cap was issued)
  uint64_t pixels_covered = 0;     // fragments rasterized (bounds and polygons)
  uint64_t ray_object_tests = 0;   // rays cast at surfaces (bound fragments that passed the depth test)
  uint64_t ray_object_hits = 0;
  uint64_t surface_writes = 0;     // hits written (passed the depth test again)
  uint64_t back_samples_culled = 0;
  uint64_t immediate_lighting = 0; // lighting an immediate-mode pipeline would do: one per write
  uint64_t lit_pixels = 0;         // pixels lit here (lighting is deferred to the final image)
  uint64_t shading_ops = 0;        // lighting evaluations (per light) for those
  uint64_t texture_fetches = 0;    // textured surfaces only
  uint64_t nodes_visited = 0;      // k-d nodes (front-to-back order only)
  double order_ms = 0.0;
  double raster_ms = 0.0;          // setup + rasterization + ray casting
  double shade_ms = 0.0;
  double ms = 0.0;                 // the whole frame

  nlohmann::json to_json() const;
};

class ImrRenderer {
 public:
  // Precomputes the surfaces and their bounds (and the k-d tree for ordering and shading).
  ImrRenderer(const Scene& scene, const ImrOptions& options = {});
  ~ImrRenderer();

  const ImrOptions& options() const { return options_; }
  // Bound triangles for one frame, objects only (the paper's "IMR triangles").
  uint64_t bound_triangles() const { return bound_triangles_; }

  // Renders one frame (ids, depth, colours: see rasterizer()). Rays are cast from the view's
  // near plane; with View::near == 0, from 1e-7 of the scene's extent (nearer hits are lost).
  ImrCounters render(const View& view);
  // The last frame's framebuffer: ids() are scene primitive indices; colors() are lit.
  Rasterizer& rasterizer() { return *raster_; }

  // The surface of scene primitive i, or null. The mutable form lets a caller declare what the
  // scene format cannot (capping, texture planes) between frames; the bound stays as built.
  const ImplicitSurface* surface_of_prim(uint32_t i) const { return caster_.surface(i); }
  ImplicitSurface* surface(uint32_t i) { return caster_.surface(i); }

 private:
  void issue(uint32_t prim, const View& view, double near, ImrCounters& counters);
  void shade(const View& view, ImrCounters& counters);
  Rgb shade_sample(uint32_t prim, const Ray& ray, double depth, Counters& shading, uint64_t& fetches) const;

  const Scene& scene_;
  ImrOptions options_;
  KdTree tree_;
  std::unique_ptr<Shader> shader_;
  SurfaceCaster caster_;                // the surfaces, keyed by scene primitive
  std::vector<CurvedBound> bounds_;
  std::vector<int32_t> bound_index_;    // per scene primitive: into bounds_, or -1
  uint64_t bound_triangles_ = 0;
  std::unique_ptr<Rasterizer> raster_;
  tbb::task_arena arena_;  // options_.threads workers, for the shading pass
};

// Immediate-mode ray casting as a FrameRenderer. stats: ImrCounters::to_json() plus
// bound_triangles and add_issue_stats' keys (method "imr"). `scene` must outlive it.
class ImrFrameRenderer final : public FrameRenderer {
 public:
  ImrFrameRenderer(const Scene& scene, const ImrOptions& options) : scene_(scene), imr_(scene, options) {}
  Result<Frame> render(const View& view) override;

 private:
  const Scene& scene_;
  ImrRenderer imr_;
};

}  // namespace frontier
