// Streaming bounds scanners (see header).
#include "data_gen/model_bounds.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
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

int type_size(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32") return 4;
  if (t == "double" || t == "float64") return 8;
  return 0;
}

double read_scalar(const unsigned char* p, const std::string& t, bool swap) {
  unsigned char b[8];
  const int n = type_size(t);
  std::memcpy(b, p, static_cast<size_t>(n));
  if (swap) std::reverse(b, b + n);
  if (t == "float" || t == "float32") { float v; std::memcpy(&v, b, 4); return v; }
  if (t == "double" || t == "float64") { double v; std::memcpy(&v, b, 8); return v; }
  if (t == "char" || t == "int8") return static_cast<int8_t>(b[0]);
  if (t == "uchar" || t == "uint8") return b[0];
  if (t == "short" || t == "int16") { int16_t v; std::memcpy(&v, b, 2); return v; }
  if (t == "ushort" || t == "uint16") { uint16_t v; std::memcpy(&v, b, 2); return v; }
  if (t == "int" || t == "int32") { int32_t v; std::memcpy(&v, b, 4); return v; }
  uint32_t v;
  std::memcpy(&v, b, 4);
  return v;
}

struct PlyProperty {
  std::string type;  // a scalar type, or "COUNT_TYPE ITEM_TYPE" for a list
  bool list = false;
};
struct PlyElement {
  std::string name;
  uint64_t count = 0;
  std::vector<std::pair<std::string, PlyProperty>> props;  // (name, property) in file order
};
struct PlyHeader {
  std::string format;
  std::vector<PlyElement> elements;
};

// Reads the header up to and including end_header, leaving `in` at the first data byte.
Result<PlyHeader> read_ply_header(std::istream& in, const std::string& path) {
  PlyHeader header;
  std::string line;
  std::getline(in, line);
  if (line != "ply" && line != "ply\r") return Status::corruption(fmt::format("{}: not a PLY file", path));
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string word;
    ls >> word;
    if (word == "format") ls >> header.format;
    else if (word == "element") {
      PlyElement e;
      ls >> e.name >> e.count;
      header.elements.push_back(e);
    } else if (word == "property" && !header.elements.empty()) {
      std::string t, name;
      ls >> t;
      PlyProperty p;
      if (t == "list") {
        std::string count_type, item_type;
        ls >> count_type >> item_type >> name;
        p = {count_type + " " + item_type, true};
      } else {
        ls >> name;
        p = {t, false};
      }
      header.elements.back().props.emplace_back(name, p);
    } else if (word == "end_header") break;
  }
  if (!in) return Status::corruption(fmt::format("{}: PLY header has no end_header", path));
  return header;
}

// Where an element's scalar properties sit in a binary record, and which are x, y and z.
struct PlyRecord {
  size_t size = 0;              // bytes per record (valid when fixed)
  bool fixed = true;            // no list properties
  std::vector<size_t> offsets;  // of property k, when fixed
  int ix = -1, iy = -1, iz = -1;
};

Result<PlyRecord> ply_record(const PlyElement& e, const std::string& path) {
  PlyRecord r;
  for (size_t k = 0; k < e.props.size(); ++k) {
    const auto& [name, prop] = e.props[k];
    if (prop.list) { r.fixed = false; continue; }
    r.offsets.push_back(r.size);
    if (type_size(prop.type) == 0)
      return Status::corruption(fmt::format("{}: unknown PLY type '{}'", path, prop.type));
    r.size += static_cast<size_t>(type_size(prop.type));
    if (name == "x") r.ix = static_cast<int>(k);
    if (name == "y") r.iy = static_cast<int>(k);
    if (name == "z") r.iz = static_cast<int>(k);
  }
  return r;
}

// The bounds of an ASCII vertex element, one vertex a line.
Status scan_ascii_vertices(std::istream& in, const PlyElement& e, const PlyRecord& rec, const std::string& path,
                           Aabb& box) {
  std::string line;
  for (uint64_t r = 0; r < e.count; ++r) {
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
  uint64_t left = e.count, index = 0;
  while (left > 0) {
    const uint64_t n = std::min<uint64_t>(left, 65536);
    in.read(reinterpret_cast<char*>(buf.data()), static_cast<std::streamsize>(n * rec.size));
    if (!in) return Status::corruption(fmt::format("{}: truncated vertex data at vertex {}", path, index));
    for (uint64_t r = 0; r < n; ++r, ++index) {
      const unsigned char* bytes = buf.data() + r * rec.size;
      // No list properties here (checked by the caller), so property k sits at offsets[k].
      auto get = [&](int k) { return read_scalar(bytes + rec.offsets[size_t(k)], e.props[size_t(k)].second.type, swap); };
      const Vec3 p(get(rec.ix), get(rec.iy), get(rec.iz));
      if (!finite(p)) return Status::corruption(fmt::format("{}: vertex {} is not finite", path, index));
      box.extend(p);
    }
    left -= n;
  }
  return Status::ok();
}

// Skips the elements before the vertices (ASCII: a line per record; binary: fixed-size records
// only, since records with lists cannot be skipped without reading them) and scans the first
// vertex element.
Result<Aabb> scan_ply(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::not_found(fmt::format("cannot open '{}': {}", path, std::strerror(errno)));
  Result<PlyHeader> header = read_ply_header(in, path);
  if (!header) return header.status();
  const std::string& format = header->format;
  const bool ascii = format == "ascii";
  const bool big = format == "binary_big_endian";
  if (!ascii && !big && format != "binary_little_endian")
    return Status::corruption(fmt::format("{}: unknown PLY format '{}'", path, format));
  const bool swap = big == (std::endian::native == std::endian::little);

  Aabb box;
  for (const PlyElement& e : header->elements) {
    const bool is_vertex = e.name == "vertex";
    Result<PlyRecord> rec = ply_record(e, path);
    if (!rec) return rec.status();
    if (is_vertex && (rec->ix < 0 || rec->iy < 0 || rec->iz < 0))
      return Status::corruption(fmt::format("{}: vertex element lacks x, y or z", path));
    if (ascii) {
      if (is_vertex) {
        if (Status st = scan_ascii_vertices(in, e, *rec, path, box); !st) return st;
        return box;
      }
      std::string line;
      for (uint64_t r = 0; r < e.count; ++r) {
        if (!std::getline(in, line))
          return Status::corruption(fmt::format("{}: truncated PLY ({} {} expected)", path, e.count, e.name));
      }
      continue;
    }
    if (!rec->fixed) {
      if (is_vertex) return Status::unsupported(fmt::format("{}: list property in the vertex element", path));
      return Status::unsupported(fmt::format("{}: element '{}' with lists precedes the vertices", path, e.name));
    }
    if (!is_vertex) {
      in.seekg(static_cast<std::streamoff>(rec->size * e.count), std::ios::cur);
      continue;
    }
    if (Status st = scan_binary_vertices(in, e, *rec, swap, path, box); !st) return st;
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
