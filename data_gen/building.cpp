// Building pieces, sidecar and --triangles fitting (see header).
#include "data_gen/building.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>

namespace frontier::gen {
namespace {

using ojson = nlohmann::ordered_json;

double topmost_wall_z(const BuildingLayout& L, int f) {
  return BuildingLayout::floor_z(f) + kCeiling + (f + 1 == L.floors() ? kSlab : 0.0);
}

bool horizontal_wall_exists(const BuildingLayout& L, int col, int j) {
  return L.slot(col, j - 1).cell != L.slot(col, j).cell;
}

// A wall along `axis` (0: runs along x, 1: along y) from u0 to u1, centred on `across`,
// from z0 to z1, with openings cut from the floor level zf.
void wall(MeshBuilder& mb, int axis, double across, double u0, double u1, double z0, double z1,
          double zf, std::vector<Opening> openings) {
  std::sort(openings.begin(), openings.end(),
            [](const Opening& a, const Opening& b) { return a.center < b.center; });
  auto emit = [&](double ua, double ub, double za, double zb) {
    if (ub - ua < 1e-3 || zb - za < 1e-3) return;
    const double c0 = across - kWall / 2, c1 = across + kWall / 2;
    if (axis == 0)
      mb.box(Vec3(ua, c0, za), Vec3(ub, c1, zb), palette::kWall);
    else
      mb.box(Vec3(c0, ua, za), Vec3(c1, ub, zb), palette::kWall);
  };
  double cursor = u0;
  for (const Opening& o : openings) {
    const double a = o.center - o.width / 2, b = o.center + o.width / 2;
    emit(cursor, a, z0, z1);
    emit(a, b, zf + o.height, z1);
    cursor = b;
  }
  emit(cursor, u1, z0, z1);
}

void vertical_wall(const BuildingLayout& L, int f, int i, int j, MeshBuilder& mb) {
  if (L.slot(i - 1, j).cell == L.slot(i, j).cell) return;
  const double h = kWall / 2;
  const bool wall_below = horizontal_wall_exists(L, i - 1, j) || horizontal_wall_exists(L, i, j);
  const bool wall_above =
      horizontal_wall_exists(L, i - 1, j + 1) || horizontal_wall_exists(L, i, j + 1);
  const double y0 = L.grid_y(j) + (wall_below ? h : -h);
  const double y1 = L.grid_y(j + 1) - (wall_above ? h : -h);
  const double zf = BuildingLayout::floor_z(f);
  wall(mb, 1, L.grid_x(i), y0, y1, zf - kSlab, topmost_wall_z(L, f), zf, L.vertical_openings(f, i, j));
}

void horizontal_wall(const BuildingLayout& L, int f, int i, int j, MeshBuilder& mb) {
  if (!horizontal_wall_exists(L, i, j)) return;
  const double h = kWall / 2, zf = BuildingLayout::floor_z(f);
  wall(mb, 0, L.grid_y(j), L.grid_x(i) - h, L.grid_x(i + 1) + h, zf - kSlab, topmost_wall_z(L, f),
       zf, L.horizontal_openings(f, i, j));
}

void slab(MeshBuilder& mb, double x0, double y0, double x1, double y1, double z) {
  mb.box(Vec3(x0, y0, z - kSlab), Vec3(x1, y1, z), palette::kSlab);
}

// Gaps in a wall run [a, b] left by openings (plus clearance), as maximal free intervals.
std::vector<std::pair<double, double>> free_runs(double a, double b, const std::vector<Opening>& openings) {
  std::vector<std::pair<double, double>> cuts;
  for (const Opening& o : openings) cuts.emplace_back(o.center - o.width / 2 - 0.25, o.center + o.width / 2 + 0.25);
  std::sort(cuts.begin(), cuts.end());
  std::vector<std::pair<double, double>> runs;
  double cursor = a;
  for (const auto& [c0, c1] : cuts) {
    if (c0 > cursor) runs.emplace_back(cursor, std::min(c0, b));
    cursor = std::max(cursor, c1);
  }
  if (cursor < b) runs.emplace_back(cursor, b);
  return runs;
}

// Corridor-wide choices (pipes, rails) drawn from the cell's own stream so that every slot
// of the corridor agrees on them.
struct RunFittings {
  int pipes = 0;
  double radius[2] = {0.04, 0.04};
  bool rails = false;
};

RunFittings run_fittings(const BuildingLayout& L, const DetailParams& d, int f, int cell) {
  Rng rng(L.shape().seed, Stream::Corridor, f, cell);
  RunFittings r;
  r.pipes = std::min(2, rng.stochastic_round(d.density));
  for (double& x : r.radius) x = rng.uniform(0.03, 0.06);
  r.rails = rng.chance(std::min(1.0, d.density));
  return r;
}

void corridor_detail(const BuildingLayout& L, const DetailParams& d, int f, int col, int row,
                     int cell, MeshBuilder& mb) {
  const Aabb cb = L.cell_bounds(f, cell);
  const double xs = std::max(L.grid_x(col), cb.lo.x), xe = std::min(L.grid_x(col + 1), cb.hi.x);
  const bool first = xs <= cb.lo.x, last = xe >= cb.hi.x;
  const RunFittings fit = run_fittings(L, d, f, cell);
  Rng rng(L.shape().seed, Stream::Corridor, f, cell, col);
  const double ceiling = cb.hi.z, yc = 0.5 * (cb.lo.y + cb.hi.y);
  if (rng.chance(std::min(1.0, d.density)))
    pendant_lamp(mb, Vec3(0.5 * (xs + xe), yc, ceiling), d);
  for (int k = 0; k < fit.pipes; ++k) {
    const double y = cb.hi.y - 0.2 - 0.17 * k, z = ceiling - 0.15 - 0.13 * k;
    pipe_run(mb, Vec3(xs + (first ? 0.005 : 0.0), y, z), Vec3(xe - (last ? 0.005 : 0.0), y, z),
             fit.radius[k], ceiling, !first, d);
  }
  if (!fit.rails) return;
  const double zr = cb.lo.z + 0.9;
  const double a = xs + (first ? 0.05 : 0.0), b = xe - (last ? 0.05 : 0.0);
  for (int side = 0; side < 2; ++side) {
    const int j = side == 0 ? row : row + 1;
    const double y = side == 0 ? cb.lo.y + kRailOffset : cb.hi.y - kRailOffset;
    for (const auto& [r0, r1] : free_runs(a, b, L.horizontal_openings(f, col, j)))
      handrail(mb, Vec3(r0, y, zr), Vec3(r1, y, zr), Vec3(0, side == 0 ? -1 : 1, 0), d);
  }
}

void spine_detail(const BuildingLayout& L, const DetailParams& d, int f, int row, int cell,
                  MeshBuilder& mb) {
  const Aabb cb = L.cell_bounds(f, cell);
  const double ys = std::max(L.grid_y(row), cb.lo.y), ye = std::min(L.grid_y(row + 1), cb.hi.y);
  const bool first = ys <= cb.lo.y, last = ye >= cb.hi.y;
  const RunFittings fit = run_fittings(L, d, f, cell);
  Rng rng(L.shape().seed, Stream::Corridor, f, cell, row);
  const double ceiling = cb.hi.z, xc = 0.5 * (cb.lo.x + cb.hi.x);
  if (rng.chance(std::min(1.0, d.density)))
    pendant_lamp(mb, Vec3(xc, 0.5 * (ys + ye), ceiling), d);
  for (int k = 0; k < fit.pipes; ++k) {
    const double x = cb.lo.x + 0.2 + 0.17 * k, z = ceiling - 0.15 - 0.13 * k;
    pipe_run(mb, Vec3(x, ys + (first ? 0.005 : 0.0), z), Vec3(x, ye - (last ? 0.005 : 0.0), z),
             fit.radius[k], ceiling, !first, d);
  }
  if (!fit.rails) return;
  const double zr = cb.lo.z + 0.9;
  const double a = ys + (first ? 0.05 : 0.0), b = ye - (last ? 0.05 : 0.0);
  handrail(mb, Vec3(cb.lo.x + kRailOffset, a, zr), Vec3(cb.lo.x + kRailOffset, b, zr), Vec3(-1, 0, 0), d);
  for (const auto& [r0, r1] : free_runs(a, b, L.vertical_openings(f, 1, row)))
    handrail(mb, Vec3(cb.hi.x - kRailOffset, r0, zr), Vec3(cb.hi.x - kRailOffset, r1, zr),
             Vec3(1, 0, 0), d);
}

void stair_detail(const BuildingLayout& L, const DetailParams& d, int f, MeshBuilder& mb) {
  const double z = BuildingLayout::floor_z(f);
  const double riser = kStorey / kSteps;
  if (L.has_flight(f)) {
    const Flight fl = L.flight(f);
    for (int i = 0; i < kSteps; ++i)
      mb.box(Vec3(fl.x0, fl.y_bottom - (i + 1) * kTread, z),
             Vec3(fl.x1, fl.y_bottom - i * kTread, z + (i + 1) * riser), palette::kStep);
    // Banister on the walkway side of the flight: posts on steps, rail along the pitch line.
    const bool west_lane = f % 2 == 0;
    const double x = west_lane ? fl.x1 - 0.06 : fl.x0 + 0.06;
    auto post_base = [&](int i) { return Vec3(x, fl.y_bottom - (i + 0.5) * kTread, z + (i + 1) * riser); };
    for (int i = 0; i < kSteps; i += 3) mb.cylinder(post_base(i), post_base(i) + Vec3(0, 0, 0.9), 0.02, d.segments, 1, palette::kRail);
    mb.cylinder(post_base(kSteps - 1), post_base(kSteps - 1) + Vec3(0, 0, 0.9), 0.02, d.segments, 1, palette::kRail);
    mb.cylinder(post_base(0) + Vec3(0, 0, 0.9), post_base(kSteps - 1) + Vec3(0, 0, 0.9), 0.025, d.segments, 1, palette::kRail);
  }
  if (f > 0) {
    // Guard rail around the hole left by the flight from the floor below.
    const Flight h = L.flight(f - 1);
    const bool west_lane = (f - 1) % 2 == 0;
    const double xb = west_lane ? h.x1 + 0.06 : h.x0 - 0.06;
    const double xw = west_lane ? h.x0 + 0.05 : h.x1 - 0.05;
    const double yn = h.y_bottom + 0.06;
    guard_rail(mb, Vec3(xb, h.y_top, z), Vec3(xb, yn, z), 1.0, d);
    guard_rail(mb, Vec3(xb + (west_lane ? -0.1 : 0.1), yn, z), Vec3(xw, yn, z), 1.0, d);
  }
}

void room_detail(const BuildingLayout& L, const DetailParams& d, int f, int col, int row, int cell,
                 MeshBuilder& mb) {
  const Aabb interior = L.cell_bounds(f, cell);
  const Vec2 hub = L.walk_line(cell)[0];
  std::vector<Segment2> walkways;
  for (const Portal& p : L.slot_wall_portals(f, col, row)) {
    const Vec3 approach = p.cell_a == cell ? p.approach_a : p.approach_b;
    const Vec2 a(approach.x, approach.y), c(p.route[0].x, p.route[0].y);
    walkways.push_back({c, a});
    walkways.push_back({a, hub});
  }
  Rng rng(L.shape().seed, Stream::Room, f, cell);
  furnish_room(mb, rng, interior, walkways, d);
}

// kMinSegments..limit ordered by distance from `from` (ties: fewer segments first).
std::vector<int> segments_by_distance(int from, int limit) {
  std::vector<int> t;
  for (int k = kMinSegments; k <= limit; ++k) t.push_back(k);
  std::stable_sort(t.begin(), t.end(), [&](int a, int b) { return std::abs(a - from) < std::abs(b - from); });
  return t;
}

double round4(double x) { return std::round(x * 1e4) / 1e4; }
ojson jvec(const Vec3& v) { return ojson::array({round4(v.x), round4(v.y), round4(v.z)}); }
ojson jvec(const Vec2& v) { return ojson::array({round4(v.x), round4(v.y)}); }
ojson jbox(const Aabb& b) { return ojson::array({jvec(b.lo), jvec(b.hi)}); }
ojson jrgb(const Rgb& c) { return ojson::array({c.r, c.g, c.b}); }

}  // namespace

Status validate(const BuildingParams& p) {
  if (p.shape.floors < 1 || p.shape.floors > kMaxFloors)
    return Status::invalid_argument(fmt::format("--floors {} is not in [1, {}]", p.shape.floors, kMaxFloors));
  if (p.shape.rooms < 1 || p.shape.rooms > kMaxRoomsPerFloor)
    return Status::invalid_argument(
        fmt::format("--rooms {} is not in [1, {}]", p.shape.rooms, kMaxRoomsPerFloor));
  if (!(p.detail.density >= 0.0 && p.detail.density <= kMaxFurniture))
    return Status::invalid_argument(
        fmt::format("--furniture {} is not in [0, {}]", p.detail.density, kMaxFurniture));
  if (p.detail.segments < kMinSegments || p.detail.segments > kMaxSegments)
    return Status::invalid_argument(fmt::format("--tessellation {} is not in [{}, {}]",
                                                p.detail.segments, kMinSegments, kMaxSegments));
  return Status::ok();
}

uint64_t building_piece_count(const BuildingLayout& L) {
  return uint64_t(L.floors()) * uint64_t(L.grid_rows()) * uint64_t(L.grid_cols());
}

void building_piece(const BuildingLayout& L, const DetailParams& d, uint64_t index, MeshBuilder& mb) {
  const uint64_t cols = uint64_t(L.grid_cols()), rows = uint64_t(L.grid_rows());
  const int col = static_cast<int>(index % cols), row = static_cast<int>((index / cols) % rows);
  const int f = static_cast<int>(index / (cols * rows));
  const Slot s = L.slot(col, row);
  const double z = BuildingLayout::floor_z(f);
  const double x0 = L.grid_x(col), x1 = L.grid_x(col + 1), y0 = L.grid_y(row), y1 = L.grid_y(row + 1);

  if (s.cell >= 0) {
    if (s.kind == CellKind::Stair && f > 0) {
      const Flight h = L.flight(f - 1);
      slab(mb, x0, y0, h.x0, y1, z);
      slab(mb, h.x1, y0, x1, y1, z);
      slab(mb, h.x0, y0, h.x1, h.y_top, z);
      slab(mb, h.x0, h.y_bottom, h.x1, y1, z);
    } else {
      slab(mb, x0, y0, x1, y1, z);
    }
    if (f + 1 == L.floors()) slab(mb, x0, y0, x1, y1, BuildingLayout::floor_z(f + 1));
  }
  vertical_wall(L, f, col, row, mb);
  if (col + 1 == L.grid_cols()) vertical_wall(L, f, col + 1, row, mb);
  horizontal_wall(L, f, col, row, mb);
  if (row + 1 == L.grid_rows()) horizontal_wall(L, f, col, row + 1, mb);

  if (s.cell < 0) return;
  switch (s.kind) {
    case CellKind::Room: room_detail(L, d, f, col, row, s.cell, mb); break;
    case CellKind::Corridor: corridor_detail(L, d, f, col, row, s.cell, mb); break;
    case CellKind::Spine: spine_detail(L, d, f, row, s.cell, mb); break;
    case CellKind::Stair: stair_detail(L, d, f, mb); break;
  }
}

MeshCounts count_building(const BuildingParams& p) {
  const BuildingLayout L(p.shape);
  return count_pieces(
      building_piece_count(L),
      [&](uint64_t i, MeshBuilder& mb) { building_piece(L, p.detail, i, mb); }, p.layout);
}

Status write_building_sidecar(const BuildingParams& p, const MeshCounts& counts,
                              const std::string& model_path, const std::string& path) {
  const BuildingLayout L(p.shape);
  const std::string temp = path + ".tmp";
  std::ofstream out(temp, std::ios::binary | std::ios::trunc);
  if (!out) return Status::io_error(fmt::format("cannot create '{}': {}", temp, std::strerror(errno)));

  ojson head = {
      {"format", "frontier-building"},
      {"version", 1},
      {"model", model_path},
      {"units", "m"},
      {"up", {0, 0, 1}},
      {"walkable", true},
      {"eye_height", kEyeHeight},
      {"parameters",
       {{"floors", p.shape.floors},
        {"rooms_per_floor", p.shape.rooms},
        {"furniture", p.detail.density},
        {"tessellation", p.detail.segments},
        {"seed", p.shape.seed},
        {"normals", p.layout.normals},
        {"colors", p.layout.colors}}},
      {"triangles", counts.triangles},
      {"vertices", counts.vertices},
      {"bounds", jbox(L.bounds())},
      {"wall_thickness", kWall},
      {"slab_thickness", kSlab},
      {"ceiling_height", kCeiling},
      {"storey_height", kStorey},
      {"palette",
       {{"structure", {jrgb(palette::kWall), jrgb(palette::kSlab), jrgb(palette::kStep)}}}},
  };
  // One small field per line; the big arrays follow, one element per line, as they are made.
  out << "{";
  bool first_field = true;
  for (const auto& [key, value] : head.items()) {
    out << (first_field ? "\n " : ",\n ") << ojson(key).dump() << ": " << value.dump();
    first_field = false;
  }
  out << ",\n \"floors\": [";
  for (int f = 0; f < L.floors(); ++f) {
    const ojson fl = {{"index", f}, {"height", round4(BuildingLayout::floor_z(f))},
                      {"ceiling", round4(BuildingLayout::floor_z(f) + kCeiling)}};
    out << (f ? ",\n  " : "\n  ") << fl.dump();
  }
  out << "\n ],\n \"rooms\": [";
  bool first = true;
  for (int f = 0; f < L.floors(); ++f)
    for (int c = 0; c < L.cells_per_floor(); ++c) {
      const auto line = L.walk_line(c);
      ojson cell = {{"id", L.cell_id(f, c)},
                    {"floor", f},
                    {"kind", cell_kind_name(L.cell_kind(c))},
                    {"bounds", jbox(L.cell_bounds(f, c))},
                    {"walk_line", {jvec(line[0]), jvec(line[1])}}};
      if (L.cell_kind(c) == CellKind::Stair && L.has_flight(f)) {
        const Flight fl = L.flight(f);
        cell["flight"] = {{"lane", {jvec(Vec2(fl.x0, fl.y_top)), jvec(Vec2(fl.x1, fl.y_bottom))}},
                          {"z", {round4(BuildingLayout::floor_z(f)), round4(BuildingLayout::floor_z(f + 1))}},
                          {"climbs_towards", {0, -1}}};
      }
      out << (first ? "\n  " : ",\n  ") << cell.dump();
      first = false;
    }
  out << "\n ],\n \"portals\": [";
  first = true;
  int64_t id = 0;
  for (int f = 0; f < L.floors(); ++f)
    L.for_each_portal(f, [&](const Portal& q) {
      ojson poly = ojson::array(), route = ojson::array();
      for (const Vec3& v : q.polygon) poly.push_back(jvec(v));
      for (const Vec3& v : q.route) route.push_back(jvec(v));
      const ojson portal = {{"id", id++},
                            {"kind", q.kind},
                            {"rooms", {L.cell_id(q.floor_a, q.cell_a), L.cell_id(q.floor_b, q.cell_b)}},
                            {"polygon", poly},
                            {"opening", jbox(q.opening)},
                            {"approach", {jvec(q.approach_a), jvec(q.approach_b)}},
                            {"route", route}};
      out << (first ? "\n  " : ",\n  ") << portal.dump();
      first = false;
    });
  out << "\n ]\n}\n";
  out.close();
  if (!out) {
    std::remove(temp.c_str());
    return Status::io_error(fmt::format("writing '{}' failed", temp));
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0)
    return Status::io_error(fmt::format("renaming '{}' to '{}': {}", temp, path, std::strerror(errno)));
  return Status::ok();
}

Result<BuildingParams> fit_building(BuildingParams p, uint64_t target, const FitOptions& o) {
  if (target == 0) return Status::invalid_argument("--triangles must be positive");
  const double n = static_cast<double>(target);
  auto error_of = [&](uint64_t c) { return std::abs(static_cast<double>(c) - n) / n; };
  BuildingParams best = p;
  double best_error = kInfinity;
  uint64_t best_count = 0;
  auto trial = [&](const BuildingParams& q) {
    const uint64_t c = count_building(q).triangles;
    const double e = error_of(c);
    if (e < best_error) best_error = e, best = q, best_count = c;
    return c;
  };
  const double good = o.tolerance / 3;

  BuildingParams smallest = p;
  if (!o.floors_fixed) smallest.shape.floors = 1;
  if (!o.rooms_fixed) smallest.shape.rooms = 1;
  if (!o.furniture_fixed) smallest.detail.density = 0.0;
  if (!o.tessellation_fixed) smallest.detail.segments = kMinSegments;
  const uint64_t smallest_count = count_building(smallest).triangles;
  if (n < static_cast<double>(smallest_count) * (1.0 - o.tolerance))
    return Status::invalid_argument(fmt::format(
        "--triangles {}: too small; the smallest building the other options allow ({} floor(s), "
        "{} room(s) per floor, furniture {}, tessellation {}) has {} triangles",
        target, smallest.shape.floors, smallest.shape.rooms, smallest.detail.density,
        smallest.detail.segments, smallest_count));

  // 1. Floors and rooms: total rooms from the triangles of a sample floor, then secant steps.
  if (!o.floors_fixed || !o.rooms_fixed) {
    BuildingParams sample = p;
    sample.shape.floors = 1;
    sample.shape.rooms = 16;
    const double per_room = std::max(1.0, static_cast<double>(count_building(sample).triangles) / 16.0);
    const double rooms_total = std::max(1.0, n / per_room);
    BuildingParams q = p;
    if (!o.floors_fixed && !o.rooms_fixed)
      q.shape.floors = std::clamp(static_cast<int>(std::lround(std::sqrt(rooms_total) / 4.0)), 1, kMaxFloors);
    if (!o.rooms_fixed)
      q.shape.rooms = std::clamp(static_cast<int>(std::lround(rooms_total / q.shape.floors)), 1, kMaxRoomsPerFloor);
    else
      q.shape.floors = std::clamp(static_cast<int>(std::lround(rooms_total / q.shape.rooms)), 1, kMaxFloors);
    int* knob = o.rooms_fixed ? &q.shape.floors : &q.shape.rooms;
    const int knob_max = o.rooms_fixed ? kMaxFloors : kMaxRoomsPerFloor;
    for (int iter = 0; iter < 8; ++iter) {
      const uint64_t c = trial(q);
      if (error_of(c) < good) break;
      const int next = std::clamp(
          static_cast<int>(std::lround(*knob * n / std::max<double>(1.0, static_cast<double>(c)))), 1, knob_max);
      if (next == *knob) break;
      *knob = next;
    }
    p = best;
  } else {
    trial(p);
  }

  // 2. Furniture density: bisection (the count grows with it, up to placement saturation).
  if (best_error >= good && !o.furniture_fixed) {
    auto bisect_density = [&](BuildingParams q) {
      double lo = 0.0, hi = std::max(2.0 * q.detail.density, 1.0);
      q.detail.density = hi;
      while (trial(q) < target && hi < kMaxFurniture) {
        lo = hi;
        hi = std::min(kMaxFurniture, hi * 2);
        q.detail.density = hi;
      }
      for (int iter = 0; iter < 24 && best_error >= good; ++iter) {
        q.detail.density = 0.5 * (lo + hi);
        (trial(q) < target ? lo : hi) = q.detail.density;
      }
    };
    bisect_density(p);
    // 3. Tessellation as a finer knob when density alone could not land close enough.
    // Nearest tessellations first, so the model keeps the look it was asked for.
    if (best_error >= good && !o.tessellation_fixed) {
      const BuildingParams base = best;
      for (int t : segments_by_distance(base.detail.segments, 48)) {
        if (best_error < good) break;
        BuildingParams q = base;
        q.detail.segments = t;
        bisect_density(q);
      }
    }
  } else if (best_error >= good && !o.tessellation_fixed) {
    const BuildingParams base = best;
    for (int t : segments_by_distance(base.detail.segments, kMaxSegments)) {
      if (best_error < good) break;
      BuildingParams q = base;
      q.detail.segments = t;
      trial(q);
    }
  }

  if (best_error > o.tolerance)
    return Status::invalid_argument(fmt::format(
        "--triangles {}: the closest building the fixed options allow has {} triangles ({:+.1f}%); "
        "leave --floors, --rooms, --furniture or --tessellation free",
        target, best_count, 100.0 * (static_cast<double>(best_count) - n) / n));
  return best;
}

}  // namespace frontier::gen
