// The window's camera rig (window_session.h): an eye and yaw / pitch about the start camera's
// fixed up vector, with e1, e2 spanning the ground plane (e2 = up x e1, so the top-down map is
// not mirrored). camera() builds the Camera from (eye, yaw, pitch) the same way every time, so a
// rig that did not move gives a bit-identical Camera and the Walkthrough goes on refining the
// same image. Pitch stays within +-89 degrees, so forward() is never parallel to up.
#pragma once

#include "src/core/scene.h"

#include <algorithm>
#include <cmath>

namespace frontier::window_detail {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMaxPitch = 89.0 * kPi / 180.0;

class Rig {
 public:
  explicit Rig(const Camera& start) : base_(start) {
    up_ = glm::length(start.up) > 0.0 ? glm::normalize(start.up) : Vec3(0.0, 0.0, 1.0);
    // e1: the world axis farthest from up, made perpendicular to it.
    const Vec3 axes[3] = {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
    Vec3 best = axes[0];
    for (const Vec3& a : axes) {
      if (std::abs(glm::dot(a, up_)) < std::abs(glm::dot(best, up_))) best = a;
    }
    e1_ = glm::normalize(best - glm::dot(best, up_) * up_);
    e2_ = glm::cross(up_, e1_);
    reset();
  }

  void reset() {
    eye = base_.eye;
    heading(base_.look_at - base_.eye, yaw, pitch);
    pitch = std::clamp(pitch, -kMaxPitch, kMaxPitch);
  }

  // Yaw and pitch of a direction (0, 0 for a zero one).
  void heading(const Vec3& direction, double& yaw_out, double& pitch_out) const {
    const double length = glm::length(direction);
    yaw_out = pitch_out = 0.0;
    if (!(length > 0.0)) return;
    const Vec3 f = direction / length;
    pitch_out = std::asin(std::clamp(glm::dot(f, up_), -1.0, 1.0));
    const Vec3 h = f - glm::dot(f, up_) * up_;
    if (glm::length(h) > 1e-12) yaw_out = std::atan2(glm::dot(h, e2_), glm::dot(h, e1_));
  }

  void look(double dyaw, double dpitch) {
    yaw = std::remainder(yaw + dyaw, 2.0 * kPi);
    pitch = std::clamp(pitch + dpitch, -kMaxPitch, kMaxPitch);
  }

  Vec3 level_forward() const { return std::cos(yaw) * e1_ + std::sin(yaw) * e2_; }
  Vec3 forward() const { return std::cos(pitch) * level_forward() + std::sin(pitch) * up_; }
  Vec3 right() const { return glm::cross(level_forward(), up_); }
  const Vec3& up() const { return up_; }
  // Ground-plane coordinates of a point (the map's axes).
  double ground_x(const Vec3& p) const { return glm::dot(p, e1_); }
  double ground_y(const Vec3& p) const { return glm::dot(p, e2_); }
  // The ground-plane rectangle a box projects to (grown into lo/hi).
  void ground_extent(const Aabb& box, double& lo_x, double& hi_x, double& lo_y, double& hi_y) const {
    for (int k = 0; k < 8; ++k) {
      const Vec3 p(k & 1 ? box.hi.x : box.lo.x, k & 2 ? box.hi.y : box.lo.y, k & 4 ? box.hi.z : box.lo.z);
      lo_x = std::min(lo_x, ground_x(p));
      hi_x = std::max(hi_x, ground_x(p));
      lo_y = std::min(lo_y, ground_y(p));
      hi_y = std::max(hi_y, ground_y(p));
    }
  }

  Camera camera() const {
    Camera c = base_;
    c.eye = eye;
    c.look_at = eye + forward();
    c.up = up_;
    return c;
  }

  Vec3 eye{0.0};
  double yaw = 0.0, pitch = 0.0;

 private:
  Camera base_;
  Vec3 up_, e1_, e2_;
};

}  // namespace frontier::window_detail
