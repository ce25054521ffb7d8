// Floor plan arithmetic (see header).
#include "data_gen/building_layout.h"

#include "data_gen/rng.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace frontier::gen {

namespace {
constexpr double kBandDepth = 2 * kRoomDepth + kCorridorDepth;
constexpr double kRoomRoomDoorChance = 0.3;
// Keeps a door's jamb clear of the corner walls.
constexpr double door_margin(double width) { return kWall / 2 + 0.35 + width / 2; }
}  // namespace

const char* cell_kind_name(CellKind k) {
  switch (k) {
    case CellKind::Room: return "room";
    case CellKind::Corridor: return "corridor";
    case CellKind::Spine: return "spine";
    case CellKind::Stair: return "stair";
  }
  return "?";
}

BuildingLayout::BuildingLayout(const BuildingShape& shape) : shape_(shape) {
  assert(shape.floors >= 1 && shape.rooms >= 1);
  // Roughly square floors: a band is kBandDepth deep and holds two rooms per column.
  const double r = shape.rooms;
  const int b0 = std::max(1, static_cast<int>(std::lround(std::sqrt(r * kRoomWidth / (2 * kBandDepth)))));
  columns_ = static_cast<int>((shape.rooms + 2 * b0 - 1) / (2 * b0));
  bands_ = static_cast<int>((shape.rooms + 2 * columns_ - 1) / (2 * columns_));
  first_band_row_ = has_stairs() ? 1 : 0;
}

double BuildingLayout::grid_x(int i) const {
  return i <= 0 ? 0.0 : kSpineWidth + (i - 1) * kRoomWidth;
}

double BuildingLayout::grid_y(int j) const {
  if (j < first_band_row_) return 0.0;
  const double base = has_stairs() ? kStairDepth : 0.0;
  const int k = j - first_band_row_;
  static constexpr double kOffset[3] = {0.0, kRoomDepth, kRoomDepth + kCorridorDepth};
  return base + (k / 3) * kBandDepth + kOffset[k % 3];
}

int BuildingLayout::room_at(int band, int column, int side) const {
  if (band < 0 || band >= bands_ || column < 0 || column >= columns_) return -1;
  const int64_t k = int64_t{band} * 2 * columns_ + 2 * column + side;
  return k < shape_.rooms ? static_cast<int>(k) : -1;
}

int BuildingLayout::corridor_length(int band) const {
  const int64_t in_band = std::min<int64_t>(2 * columns_, shape_.rooms - int64_t{band} * 2 * columns_);
  return static_cast<int>(std::min<int64_t>(columns_, (in_band + 1) / 2));
}

CellKind BuildingLayout::cell_kind(int local) const {
  if (local < shape_.rooms) return CellKind::Room;
  if (local < shape_.rooms + bands_) return CellKind::Corridor;
  if (local == shape_.rooms + bands_) return CellKind::Spine;
  return CellKind::Stair;
}

Slot BuildingLayout::slot(int col, int row) const {
  Slot s;
  if (col < 0 || col >= grid_cols() || row < 0 || row >= grid_rows()) return s;
  if (row < first_band_row_) {
    if (col == 0) s = {shape_.rooms + bands_ + 1, CellKind::Stair};
    return s;
  }
  if (col == 0) return {shape_.rooms + bands_, CellKind::Spine};
  const int k = row - first_band_row_, band = k / 3, part = k % 3, column = col - 1;
  if (part == 1) {
    if (column < corridor_length(band)) s = {shape_.rooms + band, CellKind::Corridor};
    return s;
  }
  const int room = room_at(band, column, part == 0 ? 0 : 1);
  if (room >= 0) s = {room, CellKind::Room};
  return s;
}

Aabb BuildingLayout::cell_bounds(int floor, int local) const {
  double x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  switch (cell_kind(local)) {
    case CellKind::Room: {
      const int per_band = 2 * columns_;
      const int band = local / per_band, column = (local % per_band) / 2, side = local % 2;
      const int row = first_band_row_ + 3 * band + (side == 0 ? 0 : 2);
      x0 = grid_x(column + 1), x1 = grid_x(column + 2), y0 = grid_y(row), y1 = grid_y(row + 1);
      break;
    }
    case CellKind::Corridor: {
      const int band = local - shape_.rooms;
      const int row = first_band_row_ + 3 * band + 1;
      x0 = grid_x(1), x1 = grid_x(1 + corridor_length(band));
      y0 = grid_y(row), y1 = grid_y(row + 1);
      break;
    }
    case CellKind::Spine:
      x0 = grid_x(0), x1 = grid_x(1), y0 = grid_y(first_band_row_), y1 = grid_y(grid_rows());
      break;
    case CellKind::Stair:
      x0 = grid_x(0), x1 = grid_x(1), y0 = grid_y(0), y1 = kStairDepth;
      break;
  }
  const double h = kWall / 2, z = floor_z(floor);
  return Aabb(Vec3(x0 + h, y0 + h, z), Vec3(x1 - h, y1 - h, z + kCeiling));
}

Aabb BuildingLayout::bounds() const {
  const double h = kWall / 2;
  return Aabb(Vec3(-h, -h, -kSlab), Vec3(grid_x(grid_cols()) + h, grid_y(grid_rows()) + h,
                                          floor_z(shape_.floors)));
}

std::vector<Opening> BuildingLayout::vertical_openings(int floor, int i, int j) const {
  std::vector<Opening> out;
  const Slot west = slot(i - 1, j), east = slot(i, j);
  if (west.cell == east.cell || west.cell < 0 || east.cell < 0) return out;
  const double y0 = grid_y(j), y1 = grid_y(j + 1);
  if (west.kind == CellKind::Spine && east.kind == CellKind::Corridor) {
    out.push_back({0.5 * (y0 + y1), kArchWidth, kArchHeight, west.cell, east.cell, "arch"});
  } else if (west.kind == CellKind::Room && east.kind == CellKind::Room) {
    Rng rng(shape_.seed, Stream::Door, floor, i, j, 7);
    if (rng.chance(kRoomRoomDoorChance)) {
      const double m = door_margin(kDoorWidth);
      out.push_back({rng.uniform(y0 + m, y1 - m), kDoorWidth, kDoorHeight, west.cell, east.cell, "door"});
    }
  }
  return out;
}

std::vector<Opening> BuildingLayout::horizontal_openings(int floor, int i, int j) const {
  std::vector<Opening> out;
  const Slot south = slot(i, j - 1), north = slot(i, j);
  if (south.cell == north.cell || south.cell < 0 || north.cell < 0) return out;
  const double x0 = grid_x(i), x1 = grid_x(i + 1);
  const bool room_corridor = (south.kind == CellKind::Room && north.kind == CellKind::Corridor) ||
                             (south.kind == CellKind::Corridor && north.kind == CellKind::Room);
  if (room_corridor) {
    const int room = south.kind == CellKind::Room ? south.cell : north.cell;
    Rng rng(shape_.seed, Stream::Door, floor, room);
    const double m = door_margin(kDoorWidth);
    out.push_back({rng.uniform(x0 + m, x1 - m), kDoorWidth, kDoorHeight, south.cell, north.cell, "door"});
  } else if (south.kind == CellKind::Stair && north.kind == CellKind::Spine) {
    out.push_back({stair_lane_center(1), kStairDoorWidth, kDoorHeight, south.cell, north.cell,
                   "stair_door"});
  }
  return out;
}

double BuildingLayout::stair_lane_center(int lane) const {
  const double w = (kSpineWidth - kWall) / 3.0;
  return kWall / 2 + (lane + 0.5) * w;
}

Flight BuildingLayout::flight(int floor) const {
  const double w = (kSpineWidth - kWall) / 3.0;
  const int lane = floor % 2 == 0 ? 0 : 2;
  Flight f;
  f.x0 = kWall / 2 + lane * w;
  f.x1 = f.x0 + w;
  f.y_bottom = kStairDepth - kWall / 2 - kLanding;
  f.y_top = f.y_bottom - kSteps * kTread;
  return f;
}

double BuildingLayout::stair_walk_y_south() const { return flight(0).y_top - 0.6; }
double BuildingLayout::stair_walk_y_north() const { return kStairDepth - kApproach; }

}  // namespace frontier::gen

namespace frontier::gen {

Portal BuildingLayout::vertical_portal(int floor, int i, const Opening& o) const {
  const double x = grid_x(i), z = floor_z(floor), c = o.center, w = o.width / 2;
  Portal p;
  p.floor_a = p.floor_b = floor;
  p.cell_a = o.cell_a;
  p.cell_b = o.cell_b;
  p.kind = o.kind;
  p.polygon = {Vec3(x, c - w, z), Vec3(x, c + w, z), Vec3(x, c + w, z + o.height),
               Vec3(x, c - w, z + o.height)};
  p.opening = Aabb(Vec3(x - kWall / 2, c - w, z), Vec3(x + kWall / 2, c + w, z + o.height));
  const double eye = z + kEyeHeight;
  p.approach_a = Vec3(x - kApproach, c, eye);
  p.approach_b = Vec3(x + kApproach, c, eye);
  p.route = {Vec3(x, c, eye)};
  return p;
}

Portal BuildingLayout::horizontal_portal(int floor, int j, const Opening& o) const {
  const double y = grid_y(j), z = floor_z(floor), c = o.center, w = o.width / 2;
  Portal p;
  p.floor_a = p.floor_b = floor;
  p.cell_a = o.cell_a;
  p.cell_b = o.cell_b;
  p.kind = o.kind;
  p.polygon = {Vec3(c - w, y, z), Vec3(c + w, y, z), Vec3(c + w, y, z + o.height),
               Vec3(c - w, y, z + o.height)};
  p.opening = Aabb(Vec3(c - w, y - kWall / 2, z), Vec3(c + w, y + kWall / 2, z + o.height));
  const double eye = z + kEyeHeight;
  p.approach_a = Vec3(c, y - kApproach, eye);
  p.approach_b = Vec3(c, y + kApproach, eye);
  p.route = {Vec3(c, y, eye)};
  return p;
}

Portal BuildingLayout::stair_portal(int floor) const {
  assert(has_flight(floor));
  const Flight f = flight(floor);
  const int stair = shape_.rooms + bands_ + 1;
  const double z0 = floor_z(floor), z1 = floor_z(floor + 1), zm = z1 - kSlab / 2;
  const double xc = 0.5 * (f.x0 + f.x1);
  Portal p;
  p.floor_a = floor;
  p.floor_b = floor + 1;
  p.cell_a = p.cell_b = stair;
  p.kind = "stair";
  p.polygon = {Vec3(f.x0, f.y_top, zm), Vec3(f.x1, f.y_top, zm), Vec3(f.x1, f.y_bottom, zm),
               Vec3(f.x0, f.y_bottom, zm)};
  p.opening = Aabb(Vec3(f.x0, f.y_top, z1 - kSlab), Vec3(f.x1, f.y_bottom, z1));
  p.approach_a = Vec3(xc, f.y_bottom + 0.6, z0 + kEyeHeight);
  p.route = {Vec3(xc, f.y_bottom, z0 + kEyeHeight), Vec3(xc, f.y_top, z1 + kEyeHeight)};
  p.approach_b = Vec3(xc, f.y_top - 0.6, z1 + kEyeHeight);
  return p;
}

void BuildingLayout::for_each_portal(int floor, const std::function<void(const Portal&)>& visit) const {
  for (int j = 0; j < grid_rows(); ++j)
    for (int i = 1; i < grid_cols(); ++i)
      for (const Opening& o : vertical_openings(floor, i, j)) visit(vertical_portal(floor, i, o));
  for (int j = 1; j < grid_rows(); ++j)
    for (int i = 0; i < grid_cols(); ++i)
      for (const Opening& o : horizontal_openings(floor, i, j)) visit(horizontal_portal(floor, j, o));
  if (has_flight(floor)) visit(stair_portal(floor));
}

std::vector<Portal> BuildingLayout::slot_wall_portals(int floor, int col, int row) const {
  std::vector<Portal> out;
  for (int i : {col, col + 1})
    for (const Opening& o : vertical_openings(floor, i, row)) out.push_back(vertical_portal(floor, i, o));
  for (int j : {row, row + 1})
    for (const Opening& o : horizontal_openings(floor, col, j)) out.push_back(horizontal_portal(floor, j, o));
  return out;
}

std::array<Vec2, 2> BuildingLayout::walk_line(int local) const {
  const Aabb b = cell_bounds(0, local);
  const Vec2 c(0.5 * (b.lo.x + b.hi.x), 0.5 * (b.lo.y + b.hi.y));
  constexpr double kEndGap = 0.5;
  switch (cell_kind(local)) {
    case CellKind::Room: return {c, c};
    case CellKind::Corridor: return {Vec2(b.lo.x + kEndGap, c.y), Vec2(b.hi.x - kEndGap, c.y)};
    case CellKind::Spine: return {Vec2(c.x, b.lo.y + kEndGap), Vec2(c.x, b.hi.y - kEndGap)};
    case CellKind::Stair: {
      const double x = stair_lane_center(1);
      return {Vec2(x, stair_walk_y_south()), Vec2(x, stair_walk_y_north())};
    }
  }
  return {c, c};
}

}  // namespace frontier::gen
