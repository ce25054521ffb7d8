// Distances between a point and a triangle mesh, for measuring how far a proxy lies from the
// geometry it stands for (src/paging/proxy.h). A TriangleBvh is a small bounding volume hierarchy
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
  size_t triangle_count() const { return triangles_.size(); }

 private:
  struct Node {
    Aabb box;
    uint32_t first = 0;  // leaf: into triangles_; interior: the upper child (the lower is next)
    uint32_t count = 0;  // 0: interior
  };
  uint32_t build(uint32_t first, uint32_t count, std::vector<uint32_t>& order, const std::vector<Vec3>& centroids);

  std::vector<Triangle> triangles_;
  std::vector<Node> nodes_;
};

// The largest distance from any of `samples` to the mesh of `bvh` (0 without samples).
double farthest_sample(std::span<const Vec3> samples, const TriangleBvh& bvh);

}  // namespace frontier
