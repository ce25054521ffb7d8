// Wavefront OBJ reader: polygonal faces only.
//
// Keeps the vertex positions and normals read so far (faces may refer to any earlier vertex,
// also relatively with negative indices) and hands out each `f` line as one polygon as soon as
// it is read. Normals are passed when every vertex of the face names one. Grouping, material
// and free-form statements, `l` (lines) and `p` (points) are skipped; an unknown statement is
// an error naming its line. Lines may be continued with a backslash; CRLF and tabs are blanks.
#include "src/io/read_formats.h"
#include "src/io/text_tokenizer.h"

#include <fmt/format.h>

#include <array>

namespace frontier {
namespace {

// Statements that carry no polygon: grouping, materials, smoothing, lines, points, free-form.
bool is_ignored_statement(std::string_view kw) {
  static constexpr std::array<std::string_view, 30> kIgnored = {
      "g",     "o",     "s",        "usemtl",   "mtllib",     "l",         "p",     "vp",
      "cstype", "deg",  "bmat",     "step",     "curv",       "curv2",     "surf",  "parm",
      "trim",  "hole",  "scrv",     "sp",       "end",        "con",       "mg",    "bevel",
      "c_interp", "d_interp", "lod", "shadow_obj", "trace_obj", "maplib"};
  for (std::string_view s : kIgnored) {
    if (kw == s) return true;
  }
  return kw == "usemap" || kw == "ctech" || kw == "stech";
}

// Resolves a 1-based (or negative, relative) OBJ index against `count` defined elements.
bool resolve_index(int64_t index, size_t count, size_t& out) {
  const auto n = static_cast<int64_t>(count);
  if (index > 0 && index <= n) {
    out = static_cast<size_t>(index - 1);
    return true;
  }
  if (index < 0 && index >= -n) {
    out = static_cast<size_t>(n + index);
    return true;
  }
  return false;
}

class ObjReader final : public FormatReader {
 public:
  Status open(const std::string& path) {
    header_.materials.emplace_back();
    return tok_.open(path, {.hash_comments = true, .line_continuation = true});
  }

  uint64_t bytes_read() const override { return tok_.offset(); }
  uint64_t bytes_total() const override { return tok_.size(); }

 private:
  Status read_next(InputPrimitive& out, bool& end) override;
  Status read_face(InputPrimitive& out);

  TextTokenizer tok_;
  std::vector<Vec3> positions_;
  std::vector<Vec3> normals_;
  size_t texcoords_ = 0;
};

Status ObjReader::read_next(InputPrimitive& out, bool& end) {
  std::string_view kw;
  for (;;) {
    if (Status s = tok_.next_statement(kw, end); !s || end) return s;
    if (kw == "v") {
      Vec3 p;
      Status s = tok_.next_vec3_on_line(p, "coordinate");
      if (!s) return s;
      positions_.push_back(p);  // an optional w (or vertex colour) is ignored
    } else if (kw == "vn") {
      Vec3 n;
      Status s = tok_.next_vec3_on_line(n, "normal coordinate");
      if (!s) return s;
      normals_.push_back(n);
    } else if (kw == "vt") {
      ++texcoords_;
    } else if (kw == "f" || kw == "fo") {
      return read_face(out);
    } else if (!is_ignored_statement(kw)) {
      return tok_.error(fmt::format("unknown statement {}", quote_token(kw)));
    }
    tok_.skip_line();
  }
}

Status ObjReader::read_face(InputPrimitive& out) {
  out.kind = InputPrimitive::Kind::Polygon;
  out.material = 0;
  out.vertices.clear();
  out.normals.clear();
  bool all_normals = true;
  std::string_view t;
  while (tok_.next_on_line(t)) {
    if (static_cast<int64_t>(out.vertices.size()) >= kMaxPolygonVertices) {
      return tok_.error(check_polygon_size(kMaxPolygonVertices + 1, "face"));
    }
    // t is v, v/vt, v//vn or v/vt/vn.
    std::string_view parts[3];
    int nparts = 0;
    size_t start = 0;
    for (;;) {
      const size_t slash = t.find('/', start);
      if (nparts == 3) return tok_.error(fmt::format("bad face vertex {}", quote_token(t)));
      parts[nparts++] = t.substr(start, slash == std::string_view::npos ? slash : slash - start);
      if (slash == std::string_view::npos) break;
      start = slash + 1;
    }
    int64_t index = 0;
    size_t resolved = 0;
    if (!parse_int(parts[0], index)) {
      return tok_.error(fmt::format("bad face vertex {}", quote_token(t)));
    }
    if (!resolve_index(index, positions_.size(), resolved)) {
      return tok_.error(fmt::format("face index {} out of range ({} vertices)", index, positions_.size()));
    }
    out.vertices.push_back(positions_[resolved]);
    if (nparts >= 2 && !parts[1].empty()) {
      if (!parse_int(parts[1], index)) return tok_.error(fmt::format("bad face vertex {}", quote_token(t)));
      if (!resolve_index(index, texcoords_, resolved)) {
        return tok_.error(fmt::format("texture index {} out of range ({} texture coordinates)", index, texcoords_));
      }
    }
    if (nparts == 3) {
      if (!parse_int(parts[2], index)) return tok_.error(fmt::format("bad face vertex {}", quote_token(t)));
      if (!resolve_index(index, normals_.size(), resolved)) {
        return tok_.error(fmt::format("normal index {} out of range ({} normals)", index, normals_.size()));
      }
      if (all_normals) out.normals.push_back(normals_[resolved]);
    } else {
      all_normals = false;
    }
  }
  if (!tok_.status().is_ok()) return tok_.status();
  if (!all_normals) out.normals.clear();
  const auto n = static_cast<int64_t>(out.vertices.size());
  if (std::string bad = check_polygon_size(n, "face"); !bad.empty()) return tok_.error(bad);
  tok_.skip_line();
  return Status::ok();
}

}  // namespace

Result<std::unique_ptr<SceneReader>> open_obj_reader(const std::string& path) {
  return open_format_reader<ObjReader>(path);
}

}  // namespace frontier
