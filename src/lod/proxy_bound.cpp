// Proxy bounds against the original geometry, by branch and bound down the hierarchy (the
// argument and contracts in proxy_bound.h).
#include "src/lod/proxy_bound.h"

#include "src/lod/proxy_distance.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <queue>
#include <unordered_map>
#include <utility>

namespace frontier {
namespace {

// farthest_point may exceed the true distance by this fraction of the original's diagonal (what
// it spends on triangles straddling the other mesh's creases and edges; proxy_distance.h).
constexpr double kMeasureSlack = 1e-3;
// Both searches stop refining where what is left could raise the distance found so far by no more
// than this factor: the bounds exceed the measured distance by at most that much (and farthest_
// point's slack), for a fraction of the work of settling every node exactly.
constexpr double kRefineFactor = 1.25;
// Both searches open nodes at most this many levels below the proxy's children and settle there at
// their bounds (rigorous on the original's side): the work per proxy stays bounded by 2^levels
// meshes, not its subtree, and a node's own bound is still the larger one below.
constexpr int kMaxDescent = 3;

double box_distance(const Aabb& box, const Vec3& p) {
  if (box.empty()) return kInfinity;
  const Vec3 d = glm::max(glm::max(box.lo - p, p - box.hi), Vec3(0.0));
  return glm::length(d);
}

// The BVHs of the hierarchy's meshes one measurement opens, built when first asked for.
class MeshBvhs {
 public:
  explicit MeshBvhs(std::span<const BoundNode> nodes) : nodes_(nodes) {}
  const TriangleBvh& of(uint32_t node) {
    std::unique_ptr<TriangleBvh>& bvh = bvhs_[node];
    if (!bvh) bvh = std::make_unique<TriangleBvh>(nodes_[node].positions, nodes_[node].indices);
    return *bvh;
  }

 private:
  std::span<const BoundNode> nodes_;
  std::unordered_map<uint32_t, std::unique_ptr<TriangleBvh>> bvhs_;
};

// Original -> proxy: the largest distance from any original point beneath `children` to the
// proxy of `proxy_bvh`, rigorous (see the header).
double original_to_proxy(const TriangleBvh& proxy_bvh, std::span<const BoundNode> nodes,
                         std::span<const uint32_t> children, double slack) {
  double settled = 0.0;
  struct Open {
    double bound;
    uint32_t node;
    int level;
    bool operator<(const Open& o) const { return bound < o.bound; }
  };
  std::priority_queue<Open> open;  // largest bound first
  auto offer = [&](uint32_t c, int level) {
    if (c == BoundNode::kNone) return;
    const BoundNode& n = nodes[c];
    if (n.indices.empty()) return;  // nothing beneath (a proxy is never empty over geometry)
    const double floor = std::max(0.0, settled - n.to_original);
    const double bound = n.to_original + proxy_bvh.farthest_point(n.positions, n.indices, floor, slack);
    if (bound > settled) open.push({bound, c, level});
  };
  for (uint32_t c : children) offer(c, 0);
  while (!open.empty()) {
    const auto [bound, c, level] = open.top();
    open.pop();
    if (bound <= kRefineFactor * settled) {  // every open bound is below it: close enough
      settled = std::max(settled, bound);
      break;
    }
    const BoundNode& n = nodes[c];
    if (n.original || n.cut_off() || level >= kMaxDescent) {
      settled = bound;
      continue;
    }
    offer(n.lower, level + 1);
    offer(n.upper, level + 1);
  }
  return settled;
}

// Proxy -> original for one sample: the distance from q to the original beneath `children`, or
// an upper bound on it <= kRefineFactor x `found` once it is known to be no more (the search
// stops there; `*exact` false).
double sample_to_original(const Vec3& q, std::span<const BoundNode> nodes, std::span<const uint32_t> children,
                          double found, MeshBvhs& bvhs, bool* exact) {
  const double enough = kRefineFactor * found;
  double best = kInfinity;
  struct Open {
    double lower_bound;  // on the distance
    uint32_t node;
    int level;
    bool operator>(const Open& o) const { return lower_bound > o.lower_bound; }
  };
  std::priority_queue<Open, std::vector<Open>, std::greater<Open>> open;
  for (uint32_t c : children) {
    if (c != BoundNode::kNone && !nodes[c].indices.empty()) open.push({box_distance(nodes[c].box, q), c, 0});
  }
  while (!open.empty()) {
    const auto [lower_bound, c, level] = open.top();
    open.pop();
    if (lower_bound >= best) break;
    if (best <= enough) {
      *exact = best <= found;
      return best;
    }
    const BoundNode& n = nodes[c];
    uint32_t t = 0;
    if (n.original) {
      best = std::min(best, bvhs.of(c).nearest_above(q, found, &t));
      continue;
    }
    const double d = bvhs.of(c).nearest_above(q, 0.0, &t);
    best = std::min(best, d + (n.triangle_error.empty() ? 0.0 : n.triangle_error[t]));
    if (n.cut_off() || level >= kMaxDescent) continue;
    const double below = std::max(lower_bound, d - n.to_original);
    for (uint32_t k : {n.lower, n.upper}) {
      if (k != BoundNode::kNone && !nodes[k].indices.empty()) {
        open.push({std::max(below, box_distance(nodes[k].box, q)), k, level + 1});
      }
    }
  }
  *exact = true;
  return best;
}

}  // namespace

MeasuredBound measure_against_original(std::span<const Vec3> positions, std::span<const uint32_t> indices,
                                       std::span<const BoundNode> nodes, std::span<const uint32_t> children) {
  MeasuredBound out;
  const size_t triangles = indices.size() / 3;
  out.triangle_error.assign(triangles, 0.0);
  Aabb original;
  for (uint32_t c : children) {
    if (c != BoundNode::kNone) original.extend(nodes[c].box);
  }
  if (triangles == 0 || original.empty()) return out;
  const TriangleBvh proxy_bvh(positions, indices);
  out.to_original = original_to_proxy(proxy_bvh, nodes, children, kMeasureSlack * glm::length(original.extent()));

  // The proxy's samples: centroids first (most often the farthest, so the searches after them
  // stop sooner), then vertices, then edge midpoints; a triangle's error is the largest of its own.
  MeshBvhs bvhs(nodes);
  double found = 0.0, largest = 0.0;  // the largest exact distance, the largest bound
  auto sample = [&](const Vec3& q) {
    bool exact = false;
    const double d = sample_to_original(q, nodes, children, found, bvhs, &exact);
    if (!std::isfinite(d)) return 0.0;
    if (exact) found = std::max(found, d);
    largest = std::max(largest, d);
    return d;
  };
  auto corner = [&](size_t t, int k) { return positions[indices[3 * t + static_cast<size_t>(k)]]; };
  for (size_t t = 0; t < triangles; ++t) out.triangle_error[t] = sample((corner(t, 0) + corner(t, 1) + corner(t, 2)) / 3.0);
  std::vector<double> at_vertex(positions.size(), -1.0);
  for (size_t t = 0; t < triangles; ++t) {
    double& e = out.triangle_error[t];
    for (int k = 0; k < 3; ++k) {
      double& v = at_vertex[indices[3 * t + static_cast<size_t>(k)]];
      if (v < 0.0) v = sample(corner(t, k));
      e = std::max(e, v);
    }
  }
  for (size_t t = 0; t < triangles; ++t) {
    double& e = out.triangle_error[t];
    for (int k = 0; k < 3; ++k) e = std::max(e, sample(0.5 * (corner(t, k) + corner(t, (k + 1) % 3))));
  }
  out.from_proxy = largest;
  return out;
}

std::vector<BoundNode> bound_summary(std::span<const BoundNode> nodes, uint32_t root, int levels) {
  std::vector<BoundNode> out;
  struct Todo {
    uint32_t from, to;
    int level;
  };
  std::vector<Todo> todo{{root, 0, 0}};
  out.push_back(nodes[root]);
  while (!todo.empty()) {
    const Todo t = todo.back();
    todo.pop_back();
    BoundNode& copy = out[t.to];
    const uint32_t lower = copy.lower, upper = copy.upper;
    copy.lower = copy.upper = BoundNode::kNone;
    // At the last level a proxy is cut off: its bounds stand for what lies beneath.
    if (t.level + 1 >= levels || lower == BoundNode::kNone) continue;
    for (uint32_t k : {lower, upper}) {
      const auto at = static_cast<uint32_t>(out.size());
      out.push_back(nodes[k]);
      todo.push_back({k, at, t.level + 1});
      // `copy` may have moved with the push: set the link through the index.
      if (k == lower) out[t.to].lower = at;
      else out[t.to].upper = at;
    }
  }
  return out;
}

}  // namespace frontier
