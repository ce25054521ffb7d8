// Point-to-mesh distances (contracts in proxy_distance.h). The closest point on a triangle is
// Ericson's region test (Real-Time Collision Detection, 5.1.5), in double.
#include "src/paging/proxy_distance.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace frontier {
namespace {

constexpr uint32_t kLeafTriangles = 4;

Vec3 closest_on_segment(const Vec3& p, const Vec3& s, const Vec3& e) {
  const Vec3 d = e - s;
  const double len2 = glm::dot(d, d);
  const double t = len2 > 0.0 ? std::clamp(glm::dot(p - s, d) / len2, 0.0, 1.0) : 0.0;
  return s + t * d;
}

// Degenerate triangles (collinear or coincident corners) have no interior: the nearest of their
// three edges.
Vec3 closest_on_edges(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 q[3] = {closest_on_segment(p, a, b), closest_on_segment(p, b, c), closest_on_segment(p, c, a)};
  const Vec3* best = &q[0];
  for (const Vec3& x : q) {
    if (glm::dot(p - x, p - x) < glm::dot(p - *best, p - *best)) best = &x;
  }
  return *best;
}

Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const Vec3 n = glm::cross(ab, ac);
  if (!(glm::dot(n, n) > 0.0)) return closest_on_edges(p, a, b, c);
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  const Vec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double denom = d1 - d3;
    return denom > 0.0 ? a + (d1 / denom) * ab : a;
  }
  const Vec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double denom = d2 - d6;
    return denom > 0.0 ? a + (d2 / denom) * ac : a;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double denom = (d4 - d3) + (d5 - d6);
    return denom > 0.0 ? b + ((d4 - d3) / denom) * (c - b) : b;
  }
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) return closest_on_edges(p, a, b, c);  // rounding on a near-degenerate one
  const double v = vb / sum, w = vc / sum;
  return a + v * ab + w * ac;
}

double box_distance2(const Aabb& box, const Vec3& p) {
  const Vec3 d = glm::max(glm::max(box.lo - p, p - box.hi), Vec3(0.0));
  return glm::dot(d, d);
}

}  // namespace

double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  return glm::length(p - closest_on_triangle(p, a, b, c));
}

TriangleBvh::TriangleBvh(std::span<const Vec3> positions, std::span<const uint32_t> indices) {
  triangles_.reserve(indices.size() / 3);
  std::vector<Vec3> centroids;
  centroids.reserve(indices.size() / 3);
  for (size_t i = 0; i + 2 < indices.size(); i += 3) {
    const Triangle t{positions[indices[i]], positions[indices[i + 1]], positions[indices[i + 2]]};
    triangles_.push_back(t);
    centroids.push_back((t.v0 + t.v1 + t.v2) / 3.0);
  }
  if (!triangles_.empty()) {
    nodes_.reserve(2 * triangles_.size() / kLeafTriangles + 1);
    std::vector<uint32_t> order(triangles_.size());
    std::iota(order.begin(), order.end(), 0u);
    build(0, static_cast<uint32_t>(triangles_.size()), order, centroids);
    std::vector<Triangle> sorted(triangles_.size());
    for (size_t i = 0; i < order.size(); ++i) sorted[i] = triangles_[order[i]];
    triangles_ = std::move(sorted);
  }
}

uint32_t TriangleBvh::build(uint32_t first, uint32_t count, std::vector<uint32_t>& order,
                            const std::vector<Vec3>& centroids) {
  const auto index = static_cast<uint32_t>(nodes_.size());
  nodes_.push_back({});
  Aabb box, centre_box;
  for (uint32_t i = first; i < first + count; ++i) {
    const Triangle& t = triangles_[order[i]];
    box.extend(t.v0);
    box.extend(t.v1);
    box.extend(t.v2);
    centre_box.extend(centroids[order[i]]);
  }
  nodes_[index].box = box;
  if (count <= kLeafTriangles) {
    nodes_[index].first = first;
    nodes_[index].count = count;
    return index;
  }
  const Vec3 e = centre_box.extent();
  const int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
  const uint32_t half = count / 2;
  const auto begin = order.begin() + first;
  std::nth_element(begin, begin + half, begin + count,
                   [&](uint32_t a, uint32_t b) { return centroids[a][axis] < centroids[b][axis]; });
  build(first, half, order, centroids);
  nodes_[index].first = build(first + half, count - half, order, centroids);
  return index;
}

double TriangleBvh::distance_above(const Vec3& p, double floor) const {
  if (nodes_.empty()) return kInfinity;
  const double floor2 = floor * floor;
  double best2 = kInfinity;
  // Nodes to visit with the squared distance to their box (a lower bound), nearer child on top.
  // Median splits keep the depth at log2(n / 4) + 1, each level pushing at most two entries.
  struct Entry {
    uint32_t node;
    double d2;
  };
  Entry stack[128];
  int top = 0;
  stack[top++] = {0, box_distance2(nodes_[0].box, p)};
  while (top > 0) {
    const Entry entry = stack[--top];
    if (entry.d2 >= best2) continue;
    const Node& n = nodes_[entry.node];
    if (n.count > 0) {
      for (uint32_t i = n.first; i < n.first + n.count; ++i) {
        const Triangle& t = triangles_[i];
        const Vec3 d = p - closest_on_triangle(p, t.v0, t.v1, t.v2);
        best2 = std::min(best2, glm::dot(d, d));
      }
      if (best2 <= floor2) break;
      continue;
    }
    const uint32_t lower = entry.node + 1, upper = n.first;
    const double dl = box_distance2(nodes_[lower].box, p), du = box_distance2(nodes_[upper].box, p);
    if (dl < du) {
      if (du < best2) stack[top++] = {upper, du};
      stack[top++] = {lower, dl};
    } else {
      if (dl < best2) stack[top++] = {lower, dl};
      stack[top++] = {upper, du};
    }
  }
  return std::sqrt(best2);
}

double farthest_sample(std::span<const Vec3> samples, const TriangleBvh& bvh) {
  double farthest = 0.0;
  for (const Vec3& p : samples) farthest = std::max(farthest, bvh.distance_above(p, farthest));
  return farthest;
}

}  // namespace frontier
