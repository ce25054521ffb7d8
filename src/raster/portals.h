// Cells and portals (Teller's cells-and-portals, as Hoff's culling survey describes it): the
// rooms of a closed building and the openings between them, and the traversal that finds the
// rooms a view can see through chains of openings.
//
// The model the graph describes: every point a ray from inside the building can reach lies in
// a room's interior box or in a portal's opening box; rooms are separated by walls (slabs
// vertically) centred on the boundaries of their interiors expanded by half the wall (slab)
// thickness; every hole through a wall or slab is one portal, whose polygon is the hole's
// cross-section in the wall's (slab's) mid-plane and whose two rooms lie on opposite sides of
// that plane. frontier-gen's `building` sidecar (data_gen/README.md, "The sidecar") states
// exactly this, to the 0.1 mm its numbers are rounded to (the traversal's one-pixel padding
// absorbs that).
//
// Invariants of a PortalGraph (create, from_sidecar and deserialize refuse anything else): room
// ids are dense (0..rooms-1), portal ids are dense, a portal's two rooms are distinct, in range
// and have their centres on opposite sides of its polygon's plane; every box is non-empty and
// finite; polygons are quadrilaterals of non-zero area; thicknesses are finite and not
// negative. A graph is immutable once made; every const member may be called from any number
// of threads at once.
#pragma once

#include "src/core/geometry.h"
#include "src/core/status.h"
#include "src/core/view.h"

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace frontier {

// The store section that holds a serialized PortalGraph (store/FORMAT.md, "portals").
inline constexpr std::string_view kPortalsSection = "portals";

// One room reached by the traversal, with the pixels through which it may be seen.
struct PortalVisit {
  static constexpr uint32_t kNoPortal = UINT32_MAX;
  uint32_t room = 0;
  uint32_t via_portal = kNoPortal;  // kNoPortal for the eye's own room(s)
  int depth = 0;                    // portals crossed from the eye's room
  // Pixel rectangle [x0, x1) x [y0, y1) in the View's pixel grid (x right, y down, row 0 at the
  // top): every pixel whose ray can reach the room through this visit's chain of portals.
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

struct PortalVisibility {
  bool located = false;  // the eye is in some room; otherwise nothing below is filled in
  std::vector<PortalVisit> visits;
  // Boxes whose geometry must be drawn: each visited room's region (PortalGraph::room_region)
  // once, then the opening box of each portal passed once.
  std::vector<Aabb> regions;
  uint64_t portals_tested = 0;  // portals of visited rooms examined
  uint64_t portals_passed = 0;  // of those, the ones seen through a non-empty rectangle
};

class PortalGraph {
 public:
  struct Portal {
    std::array<uint32_t, 2> rooms{0, 0};
    std::array<Vec3, 4> polygon{};  // the opening's cross-section in the wall's mid-plane
    Aabb opening;                   // the hole through the wall or slab
  };

  PortalGraph() = default;  // no rooms: rooms_at finds nothing, traverse locates nothing

  // A graph from its parts; Corruption naming what is wrong when the invariants above fail.
  static Result<PortalGraph> create(std::vector<Aabb> rooms, std::vector<Portal> portals, double wall_thickness,
                                    double slab_thickness);

  // Reads the "rooms", "portals", "wall_thickness" and "slab_thickness" of a frontier-gen
  // building sidecar in one streaming pass: room and portal objects are converted as they are
  // parsed and dropped, so memory is the graph's, not the JSON document's. NotFound when the
  // file does not exist or has no rooms and portals (a sidecar of another model); Corruption
  // naming the file and the element ("B.json: portal 12: room 99 out of range (18 rooms)") for
  // malformed content, Unsupported for another format or a newer version; IoError when the
  // file cannot be read.
  static Result<PortalGraph> from_sidecar(const std::string& path);

  // The binary section layout of store/FORMAT.md ("portals"): magic, version, payload size and
  // checksum (store/section_frame.h), then the rooms and portals as little-endian doubles. Only the parts are stored;
  // the lookup structures are rebuilt on load.
  std::vector<uint8_t> serialize() const;
  // Safe on untrusted bytes: truncated, damaged or inconsistent input gives Corruption (a newer
  // version Unsupported) whose message starts with `what`; never reads out of bounds.
  static Result<PortalGraph> deserialize(std::span<const uint8_t> bytes, const std::string& what);

  size_t room_count() const { return rooms_.size(); }
  size_t portal_count() const { return portals_.size(); }
  const std::vector<Aabb>& rooms() const { return rooms_; }  // interior boxes, indexed by room id
  const std::vector<Portal>& portals() const { return portals_; }
  double wall_thickness() const { return wall_; }
  double slab_thickness() const { return slab_; }
  // The room's interior expanded by half the wall thickness horizontally and half the slab
  // thickness vertically: the inner halves of its walls, floor and ceiling included.
  // REQUIRES room < room_count().
  Aabb room_region(uint32_t room) const;
  // Ids of the portals in the room's walls, floor and ceiling. REQUIRES room < room_count().
  std::span<const uint32_t> room_portals(uint32_t room) const;

  // Rooms whose region contains p, plus both rooms of every portal whose opening box (a little
  // enlarged) contains p, so that standing in a doorway gives both rooms. Sorted, no repeats;
  // empty outside the building. Expected O(1) per call (a uniform grid over the boxes).
  std::vector<uint32_t> rooms_at(const Vec3& p) const;

  // Hoff's recursion: the eye's rooms are visited with the whole screen; from each visit, every
  // portal that the eye sees from the room's side is projected with the view's exact camera and
  // its pixel rectangle (rounded outwards, padded by one pixel) narrows the visit's rectangle
  // for the room behind it. A portal with a corner at or behind the eye plane (or nearer than
  // the view's near plane) does not narrow; a portal the eye stands in passes unnarrowed. A
  // visit whose rectangle is empty, or lies inside an earlier rectangle of the same room, is not
  // made; after a few visits to one room, new rectangles are widened to cover that room's
  // earlier ones, so the work is finite on any graph.
  //
  // Conservative: when located, every surface point seen by a pixel ray of `view` (for a
  // closed building as described at the top, an eye in free space and a near plane nearer than
  // the closest wall) lies in some region, and its pixel lies in the rectangle of a visit to the
  // room it lies in. Not located (no visits, no regions) when the eye is in no room: the caller
  // falls back to frustum culling.
  PortalVisibility traverse(const View& view) const;

 private:
  // The uniform grid that rooms_at searches: room regions and (enlarged) openings.
  struct Locator {
    Vec3 origin{0.0};
    Vec3 cell{1.0};
    std::array<int, 3> dims{0, 0, 0};
    std::vector<uint32_t> first;  // CSR: entries of grid cell c are items[first[c] .. first[c+1])
    std::vector<uint32_t> items;  // room id, or room_count() + portal id
  };

  // Checks the invariants, then derives the planes, the adjacency and the locator.
  Status finish();
  Status check_rooms(double& magnitude);  // thicknesses, counts, room boxes; sets slack_
  Status orient_portals(double magnitude);  // checks the portals, sets normals_
  void build_adjacency();
  void build_locator();
  Aabb doorway(uint32_t portal) const;  // the opening box, a little enlarged
  // True when a ray from `eye` can cross the portal's plane leaving `room`.
  bool faces(uint32_t portal, uint32_t room, const Vec3& eye) const;

  std::vector<Aabb> rooms_;
  std::vector<Portal> portals_;
  double wall_ = 0.0;
  double slab_ = 0.0;

  // Derived by finish().
  std::vector<uint32_t> adjacency_first_;  // CSR over rooms: portals of room r at
  std::vector<uint32_t> adjacency_;        // adjacency_[adjacency_first_[r] .. adjacency_first_[r+1])
  std::vector<Vec3> normals_;              // per portal: unit plane normal pointing from rooms[0] to rooms[1]
  double slack_ = 0.0;                     // distance tolerance at the model's scale
  Locator locator_;
};

}  // namespace frontier
