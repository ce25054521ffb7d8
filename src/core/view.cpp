// Automatic camera.
#include "src/core/view.h"

namespace frontier {

Camera automatic_camera(const Aabb& bounds) {
  Camera cam;
  const Vec3 c = bounds.empty() ? Vec3(0.0) : bounds.center();
  const double radius = bounds.empty() ? 1.0 : std::max(0.5 * glm::length(bounds.extent()), 1e-9);
  cam.vfov_deg = 45.0;
  const double dist = radius / std::sin(0.5 * cam.vfov_deg * 3.14159265358979323846 / 180.0);
  const Vec3 dir = glm::normalize(Vec3(0.6, -0.8, 0.45));
  cam.eye = c + dir * dist * 1.05;
  cam.look_at = c;
  cam.up = Vec3(0.0, 0.0, 1.0);
  return cam;
}

}  // namespace frontier
