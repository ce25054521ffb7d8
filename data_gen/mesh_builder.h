// MeshBuilder: closed, outward-oriented solids (boxes, capped cylinders, spheres) appended to
// a MeshPiece, or only counted.
//
// Invariants of every solid it emits: a closed 2-manifold (each edge used by exactly two of
// its triangles, in opposite directions), triangles counter-clockwise seen from outside, no
// zero-area triangle for sizes the callers use (>= 1 mm), vertices shared within the solid
// only (vertex dedup is by construction; solids never share vertices with each other).
// With normals in the layout, faces of boxes and cylinder caps get their own vertices so that
// normals stay flat; positions then repeat, but the solid is still closed by position.
//
// A builder made without a piece counts vertices and triangles and does nothing else. Because
// callers run the same code in both modes (drawing the same random numbers), a counting pass
// predicts the written counts exactly; PlyWriter rejects any difference.
#pragma once

#include "src/core/geometry.h"
#include "src/io/ply_writer.h"

#include <cstdint>

namespace frontier::gen {

struct Rgb {
  uint8_t r = 200, g = 200, b = 200;
  bool operator==(const Rgb&) const = default;
};

class MeshBuilder {
 public:
  // `out == nullptr` makes a counting builder.
  MeshBuilder(MeshPiece* out, const PlyVertexLayout& layout) : out_(out), layout_(layout) {}

  bool counting() const { return out_ == nullptr; }
  uint64_t vertices() const { return vertices_; }
  uint64_t triangles() const { return triangles_; }

  // Axis-aligned box. REQUIRES lo < hi on every axis.
  void box(const Vec3& lo, const Vec3& hi, Rgb color);
  // Closed cylinder from a to b (radius r, `segments` >= 3 around, `rings` >= 1 along).
  void cylinder(const Vec3& a, const Vec3& b, double radius, int segments, int rings, Rgb color);
  // Closed truncated cone (radii > 0), `segments` around, one ring along.
  void frustum(const Vec3& a, double radius_a, const Vec3& b, double radius_b, int segments,
               Rgb color);
  // Latitude-longitude sphere: `segments` >= 3 around, max(2, segments / 2) bands.
  void sphere(const Vec3& center, double radius, int segments, Rgb color);

  // Bands of a sphere() with `segments` around.
  static int sphere_bands(int segments) { return segments / 2 < 2 ? 2 : segments / 2; }

  // Raw access for height fields and other meshes that are not solids: each call counts, and
  // writes only when emitting (a counting builder returns index 0).
  uint32_t raw_vertex(const Vec3& p, const Vec3& n, Rgb c) {
    ++vertices_;
    return counting() ? 0 : vertex(p, n, c);
  }
  void raw_triangle(uint32_t a, uint32_t b, uint32_t c) {
    ++triangles_;
    if (!counting()) tri(a, b, c);
  }
  // Adds counts without emitting: for callers that skip the work when counting().
  void add_counts(uint64_t vertices, uint64_t triangles) {
    vertices_ += vertices;
    triangles_ += triangles;
  }
  MeshPiece* piece() { return out_; }

 private:
  uint32_t vertex(const Vec3& p, const Vec3& n, Rgb c);
  void tri(uint32_t a, uint32_t b, uint32_t c) {
    out_->indices.push_back(a);
    out_->indices.push_back(b);
    out_->indices.push_back(c);
  }
  void quad(uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
    tri(a, b, c);
    tri(a, c, d);
  }
  void tube(const Vec3& a, double ra, const Vec3& b, double rb, int segments, int rings,
            Rgb color);

  MeshPiece* out_;
  PlyVertexLayout layout_;
  uint64_t vertices_ = 0, triangles_ = 0;
};

}  // namespace frontier::gen
