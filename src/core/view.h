// A camera turned into per-pixel primary rays. Pixel (x, y) has its ray through the pixel
// centre, y = 0 is the top row. Directions are linear in the pixel coordinates,
// dir(x, y) = base + x * step_x + y * step_y (before normalisation), so every column of pixels
// lies in one plane through the eye, and so does every row: frusta reuse these planes.
#pragma once

#include <array>

#include "src/core/geometry.h"
#include "src/core/scene.h"

namespace frontier {

struct View {
  Vec3 eye{0.0};
  Vec3 forward{0.0, 0.0, -1.0};
  Vec3 base{0.0};    // unnormalised direction of pixel (0, 0)
  Vec3 step_x{0.0};
  Vec3 step_y{0.0};
  Vec3 right{1.0, 0.0, 0.0};
  Vec3 up{0.0, 1.0, 0.0};
  double half_w = 1.0;  // tan of half the horizontal field of view
  double half_h = 1.0;
  int width = 0;
  int height = 0;
  double near = 0.0;

  View() = default;
  View(const Camera& camera, int w, int h) : eye(camera.eye), width(w), height(h), near(camera.near) {
    forward = glm::normalize(camera.look_at - camera.eye);
    right = glm::normalize(glm::cross(forward, camera.up));
    up = glm::cross(right, forward);
    half_h = std::tan(0.5 * camera.vfov_deg * 3.14159265358979323846 / 180.0);
    half_w = half_h * static_cast<double>(w) / static_cast<double>(h);
    step_x = right * (2.0 * half_w / w);
    step_y = -up * (2.0 * half_h / h);
    base = forward - half_w * right + half_h * up + 0.5 * step_x + 0.5 * step_y;
  }

  Vec3 direction(int x, int y) const { return base + double(x) * step_x + double(y) * step_y; }
  Ray ray(int x, int y) const { return Ray(eye, direction(x, y)); }
  // Hits nearer than the near plane (measured along the view axis) are ignored.
  double tmin(const Ray& r) const { return near > 0.0 ? near / glm::dot(r.dir, forward) : 0.0; }
  // Conservative pixel rectangle of the pixels whose rays can hit `box` beyond the near plane:
  // the projection of the box (a margin of one pixel), or with a near plane, of the part of the
  // box beyond it (a floor reaching behind the eye then covers only where it is seen). Returns
  // false when the box reaches behind the eye plane and there is no near plane to clip it at:
  // then it may cover any pixel.
  bool project(const Aabb& box, int& x0, int& y0, int& x1, int& y1) const {
    double xmin = kInfinity, xmax = -kInfinity, ymin = kInfinity, ymax = -kInfinity;
    auto add = [&](const Vec3& d, double z) {
      const double a = glm::dot(d, right) / z, b = glm::dot(d, up) / z;
      const double x = (a + half_w) * width / (2.0 * half_w) - 0.5;
      const double y = (half_h - b) * height / (2.0 * half_h) - 0.5;
      xmin = std::min(xmin, x);
      xmax = std::max(xmax, x);
      ymin = std::min(ymin, y);
      ymax = std::max(ymax, y);
    };
    std::array<Vec3, 8> corner;
    std::array<double, 8> depth;
    bool clipped = false;
    for (int k = 0; k < 8; ++k) {
      const Vec3 d = Vec3(k & 1 ? box.hi.x : box.lo.x, k & 2 ? box.hi.y : box.lo.y, k & 4 ? box.hi.z : box.lo.z) - eye;
      const double z = glm::dot(d, forward);
      corner[size_t(k)] = d;
      depth[size_t(k)] = z;
      const double scale = std::abs(d.x) + std::abs(d.y) + std::abs(d.z);
      if (z > 1e-9 * scale && z >= near) {
        add(d, z);
      } else if (near > 1e-6 * scale) {
        clipped = true;  // behind the near plane: only the edges' crossings of it count
      } else {
        return false;
      }
    }
    if (clipped) {
      // Where the box's edges cross the near plane: with the corners beyond it, the vertices of
      // the box cut by the plane, whose projection is the hull of theirs.
      for (int k = 0; k < 8; ++k) {
        for (int bit = 1; bit < 8; bit <<= 1) {
          if (k & bit) continue;
          const double z0 = depth[size_t(k)], z1 = depth[size_t(k | bit)];
          if ((z0 < near) == (z1 < near)) continue;
          const double s = (near - z0) / (z1 - z0);
          add(corner[size_t(k)] + s * (corner[size_t(k | bit)] - corner[size_t(k)]), near);
        }
      }
      if (!(xmin <= xmax)) return false;  // nothing beyond the near plane
    }
    x0 = static_cast<int>(std::max(std::floor(xmin) - 1.0, -1.0));
    y0 = static_cast<int>(std::max(std::floor(ymin) - 1.0, -1.0));
    x1 = static_cast<int>(std::min(std::ceil(xmax) + 1.0, double(width)));
    y1 = static_cast<int>(std::min(std::ceil(ymax) + 1.0, double(height)));
    return true;
  }
  size_t pixels() const { return static_cast<size_t>(width) * static_cast<size_t>(height); }
};

// A camera that frames the whole scene from a diagonal when the file names none.
Camera automatic_camera(const Aabb& bounds);

}  // namespace frontier
