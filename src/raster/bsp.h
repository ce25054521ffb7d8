// BSP trees after Fuchs, Abram & Grant 1983 ("Fast scene generation on general purpose raster
// systems", ../shared/seeds/bsp-trees-fuchs-abram-grant-1983.txt): Make_tree with polygon
// splitting (§2.2.1), the fewest-cuts root among k random candidates (§3.1), back-to-front and
// front-to-back traversal with back-face removal (§2.2.2, §4.2), and moving objects kept in
// their own subtree inside a region of motion that no plane of the static tree cuts (§4.1).
// Rendering (painter's through the Rasterizer, and the coverage-mask anti-aliasing of §4.2) is
// in src/raster/bsp_render.h.
//
// Invariants of a built tree (BspTree::validate() checks every one of them):
//  * Every face is a convex planar polygon lying on the plane of its origin (the input polygon it
//    was cut from) within the tolerance, and on the plane of the node that stores it.
//  * Every vertex of every face below a node's front child is at signed distance >= -tolerance
//    from the node's plane; below the back child, <= +tolerance.
//  * Area: the faces' area plus the area of fragments dropped as degenerate equals the input area
//    to 1e-9 relative (nothing is lost silently).
//  * Size: depth <= input polygons + region planes; a face count bounded by the polygon-in-plane
//    arrangement bound n (1 + m + m (m - 1) / 2), m = n - 1 + region planes.
//
// One tolerance decides everything (BspBuildOptions::tolerance): a vertex is ON a plane when its
// signed distance is within it. A polygon whose vertices are all ON is coplanar (kept at the
// node, with a flag when it faces the other way); all >= -tol: front; all <= +tol: back; else it
// is split, ON vertices going to the front part and to the back part only where they border a
// back vertex (so the parts share one chord and partition the polygon even when it is nearly
// parallel to the plane). A split fragment drops vertices within the tolerance of their predecessor, and a
// fragment with fewer than three vertices or thinner than the tolerance (2 area / longest edge)
// is dropped and counted with its area (BspStats::degenerate_*).
//
// Termination (the build is iterative, no recursion): within one node's list every input polygon
// appears at most once (a split sends its two parts to different children), and the root's
// origin is removed from both children, so the number of distinct origins strictly decreases
// along every path: depth <= input polygons (+ the region planes, which split nothing twice).
//
// Thread safety: a built tree is immutable; any number of threads may traverse it.
#pragma once

#include "src/core/geometry.h"
#include "src/core/scene.h"
#include "src/core/status.h"

#include <glm/mat4x4.hpp>

#include <cstdint>
#include <span>
#include <string>
#include <type_traits>
#include <vector>

namespace frontier {

inline constexpr uint32_t kBspNone = 0xFFFFFFFFu;
// Default tolerance relative to the model's scale: max(bounds diagonal, largest |coordinate|).
// Far above double rounding of a plane distance (~1e-16 of the coordinates), far below any
// feature a viewer resolves.
inline constexpr double kBspRelativeTolerance = 1e-9;

// Convex planar polygons in one flat vertex array. REQUIRES (checked by build): every polygon
// has >= 3 vertices, is planar within the tolerance and convex. Degenerate ones are dropped and
// counted: thinner than the tolerance, or triangles so thin that their computed plane misses
// their own vertices by more than the tolerance.
struct PolygonSoup {
  struct Polygon {
    uint32_t first = 0;  // into vertices
    uint32_t count = 0;
    uint32_t source = 0;    // what id images report (Scene's PrimRef::source)
    uint32_t material = 0;  // into material colours
  };
  std::vector<Vec3> vertices;
  std::vector<Polygon> polygons;
  std::vector<Vec3> material_colors;  // per material; missing ones are grey

  size_t size() const { return polygons.size(); }
  void add(std::span<const Vec3> polygon, uint32_t source, uint32_t material);
  void add_triangle(const Triangle& t, uint32_t source, uint32_t material) {
    const Vec3 v[3] = {t.v0, t.v1, t.v2};
    add(v, source, material);
  }
  std::span<const Vec3> polygon(size_t i) const { return {vertices.data() + polygons[i].first, polygons[i].count}; }
  Aabb bounds() const;
};

// The triangles of `scene` as a soup (curved primitives tessellated first, with `segments`
// around a circle), keeping source and material; material colours from the scene.
PolygonSoup polygon_soup(const Scene& scene, int segments = 24);

// Decodes arbitrary bytes into a small adversarial soup (at most kMaxPolygons): lattice
// triangles, coplanar stacks, near-coplanar fans, slivers and convex n-gons, with offsets down
// to and below the tolerance. Safe on any input (the BSP fuzz target and its CI seed test).
PolygonSoup decode_polygon_soup(std::span<const uint8_t> bytes);
inline constexpr size_t kDecodeMaxPolygons = 64;

// A convex region of motion: the intersection of half-spaces dot(n, p) + w <= 0 (outward unit
// normals), with its corner points (to tell on which side of a plane other regions lie).
struct BspRegion {
  std::vector<Vec4> planes;
  std::vector<Vec3> corners;
  static BspRegion box(const Aabb& box);
  bool contains(const Vec3& p, double tolerance) const;
};

// A moving object (§4.1): polygons in object-local coordinates, drawn under a rigid transform
// given per frame; the transformed object must stay inside `region` (world space) for the
// order to be right (renderers count the frames where it does not).
struct BspMovingObject {
  PolygonSoup polygons;
  BspRegion region;
};

struct BspBuildOptions {
  int candidates = 5;      // k random root candidates per node; 0 (or >= list size): all
  uint64_t seed = 1;       // for the candidate choice
  double tolerance = 0.0;  // absolute; 0: kBspRelativeTolerance x the model's scale
  // Abandon the build (Status::unsupported) after this long; 0: no limit. For benchmarks of
  // the O(n^2)-per-node 'all candidates' choice on large inputs.
  double time_budget_ms = 0.0;
};

struct BspStats {
  uint64_t input_polygons = 0;     // static polygons given to the build
  uint64_t output_polygons = 0;    // static faces in the tree (after splitting)
  uint64_t nodes = 0;              // static nodes (region-plane nodes and object slots included)
  uint64_t splits = 0;             // polygons cut in two
  uint64_t coplanar = 0;           // faces stored at a node beside its root polygon
  uint64_t degenerate_input = 0;   // zero-area input polygons dropped
  uint64_t degenerate_fragments = 0;  // split fragments dropped as degenerate (area below)
  // Area of the dropped input polygons and fragments, plus the (signed, tiny) area that merging
  // vertices closer than the tolerance took from kept ones: input = output + degenerate.
  double degenerate_area = 0.0;
  double input_area = 0.0;
  double output_area = 0.0;
  uint64_t max_depth = 0;          // deepest node (the root has depth 0)
  double mean_depth = 0.0;         // mean node depth over faces
  uint64_t classifications = 0;    // polygon/plane tests (candidate choice and partition)
  uint64_t object_polygons = 0;    // faces in the moving objects' subtrees
  int candidates = 0;
  double tolerance = 0.0;
  double build_ms = 0.0;
  uint64_t memory_bytes = 0;       // nodes, faces, vertices, origin planes

  std::string to_json() const;
  std::string to_text() const;
};

struct BspNode {
  Vec4 plane{0.0};  // unit normal and offset: signed distance dot(n, p) + w; front: >= 0
  uint32_t front = kBspNone, back = kBspNone;
  uint32_t first_face = 0, face_count = 0;  // coplanar faces, contiguous
  uint32_t object = kBspNone;  // an object slot: a leaf holding moving object `object`
};

struct BspFace {
  uint32_t first = 0, count = 0;  // into the tree's vertices (object-local for object faces)
  uint32_t source = 0, material = 0;
  uint32_t origin = 0;   // input polygon index (within its soup)
  uint32_t node = 0;
  bool flipped = false;  // faces against the node plane's normal
};

enum class BspOrder : uint8_t { BackToFront, FrontToBack };

class BspTree {
 public:
  // Builds the static tree of `statics` and one subtree per moving object. Regions must be
  // pairwise separable by their own planes and free of static geometry (else InvalidArgument).
  // Errors: InvalidArgument for non-planar or non-convex input; Unsupported when the time
  // budget runs out.
  static Result<BspTree> build(const PolygonSoup& statics, const BspBuildOptions& options = {},
                               std::span<const BspMovingObject> objects = {});

  const BspStats& stats() const { return stats_; }
  double tolerance() const { return tolerance_; }
  uint32_t root() const { return root_; }
  const std::vector<BspNode>& nodes() const { return nodes_; }
  // Faces: the static ones first (static_faces() of them), then each object's.
  const std::vector<BspFace>& faces() const { return faces_; }
  uint32_t static_faces() const { return static_faces_; }
  std::span<const Vec3> face_vertices(uint32_t face) const {
    return {vertices_.data() + faces_[face].first, faces_[face].count};
  }
  size_t object_count() const { return objects_.size(); }
  const BspRegion& object_region(size_t object) const { return objects_[object].region; }
  // Faces [first, first + count) belong to moving object `object`.
  uint32_t object_first_face(size_t object) const { return objects_[object].first_face; }
  uint32_t object_face_count(size_t object) const { return objects_[object].face_count; }
  // The object a face belongs to, kBspNone for a static face.
  uint32_t face_object(uint32_t face) const;
  Vec3 material_color(uint32_t material) const {
    return material < material_colors_.size() ? material_colors_[material] : Vec3(0.8);
  }

  // Visits faces in back-to-front or front-to-back order for `eye`: visit(face, vertices) with
  // world-space vertices (object faces transformed by object_transforms[object], identity when
  // missing). With cull_back_faces, faces whose front side looks away from the eye (or that are
  // seen edge-on) are skipped (§2.2.2). A visitor returning bool stops the traversal by
  // returning false (a front-to-back renderer whose screen is full). Returns nodes visited.
  template <class Visit>
  uint64_t traverse(const Vec3& eye, BspOrder order, bool cull_back_faces,
                    std::span<const glm::dmat4> object_transforms, Visit&& visit,
                    uint64_t* culled_back = nullptr) const;

  // Checks the invariants listed at the top of this file; the first violation as Corruption.
  Status validate() const;

 private:
  struct Object {
    uint32_t root = kBspNone;
    uint32_t first_face = 0, face_count = 0;
    BspRegion region;
    double tolerance = 0.0;
  };
  friend class BspBuilder;

  template <class Visit>
  uint64_t traverse_subtree(uint32_t root, const Vec3& eye, BspOrder order, bool cull, double tolerance,
                            const glm::dmat4* transform, std::span<const glm::dmat4> transforms,
                            std::vector<uint32_t>& stack, std::vector<Vec3>& scratch, bool& stop, uint64_t& culled,
                            Visit& visit) const;

  std::vector<BspNode> nodes_;
  std::vector<BspFace> faces_;
  std::vector<Vec3> vertices_;
  std::vector<Vec4> origin_planes_;  // static origins, then each object's (offset per object)
  std::vector<uint32_t> origin_offset_;  // per object: first origin plane
  std::vector<double> origin_area_;      // input area per static origin + object origins
  std::vector<Object> objects_;
  std::vector<Vec3> material_colors_;
  uint32_t root_ = kBspNone;
  uint32_t static_faces_ = 0;
  double tolerance_ = 0.0;
  uint64_t region_planes_ = 0;
  BspStats stats_;
};

// ---- traversal (inline: the per-face visitor is the hot loop of every frame) ----

template <class Visit>
uint64_t BspTree::traverse(const Vec3& eye, BspOrder order, bool cull_back_faces,
                           std::span<const glm::dmat4> object_transforms, Visit&& visit,
                           uint64_t* culled_back) const {
  std::vector<uint32_t> stack;
  std::vector<Vec3> scratch;
  bool stop = false;
  uint64_t culled = 0;
  const uint64_t visited = traverse_subtree(root_, eye, order, cull_back_faces, tolerance_, nullptr, object_transforms,
                                            stack, scratch, stop, culled, visit);
  if (culled_back != nullptr) *culled_back += culled;
  return visited;
}

// In-order with an explicit stack (a degenerate tree may be as deep as its input): an entry is a
// node to expand, or with the high bit set a node whose own faces are due.
template <class Visit>
uint64_t BspTree::traverse_subtree(uint32_t root, const Vec3& eye, BspOrder order, bool cull, double tolerance,
                                   const glm::dmat4* transform, std::span<const glm::dmat4> transforms,
                                   std::vector<uint32_t>& stack, std::vector<Vec3>& scratch, bool& stop,
                                   uint64_t& culled, Visit& visit) const {
  constexpr uint32_t kEmit = 0x80000000u;
  uint64_t visited = 0;
  if (root == kBspNone) return 0;
  const size_t base = stack.size();
  stack.push_back(root);
  while (stack.size() > base && !stop) {
    const uint32_t entry = stack.back();
    stack.pop_back();
    const BspNode& node = nodes_[entry & ~kEmit];
    const double side = glm::dot(Vec3(node.plane), eye) + node.plane.w;
    if (entry & kEmit) {
      // Edge-on (|side| within tolerance) faces are invisible; culling drops them with the
      // faces that look away.
      const bool eye_front = side > tolerance, eye_back = side < -tolerance;
      for (uint32_t f = node.first_face; f < node.first_face + node.face_count; ++f) {
        const BspFace& face = faces_[f];
        if (cull && !(face.flipped ? eye_back : eye_front)) {
          ++culled;
          continue;
        }
        std::span<const Vec3> v = face_vertices(f);
        if (transform != nullptr) {
          scratch.resize(v.size());
          for (size_t k = 0; k < v.size(); ++k) scratch[k] = Vec3(*transform * Vec4(v[k], 1.0));
          v = scratch;
        }
        if constexpr (std::is_same_v<decltype(visit(f, v)), bool>) {
          if (!visit(f, v)) {
            stop = true;
            break;
          }
        } else {
          visit(f, v);
        }
      }
      continue;
    }
    ++visited;
    if (node.object != kBspNone) {
      const Object& object = objects_[node.object];
      const glm::dmat4 t = node.object < transforms.size() ? transforms[node.object] : glm::dmat4(1.0);
      const Vec3 local_eye = Vec3(glm::inverse(t) * Vec4(eye, 1.0));
      visited += traverse_subtree(object.root, local_eye, order, cull, object.tolerance, &t, {}, stack, scratch,
                                  stop, culled, visit);
      continue;
    }
    // Eye in front: the back side is far. Back-to-front pushes near first (popped last).
    const bool eye_front = side >= 0.0;
    const uint32_t near = eye_front ? node.front : node.back;
    const uint32_t far = eye_front ? node.back : node.front;
    const uint32_t first = order == BspOrder::BackToFront ? far : near;
    const uint32_t last = order == BspOrder::BackToFront ? near : far;
    if (last != kBspNone) stack.push_back(last);
    if (node.face_count > 0) stack.push_back((entry & ~kEmit) | kEmit);
    if (first != kBspNone) stack.push_back(first);
  }
  return visited;
}

}  // namespace frontier
