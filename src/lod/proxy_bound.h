// A proxy's error bound measured against the original geometry it replaces (src/lod/proxy.h;
// DESIGN.md "The k-d tree, in two levels, with a proxy at every interior node").
//
// The builder keeps, for the subtree below a node, a hierarchy of BoundNodes: a leaf holds its
// cell's original triangles (curved primitives as their tessellation), an interior node its proxy
// with two measured distances to the original geometry beneath it:
//   to_original  rigorous: no point of the original triangles beneath lies farther from the proxy
//                (an upper bound over every point, as TriangleBvh::farthest_point gives);
//   from_proxy   sampled: the proxy's vertices, edge midpoints and centroids lie within it of the
//                original triangles beneath.
// measure_against_original gives both for a new proxy P over two children without touching every
// original triangle (that would make the build depth x N):
//   original -> P  branch and bound down the hierarchy. Original points under a node c lie within
//                  to_original(c) of c's mesh, so to_original(c) + h(c's mesh -> P) (h rigorous,
//                  farthest_point) bounds them all; nodes are opened largest bound first, and only
//                  while their bound exceeds the largest settled one, down to the leaves' original
//                  triangles, whose distance to P is measured directly. A node whose mesh is its
//                  original geometry (a leaf, or a proxy that kept its whole input) settles at once;
//                  a node cut off from its children (cut_off) settles at its bound, still rigorous.
//   P -> original  per sample q, the nearest original triangle beneath, searched through the same
//                  hierarchy (boxes of the original geometry and d(q, mesh) - to_original are lower
//                  bounds); a search stops as soon as q is known to lie within the largest distance
//                  found so far, or when d(q, t) + triangle_error(t) says so, t the nearest
//                  triangle of a node's mesh (triangle_error is sampled, so this side is as
//                  sampled as before).
// To keep the build affordable, both searches stop refining where what is still open could raise
// the distance found by no more than 1.25x, and open nodes at most 3 levels below the proxy's
// children (settling there at their bounds, still rigorous on the original's side): a stored
// bound exceeds the measured distance by at most about 1.25x, and a proxy's measurement touches at
// most 2 + 4 + 8 + 16 meshes, not its whole subtree. Where the search does reach the leaves, both
// sides are exact (to the slack of farthest_point).
// In the external build the nodes above the parts (merge_pending) no longer have their original
// triangles in memory: their hierarchy is the part roots' top kBoundLevels levels of proxies, the
// deepest of them cut off (their to_original and from_proxy stand for what lies beneath).
//
// Everything here is pure; measure_against_original may run on any number of threads at once
// over the same nodes, as long as no thread writes the nodes it reads.
#pragma once

#include "src/core/geometry.h"

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace frontier {

// Levels of each part's hierarchy kept for the nodes above the parts.
inline constexpr int kBoundLevels = 6;

struct BoundNode {
  static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
  std::vector<Vec3> positions;     // leaf: its original triangles; interior: its proxy
  std::vector<uint32_t> indices;   // three per triangle, into positions
  Aabb box;                        // of the original triangles beneath (empty: none)
  double to_original = 0.0;        // rigorous, see above; 0 where the mesh is the original
  double from_proxy = 0.0;         // sampled, see above; 0 where the mesh is the original
  // Per triangle of the mesh, what from_proxy is for the whole: the samples on it lie within this
  // of the original beneath (empty: 0 everywhere, the mesh is the original).
  std::vector<double> triangle_error;
  uint32_t lower = kNone, upper = kNone;  // children (indices into the same hierarchy); kNone: none
  bool original = false;           // the mesh is exactly the original geometry beneath
  bool cut_off() const { return lower == kNone && !original; }
};

struct MeasuredBound {
  double to_original = 0.0;
  double from_proxy = 0.0;
  std::vector<double> triangle_error;  // per triangle of the proxy, see BoundNode
  double distance() const { return to_original > from_proxy ? to_original : from_proxy; }
};

// The distances between the proxy (positions, indices) and the original geometry beneath
// `children` (indices into `nodes`; kNone entries ignored). REQUIRES: children's subtrees complete.
MeasuredBound measure_against_original(std::span<const Vec3> positions, std::span<const uint32_t> indices,
                                       std::span<const BoundNode> nodes, std::span<const uint32_t> children);

// The part of the hierarchy under `root` down to `levels` levels, as a new hierarchy rooted at
// index 0 (nodes at the last level cut off unless they are original).
std::vector<BoundNode> bound_summary(std::span<const BoundNode> nodes, uint32_t root, int levels);

}  // namespace frontier
