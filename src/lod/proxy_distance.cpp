// Point-to-mesh distances (contracts in proxy_distance.h). The closest point on a triangle is
// Ericson's region test (Real-Time Collision Detection, 5.1.5), in double.
#include "src/lod/proxy_distance.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace frontier {
namespace {

constexpr uint32_t kLeafTriangles = 4;
// farthest_on_triangle splits a triangle at most this deep (1/1024 of its longest edge; the slack and floor stop it sooner).
constexpr int kMaxSplits = 10;

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

double box_distance2(const Aabb& box, const Vec3& p) {
  const Vec3 d = glm::max(glm::max(box.lo - p, p - box.hi), Vec3(0.0));
  return glm::dot(d, d);
}

}  // namespace

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

double point_triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  return glm::length(p - closest_on_triangle(p, a, b, c));
}

namespace {

// An upper bound on the largest distance from a point of the triangle `corners` to s ∪ t, two
// triangles with an edge in common; +infinity if they have none. The plane through that edge
// bisecting their dihedral angle splits `corners` in two convex polygons; on each, the distance to
// its side's triangle is convex and peaks at a polygon vertex (a corner or an edge's crossing).
double straddling_bound(const Vec3 (&corners)[3], const Triangle& s, const Triangle& t) {
  const Vec3 sv[3] = {s.v0, s.v1, s.v2}, tv[3] = {t.v0, t.v1, t.v2};
  int shared_s[2], shared_t[2], count = 0;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (sv[i] == tv[j] && count < 2) {
        shared_s[count] = i;
        shared_t[count] = j;
        ++count;
      }
    }
  }
  if (count != 2) return kInfinity;
  const Vec3 e0 = sv[shared_s[0]], e = sv[shared_s[1]] - e0;
  const double e2 = glm::dot(e, e);
  if (!(e2 > 0.0)) return kInfinity;
  // Unit vectors in each triangle's plane, perpendicular to the edge, pointing into it.
  auto inward = [&](const Vec3& apex) {
    const Vec3 d = apex - e0;
    const Vec3 u = d - e * (glm::dot(d, e) / e2);
    const double l = glm::length(u);
    return l > 0.0 ? u / l : Vec3(0.0);
  };
  const Vec3 us = inward(sv[3 - shared_s[0] - shared_s[1]]);
  const Vec3 ut = inward(tv[3 - shared_t[0] - shared_t[1]]);
  const Vec3 n = us - ut;  // s's side of the bisector is where dot(p - e0, n) >= 0
  if (!(glm::dot(n, n) > 1e-24)) return kInfinity;  // folded flat onto each other
  double side[3];
  for (int k = 0; k < 3; ++k) side[k] = glm::dot(corners[k] - e0, n);
  double bound = 0.0;
  auto measure = [&](const Vec3& p, bool on_s, bool on_t) {
    if (on_s) bound = std::max(bound, point_triangle_distance(p, s.v0, s.v1, s.v2));
    if (on_t) bound = std::max(bound, point_triangle_distance(p, t.v0, t.v1, t.v2));
  };
  for (int k = 0; k < 3; ++k) {
    measure(corners[k], side[k] >= 0.0, side[k] <= 0.0);
    const int l = (k + 1) % 3;
    if ((side[k] < 0.0 && side[l] > 0.0) || (side[k] > 0.0 && side[l] < 0.0)) {
      const double f = side[k] / (side[k] - side[l]);
      measure(corners[k] + (corners[l] - corners[k]) * f, true, true);
    }
  }
  return bound;
}

}  // namespace

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
    order_ = std::move(order);
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

// The squared distance to the nearest triangle (its index into triangles_ in `*nearest`), or some
// value <= floor^2 once a triangle within `floor` is met.
double TriangleBvh::search(const Vec3& p, double floor, uint32_t* nearest) const {
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
        const double d2 = glm::dot(d, d);
        if (d2 < best2) {
          best2 = d2;
          if (nearest != nullptr) *nearest = i;
        }
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
  return best2;
}

double TriangleBvh::distance_above(const Vec3& p, double floor) const {
  if (nodes_.empty()) return kInfinity;
  return std::sqrt(search(p, floor, nullptr));
}

uint32_t TriangleBvh::nearest(const Vec3& p) const {
  if (nodes_.empty()) return UINT32_MAX;
  uint32_t at = 0;
  search(p, 0.0, &at);
  return order_[at];
}

double TriangleBvh::nearest_above(const Vec3& p, double floor, uint32_t* triangle) const {
  *triangle = UINT32_MAX;
  if (nodes_.empty()) return kInfinity;
  uint32_t at = 0;
  const double d = std::sqrt(search(p, floor, &at));
  *triangle = order_[at];
  return d;
}

double TriangleBvh::farthest_on_triangle(const Vec3& a, const Vec3& b, const Vec3& c, double floor,
                                         double slack) const {
  if (nodes_.empty()) return kInfinity;
  const Vec3 corners[3] = {a, b, c};
  Corner near[3];
  for (int k = 0; k < 3; ++k) near[k].d = std::sqrt(search(corners[k], 0.0, &near[k].triangle));
  return farthest_on_triangle(corners, near, floor, slack, kMaxSplits);
}

// abc with its corners' exact distances and nearest triangles (leaf order) already known.
double TriangleBvh::farthest_on_triangle(const Vec3 (&corners)[3], const Corner (&near)[3], double floor,
                                         double slack, int depth) const {
  const Vec3 &a = corners[0], &b = corners[1], &c = corners[2];
  const double lower = std::max({near[0].d, near[1].d, near[2].d});
  // Every point lies within longest / sqrt 3 of a corner (the circumradius bound), and the
  // distance is 1-Lipschitz.
  const double longest = std::sqrt(std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)}));
  double best = lower + longest / std::sqrt(3.0);
  if (best <= floor) return best;
  for (int k = 0; k < 3; ++k) {
    if ((k > 0 && near[k].triangle == near[0].triangle) || (k > 1 && near[k].triangle == near[1].triangle)) continue;
    const Triangle& t = triangles_[near[k].triangle];
    double m = 0.0;
    for (const Vec3& p : corners) m = std::max(m, point_triangle_distance(p, t.v0, t.v1, t.v2));
    best = std::min(best, m);
  }
  // Corners nearest to two triangles with an edge in common (abc straddles a crease or a flat
  // mesh's edge): each side of the plane bisecting their dihedral angle is bounded by its own.
  for (int i = 0; i < 3 && best > std::max(floor, 1.05 * lower + slack); ++i) {
    for (int j = i + 1; j < 3; ++j) {
      if (near[i].triangle == near[j].triangle) continue;
      best = std::min(best, straddling_bound(corners, triangles_[near[i].triangle], triangles_[near[j].triangle]));
    }
  }
  if (depth == 0 || best <= std::max(floor, 1.05 * lower + slack)) return best;
  const Vec3 mid[3] = {0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)};
  Corner at_mid[3];
  for (int k = 0; k < 3; ++k) at_mid[k].d = std::sqrt(search(mid[k], 0.0, &at_mid[k].triangle));
  const Vec3 pieces[4][3] = {{mid[0], mid[1], mid[2]}, {a, mid[0], mid[2]}, {mid[0], b, mid[1]}, {mid[2], mid[1], c}};
  const Corner piece_near[4][3] = {{at_mid[0], at_mid[1], at_mid[2]},
                                   {near[0], at_mid[0], at_mid[2]},
                                   {at_mid[0], near[1], at_mid[1]},
                                   {at_mid[2], at_mid[1], near[2]}};
  double split = 0.0;
  for (int k = 0; k < 4; ++k) {
    split = std::max(split, farthest_on_triangle(pieces[k], piece_near[k], std::max(floor, split), slack, depth - 1));
  }
  return std::min(best, split);
}

double TriangleBvh::farthest_point(std::span<const Vec3> positions, std::span<const uint32_t> indices, double floor,
                                   double slack) const {
  if (indices.empty()) return 0.0;
  if (nodes_.empty()) return kInfinity;
  // Each vertex's distance once (a vertex is shared by about six triangles); the largest of them
  // is a floor no triangle needs to be measured below. Below the floor so far, any triangle within
  // it will do (search stops there; its distance bounds the vertex's from above), and most
  // triangles are settled by those bounds (corners + longest edge / sqrt 3 <= floor). The others'
  // corners are measured exactly, once, before their triangle is.
  std::vector<Corner> near(positions.size());
  std::vector<uint8_t> state(positions.size(), 0);  // 0 unused, 1 bounded, 2 exact
  for (uint32_t i : indices) state[i] = 1;
  for (size_t v = 0; v < positions.size(); ++v) {
    if (state[v] == 0) continue;
    const double d2 = search(positions[v], floor, &near[v].triangle);
    near[v].d = std::sqrt(d2);
    if (d2 > floor * floor) state[v] = 2;
    floor = std::max(floor, near[v].d);
  }
  double farthest = floor;
  for (size_t i = 0; i + 2 < indices.size(); i += 3) {
    const uint32_t* k = &indices[i];
    const Vec3 corners[3] = {positions[k[0]], positions[k[1]], positions[k[2]]};
    const double longest = std::sqrt(std::max({glm::dot(corners[1] - corners[0], corners[1] - corners[0]),
                                               glm::dot(corners[2] - corners[1], corners[2] - corners[1]),
                                               glm::dot(corners[0] - corners[2], corners[0] - corners[2])}));
    if (std::max({near[k[0]].d, near[k[1]].d, near[k[2]].d}) + longest / std::sqrt(3.0) <= farthest) continue;
    for (int j = 0; j < 3; ++j) {
      if (state[k[j]] == 2) continue;
      near[k[j]].d = std::sqrt(search(corners[j], 0.0, &near[k[j]].triangle));
      state[k[j]] = 2;
    }
    const Corner corner_near[3] = {near[k[0]], near[k[1]], near[k[2]]};
    farthest = std::max(farthest, farthest_on_triangle(corners, corner_near, farthest, slack, kMaxSplits));
  }
  return farthest;
}

double farthest_triangle_point(std::span<const Vec3> positions, std::span<const uint32_t> indices,
                               const TriangleBvh& bvh, double floor, double slack) {
  return bvh.farthest_point(positions, indices, floor, slack);
}

double farthest_sample(std::span<const Vec3> samples, const TriangleBvh& bvh) {
  double farthest = 0.0;
  for (const Vec3& p : samples) farthest = std::max(farthest, bvh.distance_above(p, farthest));
  return farthest;
}

}  // namespace frontier
