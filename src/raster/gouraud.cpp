// The tessellated baseline (see the header): tessellation once, per-vertex lighting and
// rasterization per frame, perspective-correct interpolation of the winning triangle's colours,
// and TessellatedFrameRenderer.
#include "src/raster/gouraud.h"

#include <nlohmann/json.hpp>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <chrono>

namespace frontier {

namespace {

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

nlohmann::json TessellatedCounters::to_json() const {
  return {{"triangles_issued", triangles_issued}, {"vertices_lit", vertices_lit},
          {"shading_ops", shading_ops},           {"pixels_covered", pixels_covered},
          {"depth_passes", depth_passes},         {"order_ms", order_ms},
          {"light_ms", light_ms},                 {"raster_ms", raster_ms},
          {"interpolate_ms", interpolate_ms},     {"ms", ms}};
}

TessellatedRenderer::TessellatedRenderer(const Scene& scene, const TessellatedOptions& options)
    : scene_(scene), options_(options), tree_(KdTree::build(scene)) {
  shader_ = std::make_unique<Shader>(scene_, tree_);
  TessellateOptions t;
  t.segments = options_.segments;
  first_.reserve(scene.size() + 1);
  for (uint32_t i = 0; i < scene.size(); ++i) {
    first_.push_back(static_cast<uint32_t>(triangles_.size()));
    tessellate_primitive(triangles_, &normals_, scene, i, t);
    triangle_prim_.resize(triangles_.size(), i);
  }
  first_.push_back(static_cast<uint32_t>(triangles_.size()));
  vertex_colors_.resize(triangles_.size());
}

TessellatedRenderer::~TessellatedRenderer() = default;

Scene TessellatedRenderer::tessellated_scene() const {
  Scene out;
  out.materials = scene_.materials;
  out.lights = scene_.lights;
  out.camera = scene_.camera;
  out.background = scene_.background;
  out.input_primitives = scene_.input_primitives;
  for (size_t k = 0; k < triangles_.size(); ++k) {
    const PrimRef& p = scene_.prims[triangle_prim_[k]];
    out.add_triangle(triangles_[k], p.source, p.material, &normals_[k]);
  }
  return out;
}

TessellatedCounters TessellatedRenderer::render(const View& view) {
  const auto start = std::chrono::steady_clock::now();
  TessellatedCounters counters;
  RasterOptions raster_options;
  raster_options.threads = options_.threads;
  raster_options.cull_back_faces = options_.cull_back_faces;
  if (!raster_ || !raster_->matches(view, raster_options)) raster_ = std::make_unique<Rasterizer>(view, raster_options);
  raster_->clear();
  raster_->reset_counters();

  auto t = std::chrono::steady_clock::now();
  const std::vector<uint32_t> order = issue_order(scene_, tree_, view.eye, options_.order, options_.seed);
  counters.order_ms = ms_since(t);

  // Per-vertex lighting of every triangle issued, whether or not it will be seen.
  t = std::chrono::steady_clock::now();
  tbb::enumerable_thread_specific<Counters> local;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, triangles_.size(), 512), [&](const tbb::blocked_range<size_t>& r) {
    Counters& c = local.local();
    for (size_t k = r.begin(); k != r.end(); ++k) {
      const uint32_t material = scene_.prims[triangle_prim_[k]].material;
      const Vec3* v = &triangles_[k].v0;
      for (int j = 0; j < 3; ++j) {
        const Vec3 offset = v[j] - view.eye;
        const double distance = glm::length(offset);
        const Ray ray(view.eye, distance > 0.0 ? offset : view.forward);
        vertex_colors_[k][static_cast<size_t>(j)] = shader_->shade_surface(material, normals_[k][static_cast<size_t>(j)], ray, distance, c);
      }
    }
  });
  for (const Counters& c : local) counters.shading_ops += c.shading_ops;
  counters.light_ms = ms_since(t);

  t = std::chrono::steady_clock::now();
  for (uint32_t prim : order) {
    for (uint32_t k = first_[prim]; k < first_[prim + 1]; ++k) raster_->submit(triangles_[k], k);
    counters.triangles_issued += first_[prim + 1] - first_[prim];
  }
  raster_->flush();
  counters.raster_ms = ms_since(t);
  counters.vertices_lit = 3 * counters.triangles_issued;
  counters.pixels_covered = raster_->counters().fragments;
  counters.depth_passes = raster_->counters().depth_passes;

  // Gouraud: barycentric weights of the visible point on the winning triangle.
  t = std::chrono::steady_clock::now();
  const std::vector<uint32_t>& ids = raster_->ids();
  const std::vector<double> depth = raster_->depth_image();
  std::vector<Rgb> colors(view.pixels(), shader_->background());
  tbb::parallel_for(0, view.height, [&](int y) {
    for (int x = 0; x < view.width; ++x) {
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view.width) + static_cast<size_t>(x);
      if (ids[i] == kNoPrim) continue;
      const Triangle& tri = triangles_[ids[i]];
      const Vec3 p = view.ray(x, y).at(depth[i]);
      const Vec3 n = glm::cross(tri.v1 - tri.v0, tri.v2 - tri.v0);
      const double area = glm::dot(n, n);
      if (!(area > 0.0)) continue;
      const double b1 = glm::dot(glm::cross(p - tri.v0, tri.v2 - tri.v0), n) / area;
      const double b2 = glm::dot(glm::cross(tri.v1 - tri.v0, p - tri.v0), n) / area;
      const double b0 = 1.0 - b1 - b2;
      const auto& c = vertex_colors_[ids[i]];
      colors[i] = Rgb{static_cast<float>(b0 * c[0].r + b1 * c[1].r + b2 * c[2].r),
                      static_cast<float>(b0 * c[0].g + b1 * c[1].g + b2 * c[2].g),
                      static_cast<float>(b0 * c[0].b + b1 * c[1].b + b2 * c[2].b)};
    }
  });
  raster_->set_colors(std::move(colors));
  counters.interpolate_ms = ms_since(t);
  counters.ms = ms_since(start);
  return counters;
}

std::vector<uint32_t> TessellatedRenderer::triangle_order(const View& view) const {
  std::vector<uint32_t> order;
  order.reserve(triangles_.size());
  for (uint32_t prim : issue_order(scene_, tree_, view.eye, options_.order, options_.seed)) {
    for (uint32_t k = first_[prim]; k < first_[prim + 1]; ++k) order.push_back(k);
  }
  return order;
}

std::vector<uint32_t> TessellatedRenderer::prim_ids() {
  std::vector<uint32_t> ids = raster_->ids();
  for (uint32_t& id : ids) {
    if (id != kNoPrim) id = triangle_prim_[id];
  }
  return ids;
}

void TessellatedRenderer::add_stats(nlohmann::json& stats, const char* method, const View& view) const {
  add_issue_stats(stats, method, options_.order, view, scene_.size());
  stats["tessellation"] = options_.segments;
  stats["triangles"] = triangles();
}

Result<Frame> TessellatedFrameRenderer::render(const View& view) {
  const TessellatedCounters counters = tessellated_.render(view);
  Frame frame;
  frame.colors = tessellated_.rasterizer().colors();
  frame.ids = source_ids(scene_, tessellated_.prim_ids());
  frame.ms = counters.ms;
  frame.stats = counters.to_json();
  tessellated_.add_stats(frame.stats, "tessellated", view);
  return frame;
}

}  // namespace frontier
