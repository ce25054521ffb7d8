// The rasterizing visibility classes (see the header): the k-d tree traversals with frustum,
// z-pyramid and portal tests, paging through a CullSource, the per-frame table from submission
// ids to input ids, flat shading of a finished frame, and CullingFrameRenderer.
#include "src/raster/visibility.h"

#include "src/raster/portals.h"
#include "src/raster/zpyramid.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>

namespace frontier {

namespace {

using Clock = std::chrono::steady_clock;

// Pages the order-independent classes ask for at once.
constexpr size_t kPagesInFlight = 16;

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

bool contains(const Aabb& outer, const Aabb& inner) {
  return outer.lo.x <= inner.lo.x && outer.lo.y <= inner.lo.y && outer.lo.z <= inner.lo.z &&
         inner.hi.x <= outer.hi.x && inner.hi.y <= outer.hi.y && inner.hi.z <= outer.hi.z;
}

}  // namespace

const char* visibility_name(Visibility v) {
  switch (v) {
    case Visibility::kExhaustive: return "exhaustive";
    case Visibility::kFrustumCull: return "frustum-cull";
    case Visibility::kOcclusionCull: return "occlusion-cull";
    case Visibility::kFrustumAdvance: return "frustum-advance";
    case Visibility::kPortals: return "portals";
  }
  return "?";
}

std::optional<Visibility> parse_visibility(std::string_view text) {
  for (const Visibility v : {Visibility::kExhaustive, Visibility::kFrustumCull, Visibility::kOcclusionCull,
                             Visibility::kFrustumAdvance, Visibility::kPortals}) {
    if (text == visibility_name(v)) return v;
  }
  return std::nullopt;
}

nlohmann::json CullCounters::to_json() const {
  return {{"nodes_touched", nodes_touched},
          {"cells_touched", cells_touched},
          {"subtrees_accepted", subtrees_accepted},
          {"subtrees_rejected", subtrees_rejected},
          {"occlusion_queries", occlusion_queries},
          {"subtrees_occluded", subtrees_occluded},
          {"primitives_touched", primitives_touched},
          {"primitives_culled", primitives_culled},
          {"back_faces_culled", back_faces_culled},
          {"primitives_rasterized", primitives_rasterized},
          {"curved_primitives", curved_primitives},
          {"bound_triangles", bound_triangles},
          {"pixels_rasterized", pixels_rasterized},
          {"surface_rays", surface_rays},
          {"surface_hits", surface_hits},
          {"degenerate_primitives", degenerate_primitives},
          {"skipped_primitives", skipped_primitives},
          {"cells_waited", cells_waited},
          {"cells_unavailable", cells_unavailable},
          {"rooms_visited", rooms_visited},
          {"portals_tested", portals_tested},
          {"portals_passed", portals_passed},
          {"portal_fallback", portal_fallback},
          {"pyramid_ms", pyramid_ms},
          {"raster_ms", raster_ms},
          {"ms", ms}};
}

// The view frustum as planes n·p + d >= 0 inside: the four image borders (through the eye and
// the outer edges of the border pixels) and the near plane (the eye plane when near == 0).
// Boxes are classified with the usual nearest/farthest corner per plane and a margin that
// errs towards "inside": a primitive is only dropped when it is outside by more than rounding.
struct CullingRenderer::Planes {
  std::array<Vec3, 5> n{};
  std::array<double, 5> d{};
  double margin = 0.0;

  explicit Planes(const View& v) {
    const double w = v.width, h = v.height;
    auto dir = [&](double x, double y) { return v.base + x * v.step_x + y * v.step_y; };
    auto side = [&](int i, const Vec3& a, const Vec3& b, const Vec3& inside) {
      Vec3 normal = glm::cross(a, b);
      if (glm::dot(normal, inside) < 0.0) normal = -normal;
      n[size_t(i)] = glm::normalize(normal);
      d[size_t(i)] = -glm::dot(n[size_t(i)], v.eye);
    };
    const Vec3 centre = dir(0.5 * (w - 1.0), 0.5 * (h - 1.0));
    side(0, dir(-0.5, -0.5), dir(-0.5, h - 0.5), centre);         // left
    side(1, dir(w - 0.5, -0.5), dir(w - 0.5, h - 0.5), centre);   // right
    side(2, dir(-0.5, -0.5), dir(w - 0.5, -0.5), centre);         // top
    side(3, dir(-0.5, h - 0.5), dir(w - 0.5, h - 0.5), centre);   // bottom
    n[4] = v.forward;
    d[4] = -glm::dot(v.forward, v.eye) - v.near;
    margin = 1e-9 * (1.0 + std::abs(v.eye.x) + std::abs(v.eye.y) + std::abs(v.eye.z));
  }

  // Clears the bits of `mask` (planes still to test) that the box is entirely inside of.
  // Returns false when the box is outside one plane.
  bool classify(const Aabb& b, uint32_t& mask) const {
    for (int i = 0; i < 5; ++i) {
      if ((mask & (1u << i)) == 0) continue;
      const Vec3& p = n[size_t(i)];
      const Vec3 far(p.x >= 0.0 ? b.hi.x : b.lo.x, p.y >= 0.0 ? b.hi.y : b.lo.y, p.z >= 0.0 ? b.hi.z : b.lo.z);
      const Vec3 near(p.x >= 0.0 ? b.lo.x : b.hi.x, p.y >= 0.0 ? b.lo.y : b.hi.y, p.z >= 0.0 ? b.lo.z : b.hi.z);
      const double extent = margin * (1.0 + glm::length(far - near));
      if (glm::dot(p, far) + d[size_t(i)] < -extent) return false;
      if (glm::dot(p, near) + d[size_t(i)] > extent) mask &= ~(1u << i);
    }
    return true;
  }
};

struct CullingRenderer::Item {
  uint32_t node = 0;
  Aabb bounds;
  uint32_t mask = 0;  // frustum planes still straddled
};

CullingRenderer::CullingRenderer(const CullOptions& options, const PortalGraph* portals)
    : options_(options), portals_(portals) {}

CullingRenderer::~CullingRenderer() = default;

void CullingRenderer::reset_stamps() {
  std::fill(drawn_.begin(), drawn_.end(), 0u);
  stamp_ = 1;
}

void CullingRenderer::update_pyramid() {
  const auto t0 = Clock::now();
  pyramid_->update(*raster_);
  counters_.pyramid_ms += ms_since(t0);
  since_update_ = 0;
}

// Node tests of the class: frustum (and the portal regions). False: skip the subtree.
bool CullingRenderer::admit(const Aabb& box, uint32_t& mask) {
  if ((use_frustum_ && mask != 0) || !regions_.empty()) ++counters_.nodes_tested;
  if (use_frustum_ && mask != 0) {
    const uint32_t before = mask;
    if (!planes_->classify(box, mask)) {
      ++counters_.subtrees_rejected;
      return false;
    }
    if (before != 0 && mask == 0) ++counters_.subtrees_accepted;
  }
  if (!regions_.empty() &&
      std::none_of(regions_.begin(), regions_.end(), [&](const Aabb& r) { return r.overlaps(box); })) {
    ++counters_.subtrees_rejected;
    return false;
  }
  return true;
}

void CullingRenderer::draw_cell(int32_t cell, uint32_t mask) {
  const KdTree& tree = source_->tree();
  const Scene& scene = source_->scene();
  if (source_->generation() != generation_) {
    generation_ = source_->generation();
    reset_stamps();
  }
  if (drawn_.size() < scene.size()) drawn_.resize(scene.size(), 0u);
  source_->used(cell);
  ++counters_.cells_touched;
  const KdTree::Cell& c = tree.cell(cell);
  // Regions test per primitive only where the cell is not inside one region.
  const bool test_regions = !regions_.empty() && std::none_of(regions_.begin(), regions_.end(), [&](const Aabb& r) {
    return contains(r, c.bounds);
  });
  for (uint32_t r = c.first; r < c.first + c.count; ++r) {
    const uint32_t p = tree.ref(r);
    if (drawn_[p] == stamp_) continue;
    ++counters_.primitives_touched;
    const Aabb& bounds = tree.ref_bounds(r);
    uint32_t m = mask;
    if ((mask != 0 && !planes_->classify(bounds, m)) ||
        (test_regions &&
         std::none_of(regions_.begin(), regions_.end(), [&](const Aabb& g) { return g.overlaps(bounds); }))) {
      ++counters_.primitives_culled;
      continue;
    }
    drawn_[p] = stamp_;
    const PrimRef& ref = scene.prims[p];
    switch (ref.kind) {
      case PrimKind::Triangle:
        if (draw_triangle(scene.triangles[ref.index], ref)) ++counters_.primitives_rasterized;
        continue;
      case PrimKind::Box: {
        bool any = false;
        for (const Triangle& t : box_triangles(scene.boxes[ref.index].bounds)) any = draw_triangle(t, ref) || any;
        if (any) ++counters_.primitives_rasterized;
        continue;
      }
      case PrimKind::Sphere:
      case PrimKind::Cone:
      case PrimKind::Quadric:
        draw_curved(scene, p, ref);
        continue;
    }
    ++counters_.skipped_primitives;  // a kind added to PrimKind and not drawn here
  }
}

bool CullingRenderer::draw_triangle(const Triangle& t, const PrimRef& ref) {
  const Vec3 normal = glm::cross(t.v1 - t.v0, t.v2 - t.v0);
  if (options_.cull_back_faces && glm::dot(normal, t.v0 - view_.eye) >= 0.0) {
    ++counters_.back_faces_culled;
    return false;
  }
  raster_->submit(t, static_cast<uint32_t>(table_.size()));
  const double len = glm::length(normal);
  table_.push_back({ref.source, ref.material, len > 0.0 ? normal / len : Vec3(0.0, 0.0, 1.0)});
  ++since_update_;
  return true;
}

void CullingRenderer::draw_curved(const Scene& scene, uint32_t p, const PrimRef& ref) {
  ImplicitSurface surface;
  if (!implicit_surface_of(scene, p, surface)) {
    ++counters_.degenerate_primitives;
    return;
  }
  // The surface is copied into the frame's caster, so that it outlives the cell's eviction.
  const auto id = static_cast<uint32_t>(table_.size());
  caster_.set(id, surface);
  table_.push_back({ref.source, ref.material, Vec3(0.0)});
  const int slices = std::max(options_.bound_slices, 3);
  BoundIssueCounters issued;
  issue_curved(*raster_, curved_bound(scene, p, surface, slices, std::max(2, slices / 2)), view_, surface_near_, id,
               issued);
  ++counters_.primitives_rasterized;
  ++counters_.curved_primitives;
  counters_.bound_triangles += issued.triangles - issued.back_faces;
  since_update_ += issued.triangles - issued.back_faces;
}

// Depth-first from `root`. Missing cells: put into `deferred` (order-independent classes), or,
// without it, paged in on the spot. Front to back: the child on the eye's side first.
void CullingRenderer::traverse(Item root, bool front_to_back, std::vector<Item>* deferred) {
  std::vector<Item> stack{root};
  while (!stack.empty()) {
    Item item = stack.back();
    stack.pop_back();
    ++counters_.nodes_touched;
    if (!admit(item.bounds, item.mask)) continue;
    const KdTree& tree = source_->tree();
    const KdTree::Node node = tree.nodes()[item.node];
    if (use_pyramid_ && !node.is_link()) {  // a link's subtree root is queried with the same box
      // The tighter content bounds for cells; a node's region otherwise.
      const Aabb box = node.is_leaf() ? tree.cell(static_cast<int32_t>(node.child)).content : item.bounds;
      if (node.is_leaf() && tree.cell(static_cast<int32_t>(node.child)).count == 0 &&
          !source_->missing(static_cast<int32_t>(node.child))) {
        continue;  // an empty cell: nothing to draw
      }
      if (since_update_ >= options_.pyramid_batch) update_pyramid();
      ++counters_.occlusion_queries;
      if (!box.empty() && pyramid_->hidden(box)) {
        ++counters_.subtrees_occluded;
        continue;
      }
    }
    if (node.is_link()) {
      stack.push_back({node.child, item.bounds, item.mask});
      --counters_.nodes_touched;  // a link is the same region as its subtree root
      continue;
    }
    if (node.is_leaf()) {
      const auto cell = static_cast<int32_t>(node.child);
      if (source_->missing(cell)) {
        ++counters_.cells_waited;
        --counters_.nodes_touched;  // counted again when it is drawn
        if (deferred != nullptr) {
          deferred->push_back(item);  // asked for by render(), a few at a time
          continue;
        }
        source_->want(cell);
        while (source_->missing(cell) && source_->fetch()) {
        }
        if (source_->missing(cell)) {
          ++counters_.cells_unavailable;
          continue;
        }
        stack.push_back(item);  // now a link to the cell's subtree (or an empty, failed cell)
        continue;
      }
      draw_cell(cell, item.mask);
      continue;
    }
    const int axis = static_cast<int>(node.axis_or_leaf);
    Item lower{item.node + 1, item.bounds, item.mask}, upper{node.child, item.bounds, item.mask};
    lower.bounds.hi[axis] = node.split;
    upper.bounds.lo[axis] = node.split;
    const bool eye_below = view_.eye[axis] < node.split;
    if (front_to_back && !eye_below) std::swap(lower, upper);
    stack.push_back(upper);  // popped second
    stack.push_back(lower);
  }
}

CullCounters CullingRenderer::render(const View& view, CullSource& source) {
  const auto start = Clock::now();
  counters_ = {};
  source_ = &source;
  view_ = view;
  RasterOptions ro;
  ro.threads = options_.threads;
  raster_ = std::make_unique<Rasterizer>(view, ro);
  planes_ = std::make_unique<Planes>(view);
  table_.clear();
  caster_.clear();
  surface_near_ = surface_near(view, source.tree().bounds());
  caster_.begin_frame(view, surface_near_, options_.cull_back_faces);
  raster_->set_surface_program(&caster_);
  generation_ = source.generation();
  if (++stamp_ == 0) reset_stamps();
  since_update_ = 0;
  regions_.clear();
  const Visibility v = options_.visibility;
  use_frustum_ = v != Visibility::kExhaustive;
  use_pyramid_ = v == Visibility::kOcclusionCull;
  if (use_pyramid_) pyramid_ = std::make_unique<DepthPyramid>(*raster_);

  if (v == Visibility::kPortals) {
    if (portals_ != nullptr) {
      const PortalVisibility pv = portals_->traverse(view);
      counters_.portals_tested = pv.portals_tested;
      counters_.portals_passed = pv.portals_passed;
      counters_.rooms_visited = pv.visits.size();
      if (pv.located) {
        regions_ = pv.regions;
      } else {
        counters_.portal_fallback = true;
      }
    } else {
      counters_.portal_fallback = true;
    }
  }

  const Item root{0, source.tree().bounds(), use_frustum_ ? 0x1Fu : 0u};
  if (use_pyramid_) {
    traverse(root, true, nullptr);
  } else {
    std::vector<Item> deferred;
    traverse(root, false, &deferred);
    while (!deferred.empty()) {
      // Ask for a few pages at a time, so that a cache far smaller than the frame's cells
      // holds each page until it is drawn instead of evicting pages read but not yet used.
      for (size_t i = 0; i < std::min(deferred.size(), kPagesInFlight); ++i) {
        source.want(static_cast<int32_t>(source.tree().nodes()[deferred[i].node].child));
      }
      if (!source.fetch()) {
        counters_.cells_unavailable += deferred.size();
        break;
      }
      std::vector<Item> still;
      for (const Item& item : deferred) {
        const KdTree::Node node = source.tree().nodes()[item.node];
        if (node.is_leaf() && source.missing(static_cast<int32_t>(node.child))) {
          still.push_back(item);
        } else {
          traverse(item, false, &still);
        }
      }
      deferred.swap(still);
    }
  }
  raster_->flush();
  const RasterCounters& rc = raster_->counters();
  counters_.pixels_rasterized = rc.fragments;
  counters_.surface_rays = rc.surface_rays;
  counters_.surface_hits = rc.surface_hits;
  counters_.raster_ms = rc.setup_ms + rc.raster_ms;
  counters_.ms = ms_since(start);
  source_ = nullptr;
  return counters_;
}

std::vector<uint32_t> CullingRenderer::ids() const {
  std::vector<uint32_t> out;
  if (!raster_) return out;
  const std::vector<uint32_t>& frame = raster_->ids();
  out.resize(frame.size(), kNoPrim);
  for (size_t i = 0; i < frame.size(); ++i) {
    if (frame[i] != kNoPrim) out[i] = table_[frame[i]].source;
  }
  return out;
}

std::vector<double> CullingRenderer::depths() const {
  return raster_ ? raster_->depth_image() : std::vector<double>{};
}

std::vector<Rgb> CullingRenderer::shade(const Shader& shader, Counters& counters) const {
  std::vector<Rgb> out;
  if (!raster_) return out;
  const std::vector<uint32_t>& frame = raster_->ids();
  const std::vector<double> depth = raster_->depth_image();
  out.resize(frame.size(), shader.background());
  for (int y = 0; y < view_.height; ++y) {
    for (int x = 0; x < view_.width; ++x) {
      const size_t i = size_t(y) * size_t(view_.width) + size_t(x);
      if (frame[i] == kNoPrim) continue;
      const Entry& e = table_[frame[i]];
      const Ray ray = view_.ray(x, y);
      const ImplicitSurface* surface = caster_.surface(frame[i]);
      const Vec3 normal = surface != nullptr ? surface_normal(*surface, ray.at(depth[i]), -ray.dir) : e.normal;
      out[i] = shader.shade_surface(e.material, normal, ray, depth[i], counters);
    }
  }
  return out;
}

CullingFrameRenderer::CullingFrameRenderer(const Scene& scene, const KdTree& tree, const CullOptions& options)
    : source_(scene, tree), renderer_(options), shader_(scene, tree) {}

Result<Frame> CullingFrameRenderer::render(const View& view) {
  const CullCounters counters = renderer_.render(view, source_);
  Frame frame;
  Counters shading;  // flat shading after the frame: not the class's work, not reported
  frame.colors = renderer_.shade(shader_, shading);
  frame.ids = renderer_.ids();
  frame.ms = counters.ms;
  frame.stats = counters.to_json();
  frame.stats["visibility"] = visibility_name(renderer_.options().visibility);
  frame.stats["width"] = view.width;
  frame.stats["height"] = view.height;
  frame.stats["primitives"] = source_.scene().size();
  frame.stats["cells"] = source_.tree().cells().size();
  return frame;
}

}  // namespace frontier
