// Cells and portals (src/raster/portals.h), checked on buildings that frontier-gen makes:
// the sidecar reader against an independent full JSON parse, the section codec (round trip,
// every truncation and every byte flip reported), rooms_at against a linear scan, traversal
// properties (a wall without a door hides the room behind it; a room two doors away is seen
// through both; a door outside the narrowed rectangle is not passed) and conservativeness
// against brute-force primary rays: every surface point a pixel sees lies in a region, inside a
// visit of its room whose rectangle holds the pixel. Finally the store's "portals" section as
// frontier-build writes it and frontier-store reports it.
#include "src/io/load_scene.h"
#include "src/raster/portals.h"
#include "src/engine/ray_walk.h"
#include "src/core/scene.h"
#include "src/paging/store_model.h"
#include "src/core/view.h"
#include "store/page_file.h"
#include "store/store_file.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <vector>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_portals"); }

// A bare building of 2 floors x 6 rooms with its sidecar (made once per run). Floor 0: rooms
// 0, 2, 4 south of the corridor (6), rooms 1, 3, 5 north of it, the spine (7) to the west, the
// stairwell (8) south of the spine; floor 1 repeats it as 9..17.
const fs::path& small_building() {
  static const fs::path path = [] {
    const fs::path p = scratch() / "building.ply";
    const auto r = run_binary(proc::gen_binary(),
                              {"building", "--floors", "2", "--rooms", "6", "--furniture", "0", "--seed", "1", "-o",
                               p.string(), "--quiet"},
                              scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return p;
  }();
  return path;
}
fs::path sidecar_of(const fs::path& model) { return fs::path(model).replace_extension(".json"); }

const PortalGraph& small_graph() {
  static const PortalGraph graph = [] {
    auto g = PortalGraph::from_sidecar(sidecar_of(small_building()).string());
    EXPECT_TRUE(g.is_ok()) << g.status().to_string();
    return g.is_ok() ? std::move(g).value() : PortalGraph();
  }();
  return graph;
}

const Scene& small_scene() {
  static const Scene scene = [] {
    Scene s;
    const Status st = load_scene(small_building().string(), s);
    EXPECT_TRUE(st.is_ok()) << st.to_string();
    return s;
  }();
  return scene;
}

json read_json(const fs::path& path) {
  std::ifstream in(path);
  return json::parse(in);
}

void write_text(const fs::path& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

bool same_box(const Aabb& a, const Aabb& b) { return a.lo == b.lo && a.hi == b.hi; }

void expect_same_graph(const PortalGraph& a, const PortalGraph& b) {
  ASSERT_EQ(a.room_count(), b.room_count());
  ASSERT_EQ(a.portal_count(), b.portal_count());
  EXPECT_EQ(a.wall_thickness(), b.wall_thickness());
  EXPECT_EQ(a.slab_thickness(), b.slab_thickness());
  for (size_t r = 0; r < a.room_count(); ++r) EXPECT_TRUE(same_box(a.rooms()[r], b.rooms()[r])) << "room " << r;
  for (size_t p = 0; p < a.portal_count(); ++p) {
    const auto &x = a.portals()[p], &y = b.portals()[p];
    EXPECT_EQ(x.rooms, y.rooms) << "portal " << p;
    EXPECT_EQ(x.polygon, y.polygon) << "portal " << p;
    EXPECT_TRUE(same_box(x.opening, y.opening)) << "portal " << p;
  }
}

Vec3 json_vec(const json& j) { return {j[0].get<double>(), j[1].get<double>(), j[2].get<double>()}; }

View make_view(const Vec3& eye, const Vec3& look_at, double vfov_deg, int width, int height) {
  Camera c;
  c.eye = eye;
  c.look_at = look_at;
  c.up = Vec3(0, 0, 1);
  c.vfov_deg = vfov_deg;
  return View(c, width, height);
}

bool visited(const PortalVisibility& v, uint32_t room) {
  return std::any_of(v.visits.begin(), v.visits.end(), [&](const PortalVisit& x) { return x.room == room; });
}

// The portal joining rooms a and b (there is one in the small building).
uint32_t portal_between(const PortalGraph& g, uint32_t a, uint32_t b) {
  for (uint32_t p = 0; p < g.portal_count(); ++p) {
    const auto& r = g.portals()[p].rooms;
    if ((r[0] == a && r[1] == b) || (r[0] == b && r[1] == a)) return p;
  }
  ADD_FAILURE() << "no portal between rooms " << a << " and " << b;
  return 0;
}

// --- the sidecar ----------------------------------------------------------------------------

TEST(PortalGraph, SidecarMatchesAnIndependentParse) {
  const PortalGraph& g = small_graph();
  const json j = read_json(sidecar_of(small_building()));
  ASSERT_EQ(g.room_count(), j["rooms"].size());
  ASSERT_EQ(g.portal_count(), j["portals"].size());
  EXPECT_EQ(g.room_count(), 18u);
  EXPECT_EQ(g.wall_thickness(), j["wall_thickness"].get<double>());
  EXPECT_EQ(g.slab_thickness(), j["slab_thickness"].get<double>());
  for (size_t r = 0; r < g.room_count(); ++r) {
    const json& room = j["rooms"][r];
    EXPECT_TRUE(same_box(g.rooms()[r], Aabb(json_vec(room["bounds"][0]), json_vec(room["bounds"][1])))) << r;
  }
  std::vector<std::set<uint32_t>> around(g.room_count());
  for (size_t p = 0; p < g.portal_count(); ++p) {
    const json& portal = j["portals"][p];
    const auto& q = g.portals()[p];
    EXPECT_EQ(q.rooms[0], portal["rooms"][0].get<uint32_t>());
    EXPECT_EQ(q.rooms[1], portal["rooms"][1].get<uint32_t>());
    for (int k = 0; k < 4; ++k) EXPECT_EQ(q.polygon[k], json_vec(portal["polygon"][k]));
    EXPECT_TRUE(same_box(q.opening, Aabb(json_vec(portal["opening"][0]), json_vec(portal["opening"][1]))));
    around[q.rooms[0]].insert(static_cast<uint32_t>(p));
    around[q.rooms[1]].insert(static_cast<uint32_t>(p));
  }
  for (uint32_t r = 0; r < g.room_count(); ++r) {
    const auto list = g.room_portals(r);
    EXPECT_EQ(std::set<uint32_t>(list.begin(), list.end()), around[r]) << "portals of room " << r;
    const Aabb region = g.room_region(r);
    EXPECT_NEAR(region.hi.x - g.rooms()[r].hi.x, 0.5 * g.wall_thickness(), 1e-12);
    EXPECT_NEAR(g.rooms()[r].lo.z - region.lo.z, 0.5 * g.slab_thickness(), 1e-12);
  }
}

TEST(PortalGraph, MalformedSidecarsAreErrorsNamingTheFile) {
  const json good = read_json(sidecar_of(small_building()));
  struct Case {
    const char* name;
    std::string text;
    const char* says;  // part of the message
  };
  auto edited = [&](auto&& edit) {
    json j = good;
    edit(j);
    return j.dump();
  };
  const std::string text = good.dump();
  const std::vector<Case> cases = {
      {"not_json", "this is not json", "not valid JSON"},
      {"truncated", text.substr(0, text.size() / 2), "not valid JSON"},
      {"array", "[1, 2, 3]", "not a JSON object"},
      {"sparse_ids", edited([](json& j) { j["rooms"][3]["id"] = 4; }), "rooms[3]"},
      {"room_range", edited([](json& j) { j["portals"][2]["rooms"][1] = 99; }), "out of range"},
      {"negative_room", edited([](json& j) { j["portals"][2]["rooms"][1] = -1; }), "portals[2]"},
      {"three_corners", edited([](json& j) { j["portals"][1]["polygon"].erase(3); }), "portals[1]"},
      {"empty_room", edited([](json& j) { j["rooms"][5]["bounds"][0][0] = 100.0; }), "room 5"},
      {"string_bounds", edited([](json& j) { j["rooms"][0]["bounds"] = "box"; }), "rooms[0]"},
      {"same_side", edited([](json& j) { j["portals"][0]["rooms"] = {j["portals"][0]["rooms"][0], 17}; }),
       "opposite sides"},
      {"no_wall", edited([](json& j) { j.erase("wall_thickness"); }), "wall_thickness"},
      {"rooms_object", edited([](json& j) { j["rooms"] = json::object(); }), "rooms"},
      {"room_number", edited([](json& j) { j["rooms"][2] = 5; }), "rooms[2]: not an object"},
      {"other_format", edited([](json& j) { j["format"] = "something-else"; }), "format"},
  };
  for (const Case& c : cases) {
    const fs::path path = scratch() / (std::string("bad_") + c.name + ".json");
    write_text(path, c.text);
    const auto g = PortalGraph::from_sidecar(path.string());
    ASSERT_FALSE(g.is_ok()) << c.name;
    EXPECT_NE(g.status().code(), Status::Code::NotFound) << c.name;
    EXPECT_NE(g.status().message().find(path.string()), std::string::npos) << c.name << ": " << g.status().to_string();
    EXPECT_NE(g.status().message().find(c.says), std::string::npos) << c.name << ": " << g.status().to_string();
  }
  // No rooms and portals, or no file at all: nothing to read, which is not an error of the file.
  const fs::path other = scratch() / "terrain.json";
  write_text(other, R"({"format": "frontier-terrain", "walkable": false})");
  EXPECT_EQ(PortalGraph::from_sidecar(other.string()).status().code(), Status::Code::NotFound);
  EXPECT_EQ(PortalGraph::from_sidecar((scratch() / "missing.json").string()).status().code(),
            Status::Code::NotFound);
}

// --- the section ----------------------------------------------------------------------------

TEST(PortalGraph, SectionRoundTripIsExact) {
  const PortalGraph& g = small_graph();
  const std::vector<uint8_t> bytes = g.serialize();
  auto back = PortalGraph::deserialize(bytes, "test");
  ASSERT_TRUE(back.is_ok()) << back.status().to_string();
  expect_same_graph(g, *back);
  EXPECT_EQ(back->serialize(), bytes);
  // An empty graph round-trips too.
  auto empty = PortalGraph::deserialize(PortalGraph().serialize(), "empty");
  ASSERT_TRUE(empty.is_ok()) << empty.status().to_string();
  EXPECT_EQ(empty->room_count(), 0u);
  EXPECT_TRUE(empty->rooms_at(Vec3(0.0)).empty());
}

TEST(PortalGraph, EveryTruncationAndByteFlipIsReported) {
  const std::vector<uint8_t> bytes = small_graph().serialize();
  for (size_t n = 0; n < bytes.size(); ++n) {
    const auto g = PortalGraph::deserialize(std::span<const uint8_t>(bytes.data(), n), "cut");
    ASSERT_FALSE(g.is_ok()) << "truncated to " << n;
    EXPECT_EQ(g.status().code(), Status::Code::Corruption) << n;
    EXPECT_EQ(g.status().message().rfind("cut: ", 0), 0u) << g.status().message();
  }
  for (size_t i = 0; i < bytes.size(); ++i) {
    for (uint8_t flip : {uint8_t{0x01}, uint8_t{0x80}}) {
      std::vector<uint8_t> bad = bytes;
      bad[i] ^= flip;
      const auto g = PortalGraph::deserialize(bad, "flip");
      ASSERT_FALSE(g.is_ok()) << "byte " << i;
      // The version field may turn into a newer version: Unsupported rather than Corruption.
      if (i >= 4 && i < 8 && g.status().code() == Status::Code::Unsupported) continue;
      EXPECT_EQ(g.status().code(), Status::Code::Corruption) << "byte " << i << ": " << g.status().to_string();
    }
  }
  // Damage that keeps the checksum right is caught by the graph's own checks.
  std::vector<uint8_t> bad = bytes;
  const size_t first_portal = 24 + 32 + 48 * small_graph().room_count();
  bad[first_portal] = 0xFF;  // room a of portal 0 out of range
  const std::span<const uint8_t> payload(bad.data() + 24, bad.size() - 24);
  const uint64_t sum = store::checksum(payload);
  for (int k = 0; k < 8; ++k) bad[16 + k] = static_cast<uint8_t>(sum >> (8 * k));
  const auto g = PortalGraph::deserialize(bad, "resummed");
  ASSERT_FALSE(g.is_ok());
  EXPECT_NE(g.status().message().find("out of range"), std::string::npos) << g.status().to_string();
}

// --- rooms_at -------------------------------------------------------------------------------

TEST(PortalGraph, RoomsAtDoorwaysAndOutside) {
  const PortalGraph& g = small_graph();
  // The door between room 0 and the corridor: standing in it (anywhere across the wall) gives both.
  const uint32_t door = portal_between(g, 0, 6);
  const Aabb& opening = g.portals()[door].opening;
  for (double t : {0.0, 0.25, 0.5, 0.75, 1.0}) {
    Vec3 p = opening.center();
    p.y = opening.lo.y + t * (opening.hi.y - opening.lo.y);
    EXPECT_EQ(g.rooms_at(p), (std::vector<uint32_t>{0, 6})) << "t " << t;
  }
  EXPECT_EQ(g.rooms_at(g.rooms()[0].center()), std::vector<uint32_t>{0});
  EXPECT_EQ(g.rooms_at(g.rooms()[15].center()), std::vector<uint32_t>{15});
  // The stair hole joins the stairwells of floors 0 and 1.
  const uint32_t stair = portal_between(g, 8, 17);
  EXPECT_EQ(g.rooms_at(g.portals()[stair].opening.center()), (std::vector<uint32_t>{8, 17}));
  // Outside: beside, below and above the building.
  Aabb all;
  for (uint32_t r = 0; r < g.room_count(); ++r) all.extend(g.room_region(r));
  EXPECT_TRUE(g.rooms_at(all.lo - Vec3(1.0)).empty());
  EXPECT_TRUE(g.rooms_at(Vec3(all.center().x, all.center().y, all.hi.z + 0.5)).empty());
  EXPECT_TRUE(g.rooms_at(Vec3(all.center().x, all.center().y, all.lo.z - 0.01)).empty());
  EXPECT_TRUE(g.rooms_at(Vec3(all.hi.x + 0.01, all.center().y, 1.0)).empty());
}

TEST(PortalGraph, RoomsAtEqualsALinearScanOnALargeGrid) {
  // 60 x 50 x 4 rooms of 4 x 3 x 2.5 m, doors in x between neighbours: 12 000 rooms.
  const int nx = 60, ny = 50, nz = 4;
  const double wall = 0.2, slab = 0.3;
  auto id = [&](int x, int y, int z) { return static_cast<uint32_t>((z * ny + y) * nx + x); };
  std::vector<Aabb> rooms;
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x < nx; ++x) {
        rooms.emplace_back(Vec3(4.0 * x + wall / 2, 3.0 * y + wall / 2, 2.8 * z + slab / 2),
                           Vec3(4.0 * (x + 1) - wall / 2, 3.0 * (y + 1) - wall / 2, 2.8 * (z + 1) - slab / 2));
      }
  std::vector<PortalGraph::Portal> portals;
  for (int z = 0; z < nz; ++z)
    for (int y = 0; y < ny; ++y)
      for (int x = 0; x + 1 < nx; ++x) {
        PortalGraph::Portal p;
        p.rooms = {id(x, y, z), id(x + 1, y, z)};
        const double xm = 4.0 * (x + 1), yc = 3.0 * y + 1.5, z0 = 2.8 * z + slab / 2;
        p.polygon = {Vec3(xm, yc - 0.5, z0), Vec3(xm, yc + 0.5, z0), Vec3(xm, yc + 0.5, z0 + 2.0),
                     Vec3(xm, yc - 0.5, z0 + 2.0)};
        p.opening = Aabb(Vec3(xm - wall / 2, yc - 0.5, z0), Vec3(xm + wall / 2, yc + 0.5, z0 + 2.0));
        portals.push_back(p);
      }
  auto graph = PortalGraph::create(rooms, portals, wall, slab);
  ASSERT_TRUE(graph.is_ok()) << graph.status().to_string();
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> ux(-2.0, 4.0 * nx + 2.0), uy(-2.0, 3.0 * ny + 2.0), uz(-1.0, 2.8 * nz + 1.0);
  for (int i = 0; i < 4000; ++i) {
    Vec3 p(ux(rng), uy(rng), uz(rng));
    if (i % 4 == 0) p.x = 4.0 * std::round(p.x / 4.0) + (i % 8 == 0 ? 0.0 : 0.05);  // on and next to walls
    std::vector<uint32_t> expected;
    for (uint32_t r = 0; r < graph->room_count(); ++r) {
      if (graph->room_region(r).contains(p)) expected.push_back(r);
    }
    for (const auto& q : graph->portals()) {
      if (q.opening.contains(p)) expected.insert(expected.end(), q.rooms.begin(), q.rooms.end());
    }
    std::sort(expected.begin(), expected.end());
    expected.erase(std::unique(expected.begin(), expected.end()), expected.end());
    ASSERT_EQ(graph->rooms_at(p), expected) << "point " << p.x << " " << p.y << " " << p.z;
  }
}

// --- the traversal --------------------------------------------------------------------------

TEST(PortalTraverse, AWallWithoutADoorHidesTheRoomBehindIt) {
  const PortalGraph& g = small_graph();
  struct Case {
    Vec3 eye, look_at;
    uint32_t eye_room, hidden;
    bool alone;  // nothing but the eye's room is visited
  };
  const Case cases[] = {
      // In room 0 looking east at the wall it shares with room 2, and west at the spine's wall;
      // room 0's only door is behind the eye.
      {{9.5, 10.0, 1.7}, {10.4, 10.0, 1.7}, 0, 2, true},
      {{5.5, 10.0, 1.7}, {4.6, 10.0, 1.7}, 0, 7, true},
      // In the corridor looking south at room 4's wall: rooms 2 and 4 have doors in that wall,
      // facing the eye but outside the view.
      {{15.5, 15.0, 1.7}, {15.5, 13.7, 1.7}, 6, 2, false},
      {{15.5, 15.0, 1.7}, {15.5, 13.7, 1.7}, 6, 4, false},
  };
  for (const Case& c : cases) {
    const View view = make_view(c.eye, c.look_at, 60.0, 64, 48);
    const PortalVisibility v = g.traverse(view);
    ASSERT_TRUE(v.located);
    EXPECT_TRUE(visited(v, c.eye_room));
    EXPECT_FALSE(visited(v, c.hidden)) << "room " << c.hidden << " is behind a wall";
    if (c.alone) {
      EXPECT_EQ(v.visits.size(), 1u);
      EXPECT_EQ(v.regions.size(), 1u);
    }
  }
}

TEST(PortalTraverse, ARoomTwoDoorsAwayIsSeenThroughBoth) {
  const PortalGraph& g = small_graph();
  // Room 0's door (x 7.43..8.43) and room 1's door across the corridor (x 6.58..7.58) overlap
  // around x = 7.5: looking north along that line sees room 1 through both.
  const uint32_t door0 = portal_between(g, 0, 6), door1 = portal_between(g, 6, 1), door3 = portal_between(g, 6, 3);
  const Vec3 eye(7.5, 10.0, 1.5);
  const View view = make_view(eye, Vec3(7.5, 20.0, 1.5), 90.0, 96, 72);
  const PortalVisibility v = g.traverse(view);
  ASSERT_TRUE(v.located);
  const auto room1 = std::find_if(v.visits.begin(), v.visits.end(), [](const PortalVisit& x) { return x.room == 1; });
  ASSERT_NE(room1, v.visits.end()) << "room 1 is seen through two doors";
  EXPECT_EQ(room1->via_portal, door1);
  EXPECT_EQ(room1->depth, 2);
  // Its rectangle is narrowed to about the overlap of the two doors.
  EXPECT_LT(room1->x1 - room1->x0, view.width / 4);
  EXPECT_LT(room1->y1 - room1->y0, view.height);
  EXPECT_GT(v.portals_tested, v.portals_passed);
  for (const PortalVisit& x : v.visits) {
    if (x.room == 6) {
      EXPECT_EQ(x.via_portal, door0);
    }
  }
  // Room 3's door faces the eye inside the view frustum, but outside the rectangle of room 0's
  // door: room 3 is not visited.
  int x0, y0, x1, y1;
  ASSERT_TRUE(view.project(g.portals()[door3].opening, x0, y0, x1, y1));
  EXPECT_TRUE(x0 < x1 && y0 < y1 && x1 > 0 && x0 < view.width) << "room 3's door is in the frustum";
  EXPECT_FALSE(visited(v, 3));
  // Room 2's door is seen from its back (the eye is south of that wall): never passed.
  EXPECT_FALSE(visited(v, 2));
}

TEST(PortalTraverse, EyeOutsideEveryRoomIsNotLocated) {
  const PortalGraph& g = small_graph();
  const View view = make_view(Vec3(-20.0, -20.0, 5.0), Vec3(10.0, 10.0, 2.0), 60.0, 32, 24);
  const PortalVisibility v = g.traverse(view);
  EXPECT_FALSE(v.located);
  EXPECT_TRUE(v.visits.empty());
  EXPECT_TRUE(v.regions.empty());
}

// Casts every pixel's primary ray by brute force and checks that its hit lies in a region and
// in a visit of a room containing it whose rectangle holds the pixel.
void expect_conservative(const PortalGraph& g, const Scene& scene, const View& view, const std::string& label) {
  const PortalVisibility v = g.traverse(view);
  ASSERT_TRUE(v.located) << label;
  const double margin = 1e-6;
  auto inside = [&](const Aabb& box, const Vec3& p) {
    return p.x >= box.lo.x - margin && p.x <= box.hi.x + margin && p.y >= box.lo.y - margin &&
           p.y <= box.hi.y + margin && p.z >= box.lo.z - margin && p.z <= box.hi.z + margin;
  };
  std::atomic<int> hits{0}, outside_regions{0}, outside_visits{0}, bounds_outside{0};
  std::string first_problem;
  std::mutex mutex;
  tbb::parallel_for(0, view.height, [&](int y) {
    Counters counters;
    for (int x = 0; x < view.width; ++x) {
      const Ray ray = view.ray(x, y);
      const RayHit hit = brute_force_hit(scene, ray, view.tmin(ray), counters);
      if (!hit.hit()) continue;
      ++hits;
      const Vec3 p = ray.at(hit.t);
      Aabb prim = scene.prim_bounds(hit.prim);
      prim.lo -= Vec3(margin);
      prim.hi += Vec3(margin);
      const bool in_region = std::any_of(v.regions.begin(), v.regions.end(), [&](const Aabb& r) { return inside(r, p); });
      const bool prim_in_region =
          std::any_of(v.regions.begin(), v.regions.end(), [&](const Aabb& r) { return r.overlaps(prim); });
      const bool in_visit = std::any_of(v.visits.begin(), v.visits.end(), [&](const PortalVisit& w) {
        return x >= w.x0 && x < w.x1 && y >= w.y0 && y < w.y1 && inside(g.room_region(w.room), p);
      });
      if (!in_region) ++outside_regions;
      if (!prim_in_region) ++bounds_outside;
      if (!in_visit) ++outside_visits;
      if (!(in_region && prim_in_region && in_visit)) {
        std::lock_guard<std::mutex> lock(mutex);
        if (first_problem.empty()) {
          first_problem = "pixel (" + std::to_string(x) + "," + std::to_string(y) + ") hits (" + std::to_string(p.x) +
                          ", " + std::to_string(p.y) + ", " + std::to_string(p.z) + ")";
        }
      }
    }
  });
  EXPECT_GT(hits.load(), view.width * view.height / 2) << label << ": the building is closed";
  EXPECT_EQ(outside_regions.load(), 0) << label << ": " << first_problem;
  EXPECT_EQ(bounds_outside.load(), 0) << label << ": " << first_problem;
  EXPECT_EQ(outside_visits.load(), 0) << label << ": " << first_problem;
}

TEST(PortalTraverse, ConservativeAgainstBruteForceRays) {
  const PortalGraph& g = small_graph();
  const Scene& scene = small_scene();
  ASSERT_GT(scene.size(), 0u);
  struct Eye {
    Vec3 eye, look_at;
    const char* label;
  };
  std::vector<Eye> eyes = {
      {{7.5, 10.0, 1.5}, {7.5, 20.0, 1.5}, "through two doors"},
      {{7.93, 13.8, 1.7}, {7.93, 20.0, 1.2}, "in a doorway, looking out"},
      {{7.93, 13.8, 1.7}, {20.0, 13.0, 1.2}, "in a doorway, looking along the wall"},
      {{20.0, 15.0, 1.7}, {0.0, 15.0, 1.2}, "corridor towards the spine"},
      {{2.2, 20.0, 1.7}, {2.2, 0.0, 1.0}, "spine towards the stair door"},
      {{2.5, 7.5, 1.7}, {0.8, 3.0, 4.5}, "stairwell, up through the hole"},
      {{2.5, 4.0, 5.0}, {0.8, 4.0, 1.0}, "upper stairwell, down through the hole"},
      {{12.0, 15.0, 4.8}, {12.0, 25.0, 4.0}, "upper corridor"},
      {{7.9, 13.3, 1.6}, {12.0, 14.5, 1.4}, "beside a door, looking along the wall"},
      {{12.5, 14.2, 1.6}, {22.0, 14.9, 1.6}, "corridor, doors beside the eye"},
  };
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int i = 0; i < 8; ++i) {
    // Random eyes in rooms, corridors and spines (not stairwells: the flight is solid).
    uint32_t room;
    do {
      room = static_cast<uint32_t>(u(rng) * g.room_count());
    } while (room == 8 || room == 17);
    const Aabb& b = g.rooms()[room];
    const Vec3 eye(b.lo.x + 0.2 + u(rng) * (b.hi.x - b.lo.x - 0.4), b.lo.y + 0.2 + u(rng) * (b.hi.y - b.lo.y - 0.4),
                   b.lo.z + 0.3 + u(rng) * 2.4);
    const double yaw = 6.283185307179586 * u(rng), pitch = 0.6 * (u(rng) - 0.5);
    eyes.push_back({eye, eye + Vec3(std::cos(yaw), std::sin(yaw), std::tan(pitch)), "random"});
  }
  // Random eyes close to doors (whose corners then often lie behind the eye plane), in free space.
  const auto inside_shrunk = [&](const Vec3& p) {
    return std::any_of(g.rooms().begin(), g.rooms().end(), [&](const Aabb& b) {
      return p.x > b.lo.x + 0.05 && p.x < b.hi.x - 0.05 && p.y > b.lo.y + 0.05 && p.y < b.hi.y - 0.05;
    });
  };
  for (int i = 0; i < 8;) {
    const auto& q = g.portals()[static_cast<size_t>(u(rng) * g.portal_count())];
    const Aabb& o = q.opening;
    if (q.opening.extent().z < 1.0) continue;  // the stair hole
    const int across = o.extent().x < o.extent().y ? 0 : 1, along = 1 - across;
    Vec3 eye = o.center();
    eye[across] += (u(rng) < 0.5 ? -1.0 : 1.0) * (0.15 + 0.45 * u(rng));
    eye[along] += 1.6 * (u(rng) - 0.5);
    eye.z = o.lo.z + 0.5 + 1.5 * u(rng);
    if (!inside_shrunk(eye)) continue;
    const double yaw = 6.283185307179586 * u(rng);
    eyes.push_back({eye, eye + Vec3(std::cos(yaw), std::sin(yaw), 0.2 * (u(rng) - 0.5)), "near a door"});
    ++i;
  }
  for (size_t i = 0; i < eyes.size(); ++i) {
    const View view = make_view(eyes[i].eye, eyes[i].look_at, 75.0, 80, 60);
    expect_conservative(g, scene, view, std::to_string(i) + " " + eyes[i].label);
  }
}

// --- the store section ----------------------------------------------------------------------

TEST(PortalStore, FrontierBuildStoresTheGraphOfASidecar) {
  const fs::path with = scratch() / "with.fst";
  auto r = run_binary(FRONTIER_BUILD_PATH, {small_building().string(), "-o", with.string(), "--quiet", "--threads", "2"},
                      scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto model = StoreModel::open(with.string());
  ASSERT_TRUE(model.is_ok()) << model.status().to_string();
  ASSERT_NE((*model)->portals(), nullptr);
  expect_same_graph(*(*model)->portals(), small_graph());

  r = run_binary(FRONTIER_STORE_PATH, {"info", with.string()}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("18 rooms, 17 portals"), std::string::npos) << r.out;
  r = run_binary(FRONTIER_STORE_PATH, {"verify", with.string()}, scratch());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("18 rooms and 17 portals"), std::string::npos) << r.out;

  // The same model without its sidecar: no section.
  const fs::path bare_dir = scratch() / "bare";
  fs::create_directories(bare_dir);
  fs::copy_file(small_building(), bare_dir / "building.ply", fs::copy_options::overwrite_existing);
  const fs::path without = scratch() / "without.fst";
  r = run_binary(FRONTIER_BUILD_PATH, {(bare_dir / "building.ply").string(), "-o", without.string(), "--quiet"},
                 scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto bare = StoreModel::open(without.string());
  ASSERT_TRUE(bare.is_ok()) << bare.status().to_string();
  EXPECT_EQ((*bare)->portals(), nullptr);
  r = run_binary(FRONTIER_STORE_PATH, {"info", without.string()}, scratch());
  EXPECT_NE(r.out.find("portals     none"), std::string::npos) << r.out;

  // With the sidecar but --no-portals: no section either.
  const fs::path refused = scratch() / "refused.fst";
  r = run_binary(FRONTIER_BUILD_PATH,
                 {small_building().string(), "-o", refused.string(), "--quiet", "--no-walkable", "--no-portals"},
                 scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  auto no_portals = StoreModel::open(refused.string());
  ASSERT_TRUE(no_portals.is_ok()) << no_portals.status().to_string();
  EXPECT_EQ((*no_portals)->portals(), nullptr);
}

TEST(PortalStore, DamagedSectionIsAnErrorNamingStoreAndSection) {
  const fs::path store_path = scratch() / "damaged.fst";
  auto r = run_binary(FRONTIER_BUILD_PATH,
                      {small_building().string(), "-o", store_path.string(), "--quiet", "--no-walkable"}, scratch());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  uint64_t offset = 0;
  {
    store::PosixFileSystem fsys;
    auto reader = store::StoreReader::open(fsys, store_path.string());
    ASSERT_TRUE(reader.is_ok()) << reader.status().to_string();
    const auto handle = (*reader)->section(kPortalsSection);
    ASSERT_TRUE(handle.has_value());
    offset = handle->offset + 100;
  }
  {
    std::fstream f(store_path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(offset));
    char c = 0;
    f.read(&c, 1);
    c = static_cast<char>(c ^ 0x10);
    f.seekp(static_cast<std::streamoff>(offset));
    f.write(&c, 1);
  }
  auto model = StoreModel::open(store_path.string());
  ASSERT_FALSE(model.is_ok());
  EXPECT_EQ(model.status().code(), Status::Code::Corruption);
  EXPECT_NE(model.status().message().find(store_path.string()), std::string::npos) << model.status().to_string();
  EXPECT_NE(model.status().message().find("portals section"), std::string::npos) << model.status().to_string();
  r = run_binary(FRONTIER_STORE_PATH, {"verify", "-q", store_path.string()}, scratch());
  EXPECT_EQ(r.exit_code, 1);
}

TEST(PortalStore, BadSidecarFailsTheBuild) {
  const fs::path dir = scratch() / "bad_sidecar";
  fs::create_directories(dir);
  fs::copy_file(small_building(), dir / "b.ply", fs::copy_options::overwrite_existing);
  json j = read_json(sidecar_of(small_building()));
  j["portals"][0]["rooms"][0] = 1000;
  write_text(dir / "b.json", j.dump());
  const fs::path out = dir / "b.fst";
  const auto r = run_binary(FRONTIER_BUILD_PATH, {(dir / "b.ply").string(), "-o", out.string(), "--quiet"}, scratch());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("b.json"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace
}  // namespace frontier
