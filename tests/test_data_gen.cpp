// frontier-gen, tested as users run it: the binary is started in a child process and its files
// are checked by independent code here (a small binary PLY parser, brute-force geometry).
// Properties: byte-identical output for equal arguments; valid meshes (finite, no degenerate
// triangles, every solid closed and outward); sidecar portals in the walls between the rooms
// they join and a connected portal graph; --triangles within 5%; bounded memory on a large
// model; walk paths in free space; clear errors for impossible parameters.
// Also unit tests of the streaming writers in src/ (PlyWriter one- and two-pass, NffWriter).
#include "src/io/camera_path.h"
#include "src/io/load_scene.h"
#include "src/io/nff_writer.h"
#include "src/io/ply_writer.h"
#include "src/core/scene.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <numeric>
#include <set>
#include <sstream>
#include <thread>
#include <unordered_map>

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

using frontier::proc::gen_binary;

const fs::path& scratch_dir() { return frontier::testing::scratch_dir("frontier_datagen"); }

using frontier::proc::RunResult;
using frontier::proc::slurp;

// Runs frontier-gen with `args`; stdout and stderr are captured, peak RSS measured (wait4).
RunResult run_gen(const std::vector<std::string>& args) {
  return frontier::proc::run_binary(gen_binary(), args, scratch_dir());
}

// --- a small, strict reader of the PLY files frontier-gen writes ---------------------------
struct Mesh {
  std::vector<Vec3> pos;
  std::vector<Vec3> nor;
  std::vector<std::array<uint8_t, 3>> rgb;
  std::vector<std::array<uint32_t, 3>> tri;
  bool normals = false, colors = false;
};

std::string read_ply(const std::string& path, Mesh& m) {
  const std::string data = slurp(path);
  const size_t end = data.find("end_header\n");
  if (end == std::string::npos) return "no end_header";
  std::istringstream head(data.substr(0, end));
  std::string line;
  uint64_t nv = 0, nf = 0;
  std::vector<std::string> vprops;
  std::string section;
  while (std::getline(head, line)) {
    std::istringstream ls(line);
    std::string w;
    ls >> w;
    if (w == "format") {
      std::string f;
      ls >> f;
      if (f != "binary_little_endian") return "format " + f;
    } else if (w == "element") {
      ls >> section;
      (section == "vertex" ? nv : nf) = 0;
      ls >> (section == "vertex" ? nv : nf);
    } else if (w == "property" && section == "vertex") {
      std::string type, name;
      ls >> type >> name;
      vprops.push_back(type + " " + name);
    } else if (w == "property" && section == "face") {
      if (line != "property list uchar uint vertex_indices") return "face property " + line;
    }
  }
  const std::vector<std::string> xyz = {"float x", "float y", "float z"};
  if (vprops.size() < 3 || !std::equal(xyz.begin(), xyz.end(), vprops.begin())) return "vertex properties";
  size_t k = 3;
  if (vprops.size() > k && vprops[k] == "float nx") m.normals = true, k += 3;
  if (vprops.size() > k && vprops[k] == "uchar red") m.colors = true, k += 3;
  if (k != vprops.size()) return "unexpected vertex properties";
  const size_t vbytes = 12 + (m.normals ? 12 : 0) + (m.colors ? 3 : 0);
  const char* p = data.data() + end + 11;
  const size_t body = data.size() - (end + 11);
  if (body != nv * vbytes + nf * 13) return "file size does not match the header counts";
  m.pos.resize(nv);
  if (m.colors) m.rgb.resize(nv);
  if (m.normals) m.nor.resize(nv);
  for (uint64_t i = 0; i < nv; ++i, p += vbytes) {
    float f[3];
    std::memcpy(f, p, 12);
    m.pos[i] = Vec3(f[0], f[1], f[2]);
    if (m.normals) {
      std::memcpy(f, p + 12, 12);
      m.nor[i] = Vec3(f[0], f[1], f[2]);
    }
    if (m.colors) std::memcpy(m.rgb[i].data(), p + vbytes - 3, 3);
  }
  m.tri.resize(nf);
  for (uint64_t i = 0; i < nf; ++i, p += 13) {
    if (static_cast<uint8_t>(p[0]) != 3) return "face with " + std::to_string(int(p[0])) + " indices";
    std::memcpy(m.tri[i].data(), p + 1, 12);
    for (uint32_t v : m.tri[i])
      if (v >= nv) return "index out of range";
  }
  return {};
}

// Connected components (by shared vertex indices) with their triangles and bounds.
struct Component {
  std::vector<uint32_t> tris;
  Aabb box;
};

std::vector<Component> components(const Mesh& m) {
  std::vector<uint32_t> parent(m.pos.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const auto& t : m.tri) {
    const uint32_t a = find(t[0]);
    parent[find(t[1])] = a;
    parent[find(t[2])] = a;
  }
  std::unordered_map<uint32_t, size_t> index;
  std::vector<Component> out;
  for (uint32_t i = 0; i < m.tri.size(); ++i) {
    const uint32_t root = find(m.tri[i][0]);
    auto [it, fresh] = index.try_emplace(root, out.size());
    if (fresh) out.emplace_back();
    Component& c = out[it->second];
    c.tris.push_back(i);
    for (uint32_t v : m.tri[i]) c.box.extend(m.pos[v]);
  }
  return out;
}

// Segment p0-p1 against triangle (Moller-Trumbore), hits strictly inside the segment.
bool segment_hits_triangle(const Vec3& p0, const Vec3& p1, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 d = p1 - p0, e1 = b - a, e2 = c - a, h = glm::cross(d, e2);
  const double det = glm::dot(e1, h);
  if (std::abs(det) < 1e-14) return false;
  const double f = 1.0 / det;
  const Vec3 s = p0 - a;
  const double u = f * glm::dot(s, h);
  if (u < 0.0 || u > 1.0) return false;
  const Vec3 q = glm::cross(s, e1);
  const double v = f * glm::dot(d, q);
  if (v < 0.0 || u + v > 1.0) return false;
  const double t = f * glm::dot(e2, q);
  return t > 0.0 && t < 1.0;
}

bool segment_hits_mesh(const Mesh& m, const std::vector<Component>& comps, const Vec3& p0, const Vec3& p1) {
  const Aabb seg(p0, p1);
  for (const Component& c : comps) {
    if (!c.box.overlaps(seg)) continue;
    for (uint32_t t : c.tris) {
      const auto& v = m.tri[t];
      if (segment_hits_triangle(p0, p1, m.pos[v[0]], m.pos[v[1]], m.pos[v[2]])) return true;
    }
  }
  return false;
}

Vec3 jv(const json& j) { return Vec3(j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()); }
Aabb jb(const json& j) { return Aabb(jv(j.at(0)), jv(j.at(1))); }

bool inside(const Aabb& b, const Vec3& p, double tol) {
  return p.x >= b.lo.x - tol && p.x <= b.hi.x + tol && p.y >= b.lo.y - tol && p.y <= b.hi.y + tol &&
         p.z >= b.lo.z - tol && p.z <= b.hi.z + tol;
}

// --- the shared building ------------------------------------------------------------------
class DataGen : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    ply_ = (scratch_dir() / "bld.ply").string();
    sidecar_ = (scratch_dir() / "bld.json").string();
    const RunResult r = run_gen({"building", "-o", ply_, "--floors", "3", "--rooms", "7", "--seed", "5",
                                 "--colors", "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    mesh_ = new Mesh();
    const std::string err = read_ply(ply_, *mesh_);
    ASSERT_EQ(err, "") << err;
    comps_ = new std::vector<Component>(components(*mesh_));
    side_ = new json(json::parse(slurp(sidecar_)));
  }
  static void TearDownTestSuite() {
    delete mesh_;
    delete comps_;
    delete side_;
    mesh_ = nullptr;
    comps_ = nullptr;
    side_ = nullptr;
  }
  void SetUp() override {
    if (mesh_ == nullptr) GTEST_SKIP() << "building fixture failed";
  }

  static std::string ply_, sidecar_;
  static Mesh* mesh_;
  static std::vector<Component>* comps_;
  static json* side_;
};
std::string DataGen::ply_, DataGen::sidecar_;
Mesh* DataGen::mesh_ = nullptr;
std::vector<Component>* DataGen::comps_ = nullptr;
json* DataGen::side_ = nullptr;

TEST_F(DataGen, BuildingIsByteIdenticalForEqualArgumentsAndDiffersBySeed) {
  const std::string a = (scratch_dir() / "det_a.ply").string(), b = (scratch_dir() / "det_b.ply").string();
  const std::string c = (scratch_dir() / "det_c.ply").string();
  for (const std::string& out : {a, b})
    ASSERT_EQ(run_gen({"building", "-o", out, "--floors", "3", "--rooms", "7", "--seed", "5", "--colors",
                       "-q", "--threads", out == a ? "1" : "2"})
                  .exit_code,
              0);
  ASSERT_EQ(run_gen({"building", "-o", c, "--floors", "3", "--rooms", "7", "--seed", "6", "--colors", "-q"}).exit_code, 0);
  EXPECT_TRUE(slurp(a) == slurp(b)) << "same arguments, different thread counts: files differ";
  EXPECT_TRUE(slurp(a) == slurp(ply_)) << "same arguments: files differ";
  json ja = json::parse(slurp(fs::path(a).replace_extension(".json")));
  json jb2 = json::parse(slurp(fs::path(b).replace_extension(".json")));
  EXPECT_EQ(ja.at("model"), "det_a.ply");
  ja.erase("model");
  jb2.erase("model");
  EXPECT_TRUE(ja == jb2) << "sidecars differ";
  EXPECT_FALSE(slurp(a) == slurp(c)) << "a different seed gave the same model";
}

TEST_F(DataGen, BuildingMeshIsFiniteNonDegenerateClosedAndOutward) {
  const Mesh& m = *mesh_;
  ASSERT_GT(m.tri.size(), 10000u);
  ASSERT_TRUE(m.colors);
  for (const Vec3& p : m.pos) ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
  for (const auto& t : m.tri) {
    const Vec3 n = glm::cross(m.pos[t[1]] - m.pos[t[0]], m.pos[t[2]] - m.pos[t[0]]);
    ASSERT_GT(glm::length(n), 1e-9) << "degenerate triangle " << t[0] << " " << t[1] << " " << t[2];
  }
  // Every directed edge is used once and its reverse once: closed and consistently oriented.
  std::unordered_map<uint64_t, int> edges;
  auto key = [](uint32_t a, uint32_t b) { return (uint64_t{a} << 32) | b; };
  for (const auto& t : m.tri)
    for (int k = 0; k < 3; ++k) ++edges[key(t[k], t[(k + 1) % 3])];
  size_t bad = 0;
  for (const auto& [e, n] : edges) {
    const auto rev = edges.find(key(static_cast<uint32_t>(e & 0xffffffffu), static_cast<uint32_t>(e >> 32)));
    if (n != 1 || rev == edges.end() || rev->second != 1) ++bad;
  }
  EXPECT_EQ(bad, 0u) << "edges not shared by exactly two opposite half-edges";
  // Outward: each solid encloses positive volume.
  size_t inward = 0;
  for (const Component& c : *comps_) {
    const Vec3 o = m.pos[m.tri[c.tris[0]][0]];
    double vol = 0.0;
    for (uint32_t t : c.tris) {
      const auto& v = m.tri[t];
      vol += glm::dot(m.pos[v[0]] - o, glm::cross(m.pos[v[1]] - o, m.pos[v[2]] - o)) / 6.0;
    }
    if (!(vol > 0.0)) ++inward;
  }
  EXPECT_EQ(inward, 0u) << "of " << comps_->size() << " solids";
}

TEST_F(DataGen, DetailHoldsMoreTrianglesThanStructure) {
  std::set<std::array<uint8_t, 3>> structure;
  for (const json& c : side_->at("palette").at("structure"))
    structure.insert({c.at(0).get<uint8_t>(), c.at(1).get<uint8_t>(), c.at(2).get<uint8_t>()});
  size_t walls = 0, detail = 0;
  for (const auto& t : mesh_->tri) (structure.count(mesh_->rgb[t[0]]) ? walls : detail)++;
  EXPECT_GT(walls, 100u);
  EXPECT_GT(detail, 5 * walls) << "detail " << detail << ", structure " << walls;
}

TEST_F(DataGen, SidecarDescribesTheModel) {
  const json& s = *side_;
  EXPECT_TRUE(s.at("walkable").get<bool>());
  EXPECT_EQ(s.at("triangles").get<size_t>(), mesh_->tri.size());
  EXPECT_EQ(s.at("floors").size(), 3u);
  Aabb mesh_box;
  for (const Vec3& p : mesh_->pos) mesh_box.extend(p);
  const Aabb b = jb(s.at("bounds"));
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(mesh_box.lo[a], b.lo[a], 1e-3);
    EXPECT_NEAR(mesh_box.hi[a], b.hi[a], 1e-3);
  }
  // Rooms are interior boxes of their floor and never overlap one another.
  const json& rooms = s.at("rooms");
  for (size_t i = 0; i < rooms.size(); ++i) {
    ASSERT_EQ(rooms[i].at("id").get<size_t>(), i);
    const Aabb ri = jb(rooms[i].at("bounds"));
    const double floor_z = s.at("floors").at(rooms[i].at("floor").get<size_t>()).at("height").get<double>();
    EXPECT_NEAR(ri.lo.z, floor_z, 1e-6);
    for (size_t j = i + 1; j < rooms.size(); ++j) {
      const Aabb rj = jb(rooms[j].at("bounds"));
      const Aabb x = ri.intersection(rj);
      EXPECT_TRUE(x.hi.x - x.lo.x <= 1e-6 || x.hi.y - x.lo.y <= 1e-6 || x.hi.z - x.lo.z <= 1e-6)
          << "rooms " << i << " and " << j << " overlap";
    }
  }
}

TEST_F(DataGen, PortalsLieInWallsBetweenTheRoomsTheyJoin) {
  const json& rooms = side_->at("rooms");
  const double wall = side_->at("wall_thickness").get<double>();
  const double slab = side_->at("slab_thickness").get<double>();
  std::vector<std::vector<size_t>> graph(rooms.size());
  size_t wall_portals = 0;
  for (const json& p : side_->at("portals")) {
    const size_t a = p.at("rooms").at(0).get<size_t>(), b = p.at("rooms").at(1).get<size_t>();
    ASSERT_LT(a, rooms.size());
    ASSERT_LT(b, rooms.size());
    ASSERT_NE(a, b);
    graph[a].push_back(b);
    graph[b].push_back(a);
    const Aabb ra = jb(rooms[a].at("bounds")), rb = jb(rooms[b].at("bounds"));
    std::vector<Vec3> poly;
    for (const json& v : p.at("polygon")) poly.push_back(jv(v));
    ASSERT_EQ(poly.size(), 4u);
    // The polygon is planar on one axis: the wall's (or slab's) mid-plane.
    int axis = -1;
    for (int k = 0; k < 3; ++k)
      if (std::all_of(poly.begin(), poly.end(), [&](const Vec3& v) { return std::abs(v[k] - poly[0][k]) < 1e-6; }))
        axis = k;
    ASSERT_GE(axis, 0) << "portal " << p.at("id") << " is not axis-planar";
    const double plane = poly[0][axis];
    // The rooms sit on both sides of that plane, one wall (or slab) thickness apart: adjacent.
    const Aabb& lo_room = ra.hi[axis] <= plane + 1e-6 ? ra : rb;
    const Aabb& hi_room = ra.hi[axis] <= plane + 1e-6 ? rb : ra;
    const double gap = axis == 2 ? slab : wall;
    EXPECT_NEAR(plane - lo_room.hi[axis], gap / 2, 1e-3) << "portal " << p.at("id");
    EXPECT_NEAR(hi_room.lo[axis] - plane, gap / 2, 1e-3) << "portal " << p.at("id");
    // Inside the shared extent of both rooms on the other two axes.
    for (int k = 0; k < 3; ++k) {
      if (k == axis) continue;
      for (const Vec3& v : poly) {
        EXPECT_GE(v[k], std::max(ra.lo[k], rb.lo[k]) - 1e-3) << "portal " << p.at("id");
        EXPECT_LE(v[k], std::min(ra.hi[k], rb.hi[k]) + 1e-3) << "portal " << p.at("id");
      }
    }
    if (axis == 2) continue;  // stair portal: checked by the walk test
    ++wall_portals;
    // Against the geometry: the way through the opening is free, the wall beside it is solid.
    const Vec3 c = 0.25 * (poly[0] + poly[1] + poly[2] + poly[3]);
    const int along = axis == 0 ? 1 : 0;
    const double half = 0.5 * std::abs(poly[1][along] - poly[0][along]);
    Vec3 n(0.0), side(0.0);
    n[axis] = 0.3;
    side[along] = half + 0.12;
    const Vec3 low = Vec3(c.x, c.y, poly[0].z + 1.0);
    EXPECT_FALSE(segment_hits_mesh(*mesh_, *comps_, low - n, low + n)) << "blocked portal " << p.at("id");
    EXPECT_TRUE(segment_hits_mesh(*mesh_, *comps_, low + side - n, low + side + n))
        << "no wall beside portal " << p.at("id");
    EXPECT_TRUE(segment_hits_mesh(*mesh_, *comps_, low - side - n, low - side + n))
        << "no wall beside portal " << p.at("id");
  }
  EXPECT_GT(wall_portals, 20u);
  // The portal graph is connected.
  std::vector<bool> seen(rooms.size(), false);
  std::vector<size_t> stack = {0};
  seen[0] = true;
  while (!stack.empty()) {
    const size_t r = stack.back();
    stack.pop_back();
    for (size_t q : graph[r])
      if (!seen[q]) seen[q] = true, stack.push_back(q);
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), true), static_cast<long>(rooms.size()));
}

// Expected floor heights under an eye: its cell's floor, a door sill, or a stair pitch line.
std::vector<double> floors_under(const json& side, const Vec3& eye) {
  std::vector<double> out;
  for (const json& r : side.at("rooms")) {
    const Aabb b = jb(r.at("bounds"));
    if (inside(b, eye, 1e-3)) out.push_back(b.lo.z);
    if (r.contains("flight")) {
      const json& f = r.at("flight");
      const double x0 = f.at("lane").at(0).at(0), y_top = f.at("lane").at(0).at(1);
      const double x1 = f.at("lane").at(1).at(0), y_bottom = f.at("lane").at(1).at(1);
      const double z0 = f.at("z").at(0), z1 = f.at("z").at(1);
      if (eye.x >= x0 && eye.x <= x1 && eye.y >= y_top - 1e-3 && eye.y <= y_bottom + 1e-3)
        out.push_back(z0 + (z1 - z0) * std::clamp((y_bottom - eye.y) / (y_bottom - y_top), 0.0, 1.0));
    }
  }
  for (const json& p : side.at("portals")) {
    const Aabb o = jb(p.at("opening"));
    if (p.at("kind") != "stair" && inside(o, eye, 1e-3)) out.push_back(o.lo.z);
  }
  return out;
}

TEST_F(DataGen, WalkPathsStayInFreeSpaceAtEyeHeight) {
  const json& s = *side_;
  const double eye_h = s.at("eye_height").get<double>();
  std::vector<Aabb> spaces;
  for (const json& r : s.at("rooms")) spaces.push_back(jb(r.at("bounds")));
  for (const json& p : s.at("portals")) spaces.push_back(jb(p.at("opening")));
  bool changed_floor = false;
  for (int seed = 1; seed <= 4; ++seed) {
    const std::string cam = (scratch_dir() / ("walk" + std::to_string(seed) + ".cam")).string();
    const RunResult r = run_gen({"path", "--model", ply_, "--kind", "walk", "--frames", "2500", "--seed",
                                 std::to_string(seed), "-o", cam});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    auto frames = read_camera_path(cam);
    ASSERT_TRUE(frames.is_ok()) << frames.status().to_string();
    ASSERT_EQ(frames->size(), 2500u);
    const double z_first = frames->front().eye.z;
    for (size_t i = 0; i < frames->size(); ++i) {
      const Vec3 e = (*frames)[i].eye;
      if (std::abs(e.z - z_first) > 1.0) changed_floor = true;
      ASSERT_TRUE(std::any_of(spaces.begin(), spaces.end(), [&](const Aabb& b) { return inside(b, e, 1e-3); }))
          << "seed " << seed << " frame " << i << " outside every room and opening: " << e.x << " " << e.y << " " << e.z;
      const std::vector<double> floors = floors_under(s, e);
      ASSERT_TRUE(std::any_of(floors.begin(), floors.end(),
                              [&](double f) { return std::abs(e.z - f - eye_h) < 0.02; }))
          << "seed " << seed << " frame " << i << " not at eye height: z " << e.z;
      for (const Component& c : *comps_)
        ASSERT_FALSE(inside(c.box, e, -1e-3)) << "seed " << seed << " frame " << i << " inside a solid's box";
      if (i > 0) {
        const Vec3 p = (*frames)[i - 1].eye;
        const double step = glm::length(e - p);
        ASSERT_LT(step, 0.05 * 1.6) << "seed " << seed << " frame " << i;
        ASSERT_GT(step, 0.0) << "seed " << seed << " frame " << i;
        ASSERT_FALSE(segment_hits_mesh(*mesh_, *comps_, p, e))
            << "seed " << seed << " frames " << i - 1 << "-" << i << " pass through geometry";
      }
    }
  }
  EXPECT_TRUE(changed_floor) << "no walk used the stairs";
}

TEST_F(DataGen, OrbitAndFlyPathsFrameTheModel) {
  const Aabb b = jb(side_->at("bounds"));
  const std::string orbit = (scratch_dir() / "orbit.cam").string(), fly = (scratch_dir() / "fly.cam").string();
  ASSERT_EQ(run_gen({"path", "--model", ply_, "--kind", "orbit", "--frames", "90", "-o", orbit}).exit_code, 0);
  ASSERT_EQ(run_gen({"path", "--model", ply_, "--kind", "fly", "--frames", "600", "--seed", "3", "-o", fly}).exit_code, 0);
  auto o = read_camera_path(orbit);
  ASSERT_TRUE(o.is_ok() && o->size() == 90u);
  const double d0 = glm::length(o->front().eye - b.center());
  EXPECT_GT(d0, 0.5 * glm::length(b.extent()));
  for (const Camera& c : *o) {
    EXPECT_NEAR(glm::length(c.eye - b.center()), d0, 1e-3 * d0);
    EXPECT_LT(glm::length(c.look_at - b.center()), 1e-3);
  }
  auto f = read_camera_path(fly);
  ASSERT_TRUE(f.is_ok() && f->size() == 600u);
  Aabb grown = b;
  grown.extend(b.lo - 0.1 * b.extent());
  grown.extend(b.hi + 0.1 * b.extent());
  double longest = 0.0, total = 0.0;
  for (size_t i = 0; i < f->size(); ++i) {
    const Vec3 e = (*f)[i].eye;
    EXPECT_TRUE(inside(grown, e, 0.0)) << i;
    EXPECT_GE(e.z, b.center().z - 0.05 * b.extent().z) << i;
    const double step = glm::length((*f)[(i + 1) % f->size()].eye - e);
    longest = std::max(longest, step);
    total += step;
  }
  EXPECT_LT(longest, 4.0 * total / static_cast<double>(f->size())) << "the fly path jumps";
  // Orbit works from the PLY alone (bounds scanned from the vertices) too.
  const fs::path lone = scratch_dir() / "lone.ply";
  fs::copy_file(ply_, lone, fs::copy_options::overwrite_existing);
  const std::string orbit2 = (scratch_dir() / "orbit2.cam").string();
  ASSERT_EQ(run_gen({"path", "--model", lone.string(), "--kind", "orbit", "--frames", "90", "-o", orbit2}).exit_code, 0);
  auto o2 = read_camera_path(orbit2);
  ASSERT_TRUE(o2.is_ok());
  EXPECT_LT(glm::length(o2->front().look_at - b.center()), 1e-3);
}

TEST_F(DataGen, ProjectReadersLoadTheModels) {
  Scene scene;
  const Status st = load_scene(ply_, scene);
  ASSERT_TRUE(st.is_ok()) << st.to_string();
  EXPECT_EQ(scene.triangles.size(), mesh_->tri.size());
  EXPECT_EQ(scene.degenerate_dropped, 0u);
  const std::string nff = (scratch_dir() / "read_rings.nff").string();
  ASSERT_EQ(run_gen({"spheres", "--family", "rings", "--size", "2", "-o", nff, "-q"}).exit_code, 0);
  Scene rings;
  const Status sr = load_scene(nff, rings);
  ASSERT_TRUE(sr.is_ok()) << sr.to_string();
  EXPECT_EQ(rings.spheres.size(), 8u * 12);
  EXPECT_EQ(rings.cones.size(), 8u * 12);
  EXPECT_TRUE(rings.camera.has_value());
  EXPECT_EQ(rings.lights.size(), 2u);
}

TEST_F(DataGen, CountOnlyMatchesTheWrittenFile) {
  const RunResult r = run_gen({"building", "--count-only", "--floors", "3", "--rooms", "7", "--seed", "5", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j.at("triangles").get<size_t>(), mesh_->tri.size());
  EXPECT_EQ(j.at("vertices").get<size_t>(), mesh_->pos.size());
}

TEST(DataGenNormals, VertexNormalsAreUnitAndAgreeWithTheWinding) {
  const std::string path = (scratch_dir() / "normals.ply").string();
  ASSERT_EQ(run_gen({"building", "-o", path, "--floors", "2", "--rooms", "3", "--normals", "--tessellation", "5",
                     "-q"}).exit_code, 0);
  Mesh m;
  ASSERT_EQ(read_ply(path, m), "");
  ASSERT_TRUE(m.normals);
  for (const Vec3& n : m.nor) ASSERT_NEAR(glm::length(n), 1.0, 1e-5);
  size_t disagree = 0;
  for (const auto& t : m.tri) {
    const Vec3 g = glm::normalize(glm::cross(m.pos[t[1]] - m.pos[t[0]], m.pos[t[2]] - m.pos[t[0]]));
    for (uint32_t v : t)
      if (!(glm::dot(g, m.nor[v]) > 0.0)) ++disagree;
  }
  EXPECT_EQ(disagree, 0u) << "of " << m.tri.size() << " triangles";
}

TEST(DataGenFit, TrianglesShortcutLandsWithinFivePercent) {
  for (uint64_t n : {3000ull, 20000ull, 250000ull, 4000000ull, 100000000ull}) {
    const RunResult r = run_gen({"building", "--count-only", "--triangles", std::to_string(n), "-q"});
    ASSERT_EQ(r.exit_code, 0) << n << ": " << r.err;
    const json j = json::parse(r.out);
    const double got = j.at("triangles").get<double>();
    EXPECT_LT(std::abs(got - double(n)) / double(n), 0.05) << n << " -> " << r.out;
  }
  // With rooms fixed, floors (and density) move instead.
  const RunResult r = run_gen({"building", "--count-only", "--triangles", "2000000", "--rooms", "40", "-q"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const json j = json::parse(r.out);
  EXPECT_EQ(j.at("rooms").get<int>(), 40);
  EXPECT_LT(std::abs(j.at("triangles").get<double>() - 2e6) / 2e6, 0.05) << r.out;
  for (uint64_t n : {5000ull, 1000000000ull}) {
    const RunResult t = run_gen({"terrain", "--count-only", "--triangles", std::to_string(n)});
    ASSERT_EQ(t.exit_code, 0) << t.err;
    EXPECT_LT(std::abs(json::parse(t.out).at("triangles").get<double>() - double(n)) / double(n), 0.05);
  }
}

TEST(DataGenStreaming, LargeModelsStayUnder256MiB) {
  // ~24 M triangles each; written to /dev/null so that the disk is not what is measured.
  const RunResult b = run_gen({"building", "-o", "/dev/null", "--floors", "14", "--rooms", "260", "-q"});
  ASSERT_EQ(b.exit_code, 0) << b.err;
  EXPECT_LT(b.max_rss_kb, 256 * 1024) << "building peak RSS " << b.max_rss_kb << " KiB";
  const RunResult t = run_gen({"terrain", "-o", "/dev/null", "--grid", "3400", "-q"});
  ASSERT_EQ(t.exit_code, 0) << t.err;
  EXPECT_LT(t.max_rss_kb, 256 * 1024) << "terrain peak RSS " << t.max_rss_kb << " KiB";
  const RunResult c = run_gen({"building", "--count-only", "--floors", "14", "--rooms", "260", "-q"});
  ASSERT_EQ(c.exit_code, 0);
  EXPECT_GT(json::parse(c.out).at("triangles").get<double>(), 20e6);
}

TEST(DataGenTerrain, HeightFieldIsValidSeamlessAndDeterministic) {
  const std::string a = (scratch_dir() / "t_a.ply").string(), b = (scratch_dir() / "t_b.ply").string();
  for (const std::string& out : {a, b})
    ASSERT_EQ(run_gen({"terrain", "-o", out, "--grid", "100", "--tile", "32", "--seed", "9", "--normals",
                       "--colors", "-q"}).exit_code, 0);
  EXPECT_TRUE(slurp(a) == slurp(b));
  Mesh m;
  ASSERT_EQ(read_ply(a, m), "");
  ASSERT_TRUE(m.normals && m.colors);
  EXPECT_EQ(m.tri.size(), 2u * 100 * 100);
  std::set<std::tuple<double, double, double>> unique;
  for (const Vec3& p : m.pos) {
    ASSERT_TRUE(std::isfinite(p.z));
    unique.insert({p.x, p.y, p.z});
  }
  EXPECT_EQ(unique.size(), 101u * 101u) << "tiles disagree on their shared edges";
  double zmin = kInfinity, zmax = -kInfinity;
  for (const auto& t : m.tri) {
    const Vec3 n = glm::cross(m.pos[t[1]] - m.pos[t[0]], m.pos[t[2]] - m.pos[t[0]]);
    ASSERT_GT(n.z, 0.0) << "triangle not facing up";
    for (uint32_t v : t) zmin = std::min(zmin, m.pos[v].z), zmax = std::max(zmax, m.pos[v].z);
  }
  EXPECT_GT(zmax - zmin, 0.5) << "flat terrain";
}

// Tokens of an NFF file, and the count of each keyword.
std::map<std::string, size_t> nff_keywords(const std::string& text, bool& all_finite) {
  std::map<std::string, size_t> count;
  std::istringstream in(text);
  std::string line;
  all_finite = true;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string w;
    ls >> w;
    if (!w.empty() && (std::isalpha(static_cast<unsigned char>(w[0])))) ++count[w];
    std::string tok;
    while (ls >> tok) {
      char* end = nullptr;
      const double v = std::strtod(tok.c_str(), &end);
      if (*end == '\0' && !std::isfinite(v)) all_finite = false;
    }
  }
  return count;
}

TEST(DataGenSpheres, FamiliesWriteDeterministicNffOfTheDocumentedSize) {
  struct Case {
    const char* family;
    int size;
    size_t spheres, cones;
  };
  const Case cases[] = {{"rings", 3, 27 * 12, 27 * 12}, {"tree", 6, 127, 127}, {"flake", 2, 91, 0}, {"shells", 2, 800, 0}};
  for (const Case& c : cases) {
    const std::string a = (scratch_dir() / (std::string(c.family) + "_a.nff")).string();
    const std::string b = (scratch_dir() / (std::string(c.family) + "_b.nff")).string();
    for (const std::string& out : {a, b})
      ASSERT_EQ(run_gen({"spheres", "--family", c.family, "--size", std::to_string(c.size), "-o", out, "-q"}).exit_code, 0);
    const std::string text = slurp(a);
    EXPECT_TRUE(text == slurp(b)) << c.family;
    bool finite = false;
    auto k = nff_keywords(text, finite);
    EXPECT_TRUE(finite) << c.family;
    EXPECT_EQ(k["s"], c.spheres) << c.family;
    EXPECT_EQ(k["c"], c.cones) << c.family;
    EXPECT_EQ(k["v"], 1u) << c.family;
    EXPECT_GE(k["l"], 1u) << c.family;
    EXPECT_GE(k["f"], 1u) << c.family;
    EXPECT_EQ(k["p"], 1u) << c.family;
  }
}

void expect_failure(const std::vector<std::string>& args, int code, const std::string& mention) {
  const RunResult r = run_gen(args);
  std::string joined;
  for (const auto& a : args) joined += a + " ";
  EXPECT_EQ(r.exit_code, code) << joined << "\n" << r.err;
  EXPECT_NE(r.err.find(mention), std::string::npos) << joined << "\nstderr: " << r.err;
  EXPECT_EQ(r.exit_code < 128, true) << "crashed: " << joined;
}

TEST(DataGenErrors, ImpossibleParametersFailWithAMessageNamingTheOption) {
  const std::string out = (scratch_dir() / "never.ply").string();
  expect_failure({"building", "-o", out, "--floors", "0"}, 2, "--floors");
  expect_failure({"building", "-o", out, "--rooms", "-3"}, 2, "--rooms");
  expect_failure({"building", "-o", out, "--tessellation", "2"}, 2, "--tessellation");
  expect_failure({"building", "-o", out, "--furniture", "-1"}, 2, "--furniture");
  expect_failure({"building", "-o", out, "--triangles", "20"}, 2, "--triangles");
  expect_failure({"building", "-o", out, "--triangles", "-5"}, 2, "--triangles");
  expect_failure({"building", "-o", out, "--triangles", "900000", "--floors", "1", "--rooms", "1",
                  "--furniture", "1", "--tessellation", "8"}, 2, "--triangles");
  expect_failure({"building"}, 2, "--output");
  expect_failure({"building", "-o", "/nonexistent/dir/x.ply"}, 1, "/nonexistent/dir/x.ply");
  expect_failure({"terrain", "-o", out, "--grid", "0"}, 2, "--grid");
  expect_failure({"spheres", "--family", "cubes", "--size", "2", "-o", out}, 2, "--family");
  expect_failure({"spheres", "--family", "rings", "--size", "0", "-o", out}, 2, "--size");
  expect_failure({"spheres", "--family", "flake", "--size", "12", "-o", out}, 2, "--size");
  expect_failure({"path", "--model", out, "--kind", "walk", "--frames", "10", "-o", out + ".cam"}, 2, "sidecar");
  expect_failure({"path", "--model", out, "--kind", "jump", "--frames", "10", "-o", out + ".cam"}, 2, "--kind");
  expect_failure({"path", "--model", "/nonexistent/m.ply", "--kind", "orbit", "--frames", "10", "-o", out + ".cam"},
                 1, "/nonexistent/m.ply");
  EXPECT_FALSE(fs::exists(out)) << "a failed run left a file";
  EXPECT_FALSE(fs::exists(out + ".tmp")) << "a failed run left a temporary file";
}

// --- the writers in src/ ----------------------------------------------------------------
MeshPiece cube_piece(float offset) {
  MeshPiece p;
  for (int i = 0; i < 8; ++i)
    p.positions.insert(p.positions.end(), {offset + float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1)});
  p.indices = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
               2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
  return p;
}

TEST(DataGenPlyWriter, PiecesAreRebasedAndCountsEnforced) {
  const std::string path = (scratch_dir() / "cubes.ply").string();
  {
    auto w = PlyWriter::create(path, {}, 16, 24, {"two cubes"});
    ASSERT_TRUE(w.is_ok());
    ASSERT_TRUE((*w)->add(cube_piece(0)).is_ok());
    ASSERT_TRUE((*w)->add(cube_piece(2)).is_ok());
    ASSERT_TRUE((*w)->finish().is_ok());
  }
  Mesh m;
  ASSERT_EQ(read_ply(path, m), "");
  ASSERT_EQ(m.tri.size(), 24u);
  EXPECT_EQ(m.tri[12][0], 8u) << "second piece not rebased";
  EXPECT_EQ(m.pos[8].x, 2.0);
  EXPECT_NE(slurp(path).find("comment two cubes\n"), std::string::npos);

  const std::string bad = (scratch_dir() / "bad.ply").string();
  auto w = PlyWriter::create(bad, {}, 8, 12);
  ASSERT_TRUE(w.is_ok());
  MeshPiece nan_piece = cube_piece(0);
  nan_piece.positions[4] = std::nanf("");
  EXPECT_FALSE((*w)->add(nan_piece).is_ok());
  MeshPiece out_of_range = cube_piece(0);
  out_of_range.indices[5] = 8;
  EXPECT_FALSE((*w)->add(out_of_range).is_ok());
  EXPECT_FALSE((*w)->finish().is_ok()) << "finish with fewer triangles than declared";
  w = Status::io_error("drop");  // destroying an unfinished writer removes its temporary file
  EXPECT_FALSE(fs::exists(bad)) << "an unfinished PLY was renamed into place";
  EXPECT_FALSE(fs::exists(bad + ".tmp"));
  EXPECT_FALSE(PlyWriter::create(bad, {}, uint64_t{1} << 33, 1).is_ok()) << "32-bit index overflow accepted";
}

TEST(DataGenPlyWriter, NonSeekableOutputTakesTwoPassesAndGivesTheSameBytes) {
  const fs::path fifo = scratch_dir() / "pipe.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] { received = slurp(fifo); });
  // Written in a lambda so that the reader is always joined (closing the pipe ends it).
  const std::string problem = [&]() -> std::string {
    auto w = PlyWriter::create(fifo.string(), {false, true}, 16, 24);
    if (!w.is_ok()) return w.status().to_string();
    if (!(*w)->needs_two_passes()) return "a pipe was taken for seekable";
    for (int pass = 0; pass < 2; ++pass) {
      for (float off : {0.0f, 2.0f}) {
        MeshPiece p = cube_piece(off);
        p.colors.assign(24, static_cast<uint8_t>(off * 10));
        if (Status st = (*w)->add(p); !st.is_ok()) return st.to_string();
      }
      if (pass == 0) {
        if (Status st = (*w)->begin_face_pass(); !st.is_ok()) return st.to_string();
      }
    }
    const Status st = (*w)->finish();
    return st.is_ok() ? "" : st.to_string();
  }();
  reader.join();
  ASSERT_EQ(problem, "");
  const std::string file = (scratch_dir() / "seek.ply").string();
  {
    auto w = PlyWriter::create(file, {false, true}, 16, 24);
    ASSERT_TRUE(w.is_ok());
    ASSERT_FALSE((*w)->needs_two_passes());
    for (float off : {0.0f, 2.0f}) {
      MeshPiece p = cube_piece(off);
      p.colors.assign(24, static_cast<uint8_t>(off * 10));
      ASSERT_TRUE((*w)->add(p).is_ok());
    }
    ASSERT_TRUE((*w)->finish().is_ok());
  }
  EXPECT_TRUE(received == slurp(file)) << "pipe and file outputs differ";
}

TEST(DataGenNffWriter, WritesPrimitivesAndRejectsNonFiniteValues) {
  const std::string path = (scratch_dir() / "w.nff").string();
  {
    auto w = NffWriter::create(path);
    ASSERT_TRUE(w.is_ok());
    Camera cam;
    cam.eye = {0, -5, 1};
    cam.look_at = {0, 0, 0};
    cam.up = {0, 0, 1};
    (*w)->view(cam, 0.01, 64, 48);
    (*w)->light({1, 2, 3}, {1, 1, 1});
    (*w)->material(Material{});
    (*w)->sphere({0, 0, 0}, 0.5);
    (*w)->cone({0, 0, 0}, 0.1, {0, 0, 1}, 0.1);
    const Vec3 tri[3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    (*w)->polygon(tri);
    EXPECT_EQ((*w)->primitives(), 3u);
    ASSERT_TRUE((*w)->finish().is_ok());
  }
  bool finite = false;
  auto k = nff_keywords(slurp(path), finite);
  EXPECT_EQ(k["s"], 1u);
  EXPECT_EQ(k["c"], 1u);
  EXPECT_EQ(k["p"], 1u);
  EXPECT_EQ(k["resolution"], 1u);

  const std::string bad = (scratch_dir() / "bad.nff").string();
  {
    auto w = NffWriter::create(bad);
    ASSERT_TRUE(w.is_ok());
    (*w)->sphere({0, std::nan(""), 0}, 1.0);
    EXPECT_FALSE((*w)->finish().is_ok());
  }
  EXPECT_FALSE(fs::exists(bad));
  EXPECT_FALSE(fs::exists(bad + ".tmp"));
}

}  // namespace
// --speed: the eye moves that many metres per frame (along the orbit's circle, along the fly's
// loop) whatever --frames is, going round again when the frames outlast a loop; without it one
// loop is spread over the frames. A bad speed fails with the option named.
TEST_F(DataGen, OrbitAndFlyPathsKeepTheirSpeed) {
  const Aabb b = jb(side_->at("bounds"));
  const double speed = 0.01 * glm::length(b.extent());
  auto path = [&](const std::string& name, std::vector<std::string> args) {
    const std::string out = (scratch_dir() / name).string();
    args.insert(args.begin(), {"path", "--model", ply_});
    args.insert(args.end(), {"-o", out});
    const auto r = run_gen(args);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    auto cams = read_camera_path(out);
    EXPECT_TRUE(cams.is_ok());
    return cams.is_ok() ? *cams : std::vector<Camera>{};
  };
  auto precise = [](double v) {
    std::ostringstream s;
    s.precision(17);
    s << v;
    return s.str();
  };
  for (const std::string kind : {"orbit", "fly"}) {
    const auto slow = path(kind + "_slow.cam", {"--kind", kind, "--frames", "40", "--seed", "3", "--speed", precise(speed)});
    const auto loop = path(kind + "_loop.cam", {"--kind", kind, "--frames", "40", "--seed", "3"});
    ASSERT_EQ(slow.size(), 40u);
    ASSERT_EQ(loop.size(), 40u);
    EXPECT_LT(glm::length(slow.front().eye - loop.front().eye), 1e-5) << kind << ": the same start";
    double slow_total = 0.0, loop_total = 0.0;
    for (size_t i = 1; i < slow.size(); ++i) {
      const double step = glm::length(slow[i].eye - slow[i - 1].eye);
      // A chord of an arc `speed` long: not longer, and on these gentle curves not much shorter.
      EXPECT_LE(step, 1.02 * speed) << kind << " frame " << i;
      EXPECT_GE(step, 0.8 * speed) << kind << " frame " << i;
      slow_total += step;
      loop_total += glm::length(loop[i].eye - loop[i - 1].eye);
    }
    EXPECT_LT(slow_total, 0.5 * loop_total) << kind << ": --speed did not slow the eye";
  }
  // Round again: an orbit at a speed that laps it in 10 frames repeats itself every 10 frames.
  const auto one = path("orbit_one.cam", {"--kind", "orbit", "--frames", "1"});
  ASSERT_EQ(one.size(), 1u);
  const double horizontal = std::hypot(one[0].eye.x - b.center().x, one[0].eye.y - b.center().y);
  ASSERT_GT(horizontal, 0.0);
  const auto lap = path("orbit_lap.cam", {"--kind", "orbit", "--frames", "25", "--speed",
                                           precise(2 * std::numbers::pi * horizontal / 10.0)});
  ASSERT_EQ(lap.size(), 25u);
  for (size_t i = 10; i < lap.size(); ++i) EXPECT_LT(glm::length(lap[i].eye - lap[i - 10].eye), 1e-4) << i;
  const std::string out = (scratch_dir() / "bad_speed.cam").string();
  expect_failure({"path", "--model", ply_, "--kind", "fly", "--frames", "10", "--speed", "0", "-o", out}, 2, "--speed");
  expect_failure({"path", "--model", ply_, "--kind", "orbit", "--frames", "10", "--speed", "-1", "-o", out}, 2,
                 "--speed");
}

}  // namespace frontier
