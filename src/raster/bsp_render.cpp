// BSP frames: painter's through the Rasterizer, and the front-to-back coverage-mask renderer
// (§4.2). The mask renderer works in batches of faces in traversal order: set-up in parallel
// (clip, project, snap, integer edge functions: src/raster/clip.h, the Rasterizer's), binning
// into tiles in order, then tiles in parallel; each tile keeps its count of full pixels and
// skips faces once it is full, and the traversal stops once every tile is. BspFrameRenderer
// puts render_bsp behind the FrameRenderer interface.
#include "src/raster/bsp_render.h"

#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>

namespace frontier {
namespace {

constexpr int kSnapBits = 8;  // 1/256 pixel: every sample position of N <= 16 lies on it
constexpr int64_t kSnap = int64_t{1} << kSnapBits;
constexpr int kTile = 32;
constexpr size_t kBatchFaces = size_t{1} << 15;

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void add_counters(BspFrameCounters& a, const BspFrameCounters& b) {
  a.pixel_visits += b.pixel_visits;
  a.pixels_skipped_full += b.pixels_skipped_full;
  a.faces_skipped_full += b.faces_skipped_full;
  a.subsample_tests += b.subsample_tests;
  a.pixels_full += b.pixels_full;
}

uint64_t objects_outside(const BspTree& tree, std::span<const glm::dmat4> transforms) {
  uint64_t outside = 0;
  for (size_t o = 0; o < tree.object_count(); ++o) {
    const glm::dmat4 t = o < transforms.size() ? transforms[o] : glm::dmat4(1.0);
    const uint32_t first = tree.object_first_face(o);
    for (uint32_t f = first; f < first + tree.object_face_count(o); ++f) {
      const bool inside = std::all_of(tree.face_vertices(f).begin(), tree.face_vertices(f).end(), [&](const Vec3& v) {
        return tree.object_region(o).contains(Vec3(t * Vec4(v, 1.0)), tree.tolerance());
      });
      if (!inside) {
        ++outside;
        break;
      }
    }
  }
  return outside;
}

// The N x N coverage-mask renderer of one frame.
class MaskRenderer {
 public:
  MaskRenderer(const View& view, const BspRenderOptions& options)
      : view_(view), options_(options), n_(options.aa), words_((n_ * n_ + 63) / 64),
        arena_(options.threads > 0 ? options.threads : tbb::info::default_concurrency()) {
    clip_ = ClipTransform::of(view);
    tiles_x_ = (view.width + kTile - 1) / kTile;
    tiles_y_ = (view.height + kTile - 1) / kTile;
    const size_t pixels = view.pixels();
    mask_.assign(pixels * size_t(words_), 0);
    accum_.assign(pixels, Rgb{});
    best_.assign(pixels, 0);
    ids_.assign(pixels, kNoPrim);
    full_.assign(pixels, 0);
    tile_full_.assign(size_t(tiles_x_) * size_t(tiles_y_), 0);
    bins_.resize(tile_full_.size());
    if (options.edge_flags) {
      first_color_.assign(pixels, Rgb{-1.0f, -1.0f, -1.0f});
      mixed_.assign(pixels, 0);
    }
    for (int w = 0; w < words_; ++w) {
      const int bits = std::min(64, n_ * n_ - 64 * w);
      full_words_[w] = bits == 64 ? ~uint64_t{0} : (uint64_t{1} << bits) - 1;
    }
  }

  // Queues a face (world-space vertices) in front-to-back order. Returns false once every
  // pixel is full: nothing later can show.
  bool add(uint32_t face, std::span<const Vec3> vertices, Rgb color) {
    faces_.push_back({face, uint32_t(vertices_.size()), uint32_t(vertices.size()), color});
    vertices_.insert(vertices_.end(), vertices.begin(), vertices.end());
    if (faces_.size() >= kBatchFaces) flush();
    return !screen_full_;
  }

  void flush();
  void finish(BspFrame& frame);
  BspFrameCounters counters;

 private:
  struct Pending {
    uint32_t face, first, count;
    Rgb color;
  };
  struct Setup {
    int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // inclusive pixel box inside the screen; empty: x1 < x0
    uint32_t first_edge = 0, edge_count = 0;
  };

  struct Scratch {
    std::vector<Vec3> polygon, clipped;
    std::vector<int64_t> px, py;
  };
  void set_up(const Pending& p, Setup& s, EdgeFunction* edges, Scratch& scratch) const;
  void raster_tile(int tile, BspFrameCounters& c, std::vector<int64_t>& e0);
  bool tile_is_full(int tile) const {
    const int tx = tile % tiles_x_, ty = tile / tiles_x_;
    const int w = std::min(kTile, view_.width - tx * kTile), h = std::min(kTile, view_.height - ty * kTile);
    return tile_full_[size_t(tile)] == uint32_t(w * h);
  }

  const View& view_;
  const BspRenderOptions& options_;
  const int n_, words_;
  tbb::task_arena arena_;
  ClipTransform clip_;
  int tiles_x_ = 0, tiles_y_ = 0;
  uint64_t full_words_[4] = {0, 0, 0, 0};
  bool screen_full_ = false;

  // The batch, in traversal order (flush() empties it).
  std::vector<Pending> faces_;
  std::vector<Vec3> vertices_;               // the faces' world-space vertices
  std::vector<Setup> setups_;                // per face
  std::vector<EdgeFunction> edges_;          // a setup's are [first_edge, first_edge + edge_count)
  std::vector<std::vector<uint32_t>> bins_;  // per tile: the faces touching it, in order

  // The frame, per pixel (tile_full_: per tile).
  std::vector<uint64_t> mask_;       // words_ words of N x N coverage bits
  std::vector<Rgb> accum_;           // each face's colour times its share of the sub-samples
  std::vector<uint16_t> best_;       // the most sub-samples one face added: that face is ids_'
  std::vector<uint32_t> ids_;
  std::vector<uint8_t> full_;        // 1 once the mask is full: later faces skip the pixel
  std::vector<uint32_t> tile_full_;  // full pixels of the tile
  std::vector<Rgb> first_color_;     // edge_flags: the first face's colour
  std::vector<uint8_t> mixed_;       // edge_flags: 1 where colours mix
};

// Clip (as the Rasterizer clips), snap to 1/256 pixel, the box of pixels the face's footprint
// meets, edge functions. An empty box (x1 < x0) marks a face with nothing to draw.
void MaskRenderer::set_up(const Pending& p, Setup& s, EdgeFunction* edges, Scratch& scratch) const {
  s = Setup{};
  const int capacity = int(p.count) + ClipPlanes::kCount;  // the edges' room (flush)
  scratch.polygon.resize(size_t(capacity));
  scratch.clipped.resize(size_t(capacity));
  double farthest = 0.0;
  for (uint32_t k = 0; k < p.count; ++k) {
    scratch.polygon[k] = clip_(vertices_[p.first + k]);
    farthest = std::max(farthest, std::abs(scratch.polygon[k].z));
  }
  const ClipPlanes planes = ClipPlanes::of(view_, 0.0, farthest);
  const ClippedPolygon polygon =
      clip_to_view(scratch.polygon.data(), scratch.clipped.data(), int(p.count), capacity, planes);
  if (polygon.size < 3) return;
  scratch.px.resize(size_t(polygon.size));
  scratch.py.resize(size_t(polygon.size));
  SnapBox box;
  if (!snap_polygon(polygon.vertices, polygon.size, kSnapBits, planes, scratch.px.data(), scratch.py.data(), box)) {
    return;
  }
  // Pixels whose footprint [x - 1/2, x + 1/2] meets the box.
  s.x0 = int(std::max<int64_t>((box.xmin - kSnap / 2) >> kSnapBits, 0));
  s.y0 = int(std::max<int64_t>((box.ymin - kSnap / 2) >> kSnapBits, 0));
  s.x1 = int(std::min<int64_t>(((box.xmax + kSnap / 2) >> kSnapBits) + 1, view_.width - 1));
  s.y1 = int(std::min<int64_t>(((box.ymax + kSnap / 2) >> kSnapBits) + 1, view_.height - 1));
  if (s.x0 > s.x1 || s.y0 > s.y1) {
    s.x1 = s.x0 - 1;
    return;
  }
  s.edge_count = uint32_t(edge_functions(scratch.px.data(), scratch.py.data(), polygon.size, edges));
  if (s.edge_count == 0) s.x1 = s.x0 - 1;
}

void MaskRenderer::flush() {
  if (faces_.empty()) return;
  const auto start = std::chrono::steady_clock::now();
  const size_t count = faces_.size();
  setups_.resize(count);
  // Edge storage: a face clipped by five planes has at most count + 5 edges.
  size_t total = 0;
  for (size_t i = 0; i < count; ++i) {
    setups_[i].first_edge = uint32_t(total);
    total += faces_[i].count + 5;
  }
  edges_.resize(total);
  tbb::enumerable_thread_specific<Scratch> scratch;
  arena_.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 256), [&](const tbb::blocked_range<size_t>& r) {
      Scratch& sc = scratch.local();
      for (size_t i = r.begin(); i != r.end(); ++i) {
        const uint32_t first = setups_[i].first_edge;
        set_up(faces_[i], setups_[i], edges_.data() + first, sc);
        setups_[i].first_edge = first;
      }
    });
  });
  for (auto& bin : bins_) bin.clear();
  for (size_t i = 0; i < count; ++i) {
    const Setup& s = setups_[i];
    if (s.x1 < s.x0) continue;
    for (int ty = s.y0 / kTile; ty <= s.y1 / kTile; ++ty) {
      for (int tx = s.x0 / kTile; tx <= s.x1 / kTile; ++tx) bins_[size_t(ty * tiles_x_ + tx)].push_back(uint32_t(i));
    }
  }
  tbb::enumerable_thread_specific<BspFrameCounters> local;
  tbb::enumerable_thread_specific<std::vector<int64_t>> e0s;
  arena_.execute([&] {
    tbb::parallel_for(0, int(bins_.size()), [&](int tile) { raster_tile(tile, local.local(), e0s.local()); });
  });
  for (const BspFrameCounters& c : local) add_counters(counters, c);
  screen_full_ = true;
  for (int t = 0; t < int(bins_.size()) && screen_full_; ++t) screen_full_ = tile_is_full(t);
  faces_.clear();
  vertices_.clear();
  counters.raster_ms += ms_since(start);
}

void MaskRenderer::raster_tile(int tile, BspFrameCounters& c, std::vector<int64_t>& e0) {
  const int tx0 = (tile % tiles_x_) * kTile, ty0 = (tile / tiles_x_) * kTile;
  const int tx1 = std::min(tx0 + kTile, view_.width) - 1, ty1 = std::min(ty0 + kTile, view_.height) - 1;
  const int64_t step = kSnap / n_;                   // sample spacing
  const int64_t first = -kSnap / 2 + step / 2;       // first sample's offset from the pixel centre
  const int64_t span = step * (n_ - 1);              // first to last sample
  const double weight = 1.0 / double(n_ * n_);
  for (uint32_t index : bins_[size_t(tile)]) {
    if (tile_is_full(tile)) {
      ++c.faces_skipped_full;
      continue;
    }
    const Setup& s = setups_[index];
    const Pending& face = faces_[index];
    const EdgeFunction* edges = edges_.data() + s.first_edge;
    const int ec = int(s.edge_count);
    e0.resize(size_t(ec));
    for (int y = std::max(s.y0, ty0); y <= std::min(s.y1, ty1); ++y) {
      for (int x = std::max(s.x0, tx0); x <= std::min(s.x1, tx1); ++x) {
        const size_t p = size_t(y) * size_t(view_.width) + size_t(x);
        ++c.pixel_visits;
        if (full_[p]) {
          ++c.pixels_skipped_full;
          continue;
        }
        const int64_t sx = (int64_t(x) << kSnapBits) + first, sy = (int64_t(y) << kSnapBits) + first;
        bool reject = false, all_in = true;
        for (int k = 0; k < ec && !reject; ++k) {
          const EdgeFunction& e = edges[k];
          e0[size_t(k)] = e.a * (sx - e.ox) + e.b * (sy - e.oy) + e.bias;
          const int64_t lo = e0[size_t(k)] + std::min<int64_t>(0, e.a * span) + std::min<int64_t>(0, e.b * span);
          const int64_t hi = e0[size_t(k)] + std::max<int64_t>(0, e.a * span) + std::max<int64_t>(0, e.b * span);
          reject = hi < 0;
          all_in &= lo >= 0;
        }
        if (reject) continue;
        uint64_t bits[4] = {0, 0, 0, 0};
        if (all_in) {
          for (int w = 0; w < words_; ++w) bits[w] = full_words_[w];
        } else {
          c.subsample_tests += uint64_t(n_ * n_);
          for (int j = 0; j < n_; ++j) {
            for (int i = 0; i < n_; ++i) {
              bool inside = true;
              for (int k = 0; k < ec && inside; ++k) {
                inside = e0[size_t(k)] + edges[k].a * step * i + edges[k].b * step * j >= 0;
              }
              const int bit = j * n_ + i;
              if (inside) bits[bit >> 6] |= uint64_t{1} << (bit & 63);
            }
          }
        }
        uint64_t* mask = mask_.data() + p * size_t(words_);
        int added = 0;
        bool full = true;
        for (int w = 0; w < words_; ++w) {
          const uint64_t fresh = bits[w] & ~mask[w];
          added += std::popcount(fresh);
          mask[w] |= fresh;
          full &= mask[w] == full_words_[w];
        }
        if (added == 0) continue;
        const float f = float(double(added) * weight);
        accum_[p].r += f * face.color.r;
        accum_[p].g += f * face.color.g;
        accum_[p].b += f * face.color.b;
        if (added > best_[p]) {
          best_[p] = uint16_t(added);
          ids_[p] = face.face;
        }
        if (options_.edge_flags) {
          Rgb& fc = first_color_[p];
          if (fc.r < 0.0f) {
            fc = face.color;
          } else if (std::abs(fc.r - face.color.r) + std::abs(fc.g - face.color.g) + std::abs(fc.b - face.color.b) > 1e-6f) {
            mixed_[p] = 1;
          }
        }
        if (full) {
          full_[p] = 1;
          ++tile_full_[size_t(tile)];
          ++c.pixels_full;
        }
      }
    }
  }
}

void MaskRenderer::finish(BspFrame& frame) {
  flush();
  const size_t pixels = view_.pixels();
  frame.ids = std::move(ids_);
  if (options_.colors) {
    frame.colors.resize(pixels);
    for (size_t p = 0; p < pixels; ++p) {
      int covered = 0;
      for (int w = 0; w < words_; ++w) covered += std::popcount(mask_[p * size_t(words_) + size_t(w)]);
      const float rest = float(1.0 - double(covered) / double(n_ * n_));
      frame.colors[p] = {accum_[p].r + rest * float(options_.background.x), accum_[p].g + rest * float(options_.background.y),
                         accum_[p].b + rest * float(options_.background.z)};
      if (options_.edge_flags && covered > 0 && covered < n_ * n_) mixed_[p] = 1;
    }
  }
  if (options_.edge_flags) frame.mixed = std::move(mixed_);
}

}  // namespace

Rgb bsp_face_color(const BspTree& tree, uint32_t face, std::span<const Vec3> vertices, const Vec3& eye) {
  Vec3 normal(0.0), centroid(0.0);
  for (size_t i = 0; i < vertices.size(); ++i) {
    centroid += vertices[i];
    if (i >= 1 && i + 1 < vertices.size()) normal += glm::cross(vertices[i] - vertices[0], vertices[i + 1] - vertices[0]);
  }
  centroid /= double(vertices.size());
  const Vec3 to_eye = eye - centroid;
  const double nl = glm::length(normal), el = glm::length(to_eye);
  const double cosine = nl > 0.0 && el > 0.0 ? std::abs(glm::dot(normal, to_eye)) / (nl * el) : 1.0;
  const Vec3 c = tree.material_color(tree.faces()[face].material) * (0.1 + 0.9 * cosine);
  return {float(c.x), float(c.y), float(c.z)};
}

BspFrameCounters submit_bsp(const BspTree& tree, Rasterizer& rasterizer, BspOrder order, bool cull_back_faces,
                            std::span<const glm::dmat4> object_transforms) {
  BspFrameCounters c;
  const auto start = std::chrono::steady_clock::now();
  c.nodes_visited = tree.traverse(
      rasterizer.view().eye, order, cull_back_faces, object_transforms,
      [&](uint32_t face, std::span<const Vec3> v) {
        ++c.faces_drawn;
        // A fan: convex after splitting, and its diagonals are shared, so the top-left rule
        // hands each pixel centre to exactly one triangle.
        for (size_t k = 1; k + 1 < v.size(); ++k) rasterizer.submit({v[0], v[k], v[k + 1]}, face);
        c.triangles_submitted += v.size() - 2;
      },
      &c.faces_culled_back);
  c.traverse_ms = ms_since(start);
  return c;
}

BspFrame render_bsp(const BspTree& tree, const View& view, const BspRenderOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  BspFrame frame;
  frame.width = view.width;
  frame.height = view.height;
  const std::span<const glm::dmat4> transforms = options.object_transforms;
  const uint64_t outside = objects_outside(tree, transforms);

  if (options.order == BspOrder::BackToFront) {
    RasterOptions ro;
    ro.threads = options.threads;
    ro.depth_test = false;
    Rasterizer rasterizer(view, ro);
    std::vector<Rgb> face_colors;
    if (options.colors) face_colors.resize(tree.faces().size());
    const auto traverse_start = std::chrono::steady_clock::now();
    BspFrameCounters& c = frame.counters;
    c.nodes_visited = tree.traverse(
        view.eye, BspOrder::BackToFront, options.cull_back_faces, transforms,
        [&](uint32_t face, std::span<const Vec3> v) {
          ++c.faces_drawn;
          if (options.colors) face_colors[face] = bsp_face_color(tree, face, v, view.eye);
          for (size_t k = 1; k + 1 < v.size(); ++k) rasterizer.submit({v[0], v[k], v[k + 1]}, face);
          c.triangles_submitted += v.size() - 2;
        },
        &c.faces_culled_back);
    rasterizer.flush();
    c.raster = rasterizer.counters();
    c.raster_ms = c.raster.setup_ms + c.raster.raster_ms;
    c.traverse_ms = ms_since(traverse_start) - c.raster_ms;
    frame.ids = rasterizer.ids();
    if (options.colors) {
      const Rgb bg{float(options.background.x), float(options.background.y), float(options.background.z)};
      frame.colors.resize(frame.ids.size());
      for (size_t p = 0; p < frame.ids.size(); ++p) frame.colors[p] = frame.ids[p] == kNoPrim ? bg : face_colors[frame.ids[p]];
    }
  } else {
    BspRenderOptions o = options;
    o.aa = std::clamp(options.aa, 1, 16);
    MaskRenderer mask(view, o);
    BspFrameCounters& c = frame.counters;
    const auto traverse_start = std::chrono::steady_clock::now();
    c.nodes_visited = tree.traverse(
        view.eye, BspOrder::FrontToBack, options.cull_back_faces, transforms,
        [&](uint32_t face, std::span<const Vec3> v) {
          ++c.faces_drawn;
          return mask.add(face, v, bsp_face_color(tree, face, v, view.eye));
        },
        &c.faces_culled_back);
    mask.finish(frame);
    add_counters(c, mask.counters);
    c.raster_ms = mask.counters.raster_ms;
    c.traverse_ms = ms_since(traverse_start) - c.raster_ms;
  }
  frame.counters.objects_outside_region = outside;
  frame.counters.total_ms = ms_since(start);
  return frame;
}

BspFrameRenderer::BspFrameRenderer(BspTree tree, const BspRenderOptions& options)
    : tree_(std::move(tree)), options_(options) {}

Result<Frame> BspFrameRenderer::render(const View& view) {
  BspFrame bsp = render_bsp(tree_, view, options_);
  const BspFrameCounters& c = bsp.counters;
  const bool front_to_back = options_.order == BspOrder::FrontToBack;
  Frame frame;
  frame.colors = std::move(bsp.colors);
  frame.ids = std::move(bsp.ids);
  for (uint32_t& id : frame.ids) {
    if (id != kNoPrim) id = tree_.faces()[id].source;
  }
  frame.ms = c.total_ms;
  frame.stats = nlohmann::json::parse(tree_.stats().to_json());
  frame.stats["method"] = "bsp";
  frame.stats["order"] = front_to_back ? "front-to-back" : "back-to-front";
  frame.stats["aa"] = front_to_back ? options_.aa : 0;
  frame.stats["width"] = view.width;
  frame.stats["height"] = view.height;
  frame.stats["frame"] = {{"nodes_visited", c.nodes_visited},     {"faces_drawn", c.faces_drawn},
                          {"faces_culled_back", c.faces_culled_back}, {"pixel_visits", c.pixel_visits},
                          {"pixels_skipped_full", c.pixels_skipped_full}, {"pixels_full", c.pixels_full},
                          {"traverse_ms", c.traverse_ms},           {"raster_ms", c.raster_ms},
                          {"ms", c.total_ms}};
  return frame;
}

}  // namespace frontier
