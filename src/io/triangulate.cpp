// triangulate_polygon: ear clipping of a simple planar polygon (possibly concave, either
// winding) in the coordinate plane its Newell normal is most aligned with.
//
// The polygon is projected (relative to its first vertex, so far-from-origin models keep their
// precision) and oriented counter-clockwise in 2D; ears are clipped as (prev, v, next), which
// keeps the input's winding in every triangle. Ears are preferred strictly convex and empty
// (no other vertex inside or on them); when none is left (collinear runs, rounding) a
// zero-area ear is taken, and as a last resort the most convex vertex is clipped, so the result
// always has exactly n-2 triangles covering the polygon's area. O(n²) per polygon in the usual
// case.
#include "src/io/triangulate.h"

#include <cmath>

namespace frontier {
namespace {

struct P2 {
  double x, y;
};

// Twice the signed area of triangle abc (positive when counter-clockwise).
inline double area2(const P2& a, const P2& b, const P2& c) {
  return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

inline bool same(const P2& a, const P2& b) { return a.x == b.x && a.y == b.y; }

class EarClipper {
 public:
  explicit EarClipper(std::vector<P2> pts) : pts_(std::move(pts)), prev_(pts_.size()), next_(pts_.size()) {
    const auto n = static_cast<uint32_t>(pts_.size());
    for (uint32_t i = 0; i < n; ++i) {
      prev_[i] = i == 0 ? n - 1 : i - 1;
      next_[i] = i + 1 == n ? 0 : i + 1;
    }
  }

  void run(std::vector<std::array<uint32_t, 3>>& out) {
    size_t remaining = pts_.size();
    uint32_t start = 0;
    while (remaining > 3) {
      uint32_t ear = find_ear(start, remaining, /*strict=*/true);
      if (ear == kNone) ear = find_ear(start, remaining, /*strict=*/false);
      if (ear == kNone) ear = most_convex(start, remaining);
      out.push_back({prev_[ear], ear, next_[ear]});
      next_[prev_[ear]] = next_[ear];
      prev_[next_[ear]] = prev_[ear];
      start = next_[ear];
      --remaining;
    }
    out.push_back({prev_[start], start, next_[start]});
  }

 private:
  static constexpr uint32_t kNone = UINT32_MAX;

  uint32_t find_ear(uint32_t start, size_t remaining, bool strict) const {
    uint32_t i = start;
    for (size_t k = 0; k < remaining; ++k, i = next_[i]) {
      if (is_ear(i, strict)) return i;
    }
    return kNone;
  }

  uint32_t most_convex(uint32_t start, size_t remaining) const {
    uint32_t best = start, i = start;
    double best_area = -kInfinity;
    for (size_t k = 0; k < remaining; ++k, i = next_[i]) {
      const double a = area2(pts_[prev_[i]], pts_[i], pts_[next_[i]]);
      if (a > best_area) {
        best_area = a;
        best = i;
      }
    }
    return best;
  }

  bool is_ear(uint32_t i, bool strict) const {
    const uint32_t ia = prev_[i], ic = next_[i];
    const P2 &a = pts_[ia], &b = pts_[i], &c = pts_[ic];
    const double ar = area2(a, b, c);
    if (strict ? !(ar > 0.0) : !(ar >= 0.0)) return false;
    const double lo_x = std::min({a.x, b.x, c.x}), hi_x = std::max({a.x, b.x, c.x});
    const double lo_y = std::min({a.y, b.y, c.y}), hi_y = std::max({a.y, b.y, c.y});
    // No other remaining vertex may lie inside the ear or on its border.
    for (uint32_t j = next_[ic]; j != ia; j = next_[j]) {
      const P2& p = pts_[j];
      if (p.x < lo_x || p.x > hi_x || p.y < lo_y || p.y > hi_y) continue;
      if (same(p, a) || same(p, b) || same(p, c)) continue;
      if (area2(a, b, p) >= 0.0 && area2(b, c, p) >= 0.0 && area2(c, a, p) >= 0.0) return false;
    }
    return true;
  }

  std::vector<P2> pts_;
  std::vector<uint32_t> prev_, next_;
};

}  // namespace

bool triangulate_polygon(const std::vector<Vec3>& vertices, std::vector<std::array<uint32_t, 3>>& out) {
  out.clear();
  const size_t n = vertices.size();
  if (n < 3 || n > UINT32_MAX) return false;
  const Vec3 origin = vertices[0];
  // Newell normal (twice the vector area) and the polygon's extent, relative to vertex 0.
  Vec3 normal(0.0);
  Aabb box;
  for (size_t i = 0; i < n; ++i) {
    const Vec3 a = vertices[i] - origin;
    const Vec3 b = vertices[i + 1 == n ? 0 : i + 1] - origin;
    normal += glm::cross(a, b);
    box.extend(a);
  }
  const Vec3 e = box.extent();
  const double scale2 = glm::dot(e, e);
  const double len = glm::length(normal);
  if (!(len > 1e-14 * scale2) || !std::isfinite(len)) return false;  // also NaN coordinates
  if (n == 3) {
    out.push_back({0, 1, 2});
    return true;
  }
  // Drop the axis the normal is most aligned with; (u, v) in cyclic order so that the 2D area
  // has the sign of normal[axis]. Flip u when it is negative: the 2D polygon is then CCW.
  const Vec3 an = glm::abs(normal);
  const int axis = an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2);
  const int u = (axis + 1) % 3, v = (axis + 2) % 3;
  const double flip = normal[axis] < 0.0 ? -1.0 : 1.0;
  std::vector<P2> pts(n);
  for (size_t i = 0; i < n; ++i) {
    const Vec3 d = vertices[i] - origin;
    pts[i] = {flip * d[u], d[v]};
  }
  out.reserve(n - 2);
  EarClipper(std::move(pts)).run(out);
  return true;
}

}  // namespace frontier
