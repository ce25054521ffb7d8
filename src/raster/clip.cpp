// Clipping, snapping and edge functions (see clip.h for the invariants they keep).
#include "src/raster/clip.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace frontier {
namespace {

__extension__ typedef __int128 Int128;

// Sutherland-Hodgman against one plane: in[0, n) -> out, at most `capacity` vertices. The
// crossing on an edge is interpolated from its inside end.
int clip_to_plane(const Vec3* in, int n, Vec3* out, int capacity, const ClipPlanes& planes, int plane) {
  int size = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3& a = in[i];
    const Vec3& b = in[(i + 1) % n];
    const double da = planes.distance(plane, a), db = planes.distance(plane, b);
    const bool a_in = da >= 0.0, b_in = db >= 0.0;
    if (a_in && size < capacity) out[size++] = a;
    if (a_in != b_in && size < capacity) {
      const Vec3& inside = a_in ? a : b;
      const Vec3& outside = a_in ? b : a;
      const double d_in = a_in ? da : db, d_out = a_in ? db : da;
      out[size++] = inside + (d_in / (d_in - d_out)) * (outside - inside);
    }
  }
  return size;
}

}  // namespace

ClippedPolygon clip_to_view(Vec3* a, Vec3* b, int n, int capacity, const ClipPlanes& planes) {
  unsigned outside_all = (1u << ClipPlanes::kCount) - 1, outside_any = 0;
  for (int k = 0; k < n; ++k) {
    const unsigned code = planes.outside(a[k]);
    outside_all &= code;
    outside_any |= code;
  }
  ClippedPolygon result{a, outside_all != 0 ? 0 : n, outside_any};
  if (result.size == 0) return result;
  Vec3* in = a;
  Vec3* out = b;
  for (int p = 0; p < ClipPlanes::kCount && result.size >= 3; ++p) {
    if ((outside_any & (1u << p)) == 0) continue;
    result.size = clip_to_plane(in, result.size, out, capacity, planes, p);
    std::swap(in, out);
  }
  result.vertices = in;
  return result;
}

bool snap_polygon(const Vec3* v, int n, int bits, const ClipPlanes& planes, int64_t* px, int64_t* py, SnapBox& box) {
  for (int k = 0; k < n; ++k) {
    if (!(v[k].z > 0.0)) return false;
    const double x = std::clamp(v[k].x / v[k].z, -1.0, planes.width);
    const double y = std::clamp(v[k].y / v[k].z, -1.0, planes.height);
    px[k] = static_cast<int64_t>(std::nearbyint(std::ldexp(x, bits)));
    py[k] = static_cast<int64_t>(std::nearbyint(std::ldexp(y, bits)));
    box.xmin = std::min(box.xmin, px[k]);
    box.xmax = std::max(box.xmax, px[k]);
    box.ymin = std::min(box.ymin, py[k]);
    box.ymax = std::max(box.ymax, py[k]);
  }
  return true;
}

int edge_functions(const int64_t* px, const int64_t* py, int n, EdgeFunction* edges) {
  Int128 area = 0;
  for (int k = 0; k < n; ++k) {
    const int m = (k + 1) % n;
    area += Int128(px[k]) * py[m] - Int128(px[m]) * py[k];
  }
  if (area == 0) return 0;
  const int64_t orient = area > 0 ? 1 : -1;
  int count = 0;
  for (int k = 0; k < n; ++k) {
    const int m = (k + 1) % n;
    if (px[k] == px[m] && py[k] == py[m]) continue;
    EdgeFunction& e = edges[count++];
    e.a = -(py[m] - py[k]) * orient;
    e.b = (px[m] - px[k]) * orient;
    e.ox = px[k];
    e.oy = py[k];
    // Top-left rule (y points down): a sample on the edge is inside when the inside lies to
    // its right (a left edge) or, for a horizontal edge, below it (a top edge).
    e.bias = (e.a > 0 || (e.a == 0 && e.b > 0)) ? 0 : -1;
  }
  return count;
}

}  // namespace frontier
