// The floor plan of a generated building, as pure functions of its parameters.
//
// Z is up; metres; the building's south-west corner at floor 0 is the origin. Every floor has
// the same plan, a grid of slots (columns along x, rows along y):
//
//   column 0 (kSpineWidth wide) is the spine, a corridor along y joining all band corridors;
//   columns 1..C hold rooms (kRoomWidth wide);
//   row 0 (only when there are several floors) holds the stairwell under the spine column;
//   then each band b has three rows: rooms (south side), a corridor along x, rooms (north).
//
// Rooms fill the bands' slots in order (band, column, side), so the last band may be partial;
// its corridor ends at its last occupied column. A *cell* is a room, a band corridor, the spine
// or the stairwell of one floor (local index: rooms 0..R-1, corridors R..R+B-1, spine, stair).
//
// Walls are centred on grid lines (thickness kWall) wherever the slots on the two sides belong
// to different cells; a cell's interior is its slot rectangle shrunk by kWall/2, from the floor
// (z_f) to the ceiling (z_f + kCeiling). Openings (doors, the corridor-to-spine arches and the
// stairwell door) are cut into walls; each joins exactly two cells of the same floor and is a
// portal. Stairwells of consecutive floors are joined by a portal in the slab above the flight.
//
// Nothing here holds per-room state: memory is O(1) in the building size, and every function
// may be called from any thread.
#pragma once

#include "src/core/geometry.h"

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace frontier::gen {

using Vec2 = glm::dvec2;

// Dimensions (metres).
inline constexpr double kWall = 0.2;         // wall thickness
inline constexpr double kSlab = 0.3;         // floor slab thickness
inline constexpr double kCeiling = 3.0;      // floor to ceiling
inline constexpr double kStorey = kCeiling + kSlab;
inline constexpr double kRoomWidth = 6.0;    // along x
inline constexpr double kRoomDepth = 5.0;    // along y
inline constexpr double kCorridorDepth = 2.4;
inline constexpr double kSpineWidth = 4.5;
inline constexpr double kStairDepth = 8.8;
inline constexpr double kDoorWidth = 1.0, kDoorHeight = 2.1;
inline constexpr double kArchWidth = 1.8, kArchHeight = 2.5;  // corridor <-> spine
inline constexpr double kStairDoorWidth = 1.2;
inline constexpr int kSteps = 20;
inline constexpr double kTread = 0.28;
inline constexpr double kLanding = 1.5;
// Walking: eye height, how far in front of a portal (from the wall's mid-plane) a walker stands,
// and how far furniture keeps from the walkways portal -> approach -> hub.
inline constexpr double kEyeHeight = 1.7;
inline constexpr double kApproach = 0.8;
inline constexpr double kWalkwayClearance = 0.6;

enum class CellKind { Room, Corridor, Spine, Stair };
const char* cell_kind_name(CellKind k);

struct BuildingShape {
  int floors = 1;
  int rooms = 1;  // per floor
  uint64_t seed = 1;
};

struct Slot {
  int cell = -1;  // local cell index, -1 when empty
  CellKind kind = CellKind::Room;
};

// An opening cut into the wall on a grid edge. `center` runs along the edge (x for horizontal
// edges, y for vertical ones); the opening spans center +- width/2 and floor .. floor + height.
struct Opening {
  double center = 0.0, width = 0.0, height = 0.0;
  int cell_a = -1, cell_b = -1;  // local cells: a on the west/south side, b on the east/north
  const char* kind = "door";     // "door", "arch", "stair_door"
};

// A straight flight of kSteps steps in the stairwell of floor f, rising to floor f + 1.
struct Flight {
  double x0 = 0.0, x1 = 0.0;        // lane
  double y_bottom = 0.0, y_top = 0.0;  // the flight climbs from y_bottom (north) to y_top (south)
};

// A portal with everything a walker needs: the opening polygon (in the wall's or slab's
// mid-plane), the opening's box through the wall, and eye positions: `approach_a` in front of
// the portal inside cell a, `route` across it, `approach_b` inside cell b. A walker going from
// a to b passes approach_a, route..., approach_b (reverse for b to a); furniture keeps
// kWalkwayClearance away from these segments and from the segments joining each approach to
// its room's hub.
struct Portal {
  int floor_a = 0, floor_b = 0;  // equal except for stair portals (floor_b = floor_a + 1)
  int cell_a = -1, cell_b = -1;  // local cells
  const char* kind = "door";     // "door", "arch", "stair_door", "stair"
  std::array<Vec3, 4> polygon{};
  Aabb opening;
  Vec3 approach_a{0.0}, approach_b{0.0};
  std::vector<Vec3> route;
};

class BuildingLayout {
 public:
  explicit BuildingLayout(const BuildingShape& shape);

  const BuildingShape& shape() const { return shape_; }
  int floors() const { return shape_.floors; }
  int rooms() const { return shape_.rooms; }
  bool has_stairs() const { return shape_.floors > 1; }
  int grid_cols() const { return columns_ + 1; }
  int grid_rows() const { return first_band_row_ + 3 * bands_; }
  int cells_per_floor() const { return shape_.rooms + bands_ + 1 + (has_stairs() ? 1 : 0); }
  int64_t cell_id(int floor, int local) const { return int64_t{floor} * cells_per_floor() + local; }

  // Grid lines: x of column boundary i (0..grid_cols()), y of row boundary j (0..grid_rows()).
  double grid_x(int i) const;
  double grid_y(int j) const;
  static double floor_z(int f) { return f * kStorey; }

  Slot slot(int col, int row) const;  // out-of-grid slots are empty
  int corridor_length(int band) const;  // room columns the band's corridor spans
  CellKind cell_kind(int local) const;
  // Interior box of a local cell on floor f.
  Aabb cell_bounds(int floor, int local) const;
  Aabb bounds() const;  // everything, walls and roof included

  // Openings on the vertical grid edge x = grid_x(i), row j, between slots (i-1, j), (i, j).
  std::vector<Opening> vertical_openings(int floor, int i, int j) const;
  // Openings on the horizontal grid edge y = grid_y(j), column i, between (i, j-1), (i, j).
  std::vector<Opening> horizontal_openings(int floor, int i, int j) const;

  // Every portal of floor f: wall openings (each grid edge once, in a fixed order), then the
  // stair portal up to floor f + 1 if there is one.
  void for_each_portal(int floor, const std::function<void(const Portal&)>& visit) const;
  // Portals in the walls around slot (col, row) of floor f (not stair portals).
  std::vector<Portal> slot_wall_portals(int floor, int col, int row) const;
  // The stair portal from floor f up to f + 1. REQUIRES has_flight(f).
  Portal stair_portal(int floor) const;
  // The segment a walker follows inside a cell, at floor level (a room's is its centre twice).
  std::array<Vec2, 2> walk_line(int local) const;

  // Stairwell geometry (valid when has_stairs()).
  bool has_flight(int floor) const { return has_stairs() && floor + 1 < shape_.floors; }
  Flight flight(int floor) const;
  double stair_lane_center(int lane) const;  // lanes 0, 1 (walkway), 2
  // Door approach point and centreline of the stairwell walkway lane (x = lane 1 centre).
  double stair_walk_y_south() const;
  double stair_walk_y_north() const;

 private:
  int room_at(int band, int column, int side) const;  // -1 when no such room
  Portal vertical_portal(int floor, int i, const Opening& o) const;
  Portal horizontal_portal(int floor, int j, const Opening& o) const;

  BuildingShape shape_;
  int bands_ = 1, columns_ = 1, first_band_row_ = 0;
};

}  // namespace frontier::gen
