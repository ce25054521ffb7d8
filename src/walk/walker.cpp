// Walker: walk-mode camera physics over a CollisionGrid. Every eye move goes through
// CollisionGrid::resolve (so the clearance guarantee is resolve's, composed); the floor comes from
// the foot probe (floor_gap), a sphere trace down the distance field that never steps over a
// surface because it advances at most d - foot_clearance() from a point reading d, and a point
// reading d is truly at least d - 0.94 h from everything (foot_clearance() >= h).
#include "src/walk/walker.h"

#include <fmt/format.h>

#include <algorithm>
#include <cassert>
#include <cmath>

namespace frontier {

namespace {

// In voxels: how close the probe's contact must read to foot_clearance(), the shortest probe
// advance (so a probe grazing a surface still moves), and floor changes small enough to ignore.
constexpr double kProbeTolerance = 1e-4;
constexpr double kMinProbeStep = 1.0 / 20.0;
constexpr double kLevelTolerance = 1e-3;
// A climb (steps_climbed) is a run of pieces each rising at least this much per unit walked:
// steeper than a ramp (1 in 12) and than the flat end of a riser's rounded edge, so a run ends on
// the tread. The grid's error on a tread shows only near the next riser's foot (the concave
// crease, at most about h/4), where it joins that riser's run instead of bridging two.
constexpr double kClimbSlope = 0.25;
// Bounds on work per call: samples per probe (a probe that hits it reports a floor where it
// stopped, the conservative answer) and pieces per horizontal move (longer moves are cut short:
// 10^4 foot clearances, 1.25 km at the defaults, is a teleport, not a step).
constexpr int kMaxProbeSamples = 20000;
constexpr double kMaxPieces = 10000.0;

bool finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

Status Walker::check(const CollisionGrid& grid, const WalkParams& p) {
  const auto bad = [](const char* field, double value, const std::string& why) {
    return Status::invalid_argument(fmt::format("walk {} {}: {}", field, value, why));
  };
  if (!std::isfinite(p.eye_height)) return bad("eye_height", p.eye_height, "not finite");
  if (!std::isfinite(p.radius)) return bad("radius", p.radius, "not finite");
  if (!std::isfinite(p.step_height)) return bad("step_height", p.step_height, "not finite");
  if (!(std::isfinite(p.gravity) && p.gravity >= 0.0))
    return bad("gravity", p.gravity, "must be finite and >= 0");
  if (!(std::isfinite(p.max_fall_speed) && p.max_fall_speed > 0.0))
    return bad("max_fall_speed", p.max_fall_speed, "must be finite and > 0");
  if (!finite(p.up) || !(glm::length(p.up) > 0.0))
    return Status::invalid_argument("walk up vector must be finite and non-zero");
  if (Status s = grid.check_radius(p.radius); !s.is_ok()) return s;
  const double h = grid.voxel_size();
  if (!(p.radius >= 2.0 * h)) {
    return bad("radius", p.radius,
               fmt::format("must be at least two voxels ({}): the foot probe keeps radius / 2 "
                           "and needs one voxel",
                           2.0 * h));
  }
  if (!(p.step_height >= 0.0)) return bad("step_height", p.step_height, "must be >= 0");
  if (!(p.eye_height - p.step_height >= p.radius + h)) {
    return bad("eye_height", p.eye_height,
               fmt::format("must be at least step_height + radius + one voxel ({}) so that the "
                           "eye clears what the feet climb",
                           p.step_height + p.radius + h));
  }
  return Status::ok();
}

Walker::Walker(const CollisionGrid& grid, const WalkParams& params)
    : grid_(grid), params_(params) {
  assert(check(grid, params).is_ok());
  params_.up = glm::normalize(params.up);
  voxel_ = grid.voxel_size();
  foot_ = 0.5 * params.radius;
  level_tolerance_ = kLevelTolerance * voxel_;
}

void Walker::reset() {
  on_floor_ = true;
  fall_speed_ = 0.0;
  climb_run_ = 0.0;
  climb_counted_ = false;
}

double Walker::distance(const Vec3& p) {
  ++queries_;
  return grid_.distance(p);
}

Vec3 Walker::gradient(const Vec3& p) {
  ++queries_;
  return grid_.gradient(p);
}

Vec3 Walker::resolve(const Vec3& from, const Vec3& to) {
  ++queries_;
  return grid_.resolve(from, to, params_.radius);
}

double Walker::floor_gap(const Vec3& eye, double max_gap) {
  const double tolerance = kProbeTolerance * voxel_;
  const double min_step = kMinProbeStep * voxel_;
  const Vec3 down = -params_.up;
  const double t_max = max_gap - foot_;
  double d = distance(eye);
  if (!(d > foot_)) return d;  // the eye itself is within the foot clearance of something
  if (!(t_max > 0.0)) return kInfinity;
  // A probe point at t reading d within the tolerance of foot_ is the contact; the floor is
  // taken d below it (gap t + d), which is exact where the field is linear (a flat floor).
  double t = 0.0;  // invariant: the probe at t reads d > foot_
  for (int i = 0; i < kMaxProbeSamples; ++i) {
    if (d - foot_ <= tolerance) return t + d;
    double next = t + std::max(d - foot_, min_step);
    if (next > t_max) {
      if (t == t_max) return kInfinity;
      next = t_max;
    }
    const double dn = distance(eye + next * down);
    if (dn > foot_) {
      t = next;
      d = dn;
      continue;
    }
    if (foot_ - dn <= tolerance) return next + dn;
    // Crossed the contact level between t and next: bisect (the field is only piecewise linear).
    double hi = next;
    while (hi - t > tolerance && ++i < kMaxProbeSamples) {
      const double mid = 0.5 * (t + hi);
      const double dm = distance(eye + mid * down);
      if (std::abs(dm - foot_) <= tolerance) return mid + dm;
      if (dm > foot_) {
        t = mid;
        d = dm;
      } else {
        hi = mid;
      }
    }
    return t + d;
  }
  return t + d;
}

bool Walker::try_piece(const Vec3& pos, const Vec3& piece, Vec3& out, double& rise, Vec3& contact) {
  const Vec3& up = params_.up;
  contact = Vec3(kInfinity);
  Vec3 q = resolve(pos, pos + piece);
  if (q == pos) return false;
  const double max_gap =
      params_.eye_height + (on_floor_ ? params_.step_height : 0.0) + level_tolerance_;
  const double gap = floor_gap(q, max_gap);
  rise = params_.eye_height - gap;  // -inf without a floor in reach
  const double step_height = params_.step_height + level_tolerance_;
  if (rise > step_height) {
    contact = q - (gap - foot_) * up;
    return false;
  }
  if (rise > level_tolerance_) {
    const Vec3 raised = resolve(q, q + rise * up);
    if (glm::dot(raised - q, up) < rise - level_tolerance_) return false;  // no head room
    q = raised;
  } else if (on_floor_ && rise < -level_tolerance_ && rise >= -step_height) {
    q = resolve(q, q + rise * up);  // follow the floor down a step
  }
  out = q;
  return true;
}

bool Walker::move_piece(Vec3& pos, const Vec3& piece) {
  Vec3 out, contact;
  double rise = 0.0;
  bool moved = try_piece(pos, piece, out, rise, contact);
  if (!moved && finite(contact)) {
    // Blocked by something too high to climb: slide along it, its horizontal normal taken from
    // the distance field at the probe's contact.
    Vec3 n = gradient(contact);
    n -= glm::dot(n, params_.up) * params_.up;
    const double n_len = glm::length(n);
    if (n_len > 1e-6) {
      n /= n_len;
      const double into = glm::dot(piece, n);
      const Vec3 slid = piece - into * n;
      if (into < 0.0 && glm::length(slid) > kProbeTolerance * voxel_) {
        moved = try_piece(pos, slid, out, rise, contact);
      }
    }
  }
  if (!moved) return false;
  Vec3 walked = out - pos;
  walked -= glm::dot(walked, params_.up) * params_.up;
  if (rise > level_tolerance_ && rise >= kClimbSlope * glm::length(walked)) {
    climb_run_ += rise;
    if (!climb_counted_ && climb_run_ >= voxel_) {
      ++steps_climbed_;
      climb_counted_ = true;
    }
  } else {
    climb_run_ = 0.0;
    climb_counted_ = false;
  }
  pos = out;
  // Walked off an edge deeper than a step: the rest of the move waits for the fall.
  return !(on_floor_ && rise < -(params_.step_height + level_tolerance_));
}

void Walker::settle(Vec3& pos, double dt) {
  const Vec3& up = params_.up;
  const double next_speed = std::min(fall_speed_ + params_.gravity * dt, params_.max_fall_speed);
  const double fall = next_speed * dt;
  const double max_gap =
      params_.eye_height + std::max(params_.step_height, fall) + level_tolerance_;
  const double excess = floor_gap(pos, max_gap) - params_.eye_height;  // feet above the floor
  if (excess < -level_tolerance_) {
    pos = resolve(pos, pos - excess * up);  // below standing height: stand up, head room allowing
    on_floor_ = true;
    fall_speed_ = 0.0;
    return;
  }
  if (excess <= level_tolerance_) {
    on_floor_ = true;
    fall_speed_ = 0.0;
    return;
  }
  if (on_floor_ && excess <= params_.step_height + level_tolerance_) {
    pos = resolve(pos, pos - excess * up);
    fall_speed_ = 0.0;
    return;
  }
  if (on_floor_) {
    ++falls_;
    on_floor_ = false;
  }
  fall_speed_ = next_speed;
  const bool lands = fall >= excess;
  const Vec3 target = pos - (lands ? excess : fall) * up;
  const Vec3 reached = resolve(pos, target);
  if (reached != target) {
    fall_speed_ = 0.0;  // the eye sphere rests on something the feet have not reached
  } else if (lands) {
    on_floor_ = true;
    fall_speed_ = 0.0;
  }
  pos = reached;
}

Vec3 Walker::step(const Vec3& eye, const Vec3& desired_eye, double dt) {
  if (!finite(eye)) return eye;
  const Vec3 desired = finite(desired_eye) ? desired_eye : eye;
  if (!(dt >= 0.0) || !std::isfinite(dt)) dt = 0.0;
  const Vec3& up = params_.up;

  Vec3 pos = eye;
  Vec3 move = desired - eye;
  move -= glm::dot(move, up) * up;
  double length = glm::length(move);
  if (length > kMaxPieces * foot_) {
    move *= kMaxPieces * foot_ / length;
    length = kMaxPieces * foot_;
  }
  if (length > 0.0) {
    const int pieces = static_cast<int>(std::ceil(length / foot_));
    const Vec3 piece = move / double(pieces);
    for (int i = 0; i < pieces; ++i) {
      if (!move_piece(pos, piece)) break;
    }
  }
  settle(pos, dt);
  return pos;
}

}  // namespace frontier
