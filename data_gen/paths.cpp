// Walk, orbit and fly camera paths (see header).
#include "data_gen/paths.h"

#include "data_gen/rng.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <deque>
#include <fstream>
#include <numbers>
#include <numeric>

namespace frontier::gen {
namespace {

using json = nlohmann::json;
using Vec2 = glm::dvec2;

constexpr double kLookAhead = 1.5;     // walk: metres
constexpr double kCornerRadius = 0.5;  // walk: corner rounding

Vec3 jvec3(const json& j) { return Vec3(j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()); }
Vec2 jvec2(const json& j) { return Vec2(j.at(0).get<double>(), j.at(1).get<double>()); }
Aabb jbox(const json& j) { return Aabb(jvec3(j.at(0)), jvec3(j.at(1))); }

// Streaming parse: each element of "rooms" and "portals" is converted and dropped as soon as
// it is complete, so memory holds the compact model, not a JSON tree of it.
Result<WalkModel> parse_sidecar(const std::string& path, bool keep_cells) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::not_found(fmt::format("cannot open sidecar '{}': {}", path, std::strerror(errno)));
  WalkModel m;
  std::string section, error;
  auto fail = [&](const std::string& what) {
    if (error.empty()) error = what;
  };
  auto callback = [&](int depth, json::parse_event_t event, json& parsed) -> bool {
    if (event == json::parse_event_t::key && depth == 1) {
      section = parsed.get<std::string>();
      return true;
    }
    if (event != json::parse_event_t::object_end || depth != 2) return true;
    if (section != "rooms" && section != "portals") return true;
    if (!keep_cells) return false;
    try {
      if (section == "rooms") {
        const int64_t id = parsed.at("id").get<int64_t>();
        if (id != static_cast<int64_t>(m.cells.size()))
          fail(fmt::format("room id {} out of order (expected {})", id, m.cells.size()));
        WalkCell c;
        c.floor = parsed.at("floor").get<int>();
        c.room = parsed.at("kind").get<std::string>() == "room";
        c.bounds = jbox(parsed.at("bounds"));
        c.line[0] = jvec2(parsed.at("walk_line").at(0));
        c.line[1] = jvec2(parsed.at("walk_line").at(1));
        m.cells.push_back(c);
      } else {
        WalkPortal p;
        for (int k = 0; k < 2; ++k) {
          p.cells[k] = parsed.at("rooms").at(k).get<int64_t>();
          p.approach[k] = jvec3(parsed.at("approach").at(k));
        }
        for (const json& v : parsed.at("route")) p.route.push_back(jvec3(v));
        m.portals.push_back(std::move(p));
      }
    } catch (const json::exception& e) {
      fail(fmt::format("{} entry {}: {}", section,
                       section == "rooms" ? m.cells.size() : m.portals.size(), e.what()));
    }
    return false;
  };
  json top;
  try {
    top = json::parse(in, callback);
    if (!top.is_object()) fail("not a JSON object");
    m.walkable = top.value("walkable", false);
    m.eye_height = top.value("eye_height", 1.7);
    if (top.contains("bounds")) m.bounds = jbox(top.at("bounds"));
  } catch (const json::exception& e) {
    fail(e.what());
  }
  if (!error.empty()) return Status::corruption(fmt::format("{}: {}", path, error));
  for (size_t i = 0; i < m.portals.size(); ++i)
    for (int64_t c : m.portals[i].cells)
      if (c < 0 || c >= static_cast<int64_t>(m.cells.size()))
        return Status::corruption(fmt::format("{}: portal {} names unknown room {}", path, i, c));
  return m;
}

Vec2 xy(const Vec3& v) { return Vec2(v.x, v.y); }

// Closest point of the walk line to q, at height z.
Vec3 project(const WalkCell& c, const Vec3& q) {
  const Vec2 a = c.line[0], b = c.line[1], d = b - a;
  const double len2 = glm::dot(d, d);
  const double t = len2 > 0.0 ? std::clamp(glm::dot(xy(q) - a, d) / len2, 0.0, 1.0) : 0.0;
  const Vec2 p = a + t * d;
  return Vec3(p.x, p.y, q.z);
}

// Arc-length parametrised polyline.
class Polyline {
 public:
  void push(const Vec3& p) {
    if (!points_.empty()) {
      const double d = glm::length(p - points_.back());
      if (d < 1e-9) return;
      length_.push_back(length_.back() + d);
    } else {
      length_.push_back(0.0);
    }
    points_.push_back(p);
  }
  double length() const { return length_.empty() ? 0.0 : length_.back(); }
  size_t size() const { return points_.size(); }
  // Point at arc length s; beyond the ends the first/last segment is extended.
  Vec3 at(double s) const {
    if (points_.size() == 1) return points_[0];
    size_t i = static_cast<size_t>(std::upper_bound(length_.begin(), length_.end(), s) - length_.begin());
    i = std::clamp<size_t>(i, 1, points_.size() - 1);
    const double seg = length_[i] - length_[i - 1];
    const double t = (s - length_[i - 1]) / seg;
    return points_[i - 1] + (points_[i] - points_[i - 1]) * t;
  }

 private:
  std::vector<Vec3> points_;
  std::vector<double> length_;
};

// Circular running maximum of v over 2 * half + 1 samples.
std::vector<double> running_max(const std::vector<double>& v, size_t half) {
  const size_t m = v.size();
  if (2 * half + 1 >= m) return std::vector<double>(m, *std::max_element(v.begin(), v.end()));
  std::vector<double> out(m);
  std::deque<size_t> window;  // positions in [0, m + 2 half), values decreasing
  auto value = [&](size_t j) { return v[(j + m - half) % m]; };  // position j is sample j - half
  size_t next = 0;
  for (size_t k = 0; k < m; ++k) {
    for (; next <= k + 2 * half; ++next) {
      while (!window.empty() && value(window.back()) <= value(next)) window.pop_back();
      window.push_back(next);
    }
    while (window.front() < k) window.pop_front();
    out[k] = value(window.front());
  }
  return out;
}

// Circular running mean of v over 2 * half + 1 samples.
std::vector<double> running_mean(const std::vector<double>& v, size_t half) {
  const size_t m = v.size();
  if (2 * half + 1 >= m) return std::vector<double>(m, std::accumulate(v.begin(), v.end(), 0.0) / double(m));
  std::vector<double> prefix(m + 2 * half + 1, 0.0);  // prefix[j]: sum of positions < j
  for (size_t j = 0; j < m + 2 * half; ++j) prefix[j + 1] = prefix[j] + v[(j + m - half) % m];
  std::vector<double> out(m);
  for (size_t k = 0; k < m; ++k) out[k] = (prefix[k + 2 * half + 1] - prefix[k]) / double(2 * half + 1);
  return out;
}

// How far the fly path's eye rises over a closed curve so that it keeps `clearance` above the
// ground, sampled every `step` of arc length and interpolated linearly between samples.
//
// Why it holds between samples: a sample asks for the highest ground within clearance + step/2
// of it and adds step/2 (the curve's height changes by at most its arc length), so it covers
// every point within step/2 of it. A running maximum over +-(2h + 1) samples followed by two
// running means over +-h leaves every sample at least the largest need of itself and its two
// neighbours, so the linear interpolation between two samples is at least both their needs.
class GroundLift {
 public:
  static constexpr size_t kMaxSamples = 1 << 16;

  GroundLift(const Polyline& curve, const GroundMap& ground, double clearance) : length_(curve.length()) {
    const size_t m = std::clamp<size_t>(static_cast<size_t>(std::ceil(length_ / (0.25 * clearance))), 8, kMaxSamples);
    step_ = length_ / double(m);
    const GroundMap reach = ground.widened(clearance + 0.5 * step_);
    std::vector<double> need(m);
    for (size_t k = 0; k < m; ++k) {
      const Vec3 p = curve.at(double(k) * step_);
      const double g = reach.highest_near(p.x, p.y, 0.0);
      need[k] = std::isfinite(g) ? std::max(0.0, g + clearance + 0.5 * step_ - p.z) : 0.0;
    }
    // Smoothing over about 1% of the loop: climbs start before a rise instead of at it.
    const size_t half = std::max<size_t>(1, static_cast<size_t>(std::ceil(0.01 * length_ / step_)));
    lift_ = running_mean(running_mean(running_max(need, 2 * half + 1), half), half);
  }
  size_t samples() const { return lift_.size(); }
  // The lift at arc length s in [0, length).
  double at(double s) const {
    const double u = std::clamp(s / step_, 0.0, double(lift_.size()));
    const size_t k = std::min(static_cast<size_t>(u), lift_.size() - 1);
    const double t = u - double(k);
    return (1.0 - t) * lift_[k] + t * lift_[(k + 1) % lift_.size()];
  }

 private:
  double length_ = 0.0, step_ = 1.0;
  std::vector<double> lift_;
};

struct Waypoint {
  Vec3 p;
  bool sharp = false;
};

// The walk's polyline with corners rounded by quadratic Bezier arcs. Corners where the height
// changes (stairs) stay sharp so the eye stays exactly above the pitch line.
Polyline smooth(std::vector<Waypoint> way) {
  for (size_t i = 0; i < way.size(); ++i) {
    const bool z_prev = i > 0 && std::abs(way[i].p.z - way[i - 1].p.z) > 1e-6;
    const bool z_next = i + 1 < way.size() && std::abs(way[i].p.z - way[i + 1].p.z) > 1e-6;
    way[i].sharp = z_prev || z_next;
  }
  Polyline path;
  path.push(way.front().p);
  for (size_t i = 1; i + 1 < way.size(); ++i) {
    const Vec3 p = way[i].p, in = p - way[i - 1].p, out = way[i + 1].p - p;
    const double lin = glm::length(in), lout = glm::length(out);
    const double turn = glm::dot(in, out) / (lin * lout);
    if (way[i].sharp || turn > 0.9998) {
      path.push(p);
      continue;
    }
    const double d = std::min({kCornerRadius, 0.45 * lin, 0.45 * lout});
    const Vec3 a = p - in * (d / lin), b = p + out * (d / lout);
    for (int k = 0; k <= 8; ++k) {
      const double t = k / 8.0;
      path.push((1 - t) * (1 - t) * a + 2 * (1 - t) * t * p + t * t * b);
    }
  }
  path.push(way.back().p);
  return path;
}

Camera make_camera(const Vec3& eye, Vec3 look_at, double vfov) {
  Camera c;
  c.eye = eye;
  c.up = Vec3(0, 0, 1);
  c.vfov_deg = vfov;
  Vec3 d = look_at - eye;
  const double len = glm::length(d);
  // Never look straight up or down (up would be parallel to the view).
  if (len < 1e-9 || std::hypot(d.x, d.y) < 1e-3 * len) d = Vec3(1.0, 0.0, len < 1e-9 ? 0.0 : d.z / len);
  c.look_at = eye + d;
  // Micrometres are plenty and keep .cam lines short.
  auto round6 = [](Vec3 v) { return glm::round(v * 1e6) / 1e6; };
  c.eye = round6(c.eye);
  c.look_at = round6(c.look_at);
  if (c.look_at == c.eye) c.look_at.x += 1e-3;
  return c;
}

}  // namespace

Result<WalkModel> read_walk_sidecar(const std::string& path) { return parse_sidecar(path, true); }

Result<Aabb> read_sidecar_bounds(const std::string& path) {
  auto m = parse_sidecar(path, false);
  if (!m) return m.status();
  if (m->bounds.empty()) return Status::corruption(fmt::format("{}: no \"bounds\"", path));
  return m->bounds;
}

Result<std::vector<Camera>> walk_path(const WalkModel& m, const PathOptions& o) {
  if (!m.walkable) return Status::invalid_argument("--kind walk: the sidecar is not \"walkable\"");
  std::vector<std::vector<std::pair<size_t, int>>> incident(m.cells.size());  // (portal, side)
  for (size_t i = 0; i < m.portals.size(); ++i)
    for (int s = 0; s < 2; ++s) incident[static_cast<size_t>(m.portals[i].cells[s])].push_back({i, s});
  std::vector<size_t> starts;
  for (size_t c = 0; c < m.cells.size(); ++c)
    if (m.cells[c].room && !incident[c].empty()) starts.push_back(c);
  if (starts.empty()) return Status::invalid_argument("--kind walk: the sidecar has no room with a door");

  Rng rng(o.seed, Stream::Path, 1);
  size_t cell = starts[rng.below(static_cast<uint32_t>(starts.size()))];
  const WalkCell& first = m.cells[cell];
  std::vector<Waypoint> way;
  auto add = [&](const Vec3& p) {
    if (way.empty() || glm::length(p - way.back().p) > 1e-6) way.push_back({p});
  };
  add(Vec3(first.line[0].x, first.line[0].y, first.bounds.lo.z + m.eye_height));

  const double need = (o.frames - 1) * o.step + kLookAhead + 1.0;
  std::vector<uint32_t> visits(m.cells.size(), 0);
  visits[cell] = 1;
  size_t came_through = SIZE_MAX;
  int hops = 0;
  // Appends one hop: through the current cell to a chosen portal and across it.
  auto hop = [&] {
    // Choose the next portal: prefer cells seen less, avoid turning straight back.
    const auto& options = incident[cell];
    std::vector<double> weight(options.size());
    double total = 0.0;
    for (size_t k = 0; k < options.size(); ++k) {
      const auto& [portal, side] = options[k];
      const size_t target = static_cast<size_t>(m.portals[portal].cells[1 - side]);
      double w = 1.0 / (1.0 + 3.0 * visits[target]);
      if (portal == came_through && options.size() > 1) w = 0.0;
      if (m.cells[target].floor != m.cells[cell].floor) w *= 0.7;
      weight[k] = w;
      total += w;
    }
    double pick = rng.uniform() * total;
    size_t k = 0;
    while (k + 1 < options.size() && (pick -= weight[k]) >= 0.0) ++k;
    const auto [portal, side] = options[k];
    const WalkPortal& p = m.portals[portal];
    const Vec3 here = way.back().p;
    const Vec3 exit = p.approach[side];
    add(project(m.cells[cell], here));
    add(project(m.cells[cell], exit));
    add(exit);
    if (side == 0)
      for (const Vec3& r : p.route) add(r);
    else
      for (auto it = p.route.rbegin(); it != p.route.rend(); ++it) add(*it);
    add(p.approach[1 - side]);
    cell = static_cast<size_t>(p.cells[1 - side]);
    ++visits[cell];
    came_through = portal;
    ++hops;
  };
  // Rounded corners shorten the route, so extend it until the smooth path is long enough.
  Polyline path;
  for (double target = need; hops < 1000000; target *= 1.25) {
    double length = 0.0;
    for (size_t i = 1; i < way.size(); ++i) length += glm::length(way[i].p - way[i - 1].p);
    while (length < target && hops < 1000000) {
      const size_t before = way.size();
      hop();
      for (size_t i = std::max<size_t>(before, 1); i < way.size(); ++i)
        length += glm::length(way[i].p - way[i - 1].p);
    }
    path = smooth(way);
    if (path.length() >= need) break;
  }

  double step = o.step;
  if (path.length() < need) step = std::max(0.0, path.length() - kLookAhead) / std::max(1, o.frames - 1);
  std::vector<Camera> frames;
  frames.reserve(static_cast<size_t>(o.frames));
  for (int i = 0; i < o.frames; ++i) {
    const double s = i * step;
    frames.push_back(make_camera(path.at(s), path.at(s + kLookAhead), o.vfov_deg));
  }
  return frames;
}

Result<std::vector<Camera>> orbit_path(const Aabb& b, const PathOptions& o) {
  if (b.empty() || !(glm::length(b.extent()) > 0.0))
    return Status::invalid_argument("--kind orbit: the model has empty bounds");
  Rng rng(o.seed, Stream::Path, 2);
  const double phase = rng.uniform(0.0, 2 * std::numbers::pi);
  const double radius = 0.5 * glm::length(b.extent());
  const double dist = 1.1 * radius / std::sin(0.5 * o.vfov_deg * std::numbers::pi / 180.0);
  const double el = 25.0 * std::numbers::pi / 180.0;
  const Vec3 c = b.center();
  std::vector<Camera> frames;
  // Radians per frame: one loop over the frames, or the eye's speed along its circle.
  const double horizontal = dist * std::cos(el);
  const double turn = o.speed > 0.0 ? o.speed / horizontal : 2 * std::numbers::pi / o.frames;
  for (int i = 0; i < o.frames; ++i) {
    const double a = phase + turn * i;
    const Vec3 eye = c + dist * Vec3(std::cos(el) * std::cos(a), std::cos(el) * std::sin(a), std::sin(el));
    frames.push_back(make_camera(eye, c, o.vfov_deg));
  }
  return frames;
}

double default_clearance(const Aabb& b) {
  const Vec3 e = b.extent();
  const double side = std::max(e.x, e.y);
  return 0.01 * (side > 0.0 ? side : glm::length(e));
}

Result<std::vector<Camera>> fly_path(const Aabb& b, const GroundMap& ground, const PathOptions& o) {
  if (b.empty() || !(glm::length(b.extent()) > 0.0))
    return Status::invalid_argument("--kind fly: the model has empty bounds");
  Rng rng(o.seed, Stream::Path, 3);
  const Vec3 e = b.extent(), c = b.center();
  const int n = std::clamp(o.frames / 90, 5, 64);
  std::vector<Vec3> ctrl;
  for (int i = 0; i < n; ++i) {
    const double zlo = c.z, zhi = std::max(b.hi.z, c.z + 0.1 * glm::length(e));
    ctrl.emplace_back(rng.uniform(b.lo.x + 0.15 * e.x, b.hi.x - 0.15 * e.x),
                      rng.uniform(b.lo.y + 0.15 * e.y, b.hi.y - 0.15 * e.y), rng.uniform(zlo, zhi));
  }
  // A loop around the centre rather than a zigzag.
  std::sort(ctrl.begin(), ctrl.end(), [&](const Vec3& p, const Vec3& q) {
    return std::atan2(p.y - c.y, p.x - c.x) < std::atan2(q.y - c.y, q.x - c.x);
  });
  // Closed centripetal Catmull-Rom spline.
  Polyline curve;
  constexpr int kSamples = 48;
  for (int i = 0; i < n; ++i) {
    const Vec3 P[4] = {ctrl[(i + n - 1) % n], ctrl[i], ctrl[(i + 1) % n], ctrl[(i + 2) % n]};
    double t[4] = {0.0, 0.0, 0.0, 0.0};
    for (int k = 1; k < 4; ++k) t[k] = t[k - 1] + std::max(1e-6, std::sqrt(glm::length(P[k] - P[k - 1])));
    for (int s = 0; s < kSamples; ++s) {
      const double u = t[1] + (t[2] - t[1]) * s / kSamples;
      auto lerp = [&](const Vec3& a, const Vec3& bb, double ta, double tb) {
        return (tb - u) / (tb - ta) * a + (u - ta) / (tb - ta) * bb;
      };
      const Vec3 A1 = lerp(P[0], P[1], t[0], t[1]), A2 = lerp(P[1], P[2], t[1], t[2]),
                 A3 = lerp(P[2], P[3], t[2], t[3]);
      const Vec3 B1 = lerp(A1, A2, t[0], t[2]), B2 = lerp(A2, A3, t[1], t[3]);
      curve.push(lerp(B1, B2, t[1], t[2]));
    }
  }
  curve.push(ctrl[0]);
  const double L = curve.length();
  const double clearance = o.clearance > 0.0 ? o.clearance : default_clearance(b);
  const GroundLift lift(curve, ground, clearance);
  auto lifted = [&](double s) { return curve.at(s) + Vec3(0.0, 0.0, lift.at(s)); };
  // Frames are evenly spaced along the lifted loop (a climb does not speed the eye up): its
  // arc length tabulated over the curve's parameter, then inverted. Every eye is still a point
  // lifted(s), so the lift's guarantee holds for it.
  const size_t fine = 4 * (lift.samples() + curve.size());
  std::vector<double> arc(fine + 1, 0.0);
  Vec3 prev = lifted(0.0);
  for (size_t j = 1; j <= fine; ++j) {
    const Vec3 p = lifted(std::min(L * double(j) / double(fine), std::nextafter(L, 0.0)));
    arc[j] = arc[j - 1] + glm::length(p - prev);
    prev = p;
  }
  const double C = arc.back();
  auto at_length = [&](double along) {
    along = std::fmod(along, C);
    const size_t j = std::min<size_t>(fine - 1, static_cast<size_t>(std::upper_bound(arc.begin(), arc.end(), along) - arc.begin()) - 1);
    const double piece = arc[j + 1] - arc[j], t = piece > 0.0 ? (along - arc[j]) / piece : 0.0;
    return lifted(L * (double(j) + t) / double(fine));
  };
  std::vector<Camera> frames;
  for (int i = 0; i < o.frames; ++i) {
    const double along = o.speed > 0.0 ? o.speed * i : C * i / o.frames;
    frames.push_back(make_camera(at_length(along), at_length(along + 0.02 * C), o.vfov_deg));
  }
  return frames;
}

}  // namespace frontier::gen
