// A camera turned into per-pixel primary rays. Pixel (x, y) has its ray through the pixel
// centre, y = 0 is the top row. Directions are linear in the pixel coordinates,
// dir(x, y) = base + x * step_x + y * step_y (before normalisation), so every column of pixels
// lies in one plane through the eye, and so does every row: frusta reuse these planes.
#pragma once

#include "src/geometry.h"
#include "src/scene.h"

namespace frontier {

struct View {
  Vec3 eye{0.0};
  Vec3 forward{0.0, 0.0, -1.0};
  Vec3 base{0.0};    // unnormalised direction of pixel (0, 0)
  Vec3 step_x{0.0};
  Vec3 step_y{0.0};
  int width = 0;
  int height = 0;
  double near = 0.0;

  View() = default;
  View(const Camera& camera, int w, int h) : eye(camera.eye), width(w), height(h), near(camera.near) {
    forward = glm::normalize(camera.look_at - camera.eye);
    const Vec3 right = glm::normalize(glm::cross(forward, camera.up));
    const Vec3 up = glm::cross(right, forward);
    const double half_h = std::tan(0.5 * camera.vfov_deg * 3.14159265358979323846 / 180.0);
    const double half_w = half_h * static_cast<double>(w) / static_cast<double>(h);
    step_x = right * (2.0 * half_w / w);
    step_y = -up * (2.0 * half_h / h);
    base = forward - half_w * right + half_h * up + 0.5 * step_x + 0.5 * step_y;
  }

  Vec3 direction(int x, int y) const { return base + double(x) * step_x + double(y) * step_y; }
  Ray ray(int x, int y) const { return Ray(eye, direction(x, y)); }
  // Hits nearer than the near plane (measured along the view axis) are ignored.
  double tmin(const Ray& r) const { return near > 0.0 ? near / glm::dot(r.dir, forward) : 0.0; }
  size_t pixels() const { return static_cast<size_t>(width) * static_cast<size_t>(height); }
};

// A camera that frames the whole scene from a diagonal when the file names none.
Camera automatic_camera(const Aabb& bounds);

}  // namespace frontier
