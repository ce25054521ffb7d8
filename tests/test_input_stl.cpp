// STL, ASCII and binary (src/io/read_stl.h): the same triangles as the same mesh in PLY, in
// the same order (so frontier-build gives them the same ids), binary files whose header starts
// with "solid" told apart by their size, and malformed files (truncated, misspelt, NaN) refused
// with the file and the line or byte offset; every truncation and seeded garbling is ok or such
// an error, never a crash.
#include "preprocess/build.h"
#include "src/io/load_scene.h"
#include "src/io/read_stl.h"
#include "src/io/scene_reader.h"
#include "src/paging/store_model.h"
#include "tests/input_files.h"
#include "tests/model_read.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <random>
#include <string>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using testing::grid_mesh;
using testing::TriangleMesh;
using testing::write_file;

const fs::path& scratch() { return testing::scratch_dir("frontier_input_stl"); }

using Read = testing::ModelRead;
using testing::read_model;

void expect_mesh(const Read& r, const TriangleMesh& m, const std::string& what) {
  ASSERT_TRUE(r.status.is_ok()) << what << ": " << r.status.to_string();
  ASSERT_EQ(r.prims.size(), m.triangles.size()) << what;
  for (size_t i = 0; i < m.triangles.size(); ++i) {
    const InputPrimitive& p = r.prims[i];
    EXPECT_EQ(p.kind, InputPrimitive::Kind::Polygon);
    EXPECT_TRUE(p.normals.empty()) << "facet normals are ignored";
    ASSERT_EQ(p.vertices.size(), 3u) << what << " facet " << i;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(p.vertices[k], m.vertices[m.triangles[i][k]]) << what << " facet " << i;
  }
}

std::string upper(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  return s;
}

TEST(InputStl, AsciiAndBinaryHoldTheMeshsTriangles) {
  const TriangleMesh m = grid_mesh(7);
  const std::string ascii = testing::stl_ascii(m);
  const Read a = read_model(write_file(scratch() / "mesh.stl", ascii));
  expect_mesh(a, m, "ascii");
  EXPECT_EQ(a.declared, -1);
  EXPECT_FALSE(a.binary);
  const Read b = read_model(write_file(scratch() / "mesh_bin.stl", testing::stl_binary(m)));
  expect_mesh(b, m, "binary");
  EXPECT_EQ(b.declared, static_cast<int64_t>(m.triangles.size()));
  EXPECT_TRUE(b.binary);
  // A binary file whose header starts with "solid", as some exporters write: its size decides.
  const std::string solid_bin = testing::stl_binary(m, "solid exported by a tool that says so");
  EXPECT_EQ(detect_stl_kind(solid_bin.substr(0, 84), solid_bin.size()), StlKind::Binary);
  expect_mesh(read_model(write_file(scratch() / "solid_bin.STL", solid_bin)), m, "binary starting with solid");
  // Keywords in capitals, CRLF line ends, facets on one line, two solids in one file.
  std::string crlf;
  for (char c : upper(ascii)) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  expect_mesh(read_model(write_file(scratch() / "upper.stl", crlf)), m, "capitals and CRLF");
  // The name is the rest of the solid line; the facets may be laid out any way.
  std::string one_line = ascii.substr(ascii.find('\n') + 1);
  std::replace(one_line.begin(), one_line.end(), '\n', ' ');
  expect_mesh(read_model(write_file(scratch() / "one_line.stl", "solid facets on one line\n" + one_line)), m, "one line");
  TriangleMesh half = m, rest = m;
  half.triangles.resize(m.triangles.size() / 2);
  rest.triangles.erase(rest.triangles.begin(), rest.triangles.begin() + static_cast<std::ptrdiff_t>(half.triangles.size()));
  const std::string two = testing::stl_ascii(half) + "\n" + testing::stl_ascii(rest);
  const Read t = read_model(write_file(scratch() / "two_solids.stl", two));
  expect_mesh(t, m, "two solids");
  EXPECT_TRUE(t.warnings.empty());
}

// frontier-build of the mesh as STL (either kind) stores what it stores for the mesh as PLY:
// the same primitives with the same ids, the same bounds.
TEST(InputStl, BuildsTheSameStoreAsThePly) {
  const TriangleMesh m = grid_mesh(12);
  std::map<std::string, std::map<uint32_t, std::vector<Vec3>>> by_source;
  std::map<std::string, Aabb> bounds;
  std::map<std::string, uint64_t> spilled;
  const std::vector<std::pair<std::string, std::string>> files = {{"mesh.ply", testing::ply_binary(m)},
                                                                  {"mesh.stl", testing::stl_ascii(m)},
                                                                  {"mesh_bin.stl", testing::stl_binary(m)}};
  for (const auto& [name, bytes] : files) {
    BuildOptions o;
    o.inputs = {write_file(scratch() / name, bytes)};
    o.output = (scratch() / (name + ".frontier")).string();
    o.codec = CellCodec::Raw;
    o.quiet = true;
    o.threads = 2;
    o.cell_prims = 32;
    auto report = build_store(o);
    ASSERT_TRUE(report.is_ok()) << name << ": " << report.status().to_string();
    EXPECT_EQ(report->input_primitives, m.triangles.size()) << name;
    EXPECT_EQ(report->triangles, m.triangles.size()) << name;
    spilled[name] = report->spill_bytes;
    auto model = StoreModel::open(o.output);
    ASSERT_TRUE(model.is_ok()) << model.status().to_string();
    bounds[name] = (*model)->info().bounds;
    Scene stored;
    std::vector<std::vector<uint32_t>> cells;
    ASSERT_TRUE((*model)->load_scene(stored, cells).is_ok());
    for (uint32_t i = 0; i < stored.size(); ++i) {
      const PrimRef& p = stored.prims[i];
      ASSERT_EQ(p.kind, PrimKind::Triangle);
      const Triangle& t = stored.triangles[p.index];
      by_source[name][p.source] = {t.v0, t.v1, t.v2};  // straddlers are stored once per cell, alike
    }
  }
  for (const char* name : {"mesh.stl", "mesh_bin.stl"}) {
    EXPECT_EQ(by_source[name], by_source["mesh.ply"]) << name;
    EXPECT_EQ(bounds[name].lo, bounds["mesh.ply"].lo) << name;
    EXPECT_EQ(bounds[name].hi, bounds["mesh.ply"].hi) << name;
  }
  // Binary STL takes binary PLY's path (parsed twice, never spilled); ASCII STL is spilled.
  EXPECT_EQ(spilled["mesh_bin.stl"], 0u);
  EXPECT_GT(spilled["mesh.stl"], 0u);
}

// The same through the command-line tools: frontier-store info of the STL stores and of the PLY
// store report the same primitives and bounds.
TEST(InputStl, FrontierBuildAcceptsStl) {
  const TriangleMesh m = grid_mesh(10);
  const auto summary = [](const std::string& info) {
    std::string lines;
    for (const char* key : {"primitives ", "bounds "}) {
      const size_t at = info.find(key);
      if (at != std::string::npos) lines += info.substr(at, info.find('\n', at) - at) + "\n";
    }
    return lines;
  };
  std::map<std::string, std::string> seen;
  for (const auto& [name, bytes] : {std::pair{"cmd.ply", testing::ply_ascii(m)}, std::pair{"cmd.stl", testing::stl_ascii(m)},
                                    std::pair{"cmd_bin.stl", testing::stl_binary(m, "solid, but binary")}}) {
    const std::string in = write_file(scratch() / name, bytes);
    const std::string out = in + ".frontier";
    const auto r = proc::run_binary(FRONTIER_BUILD_PATH, {in, "-o", out, "--quiet"}, scratch());
    ASSERT_EQ(r.exit_code, 0) << name << ": " << r.err;
    EXPECT_EQ(r.err, "") << name;
    const auto info = proc::run_binary(FRONTIER_STORE_PATH, {"info", out}, scratch());
    ASSERT_EQ(info.exit_code, 0) << info.err;
    seen[name] = summary(info.out);
    EXPECT_NE(seen[name].find(fmt::format("primitives  {} ({} triangles", m.triangles.size(), m.triangles.size())),
              std::string::npos)
        << seen[name];
  }
  EXPECT_EQ(seen["cmd.stl"], seen["cmd.ply"]);
  EXPECT_EQ(seen["cmd_bin.stl"], seen["cmd.ply"]);
}

TEST(InputStl, MalformedFilesNameTheirLineOrByte) {
  const TriangleMesh m = grid_mesh(3);  // 8 triangles
  const std::string ascii = testing::stl_ascii(m);
  const std::string binary = testing::stl_binary(m);
  const auto line_of = [&](const std::string& text, const std::string& needle) {
    return 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(text.find(needle)), '\n');
  };
  const auto replace_first = [](std::string text, const std::string& from, const std::string& to) {
    return text.replace(text.find(from), from.size(), to);
  };
  std::string nan_bin = binary;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan_bin.data() + 84 + 50 * 5 + 12 + 4, &nan, 4);  // triangle 5, vertex 0, y
  std::string huge_count = binary;
  huge_count[80] = huge_count[81] = huge_count[82] = huge_count[83] = '\xff';
  const std::string typo = replace_first(ascii, "vertex 0.125", "vertx 0.125");
  const std::string nan_text = replace_first(ascii, "vertex 0.125", "vertex nan");
  const std::string inf_text = replace_first(ascii, "vertex 0.125", "vertex 1e999");
  const std::string two = replace_first(ascii, "vertex 0.125 0 0\n", "");
  struct Case {
    std::string name, bytes, expect;
  };
  const Case cases[] = {
      {"cut.stl", binary.substr(0, binary.size() - 10),
       fmt::format("byte {}: binary STL truncated: it declares 8 triangles", 84 + 50 * 7)},
      {"huge.stl", huge_count, "byte 484: binary STL truncated: it declares 4294967295 triangles"},
      {"tiny.stl", "nothing", "byte 7: not an STL file"},
      {"nan_bin.stl", nan_bin, fmt::format("byte {}: triangle 5 vertex 0 coordinate is not finite", 84 + 50 * 5)},
      {"typo.stl", typo, fmt::format("line {}: expected vertex or endloop, got 'vertx'", line_of(typo, "vertx"))},
      {"nan.stl", nan_text, fmt::format("line {}: vertex coordinate is not finite", line_of(nan_text, "vertex nan"))},
      {"inf.stl", inf_text, fmt::format("line {}: vertex coordinate is not finite", line_of(inf_text, "1e999"))},
      {"two.stl", two, fmt::format("line {}: facet has 2 vertices", line_of(two, "endloop"))},
      {"open.stl", ascii.substr(0, ascii.find("endsolid")),
       fmt::format("line {}: unexpected end of file (expected facet or endsolid)", line_of(ascii, "endsolid") - 1)},
  };
  for (const Case& c : cases) {
    const std::string path = write_file(scratch() / c.name, c.bytes);
    const Read r = read_model(path);
    ASSERT_FALSE(r.status.is_ok()) << c.name;
    EXPECT_NE(r.status.message().find(path + ": " + c.expect), std::string::npos) << c.name << ": " << r.status.message();
  }
}

// Data after the last triangle: a warning with its offset and size, never a failure.
TEST(InputStl, TrailingDataIsAWarning) {
  const TriangleMesh m = grid_mesh(3);
  const std::string binary = testing::stl_binary(m);
  const std::string ascii = testing::stl_ascii(m);
  const std::string junk(100, '\0');
  const Read b = read_model(write_file(scratch() / "trail_bin.stl", binary + junk));
  expect_mesh(b, m, "binary with trailing bytes");
  ASSERT_EQ(b.warnings.size(), 1u);
  EXPECT_NE(b.warnings[0].find(fmt::format("byte {}: 100 bytes after the last record", binary.size())),
            std::string::npos)
      << b.warnings[0];
  const Read a = read_model(write_file(scratch() / "trail.stl", ascii + "\n\n" + junk));
  expect_mesh(a, m, "ascii with trailing bytes");
  ASSERT_EQ(a.warnings.size(), 1u);
  EXPECT_NE(a.warnings[0].find(fmt::format("byte {}: 100 bytes after the last record", ascii.size() + 2)),
            std::string::npos)
      << a.warnings[0];
  EXPECT_TRUE(read_model(write_file(scratch() / "blank.stl", ascii + "\n \r\n")).warnings.empty());
}

void expect_ok_or_positioned(const std::string& path, const std::string& what) {
  Scene scene;
  std::vector<std::string> warnings;
  const Status s = load_scene(path, scene, &warnings);
  if (s.is_ok()) return;
  const std::string& msg = s.message();
  EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << what << ": " << msg;
  EXPECT_TRUE(msg.find(": line ") != std::string::npos || msg.find(": byte ") != std::string::npos ||
              msg.find(": the model has no primitives") != std::string::npos)
      << what << ": " << msg;
}

TEST(InputStl, TruncationsAndGarblingAreOkOrPositionedErrors) {
  const TriangleMesh m = grid_mesh(3);
  std::mt19937 rng(2405);
  const char kInteresting[] = {'\n', ' ', '-', '0', '9', '.', 'e', 'n', '\0', '\xff', 's'};
  for (const auto& [name, sample] : {std::pair{"f.stl", testing::stl_ascii(m)},
                                     std::pair{"f_bin.stl", testing::stl_binary(m)}}) {
    const std::string path = (scratch() / name).string();
    for (size_t len = 0; len < sample.size(); len += (name == std::string("f.stl") ? 1 : 3)) {
      write_file(path, std::string_view(sample).substr(0, len));
      expect_ok_or_positioned(path, fmt::format("{} cut to {}", name, len));
      if (HasFailure()) return;
    }
    for (int variant = 0; variant < 300; ++variant) {
      std::string bytes = sample;
      for (int e = 0, edits = 1 + static_cast<int>(rng() % 4); e < edits; ++e) {
        const size_t at = rng() % bytes.size();
        switch (rng() % 3) {
          case 0: bytes[at] = static_cast<char>(rng() & 0xff); break;
          case 1: bytes[at] = kInteresting[rng() % sizeof(kInteresting)]; break;
          default: bytes.erase(at, 1 + rng() % 3); break;
        }
        if (bytes.empty()) bytes = "x";
      }
      write_file(path, bytes);
      expect_ok_or_positioned(path, fmt::format("{} variant {}", name, variant));
      if (HasFailure()) return;
    }
  }
}

}  // namespace
}  // namespace frontier
