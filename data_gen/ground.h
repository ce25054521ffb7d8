// The ground under a fly path: a height map of the highest geometry over a grid of the model's
// xy bounds, read from the model file in one streaming pass.
//
// Invariant (conservative): for every cell, top(cell) >= the largest z of any surface point of
// the model whose (x, y) lies in the cell (closed cell). Triangles are bounded exactly by their
// plane over the cell, clamped to their highest vertex; curved primitives (spheres, cones,
// boxes, quadrics) by their bounding box. Cells nothing covers hold -infinity.
//
// Memory: the grid only (at most kMaxCellsPerSide^2 doubles: 8 MiB, and as much per widened()); the
// model is read through src/io's streaming readers (scene_reader.h).
#pragma once

#include "src/core/geometry.h"
#include "src/core/status.h"

#include <cstdint>
#include <string>
#include <vector>

namespace frontier::gen {

class GroundMap {
 public:
  static constexpr int kMaxCellsPerSide = 1024;

  // An empty map (every cell -infinity) over the xy extent of `bounds`, with square cells and
  // at most kMaxCellsPerSide along the longer side. REQUIRES: bounds not empty.
  explicit GroundMap(const Aabb& bounds, int max_cells_per_side = kMaxCellsPerSide);

  // Raises the cells a triangle covers to (an upper bound of) its height over them.
  void add_triangle(const Vec3& a, const Vec3& b, const Vec3& c);
  // Raises the cells under the xy extent of `box` to box.hi.z.
  void add_box(const Aabb& box);

  // The highest ground anywhere within `radius` (horizontal, square neighbourhood) of (x, y),
  // or -infinity when there is none. O(cells in the neighbourhood); see widen().
  double highest_near(double x, double y, double radius) const;
  // A map whose highest_near(x, y, 0) bounds this map's highest_near(x, y, radius) from above,
  // in O(1) per query: every cell holds the maximum of the cells within ceil(radius / cell);
  // a query outside the grid but within `radius` of it reads the nearest edge cell.
  GroundMap widened(double radius) const;

  double cell_size() const { return cell_; }
  int cells_x() const { return nx_; }
  int cells_y() const { return ny_; }

 private:
  // Cell index of a coordinate (may be outside [0, n)).
  int64_t column(double x) const;
  int64_t row(double y) const;
  double& top(int64_t i, int64_t j) { return top_[static_cast<size_t>(j * nx_ + i)]; }
  double top(int64_t i, int64_t j) const { return top_[static_cast<size_t>(j * nx_ + i)]; }

  double x0_ = 0.0, y0_ = 0.0, cell_ = 1.0;
  double reach_ = 0.0;  // how far outside the grid queries still see its edge (widened maps)
  int nx_ = 1, ny_ = 1;
  std::vector<double> top_;
};

// Reads `model` (any format src/io reads: .ply, .nff, .obj, .off, .stl) in one streaming pass
// into a GroundMap over `bounds` (the model's bounds). Errors: the reader's, naming the file.
Result<GroundMap> scan_ground(const std::string& model, const Aabb& bounds);

}  // namespace frontier::gen
