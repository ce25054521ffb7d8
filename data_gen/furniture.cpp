// Furniture items and fittings (see header). Items are modelled in a local frame (u along the
// item, v across it, z up) and placed with a rotation by a multiple of 90 degrees, so local
// boxes stay axis-aligned boxes.
#include "data_gen/furniture.h"

#include <algorithm>
#include <cmath>

namespace frontier::gen {
namespace {

constexpr double kItemGap = 0.12;     // between floor items
constexpr double kWallGap = 0.02;     // free-standing items from walls
constexpr int kPlacementTries = 16;
constexpr double kAreaPerItem = 7.0;  // m^2 of floor per item at density 1
constexpr double kAreaPerLamp = 12.0;

double point_segment_distance(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double len2 = glm::dot(ab, ab);
  const double t = len2 > 0.0 ? std::clamp(glm::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
  return glm::length(p - (a + t * ab));
}

double point_rect_distance(const Vec2& p, const Vec2& lo, const Vec2& hi) {
  return glm::length(p - glm::clamp(p, lo, hi));
}

// Item frame: local (u, v) in [0, W] x [0, D] mapped to the floor by rotation k (x 90 deg).
struct Frame {
  double x0 = 0, y0 = 0, z0 = 0, W = 0, D = 0;
  int k = 0;
  MeshBuilder* mb = nullptr;
  int segments = 16;

  Vec3 at(double u, double v, double z) const {
    switch (k & 3) {
      case 0: return {x0 + u, y0 + v, z0 + z};
      case 1: return {x0 + D - v, y0 + u, z0 + z};
      case 2: return {x0 + W - u, y0 + D - v, z0 + z};
      default: return {x0 + v, y0 + W - u, z0 + z};
    }
  }
  void box(double u0, double v0, double z0l, double u1, double v1, double z1l, Rgb c) const {
    const Vec3 a = at(u0, v0, z0l), b = at(u1, v1, z1l);
    mb->box(glm::min(a, b), glm::max(a, b), c);
  }
  void cyl(double ua, double va, double za, double ub, double vb, double zb, double r, Rgb c,
           int seg = 0) const {
    mb->cylinder(at(ua, va, za), at(ub, vb, zb), r, seg > 0 ? seg : segments, 1, c);
  }
  void frustum(double ua, double va, double za, double ra, double zb, double rb, Rgb c) const {
    mb->frustum(at(ua, va, za), ra, at(ua, va, zb), rb, segments, c);
  }
  void sphere(double u, double v, double z, double r, Rgb c) const {
    mb->sphere(at(u, v, z), r, segments, c);
  }
};

int thin_segments(const DetailParams& p) { return std::max(3, p.segments / 2); }

// A chair whose seat is centred at (uc, vc); the sitter faces +v when `faces_plus_v`.
void chair(const Frame& f, double uc, double vc, bool faces_plus_v) {
  constexpr double s = 0.22, seat = 0.43;
  f.box(uc - s, vc - s, seat, uc + s, vc + s, seat + 0.04, palette::kFabric);
  for (double du : {-0.18, 0.18})
    for (double dv : {-0.18, 0.18})
      f.cyl(uc + du, vc + dv, 0.0, uc + du, vc + dv, seat, 0.018, palette::kMetal);
  const double vb = faces_plus_v ? vc - s : vc + s - 0.03;
  f.box(uc - s, vb, seat + 0.2, uc + s, vb + 0.03, seat + 0.5, palette::kFabric);
  const double vp = faces_plus_v ? vc - 0.2 : vc + 0.2;
  for (double du : {-0.18, 0.18})
    f.cyl(uc + du, vp, seat + 0.04, uc + du, vp, seat + 0.5, 0.012, palette::kMetal,
          std::max(3, f.segments / 2));
}

// Table with chairs on its long sides. Footprint W x D, W in [1.3, 2.1], D in [1.6, 1.9].
void table_group(const Frame& f, Rng& rng) {
  const double top = 0.72, t0 = 0.05, t1 = f.W - 0.05, v0 = 0.45, v1 = f.D - 0.45;
  f.box(t0, v0, top, t1, v1, top + 0.04, palette::kWood);
  for (double u : {t0 + 0.07, t1 - 0.07})
    for (double v : {v0 + 0.07, v1 - 0.07}) f.cyl(u, v, 0.0, u, v, top, 0.03, palette::kWood);
  const int per_side = (t1 - t0) > 1.6 ? 2 : 1;
  for (int side = 0; side < 2; ++side)
    for (int i = 0; i < per_side; ++i) {
      if (rng.chance(0.15)) continue;  // an empty place
      const double uc = t0 + (t1 - t0) * (i + 1) / (per_side + 1);
      if (side == 0)
        chair(f, uc, 0.24, true);
      else
        chair(f, uc, f.D - 0.24, false);
    }
  // Things on the table: cups and a bowl.
  const int things = static_cast<int>(rng.below(4));
  for (int i = 0; i < things; ++i) {
    const double u = rng.uniform(t0 + 0.15, t1 - 0.15), v = rng.uniform(v0 + 0.15, v1 - 0.15);
    f.cyl(u, v, top + 0.04, u, v, top + 0.14, 0.04, palette::kLamp);
  }
}

// Desk with monitor, keyboard, desk lamp and a chair. Footprint 1.5 x 1.25.
void desk(const Frame& f, Rng& rng) {
  const double top = 0.72;
  f.box(0.0, 0.0, top, 1.5, 0.7, top + 0.03, palette::kWood);
  for (double u : {0.06, 1.44})
    for (double v : {0.06, 0.64}) f.cyl(u, v, 0.0, u, v, top, 0.025, palette::kMetal);
  const double mu = rng.uniform(0.55, 0.95);
  f.frustum(mu, 0.22, top + 0.03, 0.11, top + 0.045, 0.09, palette::kScreen);
  f.cyl(mu, 0.22, top + 0.045, mu, 0.22, top + 0.25, 0.02, palette::kScreen);
  f.box(mu - 0.3, 0.17, top + 0.2, mu + 0.3, 0.2, top + 0.56, palette::kScreen);
  f.box(mu - 0.2, 0.35, top + 0.03, mu + 0.2, 0.5, top + 0.05, palette::kScreen);
  if (rng.chance(0.6)) {
    const double lu = mu < 0.75 ? 1.3 : 0.2;
    f.cyl(lu, 0.15, top + 0.03, lu, 0.15, top + 0.05, 0.07, palette::kMetal);
    f.cyl(lu, 0.15, top + 0.05, lu, 0.3, top + 0.42, 0.012, palette::kMetal, std::max(3, f.segments / 2));
    f.sphere(lu, 0.33, top + 0.38, 0.06, palette::kLamp);
  }
  chair(f, 0.75 + rng.uniform(-0.2, 0.2), 1.0, false);
}

// Bookshelf against the wall at v = 0. Footprint W x 0.36, W in [0.8, 1.8].
void bookshelf(const Frame& f, Rng& rng) {
  const double W = f.W, D = 0.36, H = rng.uniform(1.8, 2.2), side = 0.02, plinth = 0.08;
  constexpr int kLevels = 5;
  const double gap = (H - plinth - side) / kLevels;
  f.box(side, 0.02, 0.0, W - side, D, plinth, palette::kWood);
  f.box(0.0, 0.0, 0.0, side, D, H, palette::kWood);
  f.box(W - side, 0.0, 0.0, W, D, H, palette::kWood);
  f.box(side, 0.0, H - side, W - side, D, H, palette::kWood);
  f.box(side, 0.0, plinth, W - side, 0.01, H - side, palette::kWood);
  for (int level = 0; level < kLevels; ++level) {
    const double z = plinth + level * gap;
    if (level > 0) f.box(side, 0.01, z - 0.02, W - side, D, z, palette::kWood);
    const double fill = rng.uniform(0.5, 1.0);
    double u = side + 0.01;
    while (true) {
      const double bw = rng.uniform(0.018, 0.055);
      if (u + bw > W - side - 0.01) break;
      if (!rng.chance(fill)) {
        u += bw;
        continue;
      }
      const double bh = rng.uniform(0.16, std::min(0.33, gap - 0.06));
      const double bd = rng.uniform(0.15, 0.3);
      f.box(u, 0.03, z, u + bw - 0.002, 0.03 + bd, z + bh, palette::kBooks[rng.below(6)]);
      u += bw;
    }
  }
}

// Low cabinet with drawers against the wall at v = 0. Footprint W x 0.55.
void cabinet(const Frame& f, Rng& rng) {
  const double W = f.W;
  f.box(0.03, 0.03, 0.0, W - 0.03, 0.47, 0.05, palette::kWood);
  f.box(0.0, 0.0, 0.05, W, 0.5, 0.88, palette::kWood);
  f.box(0.0, 0.0, 0.88, W, 0.52, 0.91, palette::kWood);
  const int cols = W > 1.0 ? 2 : 1, rows = 2 + static_cast<int>(rng.below(2));
  const double cw = W / cols, rh = 0.8 / rows;
  for (int c = 0; c < cols; ++c)
    for (int r = 0; r < rows; ++r) {
      const double u0 = c * cw + 0.015, u1 = (c + 1) * cw - 0.015;
      const double z0 = 0.07 + r * rh, z1 = z0 + rh - 0.02;
      f.box(u0, 0.5, z0, u1, 0.515, z1, palette::kWood);
      const double zm = 0.5 * (z0 + z1), um = 0.5 * (u0 + u1);
      f.cyl(um - 0.1, 0.53, zm, um + 0.1, 0.53, zm, 0.01, palette::kMetal, std::max(3, f.segments / 2));
    }
}

// Potted plant. Footprint 0.7 x 0.7.
void plant(const Frame& f, Rng& rng) {
  f.frustum(0.35, 0.35, 0.0, 0.17, 0.38, 0.22, palette::kPot);
  f.cyl(0.35, 0.35, 0.38, 0.35, 0.35, 0.95, 0.025, palette::kPlant);
  const int leaves = 3 + static_cast<int>(rng.below(4));
  for (int i = 0; i < leaves; ++i) {
    const double r = rng.uniform(0.12, 0.22);
    const double reach = 0.35 - r - 0.005;
    f.sphere(0.35 + rng.uniform(-reach, reach), 0.35 + rng.uniform(-reach, reach),
             rng.uniform(0.8, 1.35), r, palette::kPlant);
  }
}

enum class Item { Table, Desk, Shelf, Cabinet, Plant };

Item pick_item(Rng& rng) {
  const double x = rng.uniform();
  if (x < 0.30) return Item::Table;
  if (x < 0.50) return Item::Desk;
  if (x < 0.75) return Item::Shelf;
  if (x < 0.90) return Item::Cabinet;
  return Item::Plant;
}

struct Rect {
  Vec2 lo, hi;
};

}  // namespace

double segment_rect_distance(const Segment2& s, const Vec2& lo, const Vec2& hi) {
  // Liang-Barsky clip: does the segment enter the rectangle?
  double t0 = 0.0, t1 = 1.0;
  const Vec2 d = s.b - s.a;
  bool meets = true;
  for (int axis = 0; axis < 2 && meets; ++axis) {
    if (d[axis] == 0.0) {
      meets = s.a[axis] >= lo[axis] && s.a[axis] <= hi[axis];
      continue;
    }
    double ta = (lo[axis] - s.a[axis]) / d[axis], tb = (hi[axis] - s.a[axis]) / d[axis];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    meets = t0 <= t1;
  }
  if (meets) return 0.0;
  double best = std::min(point_rect_distance(s.a, lo, hi), point_rect_distance(s.b, lo, hi));
  for (const Vec2& c : {lo, hi, Vec2(lo.x, hi.y), Vec2(hi.x, lo.y)})
    best = std::min(best, point_segment_distance(c, s.a, s.b));
  return best;
}

void pendant_lamp(MeshBuilder& mb, const Vec3& c, const DetailParams& p) {
  const int thin = thin_segments(p);
  mb.frustum(c - Vec3(0, 0, 0.04), 0.045, c, 0.07, p.segments, palette::kMetal);
  mb.cylinder(c - Vec3(0, 0, 0.69), c - Vec3(0, 0, 0.04), 0.01, thin, 1, palette::kMetal);
  mb.sphere(c - Vec3(0, 0, 0.85), 0.16, p.segments, palette::kLamp);
}

void pipe_run(MeshBuilder& mb, const Vec3& a, const Vec3& b, double radius, double ceiling_z,
              bool flange_at_start, const DetailParams& p) {
  constexpr double kSpacing = 1.6, kFlange = 0.04;
  const double len = glm::length(b - a);
  if (len < 0.05) return;
  const Vec3 dir = (b - a) / len;
  const int joints = std::max(1, static_cast<int>(std::ceil(len / kSpacing)));
  for (int i = 0; i < joints; ++i) {
    const Vec3 s = a + dir * (len * i / joints), e = a + dir * (len * (i + 1) / joints);
    mb.cylinder(s, e, radius, p.segments, 1, palette::kMetal);
    if (i > 0 || flange_at_start) {
      const Vec3 f0 = i == 0 ? s : s - dir * (kFlange / 2);
      mb.cylinder(f0, f0 + dir * (i == 0 ? kFlange / 2 : kFlange), radius * 1.6, p.segments, 1,
                  palette::kMetal);
      mb.cylinder(Vec3(s.x, s.y, s.z + radius), Vec3(s.x, s.y, ceiling_z), 0.008,
                  thin_segments(p), 1, palette::kRail);
    }
  }
}

void handrail(MeshBuilder& mb, const Vec3& a, const Vec3& b, const Vec3& to_wall,
              const DetailParams& p) {
  const double len = glm::length(b - a);
  if (len < 0.3) return;
  mb.cylinder(a, b, 0.022, p.segments, 1, palette::kRail);
  const int brackets = std::max(2, static_cast<int>(std::ceil(len / 1.2)) + 1);
  for (int i = 0; i < brackets; ++i) {
    const double t = 0.1 + (len - 0.2) * i / (brackets - 1);
    const Vec3 q = a + (b - a) * (t / len) - Vec3(0, 0, 0.03);
    mb.cylinder(q, q + to_wall * (kRailOffset + 0.01), 0.01, thin_segments(p), 1, palette::kRail);
  }
}

void guard_rail(MeshBuilder& mb, const Vec3& a, const Vec3& b, double height,
                const DetailParams& p) {
  const double len = glm::length(b - a);
  if (len < 0.2) return;
  const int posts = std::max(2, static_cast<int>(std::ceil(len / 1.0)) + 1);
  for (int i = 0; i < posts; ++i) {
    const Vec3 q = a + (b - a) * (static_cast<double>(i) / (posts - 1));
    mb.cylinder(q, q + Vec3(0, 0, height), 0.02, p.segments, 1, palette::kRail);
  }
  const Vec3 up(0, 0, height), mid(0, 0, height / 2);
  mb.cylinder(a + up, b + up, 0.025, p.segments, 1, palette::kRail);
  mb.cylinder(a + mid, b + mid, 0.012, thin_segments(p), 1, palette::kRail);
}

void furnish_room(MeshBuilder& mb, Rng& rng, const Aabb& interior,
                  const std::vector<Segment2>& walkways, const DetailParams& p) {
  const Vec2 lo(interior.lo.x, interior.lo.y), hi(interior.hi.x, interior.hi.y);
  const double area = (hi.x - lo.x) * (hi.y - lo.y);
  std::vector<Rect> placed;
  auto fits = [&](const Rect& r) {
    if (r.lo.x < lo.x || r.lo.y < lo.y || r.hi.x > hi.x || r.hi.y > hi.y) return false;
    for (const Rect& q : placed)
      if (r.lo.x < q.hi.x + kItemGap && q.lo.x < r.hi.x + kItemGap && r.lo.y < q.hi.y + kItemGap &&
          q.lo.y < r.hi.y + kItemGap)
        return false;
    for (const Segment2& s : walkways)
      if (segment_rect_distance(s, r.lo, r.hi) < kWalkwayClearance) return false;
    return true;
  };

  const int items = rng.stochastic_round(p.density * area / kAreaPerItem);
  for (int n = 0; n < items; ++n) {
    const Item item = pick_item(rng);
    Frame f;
    f.mb = &mb;
    f.segments = p.segments;
    f.z0 = interior.lo.z;
    bool against_wall = false;
    switch (item) {
      case Item::Table: f.W = rng.uniform(1.3, 2.1), f.D = rng.uniform(1.6, 1.9); break;
      case Item::Desk: f.W = 1.5, f.D = 1.25; break;
      case Item::Shelf: f.W = rng.uniform(0.8, 1.8), f.D = 0.36, against_wall = true; break;
      case Item::Cabinet: f.W = rng.uniform(0.8, 1.4), f.D = 0.55, against_wall = true; break;
      case Item::Plant: f.W = 0.7, f.D = 0.7; break;
    }
    bool ok = false;
    for (int attempt = 0; attempt < kPlacementTries && !ok; ++attempt) {
      f.k = static_cast<int>(rng.below(4));
      const double wx = (f.k & 1) ? f.D : f.W, wy = (f.k & 1) ? f.W : f.D;
      const double g = against_wall ? 0.0 : kWallGap;
      if (wx > hi.x - lo.x - 2 * g || wy > hi.y - lo.y - 2 * g) continue;
      double x0 = rng.uniform(lo.x + g, hi.x - g - wx), y0 = rng.uniform(lo.y + g, hi.y - g - wy);
      if (against_wall) {
        // Rotation k puts the local v = 0 side on the south, east, north, west wall.
        if (f.k == 0) y0 = lo.y;
        if (f.k == 1) x0 = hi.x - wx;
        if (f.k == 2) y0 = hi.y - wy;
        if (f.k == 3) x0 = lo.x;
      }
      const Rect r{Vec2(x0, y0), Vec2(x0 + wx, y0 + wy)};
      if (!fits(r)) continue;
      placed.push_back(r);
      f.x0 = x0;
      f.y0 = y0;
      ok = true;
    }
    if (!ok) continue;
    switch (item) {
      case Item::Table: table_group(f, rng); break;
      case Item::Desk: desk(f, rng); break;
      case Item::Shelf: bookshelf(f, rng); break;
      case Item::Cabinet: cabinet(f, rng); break;
      case Item::Plant: plant(f, rng); break;
    }
  }

  // Ceiling: pendant lamps and pipes along the longer side.
  const double ceiling = interior.hi.z;
  const int lamps = rng.stochastic_round(p.density * area / kAreaPerLamp);
  for (int n = 0; n < lamps; ++n)
    pendant_lamp(mb, Vec3(rng.uniform(lo.x + 0.6, hi.x - 0.6), rng.uniform(lo.y + 0.6, hi.y - 0.6), ceiling), p);
  const int pipes = std::min(3, rng.stochastic_round(p.density * 0.8));
  const bool along_x = (hi.x - lo.x) >= (hi.y - lo.y);
  const bool near_low = rng.chance(0.5);
  for (int k = 0; k < pipes; ++k) {
    const double r = rng.uniform(0.03, 0.055), z = ceiling - 0.15 - 0.13 * k;
    const double across = near_low ? (along_x ? lo.y : lo.x) + 0.2 + 0.17 * k
                                   : (along_x ? hi.y : hi.x) - 0.2 - 0.17 * k;
    const Vec3 a = along_x ? Vec3(lo.x + 0.005, across, z) : Vec3(across, lo.y + 0.005, z);
    const Vec3 b = along_x ? Vec3(hi.x - 0.005, across, z) : Vec3(across, hi.y - 0.005, z);
    pipe_run(mb, a, b, r, ceiling, false, p);
  }
}

}  // namespace frontier::gen
