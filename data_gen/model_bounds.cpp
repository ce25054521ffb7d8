// Streaming bounds scanners (see header).
#include "data_gen/model_bounds.h"

#include "src/io/ply_header.h"
#include "src/io/text_tokenizer.h"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

namespace frontier::gen {
namespace {

std::string lower_extension(const std::string& path) {
  const size_t dot = path.rfind('.');
  std::string ext = dot == std::string::npos ? "" : path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

bool finite(const Vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Where an element's scalar properties sit in a binary record, and which are x, y and z.
struct PlyRecord {
  size_t size = 0;              // bytes per record (valid when fixed)
  bool fixed = true;            // no list properties
  std::vector<size_t> offsets;  // of property k, when fixed
  int ix = -1, iy = -1, iz = -1;
};

PlyRecord ply_record(const PlyElement& e) {
  PlyRecord r;
  for (const PlyProperty& prop : e.props) {
    if (prop.is_list) r.fixed = false;
    r.offsets.push_back(r.size);
    r.size += ply_type_size(prop.type);
  }
  r.ix = e.find("x");
  r.iy = e.find("y");
  r.iz = e.find("z");
  return r;
}

// The bounds of an ASCII vertex element, one vertex a line.
Status scan_ascii_vertices(std::istream& in, const PlyElement& e, const PlyRecord& rec, const std::string& path,
                           Aabb& box) {
  std::string line;
  for (int64_t r = 0; r < e.count; ++r) {
    if (!std::getline(in, line))
      return Status::corruption(fmt::format("{}: truncated PLY ({} {} expected)", path, e.count, e.name));
    std::istringstream ls(line);
    std::vector<double> v(e.props.size());
    for (double& x : v) ls >> x;
    if (!ls) return Status::corruption(fmt::format("{}: bad vertex line '{}'", path, line));
    const Vec3 p(v[size_t(rec.ix)], v[size_t(rec.iy)], v[size_t(rec.iz)]);
    if (!finite(p)) return Status::corruption(fmt::format("{}: vertex {} is not finite", path, r));
    box.extend(p);
  }
  return Status::ok();
}

// The bounds of a binary vertex element of fixed-size records, read 65536 records at a time.
Status scan_binary_vertices(std::istream& in, const PlyElement& e, const PlyRecord& rec, bool swap,
                            const std::string& path, Aabb& box) {
  std::vector<unsigned char> buf(rec.size * 65536);
  uint64_t left = static_cast<uint64_t>(e.count), index = 0;
  while (left > 0) {
    const uint64_t n = std::min<uint64_t>(left, 65536);
    in.read(reinterpret_cast<char*>(buf.data()), static_cast<std::streamsize>(n * rec.size));
    if (!in) return Status::corruption(fmt::format("{}: truncated vertex data at vertex {}", path, index));
    for (uint64_t r = 0; r < n; ++r, ++index) {
      const unsigned char* bytes = buf.data() + r * rec.size;
      // No list properties here (checked by the caller), so property k sits at offsets[k].
      auto get = [&](int k) { return ply_decode_double(bytes + rec.offsets[size_t(k)], e.props[size_t(k)].type, swap); };
      const Vec3 p(get(rec.ix), get(rec.iy), get(rec.iz));
      if (!finite(p)) return Status::corruption(fmt::format("{}: vertex {} is not finite", path, index));
      box.extend(p);
    }
    left -= n;
  }
  return Status::ok();
}

// The header through the scene reader's parser (src/io/ply_header.h: the same files are
// accepted, unknown header lines skipped); skips the elements before the vertices (ASCII: a
// line per record; binary: fixed-size records only, since records with lists cannot be skipped
// without reading them) and scans the first vertex element.
Result<Aabb> scan_ply(const std::string& path) {
  PlyHeader header;
  {
    TextTokenizer tok;
    if (Status s = tok.open(path, {.hash_comments = false}); !s) return s;
    if (Status s = read_ply_header(tok, header); !s) return s;
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::not_found(fmt::format("cannot open '{}': {}", path, std::strerror(errno)));
  in.seekg(static_cast<std::streamoff>(header.body_offset));

  Aabb box;
  for (const PlyElement& e : header.elements) {
    const bool is_vertex = e.name == "vertex";
    const PlyRecord rec = ply_record(e);
    if (is_vertex && (rec.ix < 0 || rec.iy < 0 || rec.iz < 0))
      return Status::corruption(fmt::format("{}: vertex element lacks x, y or z", path));
    if (header.ascii) {
      if (is_vertex) {
        if (Status st = scan_ascii_vertices(in, e, rec, path, box); !st) return st;
        return box;
      }
      std::string line;
      for (int64_t r = 0; r < e.count; ++r) {
        if (!std::getline(in, line))
          return Status::corruption(fmt::format("{}: truncated PLY ({} {} expected)", path, e.count, e.name));
      }
      continue;
    }
    if (!rec.fixed) {
      if (is_vertex) return Status::unsupported(fmt::format("{}: list property in the vertex element", path));
      return Status::unsupported(fmt::format("{}: element '{}' with lists precedes the vertices", path, e.name));
    }
    if (!is_vertex) {
      in.seekg(static_cast<std::streamoff>(rec.size * static_cast<uint64_t>(e.count)), std::ios::cur);
      continue;
    }
    if (Status st = scan_binary_vertices(in, e, rec, header.swap, path, box); !st) return st;
    return box;
  }
  return Status::corruption(fmt::format("{}: no vertex element", path));
}

// Whitespace tokenizer with line numbers, for NFF.
class Tokens {
 public:
  explicit Tokens(std::istream& in) : in_(in) {}
  bool next(std::string& tok) {
    while (true) {
      while (pos_ < line_.size() && std::isspace(static_cast<unsigned char>(line_[pos_]))) ++pos_;
      if (pos_ < line_.size() && line_[pos_] != '#') break;
      if (!std::getline(in_, line_)) return false;
      ++line_no_;
      pos_ = 0;
    }
    const size_t start = pos_;
    while (pos_ < line_.size() && !std::isspace(static_cast<unsigned char>(line_[pos_]))) ++pos_;
    tok = line_.substr(start, pos_ - start);
    return true;
  }
  // True when the next token on the current line starts like a number (NFF's optional light
  // colour); does not consume it.
  bool peek_number() const {
    size_t i = pos_;
    while (i < line_.size() && std::isspace(static_cast<unsigned char>(line_[i]))) ++i;
    return i < line_.size() && (std::isdigit(static_cast<unsigned char>(line_[i])) || line_[i] == '-' ||
                                line_[i] == '+' || line_[i] == '.');
  }
  size_t line() const { return line_no_; }

 private:
  std::istream& in_;
  std::string line_;
  size_t pos_ = 0, line_no_ = 0;
};

Result<Aabb> scan_nff(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::not_found(fmt::format("cannot open '{}': {}", path, std::strerror(errno)));
  Tokens t(in);
  Aabb box;
  std::string tok;
  auto number = [&](double& v) -> bool {
    std::string s;
    if (!t.next(s)) return false;
    char* end = nullptr;
    v = std::strtod(s.c_str(), &end);
    return end != s.c_str() && *end == '\0' && std::isfinite(v);
  };
  auto skip = [&](int n) {
    double v;
    for (int i = 0; i < n; ++i)
      if (!number(v)) return false;
    return true;
  };
  auto bad = [&](const std::string& what) {
    return Status::corruption(fmt::format("{}: line {}: {}", path, t.line(), what));
  };
  while (t.next(tok)) {
    if (tok == "v" || tok == "from" || tok == "at" || tok == "up") {
      if (tok != "v" && !skip(3)) return bad("bad view vector");
    } else if (tok == "angle" || tok == "hither") {
      if (!skip(1)) return bad("bad view number");
    } else if (tok == "resolution") {
      if (!skip(2)) return bad("bad resolution");
    } else if (tok == "b") {
      if (!skip(3)) return bad("bad background");
    } else if (tok == "l") {
      if (!skip(3)) return bad("bad light");
      if (t.peek_number() && !skip(3)) return bad("bad light colour");
    } else if (tok == "f") {
      if (!skip(8)) return bad("bad material");
    } else if (tok == "s") {
      double v[4];
      for (double& x : v)
        if (!number(x)) return bad("bad sphere");
      box.extend(Vec3(v[0], v[1], v[2]) - Vec3(std::abs(v[3])));
      box.extend(Vec3(v[0], v[1], v[2]) + Vec3(std::abs(v[3])));
    } else if (tok == "c") {
      double v[8];
      for (double& x : v)
        if (!number(x)) return bad("bad cone");
      const double r = std::max(std::abs(v[3]), std::abs(v[7]));
      for (int k : {0, 4}) {
        box.extend(Vec3(v[k], v[k + 1], v[k + 2]) - Vec3(r));
        box.extend(Vec3(v[k], v[k + 1], v[k + 2]) + Vec3(r));
      }
    } else if (tok == "p" || tok == "pp") {
      double n;
      if (!number(n) || n < 3 || n != std::floor(n)) return bad("bad polygon vertex count");
      for (int i = 0; i < static_cast<int>(n); ++i) {
        double v[3];
        for (double& x : v)
          if (!number(x)) return bad("bad polygon vertex");
        box.extend(Vec3(v[0], v[1], v[2]));
        if (tok == "pp" && !skip(3)) return bad("bad polygon normal");
      }
    } else {
      return bad(fmt::format("unknown keyword '{}'", tok));
    }
  }
  return box;
}

Result<Aabb> scan_obj(const std::string& path) {
  std::ifstream in(path);
  if (!in) return Status::not_found(fmt::format("cannot open '{}': {}", path, std::strerror(errno)));
  Aabb box;
  std::string line;
  size_t line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.size() < 2 || line[0] != 'v' || (line[1] != ' ' && line[1] != '\t')) continue;
    std::istringstream ls(line.substr(2));
    Vec3 p;
    if (!(ls >> p.x >> p.y >> p.z) || !finite(p))
      return Status::corruption(fmt::format("{}: line {}: bad vertex", path, line_no));
    box.extend(p);
  }
  return box;
}

}  // namespace

Result<Aabb> scan_model_bounds(const std::string& path) {
  const std::string ext = lower_extension(path);
  Result<Aabb> r = Status::invalid_argument(
      fmt::format("--model '{}': unknown extension (expected .ply, .nff or .obj)", path));
  if (ext == "ply") r = scan_ply(path);
  else if (ext == "nff") r = scan_nff(path);
  else if (ext == "obj") r = scan_obj(path);
  if (r && r->empty()) return Status::corruption(fmt::format("{}: no geometry", path));
  return r;
}

}  // namespace frontier::gen
