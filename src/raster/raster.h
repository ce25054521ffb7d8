// A software z-buffer rasterizer with the ray caster's camera: the rendering back end for the
// visibility-culling classes, immediate-mode ray casting and BSP rendering. It knows triangles,
// ids and a View, nothing of k-d trees or culling.
//
// Invariants (what makes a rasterized pixel comparable with the ray of view.ray(x, y)):
//  * Same camera: clip space is the inverse of the View's pixel-direction map, so pixel (x, y)
//    sits at integer screen coordinates (x, y) exactly where view.direction(x, y) points; the
//    near plane is the View's (hits nearer than `near` along the view axis do not exist).
//  * Coverage is decided by exact integer edge functions on vertices snapped to 2^-32 pixel, with
//    the top-left rule: a pixel centre on an edge shared by two triangles belongs to exactly one
//    of them, a centre on a shared vertex to exactly one triangle of the fan. No gaps, no double
//    hits, whatever the order or the thread count.
//  * Depth: the test runs on 1/w, which is affine in screen space; its plane equation comes from
//    the triangle's world-space plane, not from three projected (possibly clipped) vertices, so
//    it keeps full precision next to the near plane. The depth the buffer reports is the ray
//    parameter t along view.ray(x, y) (a Euclidean distance, like RayHit::t).
//  * Depth test: nearer wins; equal depth goes to the lower id. The result is a pure function of
//    the set of (triangle, id) submitted, independent of submission order and thread count.
//    Two modes change that on purpose: RasterOptions::depth_test = false (painter's: the last
//    triangle submitted wins) and surface bounds (submit_bound: the fragment's ray cast decides
//    what is written; see SurfaceProgram).
//
// Pipeline: submit() queues world-space triangles; flush() (run by submit() every
// kBatchTriangles and by every framebuffer accessor) sets them up in parallel (back-face and
// outside culling, Sutherland-Hodgman clipping of the homogeneous polygon against the near
// plane and a one-pixel band around the screen, snapping: src/raster/clip.h), bins them into
// square tiles and rasterizes tiles in parallel. Memory is bounded by the batch size, not the
// triangle count.
//
// Thread safety: one thread drives a Rasterizer; it uses up to `threads` workers internally.
#pragma once

#include "src/core/counters.h"
#include "src/core/primitives.h"
#include "src/core/sample_buffer.h"
#include "src/core/scene.h"
#include "src/core/view.h"
#include "src/raster/clip.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <vector>

namespace frontier {

class Shader;

struct RasterOptions {
  int threads = 0;               // 0: all cores
  bool cull_back_faces = false;  // drop triangles whose geometric normal (v1-v0)x(v2-v0) faces away
  int tile_size = 64;            // pixels per tile side
  // Near plane used when the View has none (near == 0): perspective projection needs w > 0.
  // 0 picks, per triangle, 1e-9 of its largest vertex w (so the result stays independent of
  // batching and order). Triangle parts nearer than this are lost where the ray caster would
  // see them; they cover pixels only if the triangle passes that close to the eye.
  double near_floor = 0.0;
  // false: painter's mode. Every covered fragment overwrites the pixel (id and 1/w), in
  // submission order, whatever its depth: BSP back-to-front rendering needs no depth test.
  bool depth_test = true;
};

struct RasterCounters {
  uint64_t submitted = 0;         // triangles submitted
  uint64_t clipped = 0;           // triangles that needed clipping (near plane or screen band)
  uint64_t near_clipped = 0;      // of those, cut by the near plane
  uint64_t culled_back = 0;       // back faces removed (only with cull_back_faces)
  uint64_t culled_outside = 0;    // entirely outside the view frustum or behind the near plane
  uint64_t culled_empty = 0;      // seen edge-on, or covering no pixel centre
  uint64_t fragments = 0;         // pixels inside a triangle, depth-tested
  uint64_t depth_passes = 0;      // fragments that passed the depth test (written)
  uint64_t skipped_primitives = 0;  // non-triangle primitives skipped (rasterize_scene's result only)
  // Bounds of implicit surfaces (submit_bound): a bound fragment that passes the depth test
  // casts one ray at its surface (immediate-mode ray casting).
  uint64_t surface_rays = 0;          // ray-surface tests cast from bound fragments
  uint64_t surface_hits = 0;          // of those, rays that met the surface
  uint64_t surface_writes = 0;        // hits that passed the depth test and were written
  uint64_t back_samples_culled = 0;   // hits discarded as back-facing (back-sample culling)
  double setup_ms = 0.0;          // culling, clipping, snapping, binning
  double raster_ms = 0.0;         // tile rasterization

  RasterCounters& operator+=(const RasterCounters& o);
};

// What a bound fragment's ray found on its surface.
enum class SurfaceHit : uint8_t { Miss, Hit, BackCulled };

// The per-fragment step of immediate-mode ray casting (Alex & Teller 1999, §2): triangles
// submitted with submit_bound() tessellate a conservative bound of an implicit surface; each of
// their fragments that passes the depth test calls cast(), which intersects view.ray(x, y) with
// surface `id` and, on a hit, returns the hit's 1/w (w: distance along the view axis, as the
// depth test compares), written only if it passes the depth test again.
// Thread safety: cast() is called concurrently from tile workers.
class SurfaceProgram {
 public:
  virtual ~SurfaceProgram() = default;
  // The whole ray is tested (a hit behind the stored sample still counts as a hit); the
  // rasterizer's second depth test decides what is written.
  virtual SurfaceHit cast(uint32_t id, int x, int y, double& inv_w) const = 0;
};

class Rasterizer {
 public:
  static constexpr int kSubpixelBits = 32;            // vertex snapping: 2^-32 pixel
  static constexpr size_t kBatchTriangles = 1 << 14;  // pending triangles before an automatic flush

  // REQUIRES: view.width, view.height in [1, 2^20].
  explicit Rasterizer(const View& view, const RasterOptions& options = {});
  ~Rasterizer();

  const View& view() const { return view_; }
  const RasterOptions& options() const { return options_; }
  // Whether this rasterizer renders `view` with `options` (so a renderer can keep it, with its
  // buffers and thread arena, from frame to frame instead of building a new one).
  bool matches(const View& view, const RasterOptions& options) const;

  // Empties the framebuffer (every pixel background, depth infinite) and drops pending
  // triangles. Counters are kept; reset_counters() zeroes them.
  void clear();
  void reset_counters() { counters_ = {}; }

  // Queues a world-space triangle. `id` is the caller's (kNoPrim is reserved for background).
  void submit(const Triangle& triangle, uint32_t id);
  // Queues a triangle of the bound of implicit surface `id`: its fragments are not written
  // themselves but cast a ray through `program` (see SurfaceProgram). REQUIRES: a program set.
  void submit_bound(const Triangle& triangle, uint32_t id);
  // The program bound fragments call; must outlive the flushes that use it (nullptr: none).
  void set_surface_program(const SurfaceProgram* program) { program_ = program; }
  // Rasterizes every queued triangle into the framebuffer.
  void flush();

  const RasterCounters& counters() const { return counters_; }

  // The projection the depth test uses (see ClipTransform). Consumers of inverse_depth() (a
  // depth pyramid) project with it to compare their own geometry with the buffer.
  const ClipTransform& clip_transform() const { return clip_; }
  // The near plane triangles are clipped at: View::near, else RasterOptions::near_floor; 0 when
  // neither is set (then chosen per triangle, 1e-9 of its largest vertex w).
  double near_plane() const { return view_.near > 0.0 ? view_.near : std::max(options_.near_floor, 0.0); }

  // Change tracking for incremental consumers. Tiles are options().tile_size pixels square,
  // numbered row by row (tile (tx, ty) is index ty * tiles_x() + tx, covering pixels from
  // (tx, ty) * tile_size, clipped to the image). generation() advances with every flush() that
  // had triangles and every clear(); a tile is stamped with the generation that last changed a
  // pixel of it (an id or a depth; clear() stamps them all).
  int tiles_x() const { return tiles_x_; }
  int tiles_y() const { return tiles_y_; }
  uint64_t generation() const { return generation_; }
  // Flushes, then returns, in increasing order, the tiles whose pixels changed after
  // `generation` (pass the generation() read after the previous call to see each change once).
  std::vector<int> tiles_changed_since(uint64_t generation);

  // Framebuffer (each flushes first). Row-major, top row first, index y * width + x.
  // id: the winning triangle's id, kNoPrim for background.
  uint32_t id(int x, int y);
  // Ray parameter t of the visible surface along view.ray(x, y), kInfinity for background.
  double depth(int x, int y);
  const std::vector<uint32_t>& ids();
  std::vector<double> depth_image();
  // 1/w per pixel (w: distance along the view axis), 0 for background: what the depth test uses.
  const std::vector<double>& inverse_depth();
  // depth(x, y) without the flush, for readers in parallel after ids() or inverse_depth().
  // REQUIRES: nothing submitted since that call.
  double depth_at(int x, int y) const;

  // Shading hook. REQUIRES: ids are indices into the scene `shader` was built for (as
  // rasterize_scene submits). Colours every pixel with shader.shade(id, view.ray(x, y), t) or
  // the shader's background, exactly as the ray caster shades a sample, and returns the
  // shading counters. colors() is empty until shade() runs.
  Counters shade(const Shader& shader, bool shadows);
  const std::vector<Rgb>& colors() const { return colors_; }
  // Colours computed elsewhere (one per pixel), e.g. immediate-mode ray casting's lighting.
  void set_colors(std::vector<Rgb> colors) { colors_ = std::move(colors); }

  // Copies the frame into `buffer` (resized, new frame, every pixel confirmed) so that
  // id_image(), image writers and reconstruction work on rasterized frames too.
  void to_sample_buffer(SampleBuffer& buffer);

  // A triangle after setup (defined in raster.cpp).
  struct Setup;

 private:
  Setup set_up(const Triangle& triangle, uint32_t id, RasterCounters& counters) const;
  bool set_depth_plane(const Triangle& triangle, const Vec3 (&from_eye)[3], Setup& s, RasterCounters& counters) const;
  void set_edges(const ClippedPolygon& polygon, const ClipPlanes& planes, Setup& s, RasterCounters& counters) const;
  void raster_tile(int tile, const Setup* setups, RasterCounters& counters);

  View view_;
  RasterOptions options_;
  tbb::task_arena arena_;
  ClipTransform clip_;  // world -> (x w, y w, w), pixel centres at integers
  int tiles_x_ = 0, tiles_y_ = 0;

  std::vector<Triangle> pending_;
  std::vector<uint32_t> pending_ids_;
  std::vector<uint8_t> pending_bound_;  // per pending triangle: 1 for a surface bound
  const SurfaceProgram* program_ = nullptr;
  std::vector<std::vector<uint32_t>> bins_;  // per tile: indices of this batch's setups, in order
  std::unique_ptr<Setup[]> setups_;          // kBatchTriangles, reused by every flush

  std::vector<double> inverse_depth_;  // 1/w, 0 = background
  std::vector<uint32_t> ids_;
  std::vector<Rgb> colors_;
  RasterCounters counters_;
  uint64_t generation_ = 0;
  std::vector<uint64_t> tile_generation_;  // per tile: the generation that last changed it
};

// Calls body(local, x, y, i) for every pixel i = y * width + x of `view` whose id is not kNoPrim,
// rows in parallel inside `arena`, `local` being the worker's locals.local(): the passes that
// shade a rasterized frame (`ids` is its Rasterizer::ids()).
template <class Local, class Body>
void for_each_covered_pixel(tbb::task_arena& arena, const View& view, const std::vector<uint32_t>& ids,
                            tbb::enumerable_thread_specific<Local>& locals, Body&& body) {
  arena.execute([&] {
    tbb::parallel_for(0, view.height, [&](int y) {
      Local& local = locals.local();
      for (int x = 0; x < view.width; ++x) {
        const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view.width) + static_cast<size_t>(x);
        if (ids[i] != kNoPrim) body(local, x, y, i);
      }
    });
  });
}

// Submits every triangle of `scene` with its primitive index as id (so ids()[i] indexes
// scene.prims, as SampleBuffer::prim does), skipping and counting the other kinds, and flushes.
// Returns the counters of this call.
RasterCounters rasterize_scene(const Scene& scene, Rasterizer& rasterizer);

}  // namespace frontier
