// PLY reader: ascii, binary_little_endian and binary_big_endian.
//
// The header is parsed by read_ply_header (ply_header.h: unknown header lines are skipped with
// a warning). The body is walked element by element in file order:
//   - `vertex`: x, y, z of any numeric type, optional nx, ny, nz, other properties (lists too)
//     skipped. In binary files with fixed-size vertex records the vertex section is mapped
//     read-only and indexed in place; otherwise the positions are kept in a vector.
//   - `face`: a `vertex_indices` (or `vertex_index`) list of any count/index integer types;
//     each record is one polygon, read when next() asks for it.
//   - `tristrips`: a `vertex_indices` list with -1 restarts; every triangle of a strip (with
//     the alternating winding) is its own polygon. Triangles that repeat a vertex are the
//     strip's stitching, not surface, and are skipped.
//   - anything else is skipped (binary: by size, walking lists).
// ASCII records are one line each; errors name the line of the record. Binary errors name byte
// offsets (a bad list count: where its record starts). Counts are checked against the bytes
// left in the file before anything is allocated for them, so a garbled count fails cleanly.
// Data after the last element (beyond blanks, in ASCII) is ignored with a warning.
#include "src/io/binary_stream.h"
#include "src/io/ply_header.h"
#include "src/io/read_formats.h"
#include "src/io/text_tokenizer.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <type_traits>

#include <sys/mman.h>
#include <unistd.h>

namespace frontier {
namespace {

// Decodes `count` indices of type T, each below `limit` (strips also take -1, as a signed
// value or as 0xffffffff, and store it as UINT32_MAX). On a bad index returns false with it.
template <typename T>
bool decode_indices_as(const uint8_t* q, size_t count, bool swap, uint32_t limit, bool strip,
                       uint32_t* out, int64_t& bad) {
  for (size_t j = 0; j < count; ++j) {
    const auto index = static_cast<int64_t>(load_scalar<T>(q + j * sizeof(T), swap));
    if (static_cast<uint64_t>(index) < limit) {
      out[j] = static_cast<uint32_t>(index);
    } else if (strip && (index == -1 || (sizeof(T) == 4 && index == int64_t{UINT32_MAX}))) {
      out[j] = UINT32_MAX;
    } else {
      bad = index;
      return false;
    }
  }
  return true;
}

bool decode_indices(const uint8_t* q, PlyType type, size_t count, bool swap, uint32_t limit,
                    bool strip, uint32_t* out, int64_t& bad) {
  return with_ply_type(type, [&](auto index_type) -> bool {
    using T = decltype(index_type);
    if constexpr (std::is_integral_v<T>) {
      return decode_indices_as<T>(q, count, swap, limit, strip, out, bad);
    } else {
      bad = 0;  // the header admits integer index types only
      return false;
    }
  });
}

// A PLY element as the reader walks it: its declaration and what the reader takes from it.
struct Element : PlyElement {
  enum class Role { Other, Vertex, Face, Strip };
  Role role = Role::Other;
  int index_prop = -1;  // Face/Strip: the vertex_indices list
};

class PlyReader final : public FormatReader {
 public:
  ~PlyReader() override {
    if (map_ != nullptr) ::munmap(map_, map_size_);
  }

  Status open(const std::string& path);

  int64_t declared_primitives() const override { return declared_; }
  bool binary() const override { return !ascii_; }
  uint64_t bytes_read() const override {
    if (element_ >= elements_.size()) return tok_.size();  // trailing bytes are not data
    return ascii_ ? tok_.offset() : stream_.offset();
  }
  uint64_t bytes_total() const override { return tok_.size(); }

 private:
  Status check_header();
  Status read_next(InputPrimitive& out, bool& end) override;
  Status load_vertices(const Element& e);
  Status map_vertices(const Element& e);
  Status skip_element(const Element& e);
  Status read_index_list(const Element& e, bool strip);
  Status emit_polygon(InputPrimitive& out);
  Status fetch(uint32_t i, Vec3& p, Vec3* n);
  // Which of x y z nx ny nz (0..5) vertex property k is, or -1.
  int vertex_field(size_t k) const;
  static std::string list_size_problem(int64_t n, bool strip);
  std::string index_problem(int64_t index, bool strip) const;
  void split_strip();
  // After the last element: a warning about data left in the file (once).
  void warn_trailing();

  // ASCII records are one line each, as the PLY format writes them: a record's first value may
  // follow blank lines, the others must be on its line and none may follow its last, so a bad
  // list count is reported on the line of its record (not where the misread file ends).
  Status ascii_token(std::string_view& t, bool first, std::string_view what);
  Status ascii_int(int64_t& n, bool first, std::string_view what);
  Status ascii_list_overrun(const PlyProperty& p, int64_t n, int64_t items) const;
  Status end_ascii_record(const Element& e);
  Status read_ascii_indices(const Element& e, bool strip);
  Status read_ascii_vertex(const Element& e, std::array<double, 6>& v);
  Status skip_ascii_record(const Element& e);
  // One property of an ASCII record: a scalar, or a list's count and items.
  Status skip_ascii_property(const PlyProperty& p, bool first);
  // Binary helpers. Errors about a record name the byte offset where it starts.
  Status binary_truncated(std::string_view what) const {
    if (!stream_.status().is_ok()) return Status::io_error(path_ + ": " + stream_.status().message());
    return byte_error(path_, stream_.offset(), fmt::format("truncated {}", what));
  }
  Status binary_list_overrun(const PlyProperty& p, int64_t n, uint64_t record_at) const;
  Status read_binary_indices(const Element& e, bool strip);
  Status read_binary_vertex(const Element& e, int64_t r, std::array<double, 6>& v);
  Status skip_binary_record(const Element& e);
  Status skip_binary_record_property(const PlyProperty& p, uint64_t record_at);

  std::string path_;
  TextTokenizer tok_;  // header, and the body of ascii files
  BinaryStream stream_;
  bool ascii_ = true;
  bool swap_ = false;  // binary byte order differs from the host's
  std::vector<Element> elements_;
  int64_t declared_ = 0;
  uint64_t body_offset_ = 0;

  // Vertex store: either mapped records or vectors.
  bool vertices_ready_ = false;
  uint32_t vertex_count_ = 0;
  int x_prop_ = -1, y_prop_ = -1, z_prop_ = -1;
  int nx_prop_ = -1, ny_prop_ = -1, nz_prop_ = -1;
  std::vector<Vec3> positions_;
  std::vector<Vec3> normals_;
  void* map_ = nullptr;
  size_t map_size_ = 0;
  const uint8_t* vertex_base_ = nullptr;  // record 0 in the mapping
  uint64_t vertex_file_offset_ = 0;
  size_t vertex_stride_ = 0;
  std::array<size_t, 6> field_offset_{};  // x y z nx ny nz within a record
  std::array<PlyType, 6> field_type_{};
  bool float_fast_ = false;  // mapped x y z are floats in the host byte order
  // Mapped vertex pages count in the process's RSS: once the 64 KiB blocks touched (the kernel
  // maps a fault's neighbours 64 KiB at a time) add up to kResidentWindow, they are dropped with
  // MADV_DONTNEED (the page cache keeps them), so a huge vertex element costs a bounded window.
  static constexpr size_t kResidentWindow = size_t{8} << 20;
  std::vector<uint64_t> touched_;  // a bit per 64 KiB block of the mapping
  size_t touched_blocks_ = 0;
  void touch(const uint8_t* record);

  // Walk state.
  size_t element_ = 0;
  int64_t record_ = 0;
  std::vector<uint32_t> indices_;                    // the current face / strip
  uint64_t record_offset_ = 0;                       // binary: where the current record starts
  std::vector<std::array<uint32_t, 3>> strip_tris_;  // triangles of the current strip
  size_t strip_next_ = 0;
  bool finished_ = false;  // the end was reported (and trailing data looked for)
};

Status PlyReader::open(const std::string& path) {
  path_ = path;
  header_.materials.emplace_back();
  Status s = tok_.open(path, {.hash_comments = false});
  if (!s) return s;
  PlyHeader header;
  s = read_ply_header(tok_, header);
  for (std::string& w : header.warnings) warn(std::move(w));
  if (!s) return s;
  ascii_ = header.ascii;
  swap_ = header.swap;
  body_offset_ = header.body_offset;
  for (PlyElement& e : header.elements) elements_.push_back(Element{std::move(e)});
  if (!ascii_) stream_.init(tok_.fd(), body_offset_, tok_.size());
  return check_header();
}

Status PlyReader::check_header() {
  bool have_vertex = false, have_strips = false;
  int64_t faces = 0;
  uint64_t body_left = tok_.size() > body_offset_ ? tok_.size() - body_offset_ : 0;
  for (Element& e : elements_) {
    const auto header_error = [&](std::string_view msg) {
      return Status::corruption(fmt::format("{}: line {}: {}", path_, e.line, msg));
    };
    // Every record takes at least min_size bytes (binary) or one byte per value (ascii).
    const int64_t min_record = ascii_ ? static_cast<int64_t>(e.props.size()) : e.min_size();
    if (min_record > 0 && e.count > static_cast<int64_t>(body_left / static_cast<uint64_t>(min_record))) {
      return header_error(fmt::format("element {} declares {} records, more than the {} bytes of data can hold",
                                      e.name, e.count, body_left));
    }
    if (!ascii_) body_left -= static_cast<uint64_t>(min_record * e.count);
    const auto find = [&e](std::string_view name) { return e.find(name); };
    if (e.name == "vertex") {
      if (have_vertex) return header_error("second vertex element");
      have_vertex = true;
      e.role = Element::Role::Vertex;
      x_prop_ = find("x");
      y_prop_ = find("y");
      z_prop_ = find("z");
      if (x_prop_ < 0 || y_prop_ < 0 || z_prop_ < 0) return header_error("vertex element lacks x, y or z");
      nx_prop_ = find("nx");
      ny_prop_ = find("ny");
      nz_prop_ = find("nz");
      if (nx_prop_ < 0 || ny_prop_ < 0 || nz_prop_ < 0) nx_prop_ = ny_prop_ = nz_prop_ = -1;
      for (int k : {x_prop_, y_prop_, z_prop_, nx_prop_, ny_prop_, nz_prop_}) {
        if (k >= 0 && e.props[k].is_list) return header_error(fmt::format("vertex property {} is a list", e.props[k].name));
      }
      if (e.count > int64_t{UINT32_MAX}) return header_error("more than 2^32 - 1 vertices");
      vertex_count_ = static_cast<uint32_t>(e.count);
    } else if (e.name == "face" || e.name == "tristrips") {
      const bool strip = e.name == "tristrips";
      e.role = strip ? Element::Role::Strip : Element::Role::Face;
      e.index_prop = find("vertex_indices");
      if (e.index_prop < 0 && !strip) e.index_prop = find("vertex_index");
      if (e.index_prop < 0) return header_error(fmt::format("{} element has no vertex_indices list", e.name));
      const PlyProperty& p = e.props[e.index_prop];
      if (!p.is_list || !ply_is_integer(p.type)) {
        return header_error(fmt::format("{} must be a list of integers", p.name));
      }
      if (strip) {
        have_strips = have_strips || e.count > 0;
      } else {
        faces += e.count;
      }
    }
  }
  declared_ = have_strips ? -1 : faces;
  return Status::ok();
}

Status PlyReader::read_next(InputPrimitive& out, bool& end) {
  for (;;) {
    if (strip_next_ < strip_tris_.size()) {
      const auto& tri = strip_tris_[strip_next_++];
      indices_.assign(tri.begin(), tri.end());
      return emit_polygon(out);
    }
    if (element_ >= elements_.size()) {
      if (!finished_) warn_trailing();
      finished_ = true;
      end = true;
      return Status::ok();
    }
    const Element& e = elements_[element_];
    switch (e.role) {
      case Element::Role::Vertex: {
        Status s = load_vertices(e);
        if (!s) return s;
        ++element_;
        continue;
      }
      case Element::Role::Other: {
        Status s = skip_element(e);
        if (!s) return s;
        ++element_;
        continue;
      }
      case Element::Role::Face:
      case Element::Role::Strip: {
        if (record_ >= e.count) {
          ++element_;
          record_ = 0;
          continue;
        }
        if (!vertices_ready_) {
          return Status::unsupported(fmt::format("{}: line {}: element {} comes before the vertex element",
                                                 path_, e.line, e.name));
        }
        const bool strip = e.role == Element::Role::Strip;
        Status s = read_index_list(e, strip);
        if (!s) return s;
        ++record_;
        if (strip) continue;  // its triangles are handed out at the top of the loop
        return emit_polygon(out);
      }
    }
  }
}

// Reads one face or strip record into indices_ (strips: then into strip_tris_), checking
// every index against the vertex count.
Status PlyReader::read_index_list(const Element& e, bool strip) {
  Status s = ascii_ ? read_ascii_indices(e, strip) : read_binary_indices(e, strip);
  if (s && strip) split_strip();
  return s;
}

Status PlyReader::read_ascii_indices(const Element& e, bool strip) {
  indices_.clear();
  for (size_t k = 0; k < e.props.size(); ++k) {
    const PlyProperty& p = e.props[k];
    const bool first = k == 0;
    if (static_cast<int>(k) != e.index_prop) {
      if (Status s = skip_ascii_property(p, first); !s) return s;
      continue;
    }
    int64_t n = 0;
    if (Status s = ascii_int(n, first, strip ? "strip length" : "face vertex count"); !s) return s;
    if (std::string bad = list_size_problem(n, strip); !bad.empty()) return tok_.error(bad);
    for (int64_t j = 0; j < n; ++j) {
      std::string_view t;
      int64_t index = 0;
      if (!tok_.next_on_line(t)) return ascii_list_overrun(p, n, j);
      if (!parse_int(t, index)) return tok_.error(fmt::format("expected an integer (vertex index), got {}", quote_token(t)));
      if (strip && index == -1) {
        indices_.push_back(UINT32_MAX);
        continue;
      }
      if (index < 0 || index >= static_cast<int64_t>(vertex_count_)) return tok_.error(index_problem(index, strip));
      indices_.push_back(static_cast<uint32_t>(index));
    }
  }
  return end_ascii_record(e);
}

Status PlyReader::read_binary_indices(const Element& e, bool strip) {
  record_offset_ = stream_.offset();
  for (size_t k = 0; k < e.props.size(); ++k) {
    const PlyProperty& p = e.props[k];
    if (static_cast<int>(k) != e.index_prop) {
      if (Status s = skip_binary_record_property(p, record_offset_); !s) return s;
      continue;
    }
    const uint8_t* c = stream_.take(ply_type_size(p.count_type));
    if (c == nullptr) return binary_truncated(strip ? "strip" : "face list");
    const int64_t n = ply_decode_int(c, p.count_type, swap_);
    if (std::string bad = list_size_problem(n, strip); !bad.empty()) return byte_error(path_, record_offset_, bad);
    const size_t item = ply_type_size(p.type);
    if (static_cast<uint64_t>(n) * item > stream_.remaining()) return binary_list_overrun(p, n, record_offset_);
    indices_.resize(static_cast<size_t>(n));
    size_t done = 0;
    while (done < static_cast<size_t>(n)) {
      const size_t batch = std::min<size_t>(static_cast<size_t>(n) - done, BinaryStream::kChunk / 8);
      const uint8_t* q = stream_.take(batch * item);
      if (q == nullptr) return binary_truncated(strip ? "strip" : "face list");
      int64_t bad = 0;
      if (!decode_indices(q, p.type, batch, swap_, vertex_count_, strip, indices_.data() + done, bad)) {
        return byte_error(path_, record_offset_, index_problem(bad, strip));
      }
      done += batch;
    }
  }
  return Status::ok();
}

// The triangles of the strip in indices_, into strip_tris_.
void PlyReader::split_strip() {
  strip_tris_.clear();
  strip_next_ = 0;
  size_t run = 0;  // vertices since the last restart
  for (size_t j = 0; j < indices_.size(); ++j) {
    if (indices_[j] == UINT32_MAX) {
      run = 0;
      continue;
    }
    ++run;
    if (run < 3) continue;
    const uint32_t a = indices_[j - 2], b = indices_[j - 1], c = indices_[j];
    if (a == b || b == c || a == c) continue;
    // Every other triangle of a strip is wound the other way round.
    if ((run - 3) % 2 == 0) {
      strip_tris_.push_back({a, b, c});
    } else {
      strip_tris_.push_back({b, a, c});
    }
  }
}

std::string PlyReader::list_size_problem(int64_t n, bool strip) {
  if (!strip) return check_polygon_size(n, "face");
  return n < 0 ? fmt::format("strip has a negative length {}", n) : std::string();
}

std::string PlyReader::index_problem(int64_t index, bool strip) const {
  return fmt::format("{} index {} out of range ({} vertices)", strip ? "strip" : "face", index, vertex_count_);
}

Status PlyReader::emit_polygon(InputPrimitive& out) {
  out.kind = InputPrimitive::Kind::Polygon;
  out.material = 0;
  const size_t n = indices_.size();
  out.vertices.resize(n);
  const bool with_normals = nx_prop_ >= 0;
  out.normals.resize(with_normals ? n : 0);
  if (float_fast_ && !with_normals) {
    // The common case (mapped little-endian float positions) without a Status per vertex.
    bool finite = true;
    for (size_t k = 0; k < n; ++k) {
      const uint8_t* r = vertex_base_ + static_cast<size_t>(indices_[k]) * vertex_stride_;
      touch(r);
      float f[3];
      std::memcpy(&f[0], r + field_offset_[0], 4);
      std::memcpy(&f[1], r + field_offset_[1], 4);
      std::memcpy(&f[2], r + field_offset_[2], 4);
      out.vertices[k] = Vec3(f[0], f[1], f[2]);
      finite = finite && all_finite(out.vertices[k]);
    }
    if (finite) return Status::ok();
  }
  for (size_t k = 0; k < n; ++k) {
    Status s = fetch(indices_[k], out.vertices[k], with_normals ? &out.normals[k] : nullptr);
    if (!s) return s;
  }
  return Status::ok();
}

void PlyReader::touch(const uint8_t* record) {
  const uintptr_t base = reinterpret_cast<uintptr_t>(map_) >> 16;
  for (const uint8_t* at : {record, record + vertex_stride_ - 1}) {
    const uintptr_t block = (reinterpret_cast<uintptr_t>(at) >> 16) - base;
    uint64_t& word = touched_[block / 64];
    if ((word >> (block % 64) & 1) != 0) continue;
    word |= uint64_t{1} << (block % 64);
    if (++touched_blocks_ * (size_t{1} << 16) < kResidentWindow) continue;
    ::madvise(map_, map_size_, MADV_DONTNEED);
    std::fill(touched_.begin(), touched_.end(), 0);
    touched_blocks_ = 0;
  }
}

Status PlyReader::fetch(uint32_t i, Vec3& p, Vec3* n) {
  if (vertex_base_ == nullptr) {
    p = positions_[i];
    if (n != nullptr) *n = normals_[i];
    return Status::ok();
  }
  const uint8_t* r = vertex_base_ + static_cast<size_t>(i) * vertex_stride_;
  touch(r);
  if (float_fast_) {
    float f[3];
    std::memcpy(&f[0], r + field_offset_[0], 4);
    std::memcpy(&f[1], r + field_offset_[1], 4);
    std::memcpy(&f[2], r + field_offset_[2], 4);
    p = Vec3(f[0], f[1], f[2]);
  } else {
    for (int k = 0; k < 3; ++k) p[k] = ply_decode_double(r + field_offset_[k], field_type_[k], swap_);
  }
  if (!all_finite(p)) {
    return byte_error(path_, vertex_file_offset_ + static_cast<uint64_t>(i) * vertex_stride_,
                      fmt::format("vertex {} coordinate is not finite", i));
  }
  if (n != nullptr) {
    for (int k = 0; k < 3; ++k) (*n)[k] = ply_decode_double(r + field_offset_[3 + k], field_type_[3 + k], swap_);
    if (!all_finite(*n)) {
      return byte_error(path_, vertex_file_offset_ + static_cast<uint64_t>(i) * vertex_stride_,
                        fmt::format("vertex {} normal is not finite", i));
    }
  }
  return Status::ok();
}

Status PlyReader::load_vertices(const Element& e) {
  if (!ascii_ && e.fixed_size() > 0) {
    Status s = map_vertices(e);
    if (!s) return s;
    if (vertex_base_ != nullptr || e.count == 0) {
      vertices_ready_ = true;
      return Status::ok();
    }
    // The mapping failed: fall back to reading the records.
  }
  const bool with_normals = nx_prop_ >= 0;
  positions_.reserve(static_cast<size_t>(e.count));
  if (with_normals) normals_.reserve(static_cast<size_t>(e.count));
  std::array<double, 6> v{};
  for (int64_t r = 0; r < e.count; ++r) {
    Status s = ascii_ ? read_ascii_vertex(e, v) : read_binary_vertex(e, r, v);
    if (!s) return s;
    positions_.emplace_back(v[0], v[1], v[2]);
    if (with_normals) normals_.emplace_back(v[3], v[4], v[5]);
  }
  vertices_ready_ = true;
  return Status::ok();
}

int PlyReader::vertex_field(size_t k) const {
  const int fields[6] = {x_prop_, y_prop_, z_prop_, nx_prop_, ny_prop_, nz_prop_};
  const int nfields = nx_prop_ >= 0 ? 6 : 3;
  for (int f = 0; f < nfields; ++f) {
    if (fields[f] == static_cast<int>(k)) return f;
  }
  return -1;
}

Status PlyReader::read_ascii_vertex(const Element& e, std::array<double, 6>& v) {
  for (size_t k = 0; k < e.props.size(); ++k) {
    const PlyProperty& p = e.props[k];
    const bool first = k == 0;
    if (p.is_list) {
      if (Status s = skip_ascii_property(p, first); !s) return s;
      continue;
    }
    if (const int f = vertex_field(k); f >= 0) {
      const std::string_view what = f < 3 ? "coordinate" : "normal coordinate";
      Status s = first ? tok_.next_double(v[f], what) : tok_.next_double_on_line(v[f], what);
      if (!s) return s;
      continue;
    }
    // Other properties must be numbers, but may be NaN (scanner confidence and the like).
    std::string_view t;
    double value = 0.0;
    bool finite = true;
    if (Status s = ascii_token(t, first, p.name); !s) return s;
    if (!parse_double(t, value, finite)) {
      return tok_.error(fmt::format("expected a number ({}), got {}", p.name, quote_token(t)));
    }
  }
  return end_ascii_record(e);
}

Status PlyReader::read_binary_vertex(const Element& e, int64_t r, std::array<double, 6>& v) {
  const uint64_t at = stream_.offset();
  for (size_t k = 0; k < e.props.size(); ++k) {
    const PlyProperty& p = e.props[k];
    if (p.is_list) {
      if (Status s = skip_binary_record_property(p, at); !s) return s;
      continue;
    }
    const uint8_t* q = stream_.take(ply_type_size(p.type));
    if (q == nullptr) return binary_truncated("vertex");
    if (const int f = vertex_field(k); f >= 0) v[f] = ply_decode_double(q, p.type, swap_);
  }
  if (!all_finite(Vec3(v[0], v[1], v[2])) || !all_finite(Vec3(v[3], v[4], v[5]))) {
    return byte_error(path_, at, fmt::format("vertex {} coordinate is not finite", r));
  }
  return Status::ok();
}

Status PlyReader::map_vertices(const Element& e) {
  const auto stride = static_cast<size_t>(e.fixed_size());
  const uint64_t start = stream_.offset();
  const uint64_t bytes = static_cast<uint64_t>(e.count) * stride;
  if (bytes > stream_.remaining()) {
    return byte_error(path_, start, fmt::format("truncated vertex element ({} bytes needed, {} left)", bytes,
                                                stream_.remaining()));
  }
  if (e.count == 0) return Status::ok();
  const auto page = static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
  const uint64_t map_start = start / page * page;
  map_size_ = static_cast<size_t>(start + bytes - map_start);
  void* m = ::mmap(nullptr, map_size_, PROT_READ, MAP_PRIVATE, tok_.fd(), static_cast<off_t>(map_start));
  if (m == MAP_FAILED) {
    map_size_ = 0;
    return Status::ok();  // the caller reads the records instead
  }
  ::madvise(m, map_size_, MADV_WILLNEED);
  map_ = m;
  touched_.assign((map_size_ >> 16) / 64 + 2, 0);
  vertex_base_ = static_cast<const uint8_t*>(m) + (start - map_start);
  vertex_file_offset_ = start;
  vertex_stride_ = stride;
  size_t offset = 0;
  std::vector<size_t> offsets(e.props.size());
  for (size_t k = 0; k < e.props.size(); ++k) {
    offsets[k] = offset;
    offset += ply_type_size(e.props[k].type);
  }
  const int fields[6] = {x_prop_, y_prop_, z_prop_, nx_prop_, ny_prop_, nz_prop_};
  for (int f = 0; f < 6; ++f) {
    if (fields[f] < 0) continue;
    field_offset_[f] = offsets[fields[f]];
    field_type_[f] = e.props[fields[f]].type;
  }
  float_fast_ = !swap_ && field_type_[0] == PlyType::Float32 && field_type_[1] == PlyType::Float32 &&
                field_type_[2] == PlyType::Float32;
  stream_.skip(bytes);
  return Status::ok();
}

Status PlyReader::skip_element(const Element& e) {
  if (e.props.empty()) return Status::ok();
  if (!ascii_) {
    const int64_t fixed = e.fixed_size();
    if (fixed >= 0) {
      const uint64_t bytes = static_cast<uint64_t>(e.count) * static_cast<uint64_t>(fixed);
      if (!stream_.skip(bytes)) return binary_truncated(fmt::format("element {}", e.name));
      return Status::ok();
    }
  }
  for (int64_t r = 0; r < e.count; ++r) {
    Status s = ascii_ ? skip_ascii_record(e) : skip_binary_record(e);
    if (!s) return s;
  }
  return Status::ok();
}

Status PlyReader::ascii_token(std::string_view& t, bool first, std::string_view what) {
  if (first ? tok_.next(t) : tok_.next_on_line(t)) return Status::ok();
  if (!tok_.status().is_ok()) return tok_.status();
  return first ? tok_.end_error(what) : tok_.error(fmt::format("line ends before {}", what));
}

Status PlyReader::ascii_int(int64_t& n, bool first, std::string_view what) {
  return first ? tok_.next_int(n, what) : tok_.next_int_on_line(n, what);
}

Status PlyReader::ascii_list_overrun(const PlyProperty& p, int64_t n, int64_t items) const {
  if (!tok_.status().is_ok()) return tok_.status();
  return tok_.error(fmt::format("list {} has the count {} but its line ends after {} items", p.name, n, items));
}

Status PlyReader::end_ascii_record(const Element& e) {
  if (!tok_.at_line_end()) {
    return tok_.error(fmt::format("more values on the line than element {} has properties (is a list count too small?)",
                                  e.name));
  }
  tok_.skip_line();
  return Status::ok();
}

Status PlyReader::skip_ascii_record(const Element& e) {
  for (size_t k = 0; k < e.props.size(); ++k) {
    if (Status s = skip_ascii_property(e.props[k], k == 0); !s) return s;
  }
  return end_ascii_record(e);
}

Status PlyReader::skip_ascii_property(const PlyProperty& p, bool first) {
  std::string_view t;
  if (!p.is_list) return ascii_token(t, first, p.name);
  int64_t n = 0;
  if (Status s = ascii_int(n, first, "list count"); !s) return s;
  if (n < 0) return tok_.error(fmt::format("negative list count {}", n));
  for (int64_t j = 0; j < n; ++j) {
    if (!tok_.next_on_line(t)) return ascii_list_overrun(p, n, j);
  }
  return Status::ok();
}

Status PlyReader::skip_binary_record(const Element& e) {
  const uint64_t at = stream_.offset();
  for (const PlyProperty& p : e.props) {
    if (Status s = skip_binary_record_property(p, at); !s) return s;
  }
  return Status::ok();
}

Status PlyReader::skip_binary_record_property(const PlyProperty& p, uint64_t record_at) {
  if (!p.is_list) {
    if (!stream_.skip(ply_type_size(p.type))) return binary_truncated(fmt::format("property {}", p.name));
    return Status::ok();
  }
  const uint8_t* c = stream_.take(ply_type_size(p.count_type));
  if (c == nullptr) return binary_truncated(fmt::format("list {}", p.name));
  const int64_t n = ply_decode_int(c, p.count_type, swap_);
  if (n < 0) return byte_error(path_, record_at, fmt::format("list {} has a negative count {}", p.name, n));
  if (static_cast<uint64_t>(n) * ply_type_size(p.type) > stream_.remaining()) return binary_list_overrun(p, n, record_at);
  stream_.skip(static_cast<uint64_t>(n) * ply_type_size(p.type));
  return Status::ok();
}

Status PlyReader::binary_list_overrun(const PlyProperty& p, int64_t n, uint64_t record_at) const {
  return byte_error(path_, record_at,
                    fmt::format("truncated record: list {} has the count {} ({} bytes) but only {} bytes are left", p.name, n,
                                static_cast<uint64_t>(n) * ply_type_size(p.type), stream_.remaining()));
}

void PlyReader::warn_trailing() {
  if (ascii_) {
    warn_trailing_text(tok_);
  } else if (stream_.offset() < tok_.size()) {
    warn(trailing_data_warning(path_, stream_.offset(), tok_.size() - stream_.offset()));
  }
}

}  // namespace

Result<std::unique_ptr<SceneReader>> open_ply_reader(const std::string& path) {
  return open_format_reader<PlyReader>(path);
}

}  // namespace frontier
