// The ground height map (see header). A triangle raises only the cells its xy projection meets
// (separating-axis test of the cell rectangle against the three edges); over such a cell the
// triangle's height is at most its plane's highest value at the cell's corners, and at most its
// highest vertex. Near-vertical triangles (no usable plane) raise their xy box to their top.
#include "data_gen/ground.h"

#include "src/core/primitives.h"
#include "src/io/scene_reader.h"
#include "src/io/triangulate.h"

#include <algorithm>
#include <cmath>
#include <deque>

namespace frontier::gen {
namespace {

// out[k] = max of in[j] for |j - k| <= half (clamped to [0, n)), along a strided line.
void sliding_max(const double* in, double* out, int64_t n, int64_t stride, int64_t half) {
  std::deque<int64_t> window;  // indices with decreasing values
  int64_t next = 0;
  for (int64_t k = 0; k < n; ++k) {
    for (; next < n && next <= k + half; ++next) {
      while (!window.empty() && in[window.back() * stride] <= in[next * stride]) window.pop_back();
      window.push_back(next);
    }
    while (window.front() < k - half) window.pop_front();
    out[k * stride] = in[window.front() * stride];
  }
}

}  // namespace

GroundMap::GroundMap(const Aabb& bounds, int max_cells_per_side) : x0_(bounds.lo.x), y0_(bounds.lo.y) {
  const Vec3 e = bounds.extent();
  const double longer = std::max(e.x, e.y);
  const int most = std::max(1, max_cells_per_side);
  cell_ = longer > 0.0 ? longer / most : 1.0;
  nx_ = std::clamp(static_cast<int>(std::ceil(e.x / cell_)), 1, most);
  ny_ = std::clamp(static_cast<int>(std::ceil(e.y / cell_)), 1, most);
  top_.assign(static_cast<size_t>(nx_) * static_cast<size_t>(ny_), -kInfinity);
}

int64_t GroundMap::column(double x) const { return static_cast<int64_t>(std::floor((x - x0_) / cell_)); }
int64_t GroundMap::row(double y) const { return static_cast<int64_t>(std::floor((y - y0_) / cell_)); }

void GroundMap::add_box(const Aabb& box) {
  const int64_t i0 = std::max<int64_t>(0, column(box.lo.x)), i1 = std::min<int64_t>(nx_ - 1, column(box.hi.x));
  const int64_t j0 = std::max<int64_t>(0, row(box.lo.y)), j1 = std::min<int64_t>(ny_ - 1, row(box.hi.y));
  for (int64_t j = j0; j <= j1; ++j)
    for (int64_t i = i0; i <= i1; ++i) top(i, j) = std::max(top(i, j), box.hi.z);
}

void GroundMap::add_triangle(const Vec3& a, const Vec3& b, const Vec3& c) {
  Aabb box;
  box.extend(a);
  box.extend(b);
  box.extend(c);
  const Vec3 n = glm::cross(b - a, c - a);
  const double len = glm::length(n);
  if (!(len > 0.0) || std::abs(n.z) <= 1e-6 * len) {
    add_box(box);
    return;
  }
  const double zmax = box.hi.z;
  const double gx = -n.x / n.z, gy = -n.y / n.z;  // the plane: z = a.z + gx (x - a.x) + gy (y - a.y)
  const double side = n.z > 0.0 ? 1.0 : -1.0;     // edge functions are >= 0 inside
  const Vec3 p[3] = {a, b, c};
  const int64_t i0 = std::max<int64_t>(0, column(box.lo.x)), i1 = std::min<int64_t>(nx_ - 1, column(box.hi.x));
  const int64_t j0 = std::max<int64_t>(0, row(box.lo.y)), j1 = std::min<int64_t>(ny_ - 1, row(box.hi.y));
  for (int64_t j = j0; j <= j1; ++j) {
    const double yl = y0_ + static_cast<double>(j) * cell_, yh = yl + cell_;
    for (int64_t i = i0; i <= i1; ++i) {
      const double xl = x0_ + static_cast<double>(i) * cell_, xh = xl + cell_;
      bool apart = false;
      for (int k = 0; k < 3 && !apart; ++k) {
        const Vec3& s = p[k];
        const Vec3& t = p[(k + 1) % 3];
        const double ex = t.x - s.x, ey = t.y - s.y;
        // The cell corner where the edge function side * cross(e, q - s) is largest.
        const double qx = -side * ey > 0.0 ? xh : xl, qy = side * ex > 0.0 ? yh : yl;
        const double f = side * (ex * (qy - s.y) - ey * (qx - s.x));
        const double slack = 1e-9 * (std::abs(ex) + std::abs(ey)) * (std::abs(ex) + std::abs(ey) + cell_);
        apart = f < -slack;
      }
      if (apart) continue;
      const double over = a.z + std::max(gx * (xl - a.x), gx * (xh - a.x)) + std::max(gy * (yl - a.y), gy * (yh - a.y));
      top(i, j) = std::max(top(i, j), std::min(over, zmax));
    }
  }
}

double GroundMap::highest_near(double x, double y, double radius) const {
  // Beyond the grid by more than the radius and the reach of widened(): nothing there.
  const double far = radius + reach_;
  if (x + far < x0_ || y + far < y0_ || x - far > x0_ + static_cast<double>(nx_) * cell_ ||
      y - far > y0_ + static_cast<double>(ny_) * cell_) return -kInfinity;
  const int64_t i0 = std::clamp<int64_t>(column(x - radius), 0, nx_ - 1), i1 = std::clamp<int64_t>(column(x + radius), 0, nx_ - 1);
  const int64_t j0 = std::clamp<int64_t>(row(y - radius), 0, ny_ - 1), j1 = std::clamp<int64_t>(row(y + radius), 0, ny_ - 1);
  double best = -kInfinity;
  for (int64_t j = j0; j <= j1; ++j)
    for (int64_t i = i0; i <= i1; ++i) best = std::max(best, top(i, j));
  return best;
}

GroundMap GroundMap::widened(double radius) const {
  // Beyond max(nx, ny) cells every cell already sees the whole grid.
  const int64_t half = std::min<int64_t>(std::max(nx_, ny_), static_cast<int64_t>(std::ceil(radius / cell_)));
  GroundMap out = *this;
  out.reach_ = reach_ + radius;
  std::vector<double> rows(top_.size());
  for (int64_t j = 0; j < ny_; ++j)
    sliding_max(&top_[static_cast<size_t>(j * nx_)], &rows[static_cast<size_t>(j * nx_)], nx_, 1, half);
  for (int64_t i = 0; i < nx_; ++i) sliding_max(&rows[static_cast<size_t>(i)], &out.top_[static_cast<size_t>(i)], ny_, nx_, half);
  return out;
}

Result<GroundMap> scan_ground(const std::string& model, const Aabb& bounds) {
  auto reader = open_scene_reader(model);
  if (!reader) return reader.status();
  GroundMap ground(bounds);
  InputPrimitive prim;
  std::vector<std::array<uint32_t, 3>> triangles;
  for (bool end = false;;) {
    if (Status s = (*reader)->next(prim, end); !s) return s;
    if (end) break;
    switch (prim.kind) {
      case InputPrimitive::Kind::Polygon: {
        const auto& v = prim.vertices;
        if (v.size() == 3) {
          ground.add_triangle(v[0], v[1], v[2]);
          break;
        }
        triangles.clear();
        if (triangulate_polygon(v, triangles)) {
          for (const auto& t : triangles) ground.add_triangle(v[t[0]], v[t[1]], v[t[2]]);
        } else {
          Aabb box;
          for (const Vec3& p : v) box.extend(p);
          ground.add_box(box);
        }
        break;
      }
      case InputPrimitive::Kind::Sphere: ground.add_box(bounds_of(prim.sphere)); break;
      case InputPrimitive::Kind::Cone: ground.add_box(bounds_of(prim.cone)); break;
      case InputPrimitive::Kind::Box: ground.add_box(bounds_of(prim.box)); break;
      case InputPrimitive::Kind::Quadric: ground.add_box(bounds_of(prim.quadric)); break;
    }
  }
  return ground;
}

}  // namespace frontier::gen
