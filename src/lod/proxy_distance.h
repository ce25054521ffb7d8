// Distances between a point and a triangle mesh, for measuring how far a proxy lies from the
// geometry it stands for (src/lod/proxy.h). A TriangleBvh is a small bounding volume hierarchy
// (median splits on the longest axis, four triangles a leaf) answering "how far is the nearest
// triangle" by branch and bound: O(log n) per query on surfaces, O(n log n) to build. Everything is
// in double precision, so meshes far from the origin (1e6) measure as well as those at it.
// Immutable after construction: queries may run from any number of threads at once.
#pragma once

#include "src/core/geometry.h"
#include "src/core/primitives.h"

#include <cstdint>
#include <span>
#include <vector>

namespace frontier {

// Euclidean distance from p to the closed triangle (a, b, c); degenerate triangles (segments,
// points) measure as such.
// The point of triangle (a, b, c) nearest p (Ericson, "Real-Time Collision Detection" 5.1.5;
// a degenerate triangle: the nearest point of its edges).
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);
double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

class TriangleBvh {
 public:
  // The triangles (indices[3 i], indices[3 i + 1], indices[3 i + 2]) of `positions`.
  // REQUIRES: every index < positions.size(), indices.size() a multiple of 3. Copies what it needs.
  TriangleBvh(std::span<const Vec3> positions, std::span<const uint32_t> indices);

  // Distance from p to the nearest triangle; +infinity when there are none.
  double distance(const Vec3& p) const { return distance_above(p, 0.0); }
  // The same when it exceeds `floor`; otherwise some value <= floor (the search stops at the
  // first triangle within `floor`). farthest_sample's pruning: a sample no farther than the
  // farthest one so far cannot change the maximum.
  double distance_above(const Vec3& p, double floor) const;
  // The index (in construction order) of a triangle nearest to p; UINT32_MAX when there are none.
  uint32_t nearest(const Vec3& p) const;
  // The distance to the nearest triangle and its index (construction order) in `*triangle`, when
  // it exceeds `floor`; otherwise some value <= floor and a triangle within it. +infinity and
  // UINT32_MAX when there are none.
  double nearest_above(const Vec3& p, double floor, uint32_t* triangle) const;
  // An upper bound on the largest distance from any point of the closed triangle (a, b, c) to the
  // mesh, never below its corners' distances: rigorous, not sampled. The distance to one triangle
  // T is convex, so over abc it peaks at a corner, and the mesh lies no farther than T does; the
  // distance is also 1-Lipschitz, so no point lies farther than its corners' plus longest edge /
  // sqrt 3. With T the best of the corners' nearest triangles, abc is split in four (at most ten
  // times deep) while the bound exceeds both `floor` and 1.05x its corners' distances + `slack`:
  // the result exceeds the true largest distance by at most that much where it is above `floor`
  // (or by longest edge / (1024 sqrt 3) where the splits run out).
  double farthest_on_triangle(const Vec3& a, const Vec3& b, const Vec3& c, double floor, double slack) const;
  // The largest of farthest_on_triangle over the triangles (indices as for the constructor) and
  // `floor`, each vertex's nearest triangle found once; 0 without triangles.
  double farthest_point(std::span<const Vec3> positions, std::span<const uint32_t> indices, double floor,
                        double slack) const;
  size_t triangle_count() const { return triangles_.size(); }

 private:
  struct Node {
    Aabb box;
    uint32_t first = 0;  // leaf: into triangles_; interior: the upper child (the lower is next)
    uint32_t count = 0;  // 0: interior
  };
  double search(const Vec3& p, double floor, uint32_t* nearest) const;
  struct Corner {
    double d = 0.0;         // distance to the nearest triangle
    uint32_t triangle = 0;  // that triangle, in leaf order
  };
  double farthest_on_triangle(const Vec3 (&corners)[3], const Corner (&near)[3], double floor, double slack,
                              int depth) const;
  uint32_t build(uint32_t first, uint32_t count, std::vector<uint32_t>& order, const std::vector<Vec3>& centroids);

  std::vector<Triangle> triangles_;  // in leaf order
  std::vector<uint32_t> order_;      // triangles_[i] is triangle order_[i] of the input
  std::vector<Node> nodes_;
};

// The largest distance from any of `samples` to the mesh of `bvh` (0 without samples).
double farthest_sample(std::span<const Vec3> samples, const TriangleBvh& bvh);

// An upper bound on the largest distance from any point of the triangles (indices as for
// TriangleBvh) to the mesh of `bvh`, or `floor` if larger (TriangleBvh::farthest_point).
double farthest_triangle_point(std::span<const Vec3> positions, std::span<const uint32_t> indices,
                               const TriangleBvh& bvh, double floor, double slack);

}  // namespace frontier
