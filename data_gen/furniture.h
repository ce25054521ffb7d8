// Furniture and fittings of the generated building: the detail that holds most of its
// triangles. Floor items (table groups, desks, bookshelves, cabinets, plants) are placed by
// seeded rejection sampling: inside the room, apart from each other, and at least
// kWalkwayClearance from every walkway segment, so walk paths never meet them. Ceiling
// fittings (pendant lamps, pipes) hang above kEyeHeight + 0.25 m; handrails stay below 1.1 m.
//
// Every item is built from MeshBuilder solids (closed, outward). All sizes >= 8 mm.
// The functions draw the same random numbers whether the builder counts or emits.
#pragma once

#include "data_gen/building_layout.h"
#include "data_gen/mesh_builder.h"
#include "data_gen/rng.h"

#include <vector>

namespace frontier::gen {

struct DetailParams {
  double density = 1.0;  // furniture items and fittings per unit area, relative
  int segments = 16;     // tessellation of round things (>= 3)
};

// Vertex colours: structure (walls, slabs, steps) is told apart from detail by colour.
namespace palette {
inline constexpr Rgb kWall{214, 205, 188};
inline constexpr Rgb kSlab{150, 150, 152};
inline constexpr Rgb kStep{176, 166, 150};
inline constexpr Rgb kWood{140, 95, 55};
inline constexpr Rgb kFabric{70, 95, 150};
inline constexpr Rgb kMetal{185, 185, 195};
inline constexpr Rgb kRail{70, 70, 80};
inline constexpr Rgb kLamp{250, 235, 190};
inline constexpr Rgb kPlant{50, 130, 60};
inline constexpr Rgb kPot{170, 90, 60};
inline constexpr Rgb kScreen{25, 25, 30};
inline constexpr Rgb kBooks[6] = {{160, 40, 40}, {40, 110, 60}, {40, 60, 140},
                                  {200, 160, 60}, {90, 50, 110}, {30, 30, 30}};
}  // namespace palette

struct Segment2 {
  Vec2 a, b;
};

// Floor furniture and ceiling fittings of one room (interior box).
void furnish_room(MeshBuilder& mb, Rng& rng, const Aabb& interior,
                  const std::vector<Segment2>& walkways, const DetailParams& p);

// A pendant lamp hanging from the ceiling point.
void pendant_lamp(MeshBuilder& mb, const Vec3& ceiling_point, const DetailParams& p);

// A straight pipe from a to b split into joints of at most `spacing`, with flanges and
// ceiling hangers at the joints (and at a, when flange_at_start).
void pipe_run(MeshBuilder& mb, const Vec3& a, const Vec3& b, double radius, double ceiling_z,
              bool flange_at_start, const DetailParams& p);

// A wall-mounted handrail from a to b (rail axis), with brackets reaching `to_wall`
// (unit vector from the rail towards the wall face, which is kRailOffset away).
inline constexpr double kRailOffset = 0.07;
void handrail(MeshBuilder& mb, const Vec3& a, const Vec3& b, const Vec3& to_wall,
              const DetailParams& p);

// A free-standing guard rail along a to b on the floor: posts and top and middle rails.
void guard_rail(MeshBuilder& mb, const Vec3& a, const Vec3& b, double height, const DetailParams& p);

// Distance in the plane between a segment and an axis-aligned rectangle (0 if they meet).
double segment_rect_distance(const Segment2& s, const Vec2& lo, const Vec2& hi);

}  // namespace frontier::gen
