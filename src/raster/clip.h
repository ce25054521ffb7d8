// Clipping to the view, shared by the z-buffer rasterizer (src/raster/raster.h) and the BSP
// coverage-mask renderer (src/raster/bsp_render.cpp): the projection into clip space, the
// clip planes, Sutherland-Hodgman clipping of a convex polygon, snapping to a sub-pixel
// lattice, and integer edge functions with the top-left rule.
//
// Invariants:
//  * Clip space is (x w, y w, w), w the distance along the view axis, with pixel centres at
//    integer x = X / w, y = Y / w (ClipTransform): pixel (x, y) is where view.direction(x, y)
//    points.
//  * The planes are the near plane (w >= near) and a band one pixel outside the outermost pixel
//    centres (-1 <= x <= width, -1 <= y <= height): clipping never moves an edge across a pixel
//    centre.
//  * A crossing is interpolated from the edge's inside end towards its outside one, whichever
//    polygon clips it, so two polygons sharing an edge compute bit-identical points: shared
//    edges stay shared through clipping.
//  * The result is a function of the polygon alone (the automatic near plane too), never of
//    batching, order or threads.
#pragma once

#include "src/core/geometry.h"
#include "src/core/view.h"

#include <glm/mat3x3.hpp>

#include <cstdint>

namespace frontier {

// World space -> the rasterizer's clip space: (x w, y w, w), w the distance along the view axis
// (so 1/w is what the depth test compares), pixel centres at integer x = X / w, y = Y / w.
struct ClipTransform {
  Vec3 eye{0.0};
  glm::dmat3 to_clip{1.0};  // inverse of the View's pixel-direction map (step_x, step_y, base)

  // view.direction(x, y) = M (x, y, 1) with M's columns step_x, step_y, base; so a point at
  // offset d = lambda * direction(x, y) from the eye has M^-1 d = lambda (x, y, 1).
  static ClipTransform of(const View& view) {
    return {view.eye, glm::inverse(glm::dmat3(view.step_x, view.step_y, view.base))};
  }
  Vec3 operator()(const Vec3& world) const { return to_clip * (world - eye); }
};

// The five planes of a view in clip space: plane 0 is the near plane, then x >= -1, x <= width,
// y >= -1, y <= height.
struct ClipPlanes {
  static constexpr int kCount = 5;
  static constexpr double kAutoNearFraction = 1e-9;

  double near = 0.0, width = 0.0, height = 0.0;

  // Near plane: view.near, else near_floor, else kAutoNearFraction of the polygon's farthest w
  // (perspective projection needs w > 0; parts nearer than that are lost).
  static ClipPlanes of(const View& view, double near_floor, double farthest_w) {
    const double near = view.near > 0.0 ? view.near : near_floor > 0.0 ? near_floor : kAutoNearFraction * farthest_w;
    return {near, double(view.width), double(view.height)};
  }
  // Signed distance of clip-space `v` to `plane` (inside: >= 0).
  double distance(int plane, const Vec3& v) const {
    switch (plane) {
      case 0: return v.z - near;
      case 1: return v.x + v.z;
      case 2: return width * v.z - v.x;
      case 3: return v.y + v.z;
      default: return height * v.z - v.y;
    }
  }
  // Bit p set: `v` is outside plane p.
  unsigned outside(const Vec3& v) const {
    unsigned code = 0;
    for (int p = 0; p < kCount; ++p) code |= distance(p, v) < 0.0 ? 1u << p : 0u;
    return code;
  }
};

struct ClippedPolygon {
  const Vec3* vertices = nullptr;  // in one of the caller's two buffers
  int size = 0;                    // < 3: nothing of the polygon is in view
  unsigned crossed = 0;            // planes some input vertex is outside of (bit 0: near)
};

// Clips the convex clip-space polygon a[0, n) to `planes`: against each plane that some input
// vertex is outside of, in plane order; nothing when every vertex is outside one plane (size 0).
// a and b are buffers of `capacity` vertices (a holds the input; both are overwritten). A
// clipped polygon has at most n + 5 vertices up to rounding (a vertex within rounding of a
// plane may cross it twice); vertices beyond the capacity are dropped.
ClippedPolygon clip_to_view(Vec3* a, Vec3* b, int n, int capacity, const ClipPlanes& planes);

// Screen bounds of a snapped polygon, in snapped units.
struct SnapBox {
  int64_t xmin = INT64_MAX, xmax = INT64_MIN, ymin = INT64_MAX, ymax = INT64_MIN;
};

// Projects clipped vertices v[0, n) to the screen, clamped to the band [-1, width] x
// [-1, height], and snaps them to integers in units of 2^-bits pixel (px, py, room for n).
// Returns false when a vertex is not in front of the eye (w <= 0: only rounding leaves one
// after near clipping).
bool snap_polygon(const Vec3* v, int n, int bits, const ClipPlanes& planes, int64_t* px, int64_t* py, SnapBox& box);

// An edge function E(X, Y) = a (X - ox) + b (Y - oy) + bias in snapped units, oriented so that
// the inside is E >= 0; bias is -1 on edges that are neither top nor left (y points down), so a
// sample on an edge shared by two polygons belongs to exactly one of them.
struct EdgeFunction {
  int64_t a, b, ox, oy, bias;
};

// The edge functions of the snapped polygon (px, py)[0, n), zero-length edges skipped, into
// `edges` (room for n). Returns how many, 0 when the polygon has no area. Exact for
// |coordinates| < 2^62 (the area is summed in 128 bits).
int edge_functions(const int64_t* px, const int64_t* py, int n, EdgeFunction* edges);

}  // namespace frontier
