// Make_tree (§2.2.1) with the fewest-cuts root among k random candidates (§3.1), iteratively
// (a work stack of node lists, depth first), plus region-of-motion carving for moving objects
// (§4.1), the tree's self-check and the fuzz decoder. See bsp.h for the invariants.
#include "src/raster/bsp.h"

#include "src/core/tessellate.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>

namespace frontier {
namespace {

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// Newell's normal: twice the area vector of a planar polygon, exact for any vertex order
// convention and robust for nearly collinear neighbours.
Vec3 newell(std::span<const Vec3> v) {
  Vec3 n(0.0);
  const Vec3 o = v[0];  // relative to a vertex: far-from-origin models keep their precision
  for (size_t i = 1; i + 1 < v.size(); ++i) n += glm::cross(v[i] - o, v[i + 1] - o);
  return n;
}

double area_of(std::span<const Vec3> v) { return v.size() < 3 ? 0.0 : 0.5 * glm::length(newell(v)); }

double distance(const Vec4& plane, const Vec3& p) { return glm::dot(Vec3(plane), p) + plane.w; }

bool lexicographic_less(const Vec3& a, const Vec3& b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

// Drops vertices within `tol` of their predecessor (cyclically). Returns false when what is left
// is degenerate: fewer than three vertices or thinner than tol (2 area / longest edge).
bool clean_polygon(std::vector<Vec3>& v, double tol) {
  const double tol2 = tol * tol;
  size_t n = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    if (n > 0 && glm::dot(v[i] - v[n - 1], v[i] - v[n - 1]) <= tol2) continue;
    v[n++] = v[i];
  }
  while (n > 1 && glm::dot(v[n - 1] - v[0], v[n - 1] - v[0]) <= tol2) --n;
  v.resize(n);
  if (n < 3) return false;
  double longest = 0.0;
  for (size_t i = 0; i < n; ++i) longest = std::max(longest, glm::length(v[(i + 1) % n] - v[i]));
  return 2.0 * area_of(v) > tol * longest;
}

enum class Side : uint8_t { Coplanar, Front, Back, Spanning };

}  // namespace

// ---------------------------------------------------------------------------------------------
// PolygonSoup, regions

void PolygonSoup::add(std::span<const Vec3> polygon, uint32_t source, uint32_t material) {
  polygons.push_back({uint32_t(vertices.size()), uint32_t(polygon.size()), source, material});
  vertices.insert(vertices.end(), polygon.begin(), polygon.end());
}

Aabb PolygonSoup::bounds() const {
  Aabb b;
  for (const Vec3& v : vertices) b.extend(v);
  return b;
}

PolygonSoup polygon_soup(const Scene& scene, int segments) {
  const bool triangles_only =
      std::all_of(scene.prims.begin(), scene.prims.end(), [](const PrimRef& p) { return p.kind == PrimKind::Triangle; });
  Scene tessellated;
  const Scene* source = &scene;
  if (!triangles_only) {
    TessellateOptions options;
    options.segments = segments;
    options.smooth_normals = false;
    tessellated = tessellate(scene, options);
    source = &tessellated;
  }
  PolygonSoup soup;
  soup.vertices.reserve(3 * source->prims.size());
  soup.polygons.reserve(source->prims.size());
  for (const PrimRef& p : source->prims) {
    if (p.kind == PrimKind::Triangle) soup.add_triangle(source->triangles[p.index], p.source, p.material);
  }
  for (const Material& m : scene.materials) soup.material_colors.push_back(m.color);
  return soup;
}

BspRegion BspRegion::box(const Aabb& b) {
  BspRegion r;
  for (int a = 0; a < 3; ++a) {
    Vec3 n(0.0);
    n[a] = 1.0;
    r.planes.push_back(Vec4(n, -b.hi[a]));
    r.planes.push_back(Vec4(-n, b.lo[a]));
  }
  for (int k = 0; k < 8; ++k) r.corners.push_back(Vec3(k & 1 ? b.hi.x : b.lo.x, k & 2 ? b.hi.y : b.lo.y, k & 4 ? b.hi.z : b.lo.z));
  return r;
}

bool BspRegion::contains(const Vec3& p, double tolerance) const {
  return std::all_of(planes.begin(), planes.end(), [&](const Vec4& q) { return distance(q, p) <= tolerance; });
}

uint32_t BspTree::face_object(uint32_t face) const {
  for (size_t o = 0; o < objects_.size(); ++o) {
    if (face >= objects_[o].first_face && face < objects_[o].first_face + objects_[o].face_count) return uint32_t(o);
  }
  return kBspNone;
}

// ---------------------------------------------------------------------------------------------
// The builder

class BspBuilder {
 public:
  BspBuilder(BspTree& tree, const BspBuildOptions& options, double tolerance, BspStats& stats,
             std::chrono::steady_clock::time_point start)
      : tree_(tree), options_(options), tol_(tolerance), stats_(stats), start_(start), rng_(options.seed) {}

  // Builds the subtree of `soup` (origins numbered from origin_offset) with the given regions
  // carved out as object slots (objects numbered as the regions' indices). Writes its root.
  Status build(const PolygonSoup& soup, uint32_t origin_offset, std::span<const BspRegion> regions, uint32_t& root);

 private:
  struct Fragment {
    uint32_t first, count, origin;
  };
  struct Work {
    uint32_t node, depth;
    std::vector<uint32_t> fragments;
    std::vector<uint32_t> regions;  // regions inside this cell, regions[0] being carved
    uint32_t next_plane = 0;        // of regions[0]
  };

  std::span<const Vec3> vertices(uint32_t f) const { return {pool_.data() + fragments_[f].first, fragments_[f].count}; }
  Side classify(uint32_t f, const Vec4& plane) {
    ++stats_.classifications;
    bool front = false, back = false;
    for (const Vec3& v : vertices(f)) {
      const double d = distance(plane, v);
      front |= d > tol_;
      back |= d < -tol_;
    }
    return front && back ? Side::Spanning : front ? Side::Front : back ? Side::Back : Side::Coplanar;
  }
  bool spans(uint32_t f, const Vec4& plane) { return classify(f, plane) == Side::Spanning; }
  uint32_t add_fragment(std::vector<Vec3>& v, uint32_t origin) {
    fragments_.push_back({uint32_t(pool_.size()), uint32_t(v.size()), origin});
    pool_.insert(pool_.end(), v.begin(), v.end());
    return uint32_t(fragments_.size() - 1);
  }
  // The children of the node being built (their nodes not yet allocated) and the fragments on
  // its plane.
  struct Partition {
    Work front, back;
    std::vector<uint32_t> coplanar;
  };

  // Input: every polygon's plane (origin_planes_, origin_area_), its validity and, unless it is
  // degenerate, its fragment in `fragments`.
  Status add_input(const PolygonSoup& soup, std::vector<uint32_t>& fragments);
  Status check_planar_convex(const std::vector<Vec3>& v, const Vec3& normal, const Vec4& plane, size_t i) const;
  // Sorts `fragments` but `chosen` (kBspNone: none) to the sides of `plane`, splitting those
  // that span it; coplanar ones count in stats_.coplanar only against a chosen root.
  void partition(const std::vector<uint32_t>& fragments, const Vec4& plane, uint32_t chosen, Partition& parts);
  // The node of a cell holding regions of motion: the next plane of regions[0], or (`slot`) the
  // object slot once the region is carved out. Errors for geometry inside a region and for
  // regions that overlap or cut each other.
  Status carve_region(const Work& work, std::span<const BspRegion> regions, BspNode& node, Partition& parts,
                      bool& slot);
  // The node of a cell without regions: the plane of the fewest-cuts root candidate.
  void split_by_best_root(Work& work, BspNode& node, Partition& parts);
  // Emits the node's faces, allocates its children and pushes their work.
  void finish_node(const Work& work, BspNode& node, Partition& parts, std::vector<Work>& stack);
  uint32_t choose_root(std::vector<uint32_t>& list);
  void split(uint32_t f, const Vec4& plane, std::vector<uint32_t>& front, std::vector<uint32_t>& back);
  void emit_face(uint32_t f, uint32_t node, uint32_t depth, const Vec4& plane);
  bool out_of_time() {
    if (options_.time_budget_ms > 0.0 && ms_since(start_) > options_.time_budget_ms) out_of_time_ = true;
    return out_of_time_;
  }
  uint32_t new_node() {
    tree_.nodes_.emplace_back();
    ++stats_.nodes;
    return uint32_t(tree_.nodes_.size() - 1);
  }

  BspTree& tree_;
  const BspBuildOptions& options_;
  const double tol_;
  BspStats& stats_;
  std::chrono::steady_clock::time_point start_;
  std::mt19937_64 rng_;
  uint32_t origin_offset_ = 0;
  const PolygonSoup* soup_ = nullptr;
  std::vector<Vec3> pool_;
  std::vector<Fragment> fragments_;
  std::vector<Vec3> front_v_, back_v_;
  double depth_sum_ = 0.0;
  uint64_t faces_ = 0;
  bool out_of_time_ = false;

 public:
  double depth_sum() const { return depth_sum_; }
};

uint32_t BspBuilder::choose_root(std::vector<uint32_t>& list) {
  const size_t n = list.size();
  const size_t k = options_.candidates <= 0 || size_t(options_.candidates) >= n ? n : size_t(options_.candidates);
  if (k < n) {
    // Partial Fisher-Yates: the first k entries become a uniform sample without replacement.
    for (size_t i = 0; i < k; ++i) std::swap(list[i], list[i + size_t(rng_() % (n - i))]);
  }
  uint64_t best_splits = UINT64_MAX;
  size_t best = 0;
  for (size_t c = 0; c < k && best_splits > 0; ++c) {
    if (c % 256 == 255 && out_of_time()) return uint32_t(best);
    const Vec4& plane = tree_.origin_planes_[origin_offset_ + fragments_[list[c]].origin];
    uint64_t splits = 0;
    // Branch and bound: a candidate that cannot beat the best (ties go to the first) stops.
    for (size_t i = 0; i < n && splits < best_splits; ++i) {
      if (i != c && spans(list[i], plane)) ++splits;
    }
    if (splits < best_splits) {
      best_splits = splits;
      best = c;
    }
  }
  return uint32_t(best);
}

void BspBuilder::split(uint32_t f, const Vec4& plane, std::vector<uint32_t>& front, std::vector<uint32_t>& back) {
  ++stats_.splits;
  front_v_.clear();
  back_v_.clear();
  const Fragment frag = fragments_[f];
  // Ericson's rule (Real-Time Collision Detection, 8.3.4): a vertex ON the plane goes to the
  // front part, and to the back part too only where it borders a back vertex. Both parts are
  // then sub-sequences of the convex polygon sharing exactly one chord (between the two
  // transitions), so they partition it even when several vertices are ON (a polygon nearly
  // parallel to the plane): putting every ON vertex in both parts would overlap them.
  auto side = [&](double d) { return d > tol_ ? 1 : d < -tol_ ? -1 : 0; };
  Vec3 a = pool_[frag.first + frag.count - 1];
  double da = distance(plane, a);
  for (uint32_t i = 0; i < frag.count; ++i) {
    const Vec3 b = pool_[frag.first + i];
    const double db = distance(plane, b);
    const int sa = side(da), sb = side(db);
    if (sa * sb < 0) {
      // Interpolated from the lexicographically smaller end, so that the two polygons sharing
      // this edge compute the bit-identical point (no cracks along shared edges).
      const bool a_first = lexicographic_less(a, b);
      const Vec3& p = a_first ? a : b;
      const Vec3& q = a_first ? b : a;
      const double dp = a_first ? da : db, dq = a_first ? db : da;
      const Vec3 x = p + (dp / (dp - dq)) * (q - p);
      front_v_.push_back(x);
      back_v_.push_back(x);
    }
    if (sb > 0) {
      front_v_.push_back(b);
    } else if (sb < 0) {
      if (sa == 0) back_v_.push_back(a);
      back_v_.push_back(b);
    } else {
      front_v_.push_back(b);
      if (sa < 0) back_v_.push_back(b);
    }
    a = b;
    da = db;
  }
  const uint32_t origin = frag.origin;
  for (auto [v, out] : {std::pair{&front_v_, &front}, std::pair{&back_v_, &back}}) {
    const double raw_area = area_of(*v);
    if (clean_polygon(*v, tol_)) {
      stats_.degenerate_area += raw_area - area_of(*v);  // what merging near-coincident vertices moved
      out->push_back(add_fragment(*v, origin));
    } else {
      ++stats_.degenerate_fragments;
      stats_.degenerate_area += raw_area;
    }
  }
}

void BspBuilder::emit_face(uint32_t f, uint32_t node, uint32_t depth, const Vec4& plane) {
  const Fragment& frag = fragments_[f];
  const PolygonSoup::Polygon& input = soup_->polygons[frag.origin];
  BspFace face;
  face.first = uint32_t(tree_.vertices_.size());
  face.count = frag.count;
  face.source = input.source;
  face.material = input.material;
  face.origin = frag.origin;
  face.node = node;
  face.flipped = glm::dot(Vec3(tree_.origin_planes_[origin_offset_ + frag.origin]), Vec3(plane)) < 0.0;
  const std::span<const Vec3> v = vertices(f);
  tree_.vertices_.insert(tree_.vertices_.end(), v.begin(), v.end());
  tree_.faces_.push_back(face);
  depth_sum_ += depth;
  ++faces_;
}

Status BspBuilder::add_input(const PolygonSoup& soup, std::vector<uint32_t>& fragments) {
  std::vector<Vec3> v;
  for (size_t i = 0; i < soup.size(); ++i) {
    const std::span<const Vec3> input = soup.polygon(i);
    const double area = area_of(input);
    stats_.input_area += area;
    Vec4 plane(0.0);
    v.assign(input.begin(), input.end());
    for (const Vec3& p : v) {
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
        return Status::invalid_argument(fmt::format("bsp: polygon {} has a non-finite vertex", i));
      }
    }
    if (!clean_polygon(v, tol_)) {
      ++stats_.degenerate_input;
      stats_.degenerate_area += area;
    } else {
      const Vec3 normal = glm::normalize(newell(v));
      Vec3 centroid(0.0);
      for (const Vec3& p : v) centroid += p;
      centroid /= double(v.size());
      plane = Vec4(normal, -glm::dot(normal, centroid));
      // A triangle is planar by definition: if its vertices miss the computed plane, the plane
      // is numerically unstable (a sliver barely wider than the tolerance), so it is degenerate.
      const bool planar = std::all_of(v.begin(), v.end(), [&](const Vec3& p) { return std::abs(distance(plane, p)) <= tol_; });
      if (!planar && v.size() == 3) {
        ++stats_.degenerate_input;
        stats_.degenerate_area += area;
        tree_.origin_planes_.push_back(Vec4(0.0));
        tree_.origin_area_.push_back(area);
        continue;
      }
      if (Status s = check_planar_convex(v, normal, plane, i); !s) return s;
      stats_.degenerate_area += area - area_of(v);
      fragments.push_back(add_fragment(v, uint32_t(i)));
    }
    tree_.origin_planes_.push_back(plane);
    tree_.origin_area_.push_back(area);
  }
  return Status::ok();
}

Status BspBuilder::check_planar_convex(const std::vector<Vec3>& v, const Vec3& normal, const Vec4& plane,
                                       size_t i) const {
  for (size_t k = 0; k < v.size(); ++k) {
    if (std::abs(distance(plane, v[k])) > tol_) {
      return Status::invalid_argument(fmt::format("bsp: polygon {} is not planar within {:g}", i, tol_));
    }
    const Vec3 a = v[k] - v[(k + v.size() - 1) % v.size()], b = v[(k + 1) % v.size()] - v[k];
    if (glm::dot(glm::cross(a, b), normal) < -tol_ * (glm::length(a) + glm::length(b))) {
      return Status::invalid_argument(fmt::format("bsp: polygon {} is not convex", i));
    }
  }
  return Status::ok();
}

void BspBuilder::partition(const std::vector<uint32_t>& fragments, const Vec4& plane, uint32_t chosen,
                           Partition& parts) {
  for (uint32_t f : fragments) {
    if (f == chosen) continue;
    switch (classify(f, plane)) {
      case Side::Coplanar:
        parts.coplanar.push_back(f);
        if (chosen != kBspNone) ++stats_.coplanar;
        break;
      case Side::Front: parts.front.fragments.push_back(f); break;
      case Side::Back: parts.back.fragments.push_back(f); break;
      case Side::Spanning: split(f, plane, parts.front.fragments, parts.back.fragments); break;
    }
  }
}

Status BspBuilder::carve_region(const Work& work, std::span<const BspRegion> regions, BspNode& node, Partition& parts,
                                bool& slot) {
  const uint32_t r = work.regions[0];
  const BspRegion& region = regions[r];
  if (work.regions.size() == 1 && (work.fragments.empty() || work.next_plane == region.planes.size())) {
    if (!work.fragments.empty()) {
      return Status::invalid_argument(fmt::format("bsp: static geometry inside the region of motion {}", r));
    }
    node.object = r;
    slot = true;
    return Status::ok();
  }
  if (work.next_plane == region.planes.size()) {
    return Status::invalid_argument(fmt::format("bsp: regions of motion {} and {} overlap", r, work.regions[1]));
  }
  node.plane = region.planes[work.next_plane];
  partition(work.fragments, node.plane, kBspNone, parts);
  parts.back.regions.push_back(r);
  parts.back.next_plane = work.next_plane + 1;
  for (size_t i = 1; i < work.regions.size(); ++i) {
    bool in_front = false, in_back = false;
    for (const Vec3& c : regions[work.regions[i]].corners) {
      const double d = distance(node.plane, c);
      in_front |= d > tol_;
      in_back |= d < -tol_;
    }
    if (in_front && in_back) {
      return Status::invalid_argument(
          fmt::format("bsp: region of motion {} is cut by a plane of region {}", work.regions[i], r));
    }
    (in_front ? parts.front : parts.back).regions.push_back(work.regions[i]);
  }
  if (parts.front.regions.size() > 0) parts.front.next_plane = 0;
  return Status::ok();
}

void BspBuilder::split_by_best_root(Work& work, BspNode& node, Partition& parts) {
  const uint32_t chosen = work.fragments[choose_root(work.fragments)];
  node.plane = tree_.origin_planes_[origin_offset_ + fragments_[chosen].origin];
  parts.coplanar.push_back(chosen);
  partition(work.fragments, node.plane, chosen, parts);
}

void BspBuilder::finish_node(const Work& work, BspNode& node, Partition& parts, std::vector<Work>& stack) {
  node.first_face = uint32_t(tree_.faces_.size());
  node.face_count = uint32_t(parts.coplanar.size());
  for (uint32_t f : parts.coplanar) emit_face(f, work.node, work.depth, node.plane);
  if (!parts.back.fragments.empty() || !parts.back.regions.empty()) node.back = parts.back.node = new_node();
  if (!parts.front.fragments.empty() || !parts.front.regions.empty()) node.front = parts.front.node = new_node();
  tree_.nodes_[work.node] = node;
  if (parts.back.node != kBspNone) stack.push_back(std::move(parts.back));
  if (parts.front.node != kBspNone) stack.push_back(std::move(parts.front));
}

Status BspBuilder::build(const PolygonSoup& soup, uint32_t origin_offset, std::span<const BspRegion> regions,
                         uint32_t& root) {
  soup_ = &soup;
  origin_offset_ = origin_offset;
  pool_.clear();
  fragments_.clear();
  root = kBspNone;

  Work first;
  if (Status s = add_input(soup, first.fragments); !s) return s;
  for (uint32_t r = 0; r < regions.size(); ++r) first.regions.push_back(r);
  if (first.fragments.empty() && first.regions.empty()) return Status::ok();

  // Depth first: the lists on the stack are disjoint sets of fragments, so they hold at most
  // every live fragment once.
  first.node = root = new_node();
  first.depth = 0;
  std::vector<Work> stack;
  stack.push_back(std::move(first));
  while (!stack.empty()) {
    Work work = std::move(stack.back());
    stack.pop_back();
    stats_.max_depth = std::max<uint64_t>(stats_.max_depth, work.depth);
    if (out_of_time()) {
      return Status::unsupported(fmt::format("bsp: build exceeded its time budget of {:g} ms", options_.time_budget_ms));
    }
    BspNode node;
    Partition parts{{kBspNone, work.depth + 1, {}, {}, 0}, {kBspNone, work.depth + 1, {}, {}, 0}, {}};
    if (!work.regions.empty()) {
      // Carving a region of motion: its planes first, so that no later plane cuts it.
      bool slot = false;
      if (Status s = carve_region(work, regions, node, parts, slot); !s) return s;
      if (slot) {
        tree_.nodes_[work.node] = node;
        continue;
      }
    } else {
      split_by_best_root(work, node, parts);
    }
    work.fragments = {};  // release before the children allocate
    finish_node(work, node, parts, stack);
  }
  return Status::ok();
}

// ---------------------------------------------------------------------------------------------
// BspTree

Result<BspTree> BspTree::build(const PolygonSoup& statics, const BspBuildOptions& options,
                               std::span<const BspMovingObject> objects) {
  const auto start = std::chrono::steady_clock::now();
  BspTree tree;
  tree.material_colors_ = statics.material_colors;
  Aabb bounds = statics.bounds();
  std::vector<BspRegion> regions;
  for (const BspMovingObject& o : objects) {
    for (const Vec3& c : o.region.corners) bounds.extend(c);
    regions.push_back(o.region);
    tree.region_planes_ += o.region.planes.size();
  }
  const double scale = bounds.empty() ? 1.0 : std::max(glm::length(bounds.extent()), bounds.magnitude());
  tree.tolerance_ = options.tolerance > 0.0 ? options.tolerance : kBspRelativeTolerance * std::max(scale, 1e-300);

  BspStats& stats = tree.stats_;
  stats.candidates = options.candidates;
  stats.tolerance = tree.tolerance_;
  stats.input_polygons = statics.size();
  {
    BspBuilder builder(tree, options, tree.tolerance_, stats, start);
    if (Status s = builder.build(statics, 0, regions, tree.root_); !s) return s;
    stats.output_polygons = tree.faces_.size();
    stats.mean_depth = tree.faces_.empty() ? 0.0 : builder.depth_sum() / double(tree.faces_.size());
  }
  tree.static_faces_ = uint32_t(tree.faces_.size());
  for (const BspFace& f : tree.faces_) stats.output_area += area_of(tree.face_vertices(uint32_t(&f - tree.faces_.data())));

  // Each object's own subtree, in object-local coordinates with its own tolerance.
  for (const BspMovingObject& o : objects) {
    Object object;
    object.region = o.region;
    const Aabb ob = o.polygons.bounds();
    const double oscale = ob.empty() ? 1.0 : std::max(glm::length(ob.extent()), ob.magnitude());
    object.tolerance = options.tolerance > 0.0 ? options.tolerance : kBspRelativeTolerance * std::max(oscale, 1e-300);
    object.first_face = uint32_t(tree.faces_.size());
    tree.origin_offset_.push_back(uint32_t(tree.origin_planes_.size()));
    BspStats object_stats;
    BspBuilder builder(tree, options, object.tolerance, object_stats, start);
    if (Status s = builder.build(o.polygons, tree.origin_offset_.back(), {}, object.root); !s) return s;
    object.face_count = uint32_t(tree.faces_.size()) - object.first_face;
    stats.object_polygons += object.face_count;
    tree.objects_.push_back(std::move(object));
  }
  tree.nodes_.shrink_to_fit();
  tree.faces_.shrink_to_fit();
  tree.vertices_.shrink_to_fit();
  stats.build_ms = ms_since(start);
  stats.memory_bytes = tree.nodes_.capacity() * sizeof(BspNode) + tree.faces_.capacity() * sizeof(BspFace) +
                       tree.vertices_.capacity() * sizeof(Vec3) + tree.origin_planes_.capacity() * sizeof(Vec4) +
                       tree.origin_area_.capacity() * sizeof(double);
  return tree;
}

Status BspTree::validate() const {
  std::vector<uint32_t> parent(nodes_.size(), kBspNone);
  std::vector<uint8_t> is_front(nodes_.size(), 0);
  for (uint32_t i = 0; i < nodes_.size(); ++i) {
    for (uint32_t child : {nodes_[i].front, nodes_[i].back}) {
      if (child == kBspNone) continue;
      if (child >= nodes_.size() || parent[child] != kBspNone) return Status::corruption(fmt::format("bsp: node {} has a bad child", i));
      parent[child] = i;
      is_front[child] = child == nodes_[i].front;
    }
  }
  auto fail = [](uint32_t f, const std::string& what) { return Status::corruption(fmt::format("bsp: face {} {}", f, what)); };
  uint64_t max_depth = 0;
  for (uint32_t f = 0; f < faces_.size(); ++f) {
    const BspFace& face = faces_[f];
    const uint32_t object = face_object(f);
    const double tol = object == kBspNone ? tolerance_ : objects_[object].tolerance;
    const double slack = 2.0 * tol;  // later cuts interpolate between vertices already within tol
    const std::span<const Vec3> v = face_vertices(f);
    if (v.size() < 3) return fail(f, "has fewer than three vertices");
    if (!(2.0 * area_of(v) > 0.0)) return fail(f, "has zero area");
    const Vec4& origin = origin_planes_[(object == kBspNone ? 0 : origin_offset_[object]) + face.origin];
    const Vec4& own = nodes_[face.node].plane;
    for (const Vec3& p : v) {
      if (std::abs(distance(origin, p)) > slack) return fail(f, fmt::format("leaves its source plane by {:g}", distance(origin, p)));
      if (std::abs(distance(own, p)) > slack) return fail(f, "leaves its node's plane");
    }
    if ((glm::dot(Vec3(origin), Vec3(own)) < 0.0) != face.flipped) return fail(f, "has a wrong facing flag");
    uint64_t depth = 0;
    for (uint32_t n = face.node; parent[n] != kBspNone; n = parent[n]) {
      ++depth;
      const Vec4& plane = nodes_[parent[n]].plane;
      for (const Vec3& p : v) {
        const double d = distance(plane, p);
        if (is_front[n] ? d < -slack : d > slack) return fail(f, fmt::format("is on the wrong side of node {}", parent[n]));
      }
    }
    max_depth = std::max(max_depth, depth);
  }
  const double n = double(stats_.input_polygons), m = n - 1.0 + double(region_planes_);
  if (double(max_depth) > n + double(region_planes_)) return Status::corruption("bsp: tree deeper than its input");
  if (double(stats_.output_polygons) > std::max(1.0, n) * (1.0 + m + m * (m - 1.0) / 2.0)) {
    return Status::corruption("bsp: more faces than the arrangement bound");
  }
  const double area = stats_.output_area + stats_.degenerate_area;
  if (std::abs(area - stats_.input_area) > 1e-9 * stats_.input_area + 1e-300) {
    return Status::corruption(fmt::format("bsp: area {:.17g} out for {:.17g} in", area, stats_.input_area));
  }
  for (const Object& o : objects_) {
    for (uint32_t f = 0; f < static_faces_; ++f) {
      Vec3 centroid(0.0);
      for (const Vec3& p : face_vertices(f)) centroid += p;
      centroid /= double(faces_[f].count);
      if (o.region.contains(centroid, -tolerance_)) return fail(f, "is inside a region of motion");
    }
  }
  return Status::ok();
}

// ---------------------------------------------------------------------------------------------
// Statistics

std::string BspStats::to_json() const {
  nlohmann::json j;
  j["input_polygons"] = input_polygons;
  j["output_polygons"] = output_polygons;
  j["growth"] = input_polygons ? double(output_polygons) / double(input_polygons) : 0.0;
  j["nodes"] = nodes;
  j["splits"] = splits;
  j["coplanar"] = coplanar;
  j["degenerate_input"] = degenerate_input;
  j["degenerate_fragments"] = degenerate_fragments;
  j["degenerate_area"] = degenerate_area;
  j["input_area"] = input_area;
  j["output_area"] = output_area;
  j["max_depth"] = max_depth;
  j["mean_depth"] = mean_depth;
  j["classifications"] = classifications;
  j["object_polygons"] = object_polygons;
  j["candidates"] = candidates;
  j["tolerance"] = tolerance;
  j["build_ms"] = build_ms;
  j["memory_bytes"] = memory_bytes;
  return j.dump();
}

std::string BspStats::to_text() const {
  return fmt::format(
      "BSP tree ({} candidates, tolerance {:.3g})\n"
      "  input polygons   {}\n  output polygons  {} ({:.3f}x)\n  nodes            {}\n  splits           {}\n"
      "  coplanar         {}\n  depth            max {}, mean {:.1f}\n"
      "  degenerate       {} input, {} fragments, area {:.3g} of {:.6g}\n"
      "  build            {:.1f} ms, {} classifications\n  memory           {:.2f} MB\n",
      candidates == 0 ? std::string("all") : std::to_string(candidates), tolerance, input_polygons, output_polygons,
      input_polygons ? double(output_polygons) / double(input_polygons) : 0.0, nodes, splits, coplanar, max_depth,
      mean_depth, degenerate_input, degenerate_fragments, degenerate_area, input_area, build_ms, classifications,
      double(memory_bytes) / 1e6);
}

// ---------------------------------------------------------------------------------------------
// The fuzz decoder

PolygonSoup decode_polygon_soup(std::span<const uint8_t> bytes) {
  PolygonSoup soup;
  size_t at = 0;
  auto next = [&]() -> unsigned { return at < bytes.size() ? bytes[at++] : 0u; };
  auto lattice = [&]() { return (double(next()) - 128.0) / 16.0; };
  auto point = [&]() { return Vec3(lattice(), lattice(), lattice()); };
  auto tiny = [&]() { return std::pow(10.0, -double(next() % 20)); };  // 1 down to 1e-19
  auto add = [&](std::initializer_list<Vec3> v) {
    if (soup.size() < kDecodeMaxPolygons) soup.add(std::span<const Vec3>(v.begin(), v.size()), uint32_t(soup.size()), 0);
  };
  while (at < bytes.size() && soup.size() < kDecodeMaxPolygons) {
    switch (next() % 5) {
      case 0: {  // a lattice triangle: coplanar, collinear and repeated ones come easily
        const Vec3 a = point(), b = point(), c = point();
        add({a, b, c});
        break;
      }
      case 1: {  // a coplanar stack, offsets along the normal from 1 to 1e-19
        const Vec3 a = point(), b = point(), c = point(), shift = point();
        const Vec3 n = glm::cross(b - a, c - a);
        const double len = glm::length(n);
        const Vec3 u = len > 0.0 ? n / len : Vec3(0.0, 0.0, 1.0);
        const int copies = 1 + int(next() % 6);
        const double step = tiny();
        for (int i = 0; i < copies; ++i) {
          const Vec3 o = double(i) * step * u + (double(i) / 8.0) * (shift - glm::dot(shift, u) * u);
          add({a + o, b + o, c + o});
        }
        break;
      }
      case 2: {  // a near-coplanar fan: tilts alternate around a shared centre
        const Vec3 c = point();
        const int axis = int(next() % 3), count = 3 + int(next() % 8);
        const double r = 0.25 + double(next()) / 64.0, tilt = tiny();
        auto around = [&](int i) {
          const double a = 2.0 * 3.14159265358979323846 * i / count;
          Vec3 d(0.0);
          d[(axis + 1) % 3] = r * std::cos(a);
          d[(axis + 2) % 3] = r * std::sin(a);
          d[axis] = (i % 2 ? tilt : -tilt) * r;
          return c + d;
        };
        for (int i = 0; i < count; ++i) add({c, around(i), around(i + 1)});
        break;
      }
      case 3: {  // a sliver: the apex within 1 .. 1e-19 of the opposite edge
        const Vec3 a = point(), b = point(), side = point();
        Vec3 perp = glm::cross(b - a, side);
        const double len = glm::length(perp);
        perp = len > 0.0 ? perp / len : Vec3(0.0, 0.0, 1.0);
        const double along = double(next()) / 255.0;
        add({a, b, a + along * (b - a) + tiny() * perp});
        break;
      }
      default: {  // a convex regular n-gon on a tilted plane
        const Vec3 c = point();
        const int count = 3 + int(next() % 6);
        const double r = 0.25 + double(next()) / 32.0;
        const double theta = double(next()) / 40.0, phi = double(next()) / 40.0;
        const Vec3 u(std::cos(theta), std::sin(theta), 0.0);
        const Vec3 cross = glm::cross(u, Vec3(std::sin(phi), 0.3, std::cos(phi)));
        const Vec3 w = glm::length(cross) > 1e-3 ? glm::normalize(cross) : Vec3(0.0, 0.0, 1.0);
        const Vec3 v = glm::cross(w, u);
        std::vector<Vec3> poly;
        for (int i = 0; i < count; ++i) {
          const double a = 2.0 * 3.14159265358979323846 * i / count;
          poly.push_back(c + r * (std::cos(a) * u + std::sin(a) * v));
        }
        if (soup.size() < kDecodeMaxPolygons) soup.add(poly, uint32_t(soup.size()), 0);
        break;
      }
    }
  }
  return soup;
}

}  // namespace frontier
