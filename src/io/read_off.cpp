// OFF reader (Geomview Object File Format): "OFF", the counts "nv nf ne", nv vertex lines,
// nf face lines "n i0 ... in-1 [colour]". COFF/NOFF/STOFF variants are tolerated (vertex
// colours and texture coordinates are skipped, NOFF normals are passed on); 4OFF/nOFF are not
// 3D and are refused. `#` comments are allowed anywhere.
//
// Keeps the vertex positions (faces may refer to any vertex); faces are handed out one by one.
// Anything but blanks and comments after the last face is ignored with a warning.
#include "src/io/read_formats.h"
#include "src/io/text_tokenizer.h"

#include <fmt/format.h>

namespace frontier {
namespace {

class OffReader final : public FormatReader {
 public:
  Status open(const std::string& path);

  int64_t declared_primitives() const override { return face_count_; }
  uint64_t bytes_read() const override {
    return vertices_read_ && faces_read_ == face_count_ ? tok_.size() : tok_.offset();
  }
  uint64_t bytes_total() const override { return tok_.size(); }

 private:
  Status read_vertices();
  Status read_next(InputPrimitive& out, bool& end) override;

  TextTokenizer tok_;
  bool has_normals_ = false;
  int64_t vertex_count_ = 0;
  int64_t face_count_ = 0;
  int64_t faces_read_ = 0;
  bool vertices_read_ = false;
  bool finished_ = false;  // the end was reported (and trailing data looked for)
  std::vector<Vec3> positions_;
  std::vector<Vec3> normals_;
};

Status OffReader::open(const std::string& path) {
  header_.materials.emplace_back();
  Status s = tok_.open(path, {.hash_comments = true});
  if (!s) return s;
  std::string_view t;
  if (!tok_.next(t)) return tok_.end_error("the OFF header");
  // [ST][C][N][4][n]OFF
  std::string_view prefix = t;
  if (prefix.size() < 3 || prefix.substr(prefix.size() - 3) != "OFF") {
    return tok_.error(fmt::format("not an OFF file (header {})", quote_token(t)));
  }
  prefix.remove_suffix(3);
  if (prefix.starts_with("ST")) prefix.remove_prefix(2);
  if (prefix.starts_with("C")) prefix.remove_prefix(1);
  if (prefix.starts_with("N")) {
    has_normals_ = true;
    prefix.remove_prefix(1);
  }
  if (!prefix.empty()) {
    return Status::unsupported(fmt::format("{}: line {}: unsupported OFF variant {}", path,
                                           tok_.line(), quote_token(t)));
  }
  s = tok_.next_int(vertex_count_, "vertex count");
  if (s) s = tok_.next_int(face_count_, "face count");
  if (!s) return s;
  if (vertex_count_ < 0 || face_count_ < 0) {
    return tok_.error(fmt::format("negative count ({} vertices, {} faces)", vertex_count_, face_count_));
  }
  // Each vertex and each face needs at least a few bytes: larger counts are corrupt.
  const auto room = static_cast<int64_t>(tok_.size() / 2 + 1);
  if (vertex_count_ > room || face_count_ > room || vertex_count_ > int64_t{UINT32_MAX}) {
    return tok_.error(fmt::format("counts ({} vertices, {} faces) exceed what a {}-byte file holds",
                                  vertex_count_, face_count_, tok_.size()));
  }
  std::string_view edges;
  if (tok_.next_on_line(edges)) {
    int64_t e = 0;
    if (!parse_int(edges, e)) return tok_.error(fmt::format("expected an edge count, got {}", quote_token(edges)));
  }
  tok_.skip_line();
  return Status::ok();
}

Status OffReader::read_vertices() {
  positions_.reserve(static_cast<size_t>(vertex_count_));
  if (has_normals_) normals_.reserve(static_cast<size_t>(vertex_count_));
  for (int64_t i = 0; i < vertex_count_; ++i) {
    Vec3 p;
    Status s = tok_.next_vec3(p, "coordinate");
    if (!s) return s;
    positions_.push_back(p);
    if (has_normals_) {
      s = tok_.next_vec3_on_line(p, "normal coordinate");
      if (!s) return s;
      normals_.push_back(p);
    }
    tok_.skip_line();  // colour, texture coordinates
  }
  vertices_read_ = true;
  return Status::ok();
}

Status OffReader::read_next(InputPrimitive& out, bool& end) {
  if (!vertices_read_) {
    Status s = read_vertices();
    if (!s) return s;
  }
  if (faces_read_ == face_count_) {
    if (!finished_) warn_trailing_text(tok_);
    finished_ = true;
    end = true;
    return Status::ok();
  }
  out.kind = InputPrimitive::Kind::Polygon;
  out.material = 0;
  out.vertices.clear();
  out.normals.clear();
  int64_t n = 0;
  Status s = tok_.next_int(n, "face vertex count");
  if (!s) return s;
  if (std::string bad = check_polygon_size(n, "face"); !bad.empty()) return tok_.error(bad);
  for (int64_t k = 0; k < n; ++k) {
    int64_t index = 0;
    s = tok_.next_int(index, "face vertex index");
    if (!s) return s;
    if (index < 0 || index >= vertex_count_) {
      return tok_.error(fmt::format("face index {} out of range ({} vertices)", index, vertex_count_));
    }
    out.vertices.push_back(positions_[static_cast<size_t>(index)]);
    if (has_normals_) out.normals.push_back(normals_[static_cast<size_t>(index)]);
  }
  tok_.skip_line();  // face colour
  ++faces_read_;
  return Status::ok();
}

}  // namespace

Result<std::unique_ptr<SceneReader>> open_off_reader(const std::string& path) {
  return open_format_reader<OffReader>(path);
}

}  // namespace frontier
