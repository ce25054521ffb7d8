// Scene readers and load_scene: the SPD scenes, each format's features, and malformed input
// (every truncation and seeded byte garbling must give ok or an error naming the file and a
// line or byte, never a crash). Fixtures are written into a temporary directory by the tests.
#include "src/io/load_scene.h"
#include "src/io/scene_reader.h"
#include "tests/model_read.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <fstream>
#include <random>

namespace frontier {
namespace {

namespace fs = std::filesystem;

// A fresh directory per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "frontier_readers_XXXXXX").string();
    char* made = ::mkdtemp(tmpl.data());
    EXPECT_NE(made, nullptr);
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::string write(const std::string& name, std::string_view bytes) const {
    const std::string p = file(name);
    // Unlink rather than truncate: ext4 flushes a file rewritten through truncation on close,
    // which makes the thousands of fuzz variants slow.
    std::error_code ec;
    fs::remove(p, ec);
    std::ofstream(p, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return p;
  }

 private:
  fs::path path_;
};

using ReadResult = testing::ModelRead;
ReadResult read_all(const std::string& path) { return testing::read_model(path); }

double polygon_area(const std::vector<Vec3>& poly) {
  Vec3 n(0.0);
  for (size_t i = 0; i < poly.size(); ++i) n += glm::cross(poly[i] - poly[0], poly[(i + 1) % poly.size()] - poly[0]);
  return 0.5 * glm::length(n);
}

double scene_triangle_area(const Scene& s) {
  double a = 0.0;
  for (const Triangle& t : s.triangles) a += 0.5 * glm::length(glm::cross(t.v1 - t.v0, t.v2 - t.v0));
  return a;
}

size_t count_kind(const Scene& s, PrimKind k) {
  return static_cast<size_t>(std::count_if(s.prims.begin(), s.prims.end(), [k](const PrimRef& p) { return p.kind == k; }));
}

// ---------------------------------------------------------------------------------------------
// SPD scenes

struct SpdExpectation {
  const char* name;
  uint32_t primitives, spheres, cones, polygons;
  size_t lights;
};

void check_spd(const SpdExpectation& e) {
  const std::string path = std::string(FRONTIER_DATA_DIR "/spd/") + e.name;
  Scene scene;
  const Status s = load_scene(path, scene);
  ASSERT_TRUE(s.is_ok()) << s.to_string();
  EXPECT_EQ(scene.input_primitives, e.primitives);
  EXPECT_EQ(count_kind(scene, PrimKind::Sphere), e.spheres);
  EXPECT_EQ(count_kind(scene, PrimKind::Cone), e.cones);
  EXPECT_EQ(scene.triangles.size(), 2u * e.polygons);  // the SPD ground polygons are quads
  EXPECT_EQ(scene.degenerate_dropped, 0u);
  EXPECT_EQ(scene.lights.size(), e.lights);
  ASSERT_TRUE(scene.camera.has_value());
  EXPECT_DOUBLE_EQ(scene.camera->vfov_deg, 45.0);
  EXPECT_EQ(scene.camera->width, 512);
  EXPECT_EQ(scene.camera->height, 512);
  EXPECT_EQ(scene.background, Vec3(0.078, 0.361, 0.753));
  // Source ids: every input primitive appears, in file order.
  std::vector<int> seen(scene.input_primitives, 0);
  uint32_t last = 0;
  for (const PrimRef& p : scene.prims) {
    ASSERT_LT(p.source, scene.input_primitives);
    ASSERT_GE(p.source, last);
    last = p.source;
    ++seen[p.source];
    ASSERT_LT(p.material, scene.materials.size());
  }
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 0), 0);

  const ReadResult r = read_all(path);
  ASSERT_TRUE(r.status.is_ok());
  EXPECT_EQ(r.prims.size(), e.primitives);
  EXPECT_EQ(static_cast<uint32_t>(std::count_if(r.prims.begin(), r.prims.end(), [](const InputPrimitive& p) {
              return p.kind == InputPrimitive::Kind::Polygon;
            })),
            e.polygons);
  EXPECT_EQ(r.declared, -1);
}

TEST(NffSpd, Rings) {
  check_spd({"rings.nff", 8401, 4200, 4200, 1, 3});
  Scene scene;
  ASSERT_TRUE(load_scene(FRONTIER_DATA_DIR "/spd/rings.nff", scene).is_ok());
  const Camera& c = *scene.camera;
  EXPECT_EQ(c.eye, Vec3(-1, -2.61313, 0.5));
  EXPECT_EQ(c.look_at, Vec3(-1, -1.61313, 0.5));
  EXPECT_EQ(c.up, Vec3(0, 0, 1));
  EXPECT_DOUBLE_EQ(c.near, 1.0);
  EXPECT_EQ(scene.lights[1].position, Vec3(-4, -2.61313, 1));
  EXPECT_EQ(scene.materials.size(), 841u);  // one per `f`
  EXPECT_EQ(scene.materials[0].color, Vec3(1, 1, 1));
  EXPECT_DOUBLE_EQ(scene.materials[0].shine, 100000);
  EXPECT_EQ(scene.materials[1].color, Vec3(1, 0, 0));
  EXPECT_DOUBLE_EQ(scene.materials[1].kd, 0.5);
  EXPECT_DOUBLE_EQ(scene.materials[1].ks, 0.2);
  // The ground quad comes first and uses material 0; the first cone material 1.
  EXPECT_EQ(scene.prims[0].kind, PrimKind::Triangle);
  EXPECT_EQ(scene.prims[0].material, 0u);
  EXPECT_EQ(scene.prims[2].kind, PrimKind::Cone);
  EXPECT_EQ(scene.prims[2].source, 1u);
  EXPECT_EQ(scene.prims[2].material, 1u);
}

TEST(NffSpd, Tree) {
  check_spd({"tree.nff", 8191, 4095, 4095, 1, 7});
  Scene scene;
  ASSERT_TRUE(load_scene(FRONTIER_DATA_DIR "/spd/tree.nff", scene).is_ok());
  EXPECT_EQ(scene.camera->eye, Vec3(4.5, 0.4, 2));
  EXPECT_EQ(scene.materials.size(), 2u);
}

TEST(NffSpd, Shells) {
  check_spd({"shells.nff", 5761, 5761, 0, 0, 1});
  Scene scene;
  ASSERT_TRUE(load_scene(FRONTIER_DATA_DIR "/spd/shells.nff", scene).is_ok());
  EXPECT_DOUBLE_EQ(scene.camera->near, 0.5);
  ASSERT_EQ(scene.materials.size(), 1u);
  EXPECT_DOUBLE_EQ(scene.materials[0].ior, 1.0);
  EXPECT_DOUBLE_EQ(scene.materials[0].shine, 45.2776);
}

// ---------------------------------------------------------------------------------------------
// NFF features

TEST(NffReader, ConeAcrossLinesAndSphere) {
  TempDir dir;
  const auto path = dir.write("cone.nff", "f 1 0 0 1 0 1 0 1\nc 0 0 0 1\n 0 0 2\n 0.5\ns 1 2 3 4\n");
  const ReadResult r = read_all(path);
  ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
  ASSERT_EQ(r.prims.size(), 2u);
  EXPECT_EQ(r.prims[0].kind, InputPrimitive::Kind::Cone);
  EXPECT_EQ(r.prims[0].cone.base, Vec3(0, 0, 0));
  EXPECT_EQ(r.prims[0].cone.base_radius, 1.0);
  EXPECT_EQ(r.prims[0].cone.apex, Vec3(0, 0, 2));
  EXPECT_EQ(r.prims[0].cone.apex_radius, 0.5);
  EXPECT_EQ(r.prims[1].kind, InputPrimitive::Kind::Sphere);
  EXPECT_EQ(r.prims[1].sphere.center, Vec3(1, 2, 3));
  EXPECT_EQ(r.prims[1].sphere.radius, 4.0);
  EXPECT_FALSE(r.header.camera.has_value());
}

TEST(NffReader, PatchNormalsReachTheScene) {
  TempDir dir;
  const auto path = dir.write("patch.nff",
                              "pp 4\n0 0 0  0 0 1\n1 0 0  0 0.6 0.8\n1 1 0  0 0.8 0.6\n0 1 0  0 0 1\n");
  const ReadResult r = read_all(path);
  ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
  ASSERT_EQ(r.prims.size(), 1u);
  ASSERT_EQ(r.prims[0].normals.size(), 4u);
  EXPECT_EQ(r.prims[0].normals[1], Vec3(0, 0.6, 0.8));
  Scene scene;
  ASSERT_TRUE(load_scene(path, scene).is_ok());
  ASSERT_EQ(scene.triangles.size(), 2u);
  ASSERT_EQ(scene.triangle_normals.size(), 2u);
  // Each triangle vertex carries the normal of the polygon vertex at the same position.
  for (size_t t = 0; t < 2; ++t) {
    const Triangle& tri = scene.triangles[t];
    const Vec3* v[3] = {&tri.v0, &tri.v1, &tri.v2};
    for (int k = 0; k < 3; ++k) {
      const auto it = std::find(r.prims[0].vertices.begin(), r.prims[0].vertices.end(), *v[k]);
      ASSERT_NE(it, r.prims[0].vertices.end());
      EXPECT_EQ(scene.triangle_normals[t][k], r.prims[0].normals[it - r.prims[0].vertices.begin()]);
    }
  }
}

TEST(NffReader, ConcaveStarIsTriangulatedInside) {
  TempDir dir;
  std::string text = "p 10\n";
  std::vector<Vec3> star;
  for (int i = 0; i < 10; ++i) {
    const double a = std::numbers::pi * i / 5, r = i % 2 == 0 ? 2.0 : 0.7;
    star.emplace_back(r * std::cos(a), 5.0, r * std::sin(a));
    text += fmt::format("{:.17g} {:.17g} {:.17g}\n", star.back().x, star.back().y, star.back().z);
  }
  const auto path = dir.write("star.nff", text);
  Scene scene;
  ASSERT_TRUE(load_scene(path, scene).is_ok());
  ASSERT_EQ(scene.triangles.size(), 8u);
  EXPECT_EQ(scene.input_primitives, 1u);
  EXPECT_NEAR(scene_triangle_area(scene), polygon_area(star), 1e-12);
  for (const PrimRef& p : scene.prims) EXPECT_EQ(p.source, 0u);
  // A fan from vertex 0 would cover points outside the star: check every centroid is inside.
  for (const Triangle& t : scene.triangles) {
    const Vec3 c = (t.v0 + t.v1 + t.v2) / 3.0;
    bool in = false;
    for (size_t i = 0, j = star.size() - 1; i < star.size(); j = i++) {
      if ((star[i].z > c.z) != (star[j].z > c.z) &&
          c.x < star[i].x + (c.z - star[i].z) / (star[j].z - star[i].z) * (star[j].x - star[i].x)) {
        in = !in;
      }
    }
    EXPECT_TRUE(in);
  }
}

TEST(NffReader, LightsWithAndWithoutColour) {
  TempDir dir;
  const auto path = dir.write("lights.nff", "l 1 2 3\nl 4 5 6 0.5 0.25 0.125\nl 7 8 9\ns 0 0 0 1\nl 1 1 1 1 1 0\n");
  const ReadResult r = read_all(path);
  ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
  ASSERT_EQ(r.header.lights.size(), 4u);
  EXPECT_EQ(r.header.lights[0].position, Vec3(1, 2, 3));
  EXPECT_EQ(r.header.lights[0].color, Vec3(1, 1, 1));
  EXPECT_EQ(r.header.lights[1].color, Vec3(0.5, 0.25, 0.125));
  EXPECT_EQ(r.header.lights[2].position, Vec3(7, 8, 9));
  EXPECT_EQ(r.header.lights[3].color, Vec3(1, 1, 0));
  EXPECT_EQ(r.prims.size(), 1u);
}

TEST(NffReader, CameraKeywords) {
  TempDir dir;
  const auto path = dir.write("cam.nff",
                              "b 0.1 0.2 0.3\r\nv\r\nfrom 1 2 3\r\nat 4 5 6\r\nup 0 1 0\r\n"
                              "angle 30\r\nhither 0.01\r\nresolution 640 480\r\n# comment\r\n\ts\t0 0 0 1\r\n");
  const ReadResult r = read_all(path);
  ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
  ASSERT_TRUE(r.header.camera.has_value());
  EXPECT_EQ(r.header.camera->eye, Vec3(1, 2, 3));
  EXPECT_EQ(r.header.camera->look_at, Vec3(4, 5, 6));
  EXPECT_EQ(r.header.camera->up, Vec3(0, 1, 0));
  EXPECT_EQ(r.header.camera->vfov_deg, 30.0);
  EXPECT_EQ(r.header.camera->near, 0.01);
  EXPECT_EQ(r.header.camera->width, 640);
  EXPECT_EQ(r.header.camera->height, 480);
  EXPECT_EQ(r.header.background, Vec3(0.1, 0.2, 0.3));
  EXPECT_EQ(r.prims.size(), 1u);
}

TEST(NffReader, DefaultMaterialBeforeAnyF) {
  TempDir dir;
  const auto path = dir.write("mat.nff", "s 0 0 0 1\nf 1 0 0 1 0 1 0 1\ns 1 0 0 1\nf 0 1 0 1 0 1 0 1\ns 2 0 0 1\n");
  Scene scene;
  ASSERT_TRUE(load_scene(path, scene).is_ok());
  ASSERT_EQ(scene.materials.size(), 3u);  // the default, then the two `f`s
  ASSERT_EQ(scene.prims.size(), 3u);
  EXPECT_EQ(scene.prims[0].material, 0u);
  EXPECT_EQ(scene.prims[1].material, 1u);
  EXPECT_EQ(scene.prims[2].material, 2u);
  EXPECT_EQ(scene.materials[2].color, Vec3(0, 1, 0));
}

TEST(NffReader, UnknownKeywordNamesTheLine) {
  TempDir dir;
  const auto path = dir.write("bad.nff", "s 0 0 0 1\n\n# fine\nsphere 1 2 3 4\n");
  Scene scene;
  const Status s = load_scene(path, scene);
  ASSERT_FALSE(s.is_ok());
  EXPECT_NE(s.message().find("bad.nff: line 4:"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("sphere"), std::string::npos) << s.message();
}

TEST(NffReader, BadNumbersNameTheirLine) {
  TempDir dir;
  struct Case {
    const char* text;
    const char* expect;
  };
  const Case cases[] = {
      {"s 0 0 0 1\ns 0 nan 0 1\n", "line 2: sphere centre is not finite"},
      {"p 3\n0 0 0\n1 0 0\n0 inf 0\n", "line 4: vertex coordinate is not finite"},
      {"p 3\n0 0 0\n1 0 0\n", "unexpected end of file"},
      {"p 2\n0 0 0\n1 0 0\n", "line 1: polygon has 2 vertices"},
      {"p 2147483648\n0 0 0\n", "line 1: polygon has 2147483648 vertices (limit"},
      {"c 0 0 0 1\n0 0 x 1\n", "line 2: expected a number (cone apex point), got 'x'"},
      {"s 0 0 0 -1\n", "line 1: sphere radius is negative"},
      {"resolution -5 10\n", "line 1: resolution"},
  };
  for (size_t i = 0; i < std::size(cases); ++i) {
    const auto path = dir.write("num.nff", cases[i].text);
    const ReadResult r = read_all(path);
    ASSERT_FALSE(r.status.is_ok()) << cases[i].text;
    EXPECT_NE(r.status.message().find("num.nff: "), std::string::npos) << r.status.message();
    EXPECT_NE(r.status.message().find(cases[i].expect), std::string::npos) << r.status.message();
  }
}

// ---------------------------------------------------------------------------------------------
// PLY writer for fixtures: ascii and both binary byte orders from the same description.

enum class PlyFormat { Ascii, LittleEndian, BigEndian };

struct TestProp {
  std::string type;
  std::string name;
  std::string count_type;  // empty: a scalar
};

struct TestElement {
  std::string name;
  std::vector<TestProp> props;
  // records[r][p] holds the values of property p (one for a scalar).
  std::vector<std::vector<std::vector<double>>> records;
};

void put_binary(std::string& out, const std::string& type, double v, bool big) {
  char bytes[8];
  size_t n = 0;
  const auto store = [&](auto x) {
    n = sizeof(x);
    std::memcpy(bytes, &x, n);
  };
  if (type == "char" || type == "int8") store(static_cast<int8_t>(v));
  else if (type == "uchar" || type == "uint8") store(static_cast<uint8_t>(v));
  else if (type == "short" || type == "int16") store(static_cast<int16_t>(v));
  else if (type == "ushort" || type == "uint16") store(static_cast<uint16_t>(v));
  else if (type == "int" || type == "int32") store(static_cast<int32_t>(v));
  else if (type == "uint" || type == "uint32") store(static_cast<uint32_t>(static_cast<int64_t>(v)));
  else if (type == "float" || type == "float32") store(static_cast<float>(v));
  else store(v);
  if (big == (std::endian::native == std::endian::little)) std::reverse(bytes, bytes + n);
  out.append(bytes, n);
}

std::string write_ply(PlyFormat format, const std::vector<TestElement>& elements,
                      const std::string& extra_header = "") {
  std::string out = "ply\n";
  out += format == PlyFormat::Ascii ? "format ascii 1.0\n"
         : format == PlyFormat::LittleEndian ? "format binary_little_endian 1.0\n"
                                             : "format binary_big_endian 1.0\n";
  out += "comment written by test_readers\nobj_info nothing\n" + extra_header;
  for (const TestElement& e : elements) {
    out += fmt::format("element {} {}\n", e.name, e.records.size());
    for (const TestProp& p : e.props) {
      if (p.count_type.empty()) {
        out += fmt::format("property {} {}\n", p.type, p.name);
      } else {
        out += fmt::format("property list {} {} {}\n", p.count_type, p.type, p.name);
      }
    }
  }
  out += "end_header\n";
  for (const TestElement& e : elements) {
    for (const auto& rec : e.records) {
      for (size_t k = 0; k < e.props.size(); ++k) {
        const TestProp& p = e.props[k];
        if (format == PlyFormat::Ascii) {
          if (!p.count_type.empty()) out += fmt::format("{} ", rec[k].size());
          for (double v : rec[k]) out += fmt::format("{:.17g} ", v);
        } else {
          if (!p.count_type.empty()) put_binary(out, p.count_type, static_cast<double>(rec[k].size()), format == PlyFormat::BigEndian);
          for (double v : rec[k]) put_binary(out, p.type, v, format == PlyFormat::BigEndian);
        }
      }
      if (format == PlyFormat::Ascii) out += "\n";
    }
  }
  return out;
}

const std::vector<Vec3> kMeshVertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                         {0.5, 1.5, 0}, {2, 0, 0.25}, {2, 1, -0.5}, {3, 0.5, 1}};
const std::vector<std::vector<int>> kMeshFaces = {{1, 5, 6}, {0, 1, 2, 3}, {0, 1, 2, 4, 3}, {5, 7, 6}};

// The small mesh with extra vertex and face properties (scalars and lists) to be skipped.
std::vector<TestElement> small_mesh(const std::string& coord_type = "float",
                                    const std::string& count_type = "uchar",
                                    const std::string& index_type = "int") {
  TestElement v{"vertex",
                {{"uchar", "red", ""}, {coord_type, "x", ""}, {coord_type, "y", ""}, {"short", "extra", "uchar"},
                 {coord_type, "z", ""}, {"float", "confidence", ""}},
                {}};
  for (size_t i = 0; i < kMeshVertices.size(); ++i) {
    const Vec3& p = kMeshVertices[i];
    v.records.push_back({{200.0}, {p.x}, {p.y}, std::vector<double>(i % 3, 7.0), {p.z}, {0.5}});
  }
  TestElement f{"face", {{"uchar", "flags", ""}, {index_type, "vertex_indices", count_type}, {"float", "texcoord", "uchar"}}, {}};
  for (const auto& face : kMeshFaces) {
    std::vector<double> idx(face.begin(), face.end());
    f.records.push_back({{3.0}, idx, std::vector<double>(2 * face.size(), 0.25)});
  }
  TestElement other{"material", {{"float", "shine", ""}, {"int", "names", "int"}}, {{{1.0}, {1, 2, 3}}, {{2.0}, {}}}};
  return {v, other, f};
}

void expect_mesh(const ReadResult& r) {
  ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
  ASSERT_EQ(r.prims.size(), kMeshFaces.size());
  for (size_t i = 0; i < kMeshFaces.size(); ++i) {
    ASSERT_EQ(r.prims[i].vertices.size(), kMeshFaces[i].size());
    for (size_t k = 0; k < kMeshFaces[i].size(); ++k) EXPECT_EQ(r.prims[i].vertices[k], kMeshVertices[kMeshFaces[i][k]]);
    EXPECT_TRUE(r.prims[i].normals.empty());
    EXPECT_EQ(r.prims[i].material, 0u);
  }
  EXPECT_EQ(r.declared, static_cast<int64_t>(kMeshFaces.size()));
  EXPECT_EQ(r.header.materials.size(), 1u);
}

TEST(PlyReader, AsciiAndBothBinaryOrdersAgree) {
  TempDir dir;
  const auto mesh = small_mesh();
  const ReadResult a = read_all(dir.write("a.ply", write_ply(PlyFormat::Ascii, mesh)));
  const ReadResult le = read_all(dir.write("le.ply", write_ply(PlyFormat::LittleEndian, mesh)));
  const ReadResult be = read_all(dir.write("be.ply", write_ply(PlyFormat::BigEndian, mesh)));
  expect_mesh(a);
  expect_mesh(le);
  expect_mesh(be);
  Scene sa, sle, sbe;
  ASSERT_TRUE(load_scene(dir.file("a.ply"), sa).is_ok());
  ASSERT_TRUE(load_scene(dir.file("le.ply"), sle).is_ok());
  ASSERT_TRUE(load_scene(dir.file("be.ply"), sbe).is_ok());
  // 1 + 2 + 3 + 1 triangles, sources 0 1 1 2 2 2 3.
  ASSERT_EQ(sa.triangles.size(), 7u);
  EXPECT_EQ(sa.input_primitives, 4u);
  const uint32_t sources[] = {0, 1, 1, 2, 2, 2, 3};
  for (size_t i = 0; i < 7; ++i) {
    EXPECT_EQ(sa.prims[i].source, sources[i]);
    EXPECT_EQ(sa.triangles[i].v0, sle.triangles[i].v0);
    EXPECT_EQ(sa.triangles[i].v2, sbe.triangles[i].v2);
  }
}

TEST(PlyReader, CoordinateAndIndexTypes) {
  TempDir dir;
  for (const char* coord : {"float", "double", "float64", "float32", "int", "short"}) {
    for (const char* count : {"uchar", "int", "uint8", "ushort"}) {
      for (const char* index : {"int", "uint", "uchar", "int32", "ushort"}) {
        for (PlyFormat f : {PlyFormat::Ascii, PlyFormat::LittleEndian, PlyFormat::BigEndian}) {
          std::vector<TestElement> mesh = small_mesh(coord, count, index);
          // Integer coordinate types cannot hold 0.5: scale the mesh up for them.
          const bool integral = std::string(coord) == "int" || std::string(coord) == "short";
          if (integral) {
            for (auto& rec : mesh[0].records) {
              for (int k : {1, 2, 4}) rec[k][0] *= 4;
            }
          }
          const ReadResult r = read_all(dir.write("t.ply", write_ply(f, mesh)));
          ASSERT_TRUE(r.status.is_ok()) << coord << " " << count << " " << index << ": " << r.status.to_string();
          ASSERT_EQ(r.prims.size(), kMeshFaces.size());
          EXPECT_EQ(r.prims[2].vertices[3], kMeshVertices[4] * (integral ? 4.0 : 1.0)) << coord << " " << index;
        }
      }
    }
  }
}

TEST(PlyReader, NormalsArePassedPerVertex) {
  TempDir dir;
  TestElement v{"vertex", {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}, {"float", "nx", ""}, {"float", "ny", ""}, {"float", "nz", ""}}, {}};
  for (int i = 0; i < 4; ++i) v.records.push_back({{double(i % 2)}, {double(i / 2)}, {0.0}, {0.0}, {0.6}, {0.8 + i}});
  TestElement f{"face", {{"int", "vertex_index", "uchar"}}, {{{0, 1, 3, 2}}}};
  for (PlyFormat fm : {PlyFormat::Ascii, PlyFormat::LittleEndian, PlyFormat::BigEndian}) {
    const auto path = dir.write("n.ply", write_ply(fm, {v, f}));
    const ReadResult r = read_all(path);
    ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
    ASSERT_EQ(r.prims.size(), 1u);
    ASSERT_EQ(r.prims[0].normals.size(), 4u);
    EXPECT_NEAR(r.prims[0].normals[2].z, 3.8, 1e-6);  // vertex 3
    Scene scene;
    ASSERT_TRUE(load_scene(path, scene).is_ok());
    EXPECT_EQ(scene.triangle_normals.size(), 2u);
  }
}

TEST(PlyReader, TriangleStripsWithRestarts) {
  TempDir dir;
  TestElement v{"vertex", {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}}, {}};
  for (int i = 0; i < 8; ++i) v.records.push_back({{double(i / 2)}, {double(i % 2)}, {0.0}});
  // Strip 0 1 2 3 4 | 5 6 7, and a stitching triangle (repeated 4) that must not appear.
  TestElement s{"tristrips", {{"int", "vertex_indices", "int"}}, {{{0, 1, 2, 3, 4, 4, -1, 5, 6, 7}}}};
  for (PlyFormat fm : {PlyFormat::Ascii, PlyFormat::LittleEndian, PlyFormat::BigEndian}) {
    const ReadResult r = read_all(dir.write("s.ply", write_ply(fm, {v, s})));
    ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
    EXPECT_EQ(r.declared, -1);
    const std::vector<std::array<int, 3>> expected = {{0, 1, 2}, {2, 1, 3}, {2, 3, 4}, {5, 6, 7}};
    ASSERT_EQ(r.prims.size(), expected.size());
    for (size_t t = 0; t < expected.size(); ++t) {
      ASSERT_EQ(r.prims[t].vertices.size(), 3u);
      for (int k = 0; k < 3; ++k) {
        const Vec3 want(double(expected[t][k] / 2), double(expected[t][k] % 2), 0.0);
        EXPECT_EQ(r.prims[t].vertices[k], want) << "triangle " << t;
      }
    }
    // Alternating winding keeps the triangles of one strip facing the same way.
    const auto nz = [&](size_t t) {
      const auto& p = r.prims[t].vertices;
      return glm::cross(p[1] - p[0], p[2] - p[0]).z;
    };
    EXPECT_LT(nz(0), 0.0);
    EXPECT_LT(nz(1), 0.0);
    EXPECT_LT(nz(2), 0.0);
  }
}

TEST(PlyReader, QuadsAndPentagonsAreTriangulated) {
  TempDir dir;
  Scene scene;
  ASSERT_TRUE(load_scene(dir.write("q.ply", write_ply(PlyFormat::LittleEndian, small_mesh())), scene).is_ok());
  double expected = 0.0;
  for (const auto& face : kMeshFaces) {
    std::vector<Vec3> poly;
    for (int i : face) poly.push_back(kMeshVertices[i]);
    expected += polygon_area(poly);
  }
  // The unit square and the house-shaped pentagon have known areas.
  EXPECT_NEAR(polygon_area({kMeshVertices[0], kMeshVertices[1], kMeshVertices[2], kMeshVertices[3]}), 1.0, 1e-15);
  EXPECT_NEAR(polygon_area({kMeshVertices[0], kMeshVertices[1], kMeshVertices[2], kMeshVertices[4], kMeshVertices[3]}), 1.25, 1e-15);
  EXPECT_EQ(scene.triangles.size(), 1u + 2 + 3 + 1);
  EXPECT_NEAR(scene_triangle_area(scene), expected, 1e-12);
}

TEST(PlyReader, OutOfRangeIndicesAndNonFiniteCoordinates) {
  TempDir dir;
  {
    auto mesh = small_mesh();
    mesh[2].records[1][1][2] = 99;
    const ReadResult a = read_all(dir.write("model.ply", write_ply(PlyFormat::Ascii, mesh)));
    ASSERT_FALSE(a.status.is_ok());
    EXPECT_NE(a.status.message().find("model.ply: line 31: face index 99 out of range (8 vertices)"), std::string::npos)
        << a.status.message();
    const ReadResult b = read_all(dir.write("model.ply", write_ply(PlyFormat::BigEndian, mesh)));
    ASSERT_FALSE(b.status.is_ok());
    EXPECT_NE(b.status.message().find("model.ply: byte "), std::string::npos) << b.status.message();
    EXPECT_NE(b.status.message().find("face index 99 out of range (8 vertices)"), std::string::npos);
  }
  {
    auto mesh = small_mesh("double");
    mesh[0].records[5][2][0] = std::numeric_limits<double>::quiet_NaN();
    const ReadResult a = read_all(dir.write("nan.ply", write_ply(PlyFormat::Ascii, mesh)));
    ASSERT_FALSE(a.status.is_ok());
    EXPECT_NE(a.status.message().find("nan.ply: line 25: coordinate is not finite"), std::string::npos)
        << a.status.message();
    for (PlyFormat f : {PlyFormat::LittleEndian, PlyFormat::BigEndian}) {
      const ReadResult b = read_all(dir.write("nan.ply", write_ply(f, mesh)));
      ASSERT_FALSE(b.status.is_ok());
      EXPECT_NE(b.status.message().find("nan.ply: byte "), std::string::npos) << b.status.message();
      EXPECT_NE(b.status.message().find("vertex 5 coordinate is not finite"), std::string::npos) << b.status.message();
    }
  }
}

TEST(PlyReader, AbsurdCountsAreErrorsNotAllocations) {
  TempDir dir;
  // A face list claiming 2^31 vertices, an element claiming 10^15 records, a negative count.
  std::string body;
  put_binary(body, "float", 0, false);
  put_binary(body, "float", 0, false);
  put_binary(body, "float", 0, false);
  put_binary(body, "int", 2147483647.0, false);
  put_binary(body, "int", 0, false);
  const std::string header = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
                             "property float y\nproperty float z\nelement face 1\n"
                             "property list int int vertex_indices\nend_header\n";
  ReadResult r = read_all(dir.write("big.ply", header + body));
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_NE(r.status.message().find("byte "), std::string::npos) << r.status.message();
  EXPECT_NE(r.status.message().find("2147483647 vertices"), std::string::npos) << r.status.message();

  r = read_all(dir.write("huge.ply", "ply\nformat ascii 1.0\nelement vertex 1000000000000000\nproperty float x\n"
                                     "property float y\nproperty float z\nend_header\n0 0 0\n"));
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_NE(r.status.message().find("huge.ply: line 3:"), std::string::npos) << r.status.message();

  r = read_all(dir.write("neg.ply", "ply\nformat ascii 1.0\nelement vertex -3\nproperty float x\nend_header\n"));
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_NE(r.status.message().find("neg.ply: line 3: element vertex has a negative count"), std::string::npos)
      << r.status.message();
}

TEST(PlyReader, HeaderErrors) {
  TempDir dir;
  struct Case {
    std::string text;
    const char* expect;
  };
  const Case cases[] = {
      {"plx\n", "line 1: not a PLY file"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n",
       "line 3: vertex element lacks x, y or z"},
      {"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
       "element face 0\nproperty int foo\nend_header\n",
       "line 7: face element has no vertex_indices list"},
      {"ply\nformat ascii 1.0\nelement vertex 0\nproperty fluffy x\nend_header\n", "line 4: unknown type 'fluffy'"},
      {"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n", "line 4: unexpected end of file (expected end_header)"},
      {"ply\nelement vertex 0\nend_header\n", "line 3: header has no format line"},
      {"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n"
       "element vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n3 0 1 2\n0 0 0\n1 0 0\n0 1 0\n",
       "line 3: element face comes before the vertex element"},
  };
  for (const Case& c : cases) {
    const ReadResult r = read_all(dir.write("h.ply", c.text));
    ASSERT_FALSE(r.status.is_ok()) << c.text;
    EXPECT_NE(r.status.message().find(std::string("h.ply: ") + c.expect), std::string::npos) << r.status.message();
  }
}

TEST(PlyReader, FaceWithTwoVerticesIsAnError) {
  TempDir dir;
  auto mesh = small_mesh();
  mesh[2].records[3][1] = {5, 7};
  const ReadResult r = read_all(dir.write("two.ply", write_ply(PlyFormat::LittleEndian, mesh)));
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_NE(r.status.message().find("face has 2 vertices"), std::string::npos) << r.status.message();
  EXPECT_EQ(r.prims.size(), 3u);
}

TEST(PlyReader, CrlfHeaderAndEmptyMesh) {
  TempDir dir;
  const ReadResult r = read_all(dir.write("crlf.ply", "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty float x\r\n"
                                                      "property float y\r\nproperty float z\r\nelement face 1\r\n"
                                                      "property list uchar int vertex_indices\r\nend_header\r\n"
                                                      "0 0 0\r\n1 0 0\r\n0 1 0\r\n3 0 1 2\r\n"));
  ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
  EXPECT_EQ(r.prims.size(), 1u);
  const ReadResult e = read_all(dir.write("empty.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 0\n"
                                                       "property float x\nproperty float y\nproperty float z\n"
                                                       "element face 0\nproperty list uchar int vertex_indices\nend_header\n"));
  ASSERT_TRUE(e.status.is_ok()) << e.status.to_string();
  EXPECT_TRUE(e.prims.empty());
  EXPECT_EQ(e.declared, 0);
}

// ---------------------------------------------------------------------------------------------
// OBJ

TEST(ObjReader, IndexFormsNegativeIndicesAndNgons) {
  TempDir dir;
  const auto path = dir.write("m.obj",
                              "# a comment\r\n"
                              "mtllib m.mtl\r\n"
                              "o thing\r\n"
                              "v 0 0 0\r\nv 1 0 0\r\nv\t1 1 0\r\nv 0 1 0 1.0\r\n"
                              "vt 0 0\r\nvt 1 0\r\nvt 1 1\r\n"
                              "vn 0 0 1\r\nvn 0 0.6 0.8\r\n"
                              "g group\r\nusemtl red\r\ns off\r\n"
                              "f 1 2 3\r\n"
                              "f 1/1 2/2 3/3 4/1\r\n"
                              "f 1//1 2//2 3//1\r\n"
                              "f\t-4/-3/-2\t-3/-2/-1 -2/-1/-2 \\\r\n -1/1/1\r\n"
                              "f 1//1 2 3\r\n"
                              "l 1 2\r\np 3\r\n"
                              "v 5 5 5\r\nv 6 5 5\r\nv 5 6 5\r\nv 6 6 5\r\nv 5.5 7 5\r\n"
                              "f -5 -4 -2 -1 -3 # a pentagon with relative indices\r\n");
  const ReadResult r = read_all(path);
  ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
  ASSERT_EQ(r.prims.size(), 6u);
  EXPECT_EQ(r.prims[0].vertices, (std::vector<Vec3>{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}}));
  EXPECT_EQ(r.prims[1].vertices.size(), 4u);
  EXPECT_TRUE(r.prims[1].normals.empty());
  ASSERT_EQ(r.prims[2].normals.size(), 3u);
  EXPECT_EQ(r.prims[2].normals[1], Vec3(0, 0.6, 0.8));
  ASSERT_EQ(r.prims[3].vertices.size(), 4u);  // continued across a line
  EXPECT_EQ(r.prims[3].vertices[0], Vec3(0, 0, 0));
  EXPECT_EQ(r.prims[3].vertices[3], Vec3(0, 1, 0));
  ASSERT_EQ(r.prims[3].normals.size(), 4u);
  EXPECT_EQ(r.prims[3].normals[1], Vec3(0, 0.6, 0.8));
  EXPECT_TRUE(r.prims[4].normals.empty());  // only some vertices have normals
  ASSERT_EQ(r.prims[5].vertices.size(), 5u);
  EXPECT_EQ(r.prims[5].vertices[0], Vec3(5, 5, 5));
  EXPECT_EQ(r.prims[5].vertices[3], Vec3(5.5, 7, 5));
  EXPECT_EQ(r.declared, -1);
  Scene scene;
  ASSERT_TRUE(load_scene(path, scene).is_ok());
  EXPECT_EQ(scene.input_primitives, 6u);
  EXPECT_EQ(scene.triangles.size(), 1u + 2 + 1 + 2 + 1 + 3);
}

TEST(ObjReader, Errors) {
  TempDir dir;
  struct Case {
    const char* text;
    const char* expect;
  };
  const Case cases[] = {
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "model.obj: line 4: face index 4 out of range (3 vertices)"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "model.obj: line 4: face index 0 out of range"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", "model.obj: line 4: face index -4 out of range"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//2 2 3\n", "model.obj: line 4: normal index 2 out of range (0 normals)"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "model.obj: line 4: face has 2 vertices"},
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "model.obj: line 4: bad face vertex 'x'"},
      {"v 0 0 0\n\n\n\n\n\nv 1 nan 0\n", "model.obj: line 7: coordinate is not finite"},
      {"v 0 0 0\nv 1 0\n", "model.obj: line 2: line ends before coordinate"},
      {"v 0 0 0\nbogus 1 2\n", "model.obj: line 2: unknown statement 'bogus'"},
  };
  for (const Case& c : cases) {
    const ReadResult r = read_all(dir.write("model.obj", c.text));
    ASSERT_FALSE(r.status.is_ok()) << c.text;
    EXPECT_NE(r.status.message().find(c.expect), std::string::npos) << r.status.message();
  }
}

// ---------------------------------------------------------------------------------------------
// OFF

TEST(OffReader, BasicCube) {
  TempDir dir;
  const auto path = dir.write("cube.off",
                              "OFF\n# a cube\n8 6 12\n"
                              "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
                              "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n");
  const ReadResult r = read_all(path);
  ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
  EXPECT_EQ(r.declared, 6);
  ASSERT_EQ(r.prims.size(), 6u);
  EXPECT_EQ(r.prims[1].vertices[2], Vec3(1, 1, 1));
  Scene scene;
  ASSERT_TRUE(load_scene(path, scene).is_ok());
  EXPECT_EQ(scene.triangles.size(), 12u);
  EXPECT_NEAR(scene_triangle_area(scene), 6.0, 1e-12);
}

TEST(OffReader, ColoursNormalsAndCountsOnTheHeaderLine) {
  TempDir dir;
  const ReadResult c = read_all(dir.write("c.off",
                                          "COFF 4 2 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n"
                                          "0 1 0 9 9 9 255\n3 0 1 2 1.0 0.0 0.0\n3 0 2 3 0 255 0 # face colour\n"));
  ASSERT_TRUE(c.status.is_ok()) << c.status.to_string();
  ASSERT_EQ(c.prims.size(), 2u);
  EXPECT_EQ(c.prims[1].vertices[2], Vec3(0, 1, 0));
  const ReadResult n = read_all(dir.write("n.off", "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 1 0\n0 1 0 1 0 0\n3 0 1 2\n"));
  ASSERT_TRUE(n.status.is_ok()) << n.status.to_string();
  ASSERT_EQ(n.prims[0].normals.size(), 3u);
  EXPECT_EQ(n.prims[0].normals[2], Vec3(1, 0, 0));
}

TEST(OffReader, Errors) {
  TempDir dir;
  struct Case {
    const char* text;
    const char* expect;
  };
  const Case cases[] = {
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "m.off: line 6: face index 3 out of range (3 vertices)"},
      {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n", "m.off: line 5: unexpected end of file"},
      {"OFF\n3 -1 0\n", "m.off: line 2: negative count"},
      {"OFF\n3000000000 1 0\n", "m.off: line 2: counts"},
      {"OFF\n3 1 0\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n", "m.off: line 4: coordinate is not finite"},
      {"PLY\n", "m.off: line 1: not an OFF file"},
      {"", "m.off: line 1: unexpected end of file"},
  };
  for (const Case& c : cases) {
    const ReadResult r = read_all(dir.write("m.off", c.text));
    ASSERT_FALSE(r.status.is_ok()) << c.text;
    EXPECT_NE(r.status.message().find(c.expect), std::string::npos) << r.status.message();
  }
}

// ---------------------------------------------------------------------------------------------
// load_scene and the reader front end

TEST(ReaderLoadScene, DegenerateTrianglesAreDroppedAndCounted) {
  TempDir dir;
  const auto path = dir.write("deg.off",
                              "OFF\n5 5 0\n0 0 0\n1 0 0\n0 1 0\n2 0 0\n1e-9 1e10 0\n"
                              "3 0 1 2\n3 0 1 3\n3 1 1 2\n4 0 1 3 2\n3 0 1 4\n");
  Scene scene;
  const Status s = load_scene(path, scene);
  ASSERT_TRUE(s.is_ok()) << s.to_string();
  EXPECT_EQ(scene.input_primitives, 5u);
  // Face 1 is collinear, face 2 repeats a vertex: both dropped. Face 3 is a quad with a
  // vertex on an edge, which ear clipping splits into two proper triangles. Face 4 is 1e10
  // long and 1 wide: relative area 1e-10, above the 1e-14 cut, so it stays.
  EXPECT_EQ(scene.degenerate_dropped, 2u);
  std::vector<uint32_t> sources;
  for (const PrimRef& p : scene.prims) sources.push_back(p.source);
  EXPECT_EQ(sources, (std::vector<uint32_t>{0, 3, 3, 4}));
}

TEST(ReaderLoadScene, NeedleBelowRelativeAreaIsDropped) {
  TempDir dir;
  const auto path = dir.write("needle.nff", "p 3\n0 0 0\n1e8 0 0\n0 1e-8 0\np 3\n0 0 0\n1 0 0\n0 1 0\n");
  Scene scene;
  ASSERT_TRUE(load_scene(path, scene).is_ok());
  EXPECT_EQ(scene.degenerate_dropped, 1u);
  ASSERT_EQ(scene.prims.size(), 1u);
  EXPECT_EQ(scene.prims[0].source, 1u);
  EXPECT_EQ(scene.input_primitives, 2u);
}

TEST(ReaderOpen, ExtensionsAndMissingFiles) {
  TempDir dir;
  const auto upper = dir.write("UPPER.NFF", "s 0 0 0 1\n");
  Scene scene;
  EXPECT_TRUE(load_scene(upper, scene).is_ok());
  EXPECT_EQ(scene.spheres.size(), 1u);
  const Status unknown = load_scene(dir.write("x.stp", "solid"), scene);
  EXPECT_EQ(unknown.code(), Status::Code::Unsupported);
  EXPECT_NE(unknown.message().find("x.stp"), std::string::npos);
  const Status missing = load_scene(dir.file("missing.ply"), scene);
  EXPECT_EQ(missing.code(), Status::Code::NotFound);
  EXPECT_NE(missing.message().find("missing.ply"), std::string::npos);
}

TEST(ReaderProgress, BytesReadReachesTheTotal) {
  TempDir dir;
  for (PlyFormat f : {PlyFormat::Ascii, PlyFormat::LittleEndian}) {
    const auto path = dir.write("p.ply", write_ply(f, small_mesh()));
    auto reader = open_scene_reader(path);
    ASSERT_TRUE(reader.is_ok());
    EXPECT_EQ((*reader)->bytes_total(), fs::file_size(path));
    InputPrimitive p;
    bool end = false;
    while ((*reader)->next(p, end).is_ok() && !end) {
    }
    EXPECT_TRUE(end);
    EXPECT_EQ((*reader)->bytes_read(), (*reader)->bytes_total());
  }
}

TEST(ReaderLargeTokens, LongGarbageTokenIsAnError) {
  TempDir dir;
  const auto path = dir.write("long.nff", "s 0 0 0 1\n" + std::string(100000, '7') + "\n");
  const ReadResult r = read_all(path);
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_NE(r.status.message().find("long.nff: line 2:"), std::string::npos) << r.status.message();
}

TEST(ReaderLargeFile, ChunkBoundariesDoNotSplitTokens) {
  // Many primitives in a file several chunks long: every one must come back intact.
  TempDir dir;
  std::string text;
  const int n = 60000;
  for (int i = 0; i < n; ++i) text += fmt::format("s {} {}.125 -{}.5 {}.0625\r\n", i, i, i, i + 1);
  const ReadResult r = read_all(dir.write("many.nff", text));
  ASSERT_TRUE(r.status.is_ok()) << r.status.to_string();
  ASSERT_EQ(r.prims.size(), static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    ASSERT_EQ(r.prims[i].sphere.center, Vec3(i, i + 0.125, -(i + 0.5))) << i;
    ASSERT_EQ(r.prims[i].sphere.radius, i + 1.0625) << i;
  }
}

// ---------------------------------------------------------------------------------------------
// Malformed input: truncations and garbling never crash; errors name the file and position.

struct Sample {
  std::string name;
  std::string bytes;
};

std::vector<Sample> fuzz_samples() {
  std::string nff = "b 0.1 0.2 0.3\nv\nfrom 0 -5 1\nat 0 0 0\nup 0 0 1\nangle 40\nhither 0.1\nresolution 64 48\n"
                    "l 1 2 3\nl 4 5 6 0.5 0.5 0.5\nf 1 0 0 1 0 10 0 1\n"
                    "c 0 0 0 1 0 0 2 0.5\ns 1 2 3 0.5\np 5\n0 0 0\n2 0 0\n2 2 0\n1 0.5 0\n0 2 0\n"
                    "pp 3\n0 0 1 0 0 1\n1 0 1 0 0 1\n0 1 1 0 0 1\n";
  std::string obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
                    "f 1/1/1 2/1/1 3/1/1\nf -4 -3 -2 -1\ng x\nf 1//1 3//1 4//1\n";
  std::string off = "OFF\n5 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 1.5 0\n3 0 1 2\n4 0 1 2 3 255 0 0\n5 0 1 2 4 3\n";
  std::vector<TestElement> mesh = small_mesh();
  TestElement strips{"tristrips", {{"int", "vertex_indices", "int"}}, {{{0, 1, 2, 3, -1, 4, 5, 6}}}};
  mesh.push_back(strips);
  return {{"f.nff", nff},
          {"f.obj", obj},
          {"f.off", off},
          {"a.ply", write_ply(PlyFormat::Ascii, mesh)},
          {"le.ply", write_ply(PlyFormat::LittleEndian, mesh)},
          {"be.ply", write_ply(PlyFormat::BigEndian, mesh)}};
}

void expect_ok_or_positioned_error(const std::string& path, const std::string& name, const std::string& what) {
  Scene scene;
  const Status s = load_scene(path, scene);
  if (s.is_ok()) return;
  const std::string& m = s.message();
  EXPECT_EQ(m.rfind(path, 0), 0u) << what << ": " << m;
  // A file cut short before its first primitive holds none: that error names no position.
  EXPECT_TRUE(m.find(": line ") != std::string::npos || m.find(": byte ") != std::string::npos ||
              m == no_primitives_error(path, 0).message())
      << what << ": " << m;
}

TEST(ReaderMalformed, EveryTruncationIsOkOrAnError) {
  TempDir dir;
  for (const Sample& sample : fuzz_samples()) {
    const auto path = dir.file(sample.name);
    for (size_t len = 0; len < sample.bytes.size(); ++len) {
      dir.write(sample.name, std::string_view(sample.bytes).substr(0, len));
      expect_ok_or_positioned_error(path, sample.name, fmt::format("{} truncated to {}", sample.name, len));
      if (HasFailure()) return;
    }
    // The whole file is valid.
    Scene scene;
    dir.write(sample.name, sample.bytes);
    const Status s = load_scene(path, scene);
    EXPECT_TRUE(s.is_ok()) << s.to_string();
  }
}

TEST(ReaderMalformed, TruncatedBinaryFacesNameAByte) {
  TempDir dir;
  const std::string bytes = write_ply(PlyFormat::LittleEndian, small_mesh());
  const auto path = dir.write("t.ply", bytes.substr(0, bytes.size() - 5));
  const ReadResult r = read_all(path);
  ASSERT_FALSE(r.status.is_ok());
  EXPECT_NE(r.status.message().find("t.ply: byte "), std::string::npos) << r.status.message();
  EXPECT_NE(r.status.message().find("truncated"), std::string::npos) << r.status.message();
  EXPECT_EQ(r.prims.size(), 3u);  // the complete faces came through
}

TEST(ReaderMalformed, SeededGarblingIsOkOrAnError) {
  TempDir dir;
  std::mt19937 rng(20240501);
  const char kInteresting[] = {'\n', '\r', ' ', '-', '0', '9', '.', 'e', '#', '/', '\\', '\0', '\x7f', '\xff', 'n'};
  for (const Sample& sample : fuzz_samples()) {
    const auto path = dir.file(sample.name);
    for (int variant = 0; variant < 300; ++variant) {
      std::string bytes = sample.bytes;
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int e = 0; e < edits; ++e) {
        const size_t at = rng() % bytes.size();
        switch (rng() % 4) {
          case 0: bytes[at] = static_cast<char>(rng() & 0xff); break;
          case 1: bytes[at] = kInteresting[rng() % sizeof(kInteresting)]; break;
          case 2: bytes.erase(at, 1 + rng() % 3); break;
          default: bytes.insert(at, 1, kInteresting[rng() % sizeof(kInteresting)]); break;
        }
        if (bytes.empty()) bytes = "x";
      }
      dir.write(sample.name, bytes);
      expect_ok_or_positioned_error(path, sample.name, fmt::format("{} variant {}", sample.name, variant));
      if (HasFailure()) return;
    }
  }
}

}  // namespace
}  // namespace frontier
