// PLY (and OFF) files as real exporters and real accidents make them: header lines PLY does not
// define (Blender's "Created by ..."), a list count that does not match its record, data after
// the last element. Errors name the record's line or byte offset; what a reader can read past
// is a warning (file and position, told once), never silence and never a failure.
#include "src/io/scene_reader.h"
#include "tests/input_files.h"
#include "tests/model_read.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;
using testing::grid_mesh;
using testing::TriangleMesh;
using testing::write_file;

const fs::path& scratch() { return testing::scratch_dir("frontier_input_ply"); }

size_t count_of(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

proc::RunResult build(const std::string& in) {
  return run_binary(FRONTIER_BUILD_PATH, {in, "-o", (scratch() / "out.frontier").string(), "--quiet"}, scratch());
}

// Reading `in` fails with `expect` in its message, and so does frontier-build (exit 1). Returns
// the primitives read before the error.
size_t expect_error_everywhere(const std::string& in, const std::string& expect) {
  const testing::ModelRead read = testing::read_model(in);
  EXPECT_FALSE(read.status.is_ok()) << in;
  EXPECT_NE(read.status.message().find(expect), std::string::npos) << "expected '" << expect << "': " << read.status.message();
  const auto r = build(in);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find(expect), std::string::npos) << "expected '" << expect << "': " << r.err;
  return read.prims.size();
}

constexpr const char* kBlender = "Created by Blender 3.6.2 - www.blender.org\n";

TEST(InputPlyHeader, UnknownHeaderLinesAreSkippedWithAWarning) {
  const TriangleMesh m = grid_mesh(6);
  for (bool binary : {false, true}) {
    const std::string in = write_file(scratch() / (binary ? "blender_bin.ply" : "blender.ply"),
                                      binary ? testing::ply_binary(m, kBlender) : testing::ply_ascii(m, kBlender));
    const testing::ModelRead read = testing::read_model(in);
    ASSERT_TRUE(read.status.is_ok()) << read.status.to_string();
    EXPECT_EQ(read.prims.size(), m.triangles.size());
    // frontier-build reads binary PLY twice: the warning is still told once.
    const auto r = build(in);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(count_of(r.err, in + ": line 3: skipped a header line with the unknown keyword 'Created'"), 1u) << r.err;
  }
  // Standard comments are no news.
  const std::string plain = write_file(scratch() / "plain.ply", testing::ply_ascii(m, "comment made by hand\n"));
  const auto r = build(plain);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
}

TEST(InputPlyHeader, WarningsAreKeptByTheReader) {
  const std::string in = write_file(scratch() / "two_unknown.ply",
                                    testing::ply_ascii(grid_mesh(3), std::string(kBlender) + "author someone\n"));
  auto reader = open_scene_reader(in);
  ASSERT_TRUE(reader.is_ok()) << reader.status().to_string();
  const auto& w = (*reader)->warnings();
  ASSERT_EQ(w.size(), 2u);
  EXPECT_EQ(w[0], in + ": line 3: skipped a header line with the unknown keyword 'Created'");
  EXPECT_EQ(w[1], in + ": line 4: skipped a header line with the unknown keyword 'author'");
}

// ply_ascii(m) with line `line` of its body (0-based) replaced by `text`; `file_line` is set to
// that line's number in the file (1-based).
std::string with_body_line(const TriangleMesh& m, size_t line, const std::string& text, size_t& file_line) {
  const std::string all = testing::ply_ascii(m);
  size_t start = all.find("end_header\n") + 11;
  file_line = static_cast<size_t>(std::count(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(start), '\n')) + line + 1;
  for (size_t k = 0; k < line; ++k) start = all.find('\n', start) + 1;
  return all.substr(0, start) + text + all.substr(all.find('\n', start));
}

TEST(InputPlyPositions, AsciiRecordErrorsNameTheRecordsLine) {
  const TriangleMesh m = grid_mesh(20);  // 400 vertices, 722 faces: the file ends some 700 lines later
  const size_t face = 20;
  const auto& t = m.triangles[face];
  struct Case {
    size_t body_line;
    std::string text;
    std::string expect;
  };
  const Case cases[] = {
      // The count says 9 but the record holds 3 indices.
      {m.vertices.size() + face, fmt::format("9 {} {} {}", t[0], t[1], t[2]),
       "list vertex_indices has the count 9 but its line ends after 3 items"},
      // The count says 3 but the record holds 4.
      {m.vertices.size() + face, fmt::format("3 {} {} {} 7", t[0], t[1], t[2]),
       "more values on the line than element face has properties"},
      // A vertex without z.
      {37, "0.5 0.25", "line ends before coordinate"},
  };
  for (const Case& c : cases) {
    size_t line = 0;
    const std::string in = write_file(scratch() / "overrun.ply", with_body_line(m, c.body_line, c.text, line));
    expect_error_everywhere(in, fmt::format("{}: line {}: {}", in, line, c.expect));
  }
}

TEST(InputPlyPositions, BinaryListCountOverrunNamesItsRecordOffset) {
  const TriangleMesh m = grid_mesh(20);
  std::string bytes = testing::ply_binary(m);
  const size_t last = m.triangles.size() - 1;
  const uint64_t record = testing::ply_binary_face_offset(m, last);
  ASSERT_EQ(bytes[record], '\3');
  bytes[record] = static_cast<char>(200);  // 800 bytes of indices, 12 left in the file
  const std::string in = write_file(scratch() / "overrun_bin.ply", bytes);
  const size_t read = expect_error_everywhere(
      in, fmt::format("{}: byte {}: truncated record: list vertex_indices has the count 200", in, record));
  EXPECT_EQ(read, last);  // the faces before it came through
}

// Data after the last element or face: told once, with where it starts and how much there is.
TEST(InputTrailingData, WarnedOnceWithItsOffsetAndSize) {
  const TriangleMesh m = grid_mesh(8);
  struct Case {
    std::string name, model, trailing;
    size_t skip;  // blanks before the data
  };
  const std::string zeros(4096, '\0');
  const Case cases[] = {
      {"zeros.ply", testing::ply_ascii(m), zeros, 0},
      {"zeros_bin.ply", testing::ply_binary(m), zeros, 0},
      {"zeros.off", testing::off_text(m), zeros, 0},
      {"junk.ply", testing::ply_ascii(m), "\n \t\njunk\n", 4},
      {"junk.off", testing::off_text(m), "\n# a comment is fine\n3 0 1 2\n", 21},
      {"blanks_bin.ply", testing::ply_binary(m), "\n\n", 0},  // binary: every byte counts
  };
  for (const Case& c : cases) {
    const std::string in = write_file(scratch() / c.name, c.model + c.trailing);
    const auto r = build(in);
    EXPECT_EQ(r.exit_code, 0) << c.name << ": " << r.err;
    const std::string expect = fmt::format("{}: byte {}: {} bytes after the last record, ignored", in,
                                           c.model.size() + c.skip, c.trailing.size() - c.skip);
    EXPECT_EQ(count_of(r.err, expect), 1u) << c.name << ": expected '" << expect << "', got: " << r.err;
  }
  // Blanks (and OFF's comments) after ASCII data are not data.
  for (const auto& [name, bytes] : {std::pair{"blanks.ply", testing::ply_ascii(m) + "\n\r\n  \t\n"},
                                    std::pair{"comment.off", testing::off_text(m) + "\n# the end\n\n"}}) {
    const auto r = build(write_file(scratch() / name, bytes));
    EXPECT_EQ(r.exit_code, 0) << name << ": " << r.err;
    EXPECT_EQ(r.err, "") << name;
  }
}

// Counting 2 GiB of trailing zeros takes the file size (binary) or one look at the first
// byte that is not blank (ASCII), not a read of everything.
TEST(InputTrailingData, IsNotReadToBeCounted) {
  const TriangleMesh m = grid_mesh(8);
  const uint64_t trailing = uint64_t{2} << 30;
  for (const auto& [name, model] : {std::pair{"sparse.ply", testing::ply_ascii(m)},
                                    std::pair{"sparse_bin.ply", testing::ply_binary(m)},
                                    std::pair{"sparse.off", testing::off_text(m)}}) {
    const fs::path path = scratch() / name;
    write_file(path, model + '\1');  // a byte that is not blank, then a hole of zeros
    fs::resize_file(path, model.size() + trailing);
    const auto rchar = [] {
      std::ifstream io("/proc/self/io");
      std::string key;
      uint64_t value = 0;
      while (io >> key >> value) {
        if (key == "rchar:") return value;
      }
      return uint64_t{0};
    };
    const uint64_t before = rchar();
    auto reader = open_scene_reader(path.string());
    ASSERT_TRUE(reader.is_ok()) << reader.status().to_string();
    InputPrimitive p;
    bool end = false;
    size_t n = 0;
    while ((*reader)->next(p, end).is_ok() && !end) ++n;
    EXPECT_TRUE(end) << name;
    EXPECT_EQ(n, m.triangles.size()) << name;
    const uint64_t read = rchar() - before;
    EXPECT_LT(read, uint64_t{8} << 20) << name << ": read " << read << " bytes";
    ASSERT_EQ((*reader)->warnings().size(), 1u) << name;
    EXPECT_NE((*reader)->warnings()[0].find(fmt::format("byte {}: {} bytes after the last record", model.size(),
                                                        trailing)),
              std::string::npos)
        << (*reader)->warnings()[0];
    // Asking again after the end tells nothing new.
    EXPECT_TRUE((*reader)->next(p, end).is_ok());
    EXPECT_EQ((*reader)->warnings().size(), 1u);
    fs::remove(path);
  }
}

}  // namespace
}  // namespace frontier
