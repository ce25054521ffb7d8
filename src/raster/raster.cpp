// The z-buffer rasterizer: setup (cull, clip, snap), binning into tiles, tile rasterization.
//
// Exactness: snapped vertices are integers in units of 2^-kSubpixelBits pixel, bounded by the
// one-pixel band the polygon is clipped to (|coordinate| <= 2^53 for screens up to 2^20), so
// an edge function, a difference of two products of 54-bit integers, is exact in 128 bits.
// Exact edge functions are what make the top-left rule a partition: deciding E == 0 by the
// sign of (A, B) is the same as sampling at the pixel centre moved right by an infinitesimal e
// and down by e^2, a point on no edge, which lies in exactly one triangle of a mesh.
// Shared edges stay shared through clipping because an intersection is always interpolated
// from the edge's inside vertex towards its outside one, whichever triangle clips it
// (src/raster/clip.h, which the BSP coverage-mask renderer shares).
#include "src/raster/raster.h"

#include "src/engine/shading.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <memory>

namespace frontier {
namespace {

__extension__ typedef __int128 Int128;

// A triangle clipped by five planes has at most 8 vertices; rounding can in principle add a
// few (a vertex within rounding of a plane crossing it twice), so there is room for 16.
constexpr int kMaxVertices = 16;

// n as a double, within a few units in the last place (signed conversions only: cheaper than
// the library's and than unsigned ones).
double approximate(Int128 n) {
  const uint64_t low = static_cast<uint64_t>(n);
  return static_cast<double>(static_cast<int64_t>(n >> 64)) * 0x1p64 +
         static_cast<double>(static_cast<int64_t>(low >> 1)) * 2.0;
}

// One edge function along the rows of a triangle's bounding box: E(x) = step x + r >= 0 on row
// y, r advancing by dr per row, with a floating-point estimate of the crossing -r / step that
// only steers the exact search (clip_span).
struct EdgeWalk {
  Int128 step, r, dr;
  double crossing, dcrossing;
};

// Narrows [lo, hi] to the integers x with E(x) >= 0 (step != 0; empty: lo > hi). Exact: the
// estimated crossing is corrected by evaluating E, a step or two however far the estimate is
// off (at most the span's width).
void clip_span(const EdgeWalk& e, int64_t& lo, int64_t& hi) {
  auto inside = [&](int64_t x) { return e.step * x + e.r >= 0; };
  const double crossing = e.crossing;
  if (e.step > 0) {  // inside from the crossing on: the least inside x in [lo, hi + 1]
    int64_t x = crossing <= double(lo) ? lo : crossing > double(hi) ? hi + 1 : static_cast<int64_t>(std::ceil(crossing));
    while (x > lo && inside(x - 1)) --x;
    while (x <= hi && !inside(x)) ++x;
    lo = x;
  } else {  // inside up to the crossing: the greatest inside x in [lo - 1, hi]
    int64_t x = crossing >= double(hi) ? hi : crossing < double(lo) ? lo - 1 : static_cast<int64_t>(std::floor(crossing));
    while (x < hi && inside(x + 1)) ++x;
    while (x >= lo && !inside(x)) --x;
    hi = x;
  }
}

RasterCounters difference(const RasterCounters& after, const RasterCounters& before) {
  RasterCounters d;
  d.submitted = after.submitted - before.submitted;
  d.clipped = after.clipped - before.clipped;
  d.near_clipped = after.near_clipped - before.near_clipped;
  d.culled_back = after.culled_back - before.culled_back;
  d.culled_outside = after.culled_outside - before.culled_outside;
  d.culled_empty = after.culled_empty - before.culled_empty;
  d.fragments = after.fragments - before.fragments;
  d.depth_passes = after.depth_passes - before.depth_passes;
  d.skipped_primitives = after.skipped_primitives - before.skipped_primitives;
  d.setup_ms = after.setup_ms - before.setup_ms;
  d.raster_ms = after.raster_ms - before.raster_ms;
  return d;
}

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

struct Rasterizer::Setup {
  using Edge = EdgeFunction;  // in snapped units (X = x << kSubpixelBits)
  uint32_t id;
  bool bound;                  // a surface bound: fragments cast a ray (SurfaceProgram)
  int edge_count;              // 0: nothing to rasterize
  int x0, y0, x1, y1;          // inclusive pixel bounding box, inside the screen
  double inv_c, inv_x, inv_y;  // 1/w = inv_c + inv_x x + inv_y y
  Edge edges[kMaxVertices];
};

RasterCounters& RasterCounters::operator+=(const RasterCounters& o) {
  submitted += o.submitted;
  clipped += o.clipped;
  near_clipped += o.near_clipped;
  culled_back += o.culled_back;
  culled_outside += o.culled_outside;
  culled_empty += o.culled_empty;
  fragments += o.fragments;
  depth_passes += o.depth_passes;
  skipped_primitives += o.skipped_primitives;
  surface_rays += o.surface_rays;
  surface_hits += o.surface_hits;
  surface_writes += o.surface_writes;
  back_samples_culled += o.back_samples_culled;
  setup_ms += o.setup_ms;
  raster_ms += o.raster_ms;
  return *this;
}

Rasterizer::Rasterizer(const View& view, const RasterOptions& options)
    : view_(view),
      options_(options),
      arena_(options.threads > 0 ? options.threads : tbb::info::default_concurrency()) {
  clip_ = ClipTransform::of(view);
  options_.tile_size = std::max(options_.tile_size, 8);
  tiles_x_ = (view.width + options_.tile_size - 1) / options_.tile_size;
  tiles_y_ = (view.height + options_.tile_size - 1) / options_.tile_size;
  bins_.resize(static_cast<size_t>(tiles_x_) * static_cast<size_t>(tiles_y_));
  tile_generation_.resize(bins_.size());
  setups_ = std::make_unique_for_overwrite<Setup[]>(kBatchTriangles);
  clear();
}

Rasterizer::~Rasterizer() = default;

bool Rasterizer::matches(const View& v, const RasterOptions& o) const {
  return v.width == view_.width && v.height == view_.height && v.eye == view_.eye && v.base == view_.base &&
         v.step_x == view_.step_x && v.step_y == view_.step_y && v.near == view_.near && o.threads == options_.threads &&
         o.cull_back_faces == options_.cull_back_faces && std::max(o.tile_size, 8) == options_.tile_size &&
         o.near_floor == options_.near_floor && o.depth_test == options_.depth_test;
}

void Rasterizer::clear() {
  pending_.clear();
  pending_ids_.clear();
  pending_bound_.clear();
  inverse_depth_.assign(view_.pixels(), 0.0);
  ids_.assign(view_.pixels(), kNoPrim);
  colors_.clear();
  ++generation_;
  std::fill(tile_generation_.begin(), tile_generation_.end(), generation_);
}

void Rasterizer::submit(const Triangle& triangle, uint32_t id) {
  pending_.push_back(triangle);
  pending_ids_.push_back(id);
  pending_bound_.push_back(0);
  if (pending_.size() >= kBatchTriangles) flush();
}

void Rasterizer::submit_bound(const Triangle& triangle, uint32_t id) {
  pending_.push_back(triangle);
  pending_ids_.push_back(id);
  pending_bound_.push_back(1);
  if (pending_.size() >= kBatchTriangles) flush();
}

Rasterizer::Setup Rasterizer::set_up(const Triangle& tri, uint32_t id, RasterCounters& counters) const {
  Setup s;
  s.id = id;
  s.edge_count = 0;
  ++counters.submitted;
  const Vec3 from_eye[3] = {tri.v0 - view_.eye, tri.v1 - view_.eye, tri.v2 - view_.eye};
  if (!set_depth_plane(tri, from_eye, s, counters)) return s;

  Vec3 polygon[kMaxVertices], scratch[kMaxVertices];
  double farthest = 0.0;
  for (int k = 0; k < 3; ++k) {
    polygon[k] = clip_.to_clip * from_eye[k];
    farthest = std::max(farthest, std::abs(polygon[k].z));
  }
  const ClipPlanes planes = ClipPlanes::of(view_, options_.near_floor, farthest);
  const ClippedPolygon clipped = clip_to_view(polygon, scratch, 3, kMaxVertices, planes);
  if (clipped.size < 3) {
    ++counters.culled_outside;
    return s;
  }
  if (clipped.crossed != 0) {
    ++counters.clipped;
    if (clipped.crossed & 1u) ++counters.near_clipped;
  }
  set_edges(clipped, planes, s, counters);
  return s;
}

// Facing and the depth plane, from world space relative to the eye. det is the signed volume of
// (eye, v0, v1, v2): negative when the geometric normal faces the eye; zero edge-on (the ray
// caster never reports a hit on a triangle seen edge-on either). Returns false when culled.
bool Rasterizer::set_depth_plane(const Triangle& tri, const Vec3 (&from_eye)[3], Setup& s,
                                 RasterCounters& counters) const {
  const Vec3 normal = glm::cross(tri.v1 - tri.v0, tri.v2 - tri.v0);
  const double det = glm::dot(from_eye[0], normal);
  if (!(det != 0.0) || !std::isfinite(det)) {
    ++counters.culled_empty;
    return false;
  }
  if (options_.cull_back_faces && det > 0.0) {
    ++counters.culled_back;
    return false;
  }
  // A point p = eye + lambda * direction(x, y) of the plane has lambda = det / (n . direction).
  s.inv_c = glm::dot(normal, view_.base) / det;
  s.inv_x = glm::dot(normal, view_.step_x) / det;
  s.inv_y = glm::dot(normal, view_.step_y) / det;
  return true;
}

// Snapping, the box of pixel centres covered and the edge functions of a clipped triangle.
void Rasterizer::set_edges(const ClippedPolygon& polygon, const ClipPlanes& planes, Setup& s,
                           RasterCounters& counters) const {
  int64_t px[kMaxVertices], py[kMaxVertices];
  SnapBox box;
  if (!snap_polygon(polygon.vertices, polygon.size, kSubpixelBits, planes, px, py, box)) {
    ++counters.culled_outside;
    return;
  }
  // Pixel centres inside the box: ceil of the minimum, floor of the maximum.
  constexpr int64_t kOne = int64_t{1} << kSubpixelBits;
  s.x0 = static_cast<int>(std::max<int64_t>((box.xmin + kOne - 1) >> kSubpixelBits, 0));
  s.y0 = static_cast<int>(std::max<int64_t>((box.ymin + kOne - 1) >> kSubpixelBits, 0));
  s.x1 = static_cast<int>(std::min<int64_t>(box.xmax >> kSubpixelBits, view_.width - 1));
  s.y1 = static_cast<int>(std::min<int64_t>(box.ymax >> kSubpixelBits, view_.height - 1));
  if (s.x0 > s.x1 || s.y0 > s.y1) {
    ++counters.culled_empty;
    return;
  }
  s.edge_count = edge_functions(px, py, polygon.size, s.edges);
  if (s.edge_count == 0) ++counters.culled_empty;
}

void Rasterizer::raster_tile(int tile, const Setup* setups, RasterCounters& counters) {
  const int size = options_.tile_size;
  const int tx0 = (tile % tiles_x_) * size, ty0 = (tile / tiles_x_) * size;
  const int tx1 = std::min(tx0 + size, view_.width) - 1, ty1 = std::min(ty0 + size, view_.height) - 1;
  const size_t width = static_cast<size_t>(view_.width);
  double* const depth = inverse_depth_.data();
  uint32_t* const ids = ids_.data();
  const bool depth_test = options_.depth_test;
  bool changed = false;
  for (uint32_t index : bins_[static_cast<size_t>(tile)]) {
    const Setup& s = setups[index];
    const int x0 = std::max(s.x0, tx0), x1 = std::min(s.x1, tx1);
    const int y0 = std::max(s.y0, ty0), y1 = std::min(s.y1, ty1);
    auto nearer = [&](double inv, size_t i) { return inv > depth[i] || (inv == depth[i] && s.id < ids[i]); };
    auto fragment = [&](int x, int y) {
      const size_t i = static_cast<size_t>(y) * width + static_cast<size_t>(x);
      double inv = s.inv_c + s.inv_x * x + s.inv_y * y;
      if (inv > 0.0 && (!depth_test || nearer(inv, i))) {
        if (s.bound) {
          // The bound encloses the surface, so its fragment is never behind the surface's
          // hit: a bound fragment that fails the test hides a surface that would fail it too.
          ++counters.surface_rays;
          const SurfaceHit hit = program_->cast(s.id, x, y, inv);
          if (hit == SurfaceHit::BackCulled) ++counters.back_samples_culled;
          if (hit != SurfaceHit::Hit) return;
          ++counters.surface_hits;
          if (!(inv > 0.0) || (depth_test && !nearer(inv, i))) return;
          ++counters.surface_writes;
        }
        depth[i] = inv;
        ids[i] = s.id;
        ++counters.depth_passes;
        changed = true;
      }
    };
    // Each edge bounds x from one side on every row.
    if (x0 > x1 || y0 > y1) continue;
    EdgeWalk walk[kMaxVertices];
    const Int128 first_row = Int128(y0) << kSubpixelBits;
    for (int k = 0; k < s.edge_count; ++k) {
      const Setup::Edge& e = s.edges[k];
      EdgeWalk& w = walk[k];
      w.step = Int128(e.a) << kSubpixelBits;
      w.r = Int128(e.b) * (first_row - e.oy) + e.bias - Int128(e.a) * e.ox;
      w.dr = Int128(e.b) << kSubpixelBits;
      w.crossing = w.dcrossing = 0.0;
      if (e.a != 0) {
        const double scale = -1.0 / approximate(w.step);
        w.crossing = approximate(w.r) * scale;
        w.dcrossing = approximate(w.dr) * scale;
      }
    }
    for (int y = y0; y <= y1; ++y) {
      int64_t lo = x0, hi = x1;
      for (int k = 0; k < s.edge_count && lo <= hi; ++k) {
        const EdgeWalk& w = walk[k];
        if (w.step != 0) {
          clip_span(w, lo, hi);
        } else if (w.r < 0) {
          hi = lo - 1;
        }
      }
      if (lo <= hi) counters.fragments += static_cast<uint64_t>(hi - lo + 1);
      for (int x = static_cast<int>(lo); x <= static_cast<int>(hi); ++x) fragment(x, y);
      for (int k = 0; k < s.edge_count; ++k) {
        walk[k].r += walk[k].dr;
        walk[k].crossing += walk[k].dcrossing;
      }
    }
  }
  // Every depth pass changes its pixel (it raises (1/w, -id) strictly), so this stamps exactly
  // the tiles whose content changed. One task per tile: no other thread writes this entry.
  if (changed) tile_generation_[static_cast<size_t>(tile)] = generation_;
}

void Rasterizer::flush() {
  if (pending_.empty()) return;
  const size_t n = pending_.size();
  ++generation_;
  tbb::enumerable_thread_specific<RasterCounters> local;

  auto start = std::chrono::steady_clock::now();
  Setup* const setups = setups_.get();  // n <= kBatchTriangles: submit() flushes at that size
  arena_.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
      RasterCounters& c = local.local();
      for (size_t i = r.begin(); i != r.end(); ++i) {
        setups[i] = set_up(pending_[i], pending_ids_[i], c);
        setups[i].bound = pending_bound_[i] != 0;
      }
    });
  });
  // Binning in submission order (the result does not depend on it, the work split does).
  for (std::vector<uint32_t>& bin : bins_) bin.clear();
  const int size = options_.tile_size;
  for (size_t i = 0; i < n; ++i) {
    const Setup& s = setups[i];
    if (s.edge_count == 0) continue;
    for (int ty = s.y0 / size; ty <= s.y1 / size; ++ty) {
      for (int tx = s.x0 / size; tx <= s.x1 / size; ++tx) {
        bins_[static_cast<size_t>(ty) * static_cast<size_t>(tiles_x_) + static_cast<size_t>(tx)].push_back(
            static_cast<uint32_t>(i));
      }
    }
  }
  counters_.setup_ms += ms_since(start);

  start = std::chrono::steady_clock::now();
  arena_.execute([&] {
    tbb::parallel_for(0, tiles_x_ * tiles_y_, [&](int tile) { raster_tile(tile, setups, local.local()); });
  });
  counters_.raster_ms += ms_since(start);

  for (const RasterCounters& c : local) counters_ += c;
  pending_.clear();
  pending_ids_.clear();
  pending_bound_.clear();
}

std::vector<int> Rasterizer::tiles_changed_since(uint64_t generation) {
  flush();
  std::vector<int> tiles;
  for (size_t tile = 0; tile < tile_generation_.size(); ++tile) {
    if (tile_generation_[tile] > generation) tiles.push_back(static_cast<int>(tile));
  }
  return tiles;
}

uint32_t Rasterizer::id(int x, int y) {
  flush();
  return ids_[static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x)];
}

double Rasterizer::depth_at(int x, int y) const {
  const double inv = inverse_depth_[static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x)];
  return inv > 0.0 ? glm::length(view_.direction(x, y)) / inv : kInfinity;
}

double Rasterizer::depth(int x, int y) {
  flush();
  return depth_at(x, y);
}

const std::vector<uint32_t>& Rasterizer::ids() {
  flush();
  return ids_;
}

const std::vector<double>& Rasterizer::inverse_depth() {
  flush();
  return inverse_depth_;
}

std::vector<double> Rasterizer::depth_image() {
  flush();
  std::vector<double> t(view_.pixels());
  for (int y = 0; y < view_.height; ++y) {
    for (int x = 0; x < view_.width; ++x) t[static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x)] = depth_at(x, y);
  }
  return t;
}

Counters Rasterizer::shade(const Shader& shader, bool shadows) {
  flush();
  colors_.assign(view_.pixels(), shader.background());
  tbb::enumerable_thread_specific<Counters> local;
  for_each_covered_pixel(arena_, view_, ids_, local, [&](Counters& c, int x, int y, size_t i) {
    colors_[i] = shader.shade(ids_[i], view_.ray(x, y), depth_at(x, y), shadows, c);
  });
  Counters total;
  for (const Counters& c : local) total += c;
  return total;
}

void Rasterizer::to_sample_buffer(SampleBuffer& buffer) {
  flush();
  buffer.resize(view_.width, view_.height);
  buffer.begin_frame();
  for (int y = 0; y < view_.height; ++y) {
    for (int x = 0; x < view_.width; ++x) {
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view_.width) + static_cast<size_t>(x);
      buffer.claim(i);
      buffer.set(i, ids_[i], depth_at(x, y), colors_.empty() ? Rgb{} : colors_[i]);
    }
  }
}

RasterCounters rasterize_scene(const Scene& scene, Rasterizer& rasterizer) {
  const RasterCounters before = rasterizer.counters();
  uint64_t skipped = 0;
  for (size_t i = 0; i < scene.prims.size(); ++i) {
    const PrimRef& p = scene.prims[i];
    if (p.kind == PrimKind::Triangle) {
      rasterizer.submit(scene.triangles[p.index], static_cast<uint32_t>(i));
    } else {
      ++skipped;
    }
  }
  rasterizer.flush();
  RasterCounters d = difference(rasterizer.counters(), before);
  d.skipped_primitives += skipped;
  return d;
}

}  // namespace frontier
