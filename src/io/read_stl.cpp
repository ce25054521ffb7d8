// STL reader, binary and ASCII (layout and detection: read_stl.h).
//
// Both hold nothing but the current facet, so memory is one read chunk however large the file.
// Binary: the triangle count is checked against the file size when the file is opened (a
// truncated file fails at once, naming the byte where its last complete triangle ends); NaN or
// infinite coordinates are errors naming the triangle's byte offset; bytes after the last
// triangle are ignored with a warning. Binary STL is fixed-size records, cheap to parse again,
// so binary() is true (frontier-build reads such inputs twice rather than spilling them).
// ASCII: keywords in any case, tokens separated by any blanks and line ends; errors name the
// line. A facet's loop of more than three vertices is one polygon (triangulated like other
// formats' faces). Anything after the last endsolid that is not another solid is ignored with a
// warning.
#include "src/io/read_stl.h"

#include "src/io/binary_stream.h"
#include "src/io/read_formats.h"
#include "src/io/text_tokenizer.h"

#include <fmt/format.h>

#include <bit>
#include <cctype>

namespace frontier {

namespace {

// Case-insensitive comparison with a lower-case keyword.
bool keyword_is(std::string_view token, std::string_view keyword) {
  if (token.size() != keyword.size()) return false;
  for (size_t i = 0; i < token.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(token[i])) != keyword[i]) return false;
  }
  return true;
}

bool starts_with_solid(std::string_view head) {
  size_t i = 0;
  while (i < head.size() && std::isspace(static_cast<unsigned char>(head[i]))) ++i;
  head.remove_prefix(i);
  if (head.size() < 5 || !keyword_is(head.substr(0, 5), "solid")) return false;
  return head.size() == 5 || std::isspace(static_cast<unsigned char>(head[5]));
}

}  // namespace

StlKind detect_stl_kind(std::string_view head, uint64_t file_size) {
  if (head.size() >= kStlPrefixBytes) {
    const auto count = load_scalar<uint32_t>(reinterpret_cast<const uint8_t*>(head.data()) + kStlHeaderBytes,
                                             std::endian::native == std::endian::big);
    if (kStlPrefixBytes + kStlTriangleBytes * count == file_size) return StlKind::Binary;
  }
  return starts_with_solid(head) ? StlKind::Ascii : StlKind::Binary;
}

namespace {

class StlReader final : public FormatReader {
 public:
  Status open(const std::string& path);

  int64_t declared_primitives() const override { return binary_ ? count_ : -1; }
  bool binary() const override { return binary_; }
  uint64_t bytes_read() const override {
    if (finished_) return tok_.size();  // trailing bytes are not data
    return binary_ ? stream_.offset() : tok_.offset();
  }
  uint64_t bytes_total() const override { return tok_.size(); }

 private:
  Status read_next(InputPrimitive& out, bool& end) override {
    start_facet(out);
    return binary_ ? read_binary(out, end) : read_ascii(out, end);
  }
  static void start_facet(InputPrimitive& out) {
    out.kind = InputPrimitive::Kind::Polygon;
    out.material = 0;
    out.vertices.clear();
    out.normals.clear();
  }
  Status open_binary();
  Status read_binary(InputPrimitive& out, bool& end);
  Status read_ascii(InputPrimitive& out, bool& end);
  Status read_facet(InputPrimitive& out);
  // The next token, which must be `keyword` (any case).
  Status expect(std::string_view keyword);
  // Between solids: true when another one starts; else the end (with a warning about anything
  // left that is not blanks).
  bool another_solid();

  std::string path_;
  TextTokenizer tok_;  // opens the file; the body of ASCII files
  BinaryStream stream_;
  bool binary_ = false;
  int64_t count_ = 0;        // binary: triangles declared
  int64_t read_ = 0;         // binary: triangles handed out
  bool in_solid_ = false;    // ASCII: between solid and endsolid
  bool finished_ = false;    // the end was reported
};

Status StlReader::open(const std::string& path) {
  path_ = path;
  header_.materials.emplace_back();
  if (Status s = tok_.open(path, {.hash_comments = false}); !s) return s;
  const std::string_view head = tok_.peek_bytes(kStlPrefixBytes);
  if (!tok_.status().is_ok()) return tok_.status();
  binary_ = detect_stl_kind(head, tok_.size()) == StlKind::Binary;
  if (binary_) return open_binary();
  std::string_view t;
  tok_.next(t);  // "solid": detect_stl_kind saw it
  tok_.skip_line();  // the solid's name
  in_solid_ = true;
  return Status::ok();
}

Status StlReader::open_binary() {
  const uint64_t size = tok_.size();
  if (size < kStlPrefixBytes) {
    return byte_error(path_, size, fmt::format("not an STL file: neither ASCII (\"solid ...\") nor binary (the "
                                               "{}-byte header and count need {} bytes, the file has {})",
                                               kStlHeaderBytes, kStlPrefixBytes, size));
  }
  count_ = load_scalar<uint32_t>(reinterpret_cast<const uint8_t*>(tok_.peek_bytes(kStlPrefixBytes).data()) +
                                     kStlHeaderBytes,
                                 std::endian::native == std::endian::big);
  const uint64_t complete = (size - kStlPrefixBytes) / kStlTriangleBytes;
  if (static_cast<uint64_t>(count_) > complete) {
    return byte_error(path_, kStlPrefixBytes + complete * kStlTriangleBytes,
                      fmt::format("binary STL truncated: it declares {} triangles ({} bytes) but the file ends "
                                  "inside triangle {} ({} bytes)",
                                  count_, kStlPrefixBytes + kStlTriangleBytes * static_cast<uint64_t>(count_),
                                  complete, size));
  }
  stream_.init(tok_.fd(), kStlPrefixBytes, size);
  return Status::ok();
}

Status StlReader::read_binary(InputPrimitive& out, bool& end) {
  if (read_ == count_) {
    if (!finished_ && stream_.offset() < tok_.size()) {
      warn(trailing_data_warning(path_, stream_.offset(), tok_.size() - stream_.offset()));
    }
    finished_ = end = true;
    return Status::ok();
  }
  const uint64_t at = stream_.offset();
  const uint8_t* r = stream_.take(kStlTriangleBytes);
  if (r == nullptr) {
    if (!stream_.status().is_ok()) return Status::io_error(path_ + ": " + stream_.status().message());
    return byte_error(path_, at, fmt::format("truncated triangle {}", read_));
  }
  constexpr bool kSwap = std::endian::native == std::endian::big;
  out.vertices.resize(3);
  for (int v = 0; v < 3; ++v) {
    const uint8_t* p = r + 12 * (v + 1);  // after the normal
    out.vertices[v] = Vec3(load_scalar<float>(p, kSwap), load_scalar<float>(p + 4, kSwap),
                           load_scalar<float>(p + 8, kSwap));
    if (!all_finite(out.vertices[v])) {
      return byte_error(path_, at, fmt::format("triangle {} vertex {} coordinate is not finite", read_, v));
    }
  }
  ++read_;
  return Status::ok();
}

Status StlReader::read_ascii(InputPrimitive& out, bool& end) {
  for (;;) {
    if (!in_solid_) {
      if (!finished_ && another_solid()) continue;
      finished_ = end = true;
      return Status::ok();
    }
    std::string_view t;
    if (!tok_.next(t)) return tok_.end_error("facet or endsolid");
    if (keyword_is(t, "facet")) return read_facet(out);
    if (!keyword_is(t, "endsolid")) return tok_.error(fmt::format("expected facet or endsolid, got {}", quote_token(t)));
    tok_.skip_line();  // the solid's name
    in_solid_ = false;
  }
}

bool StlReader::another_solid() {
  const uint64_t at = tok_.skip_space();
  if (at >= tok_.size()) return false;
  const std::string_view next = tok_.peek_bytes(6);
  if (next.size() >= 5 && keyword_is(next.substr(0, 5), "solid") &&
      (next.size() == 5 || std::isspace(static_cast<unsigned char>(next[5])))) {
    std::string_view t;
    tok_.next(t);
    tok_.skip_line();
    in_solid_ = true;
    return true;
  }
  warn(trailing_data_warning(path_, at, tok_.size() - at));
  return false;
}

Status StlReader::read_facet(InputPrimitive& out) {
  std::string_view t;
  // "normal nx ny nz": read past, not checked (some writers put NaN there for slivers).
  if (tok_.peek(t) && keyword_is(t, "normal")) {
    for (int k = 0; k < 4; ++k) {
      if (!tok_.next(t)) return tok_.end_error("facet normal");
    }
  }
  if (Status s = expect("outer"); !s) return s;
  if (Status s = expect("loop"); !s) return s;
  for (;;) {
    if (!tok_.next(t)) return tok_.end_error("vertex or endloop");
    if (keyword_is(t, "endloop")) break;
    if (!keyword_is(t, "vertex")) return tok_.error(fmt::format("expected vertex or endloop, got {}", quote_token(t)));
    if (static_cast<int64_t>(out.vertices.size()) >= kMaxPolygonVertices) {
      return tok_.error(check_polygon_size(kMaxPolygonVertices + 1, "facet"));
    }
    Vec3 p;
    if (Status s = tok_.next_vec3(p, "vertex coordinate"); !s) return s;
    out.vertices.push_back(p);
  }
  if (std::string bad = check_polygon_size(static_cast<int64_t>(out.vertices.size()), "facet"); !bad.empty()) {
    return tok_.error(bad);
  }
  return expect("endfacet");
}

Status StlReader::expect(std::string_view keyword) {
  std::string_view t;
  if (!tok_.next(t)) return tok_.end_error(keyword);
  if (!keyword_is(t, keyword)) return tok_.error(fmt::format("expected {}, got {}", keyword, quote_token(t)));
  return Status::ok();
}

}  // namespace

Result<std::unique_ptr<SceneReader>> open_stl_reader(const std::string& path) {
  return open_format_reader<StlReader>(path);
}

}  // namespace frontier
