// PLY reader: ascii, binary_little_endian and binary_big_endian.
//
// The header is parsed with the text tokenizer (errors name its lines). The body is walked
// element by element in file order:
//   - `vertex`: x, y, z of any numeric type, optional nx, ny, nz, other properties (lists too)
//     skipped. In binary files with fixed-size vertex records the vertex section is mapped
//     read-only and indexed in place; otherwise the positions are kept in a vector.
//   - `face`: a `vertex_indices` (or `vertex_index`) list of any count/index integer types;
//     each record is one polygon, read when next() asks for it.
//   - `tristrips`: a `vertex_indices` list with -1 restarts; every triangle of a strip (with
//     the alternating winding) is its own polygon. Triangles that repeat a vertex are the
//     strip's stitching, not surface, and are skipped.
//   - anything else is skipped (binary: by size, walking lists).
// Binary errors name byte offsets. Counts are checked against the bytes left in the file
// before anything is allocated for them, so a garbled count fails cleanly.
#include "src/io/read_formats.h"
#include "src/io/text_tokenizer.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cstring>
#include <type_traits>

#include <sys/mman.h>
#include <unistd.h>

namespace frontier {
namespace {

enum class PlyType : uint8_t { Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32, Float64 };

bool parse_ply_type(std::string_view s, PlyType& t) {
  struct Name {
    std::string_view name;
    PlyType type;
  };
  static constexpr std::array<Name, 16> kNames = {{
      {"char", PlyType::Int8},     {"int8", PlyType::Int8},       {"uchar", PlyType::UInt8},
      {"uint8", PlyType::UInt8},   {"short", PlyType::Int16},     {"int16", PlyType::Int16},
      {"ushort", PlyType::UInt16}, {"uint16", PlyType::UInt16},   {"int", PlyType::Int32},
      {"int32", PlyType::Int32},   {"uint", PlyType::UInt32},     {"uint32", PlyType::UInt32},
      {"float", PlyType::Float32}, {"float32", PlyType::Float32}, {"double", PlyType::Float64},
      {"float64", PlyType::Float64},
  }};
  for (const Name& n : kNames) {
    if (n.name == s) {
      t = n.type;
      return true;
    }
  }
  return false;
}

constexpr size_t size_of(PlyType t) {
  switch (t) {
    case PlyType::Int8: case PlyType::UInt8: return 1;
    case PlyType::Int16: case PlyType::UInt16: return 2;
    case PlyType::Int32: case PlyType::UInt32: case PlyType::Float32: return 4;
    case PlyType::Float64: return 8;
  }
  return 1;
}

constexpr bool is_integer(PlyType t) { return t != PlyType::Float32 && t != PlyType::Float64; }

template <typename T>
inline T load(const uint8_t* p, bool swap) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  if constexpr (sizeof(T) > 1) {
    if (swap) {
      if constexpr (sizeof(T) == 2) {
        uint16_t u;
        std::memcpy(&u, &v, 2);
        u = __builtin_bswap16(u);
        std::memcpy(&v, &u, 2);
      } else if constexpr (sizeof(T) == 4) {
        uint32_t u;
        std::memcpy(&u, &v, 4);
        u = __builtin_bswap32(u);
        std::memcpy(&v, &u, 4);
      } else {
        uint64_t u;
        std::memcpy(&u, &v, 8);
        u = __builtin_bswap64(u);
        std::memcpy(&v, &u, 8);
      }
    }
  }
  return v;
}

// Calls f(T{}) with T the C++ type of PLY type t: the one switch over types that the
// decoders below share.
template <typename F>
inline decltype(auto) with_ply_type(PlyType t, F&& f) {
  switch (t) {
    case PlyType::Int8: return f(int8_t{});
    case PlyType::UInt8: return f(uint8_t{});
    case PlyType::Int16: return f(int16_t{});
    case PlyType::UInt16: return f(uint16_t{});
    case PlyType::Int32: return f(int32_t{});
    case PlyType::UInt32: return f(uint32_t{});
    case PlyType::Float32: return f(float{});
    case PlyType::Float64: break;
  }
  return f(double{});
}

inline double decode_double(const uint8_t* p, PlyType t, bool swap) {
  return with_ply_type(t, [&](auto type) -> double { return load<decltype(type)>(p, swap); });
}

// Decodes `count` indices of type T, each below `limit` (strips also take -1, as a signed
// value or as 0xffffffff, and store it as UINT32_MAX). On a bad index returns false with it.
template <typename T>
bool decode_indices_as(const uint8_t* q, size_t count, bool swap, uint32_t limit, bool strip,
                       uint32_t* out, int64_t& bad) {
  for (size_t j = 0; j < count; ++j) {
    const auto index = static_cast<int64_t>(load<T>(q + j * sizeof(T), swap));
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

// Integer types only (0 for the others).
inline int64_t decode_int(const uint8_t* p, PlyType t, bool swap) {
  return with_ply_type(t, [&](auto type) -> int64_t {
    using T = decltype(type);
    if constexpr (std::is_integral_v<T>) {
      return load<T>(p, swap);
    } else {
      return 0;
    }
  });
}

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::Float32;  // item type for lists
  bool is_list = false;
  PlyType count_type = PlyType::UInt8;
};

struct PlyElement {
  enum class Role { Other, Vertex, Face, Strip };
  std::string name;
  int64_t count = 0;
  int64_t line = 0;  // header line, for errors about the declaration
  std::vector<PlyProperty> props;
  Role role = Role::Other;
  int index_prop = -1;  // Face/Strip: the vertex_indices list

  // Bytes of one binary record, or -1 when it holds a list.
  int64_t fixed_size() const {
    int64_t n = 0;
    for (const PlyProperty& p : props) {
      if (p.is_list) return -1;
      n += static_cast<int64_t>(size_of(p.type));
    }
    return n;
  }
  // Fewest bytes one binary record can take (lists empty).
  int64_t min_size() const {
    int64_t n = 0;
    for (const PlyProperty& p : props) n += static_cast<int64_t>(size_of(p.is_list ? p.count_type : p.type));
    return n;
  }
};

// Buffered sequential reads of the binary body at explicit file offsets (pread), 1 MiB at a
// time. take(n) hands out n contiguous bytes (n <= kChunk).
class BinaryStream {
 public:
  static constexpr size_t kChunk = size_t{1} << 20;

  void init(int fd, uint64_t offset, uint64_t file_size) {
    fd_ = fd;
    buffer_offset_ = offset;
    file_size_ = file_size;
    const uint64_t body = file_size > offset ? file_size - offset : 0;
    capacity_ = static_cast<size_t>(std::min<uint64_t>(kChunk, body + 1));
    buffer_ = std::make_unique<uint8_t[]>(capacity_);
    pos_ = end_ = 0;
  }
  uint64_t offset() const { return buffer_offset_ + pos_; }
  uint64_t remaining() const { return file_size_ > offset() ? file_size_ - offset() : 0; }
  const Status& status() const { return status_; }

  // Next n bytes, or nullptr when the file ends first (or a read fails: see status()).
  const uint8_t* take(size_t n) {
    if (end_ - pos_ < n && !fill(n)) return nullptr;
    const uint8_t* p = buffer_.get() + pos_;
    pos_ += n;
    return p;
  }
  bool skip(uint64_t n) {
    if (n <= end_ - pos_) {
      pos_ += static_cast<size_t>(n);
      return true;
    }
    if (n > remaining()) return false;
    buffer_offset_ = offset() + n;
    pos_ = end_ = 0;
    return true;
  }

 private:
  bool fill(size_t n) {
    if (n > capacity_) {
      // Only possible when the body is smaller than n: the file ends first.
      return false;
    }
    const size_t have = end_ - pos_;
    std::memmove(buffer_.get(), buffer_.get() + pos_, have);
    buffer_offset_ += pos_;
    pos_ = 0;
    end_ = have;
    while (end_ < n) {
      const uint64_t at = buffer_offset_ + end_;
      if (at >= file_size_) return false;
      const size_t want = static_cast<size_t>(std::min<uint64_t>(capacity_ - end_, file_size_ - at));
      const ssize_t r = ::pread(fd_, buffer_.get() + end_, want, static_cast<off_t>(at));
      if (r < 0 && errno == EINTR) continue;
      if (r < 0) {
        status_ = Status::io_error(fmt::format("byte {}: read failed: {}", at, std::strerror(errno)));
        return false;
      }
      if (r == 0) return false;
      end_ += static_cast<size_t>(r);
    }
    return true;
  }

  int fd_ = -1;
  std::unique_ptr<uint8_t[]> buffer_;
  size_t capacity_ = 0;
  size_t pos_ = 0;
  size_t end_ = 0;
  uint64_t buffer_offset_ = 0;
  uint64_t file_size_ = 0;
  Status status_;
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
  Status parse_header();
  Status check_header();
  Status read_next(InputPrimitive& out, bool& end) override;
  Status load_vertices(const PlyElement& e);
  Status map_vertices(const PlyElement& e);
  Status skip_element(const PlyElement& e);
  Status read_index_list(const PlyElement& e, bool strip);
  Status emit_polygon(InputPrimitive& out);
  Status fetch(uint32_t i, Vec3& p, Vec3* n);

  // Ascii helpers.
  Status skip_ascii_record(const PlyElement& e);
  // One property of an ASCII record: a scalar, or a list's count and items.
  Status skip_ascii_property(const PlyProperty& p);
  // Binary helpers.
  Status binary_truncated(std::string_view what) const {
    if (!stream_.status().is_ok()) return Status::io_error(path_ + ": " + stream_.status().message());
    return byte_error(path_, stream_.offset(), fmt::format("truncated {}", what));
  }
  Status skip_binary_record(const PlyElement& e);
  Status skip_binary_record_property(const PlyProperty& p);

  std::string path_;
  TextTokenizer tok_;  // header, and the body of ascii files
  BinaryStream stream_;
  bool ascii_ = true;
  bool swap_ = false;  // binary byte order differs from the host's
  std::vector<PlyElement> elements_;
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
};

Status PlyReader::open(const std::string& path) {
  path_ = path;
  header_.materials.emplace_back();
  Status s = tok_.open(path, {.hash_comments = false});
  if (!s) return s;
  s = parse_header();
  if (!s) return s;
  if (!ascii_) stream_.init(tok_.fd(), body_offset_, tok_.size());
  return check_header();
}

Status PlyReader::parse_header() {
  std::string_view t;
  if (!tok_.next(t) || t != "ply") {
    if (!tok_.status().is_ok()) return tok_.status();
    return tok_.error("not a PLY file (no 'ply' magic)");
  }
  tok_.skip_line();
  bool have_format = false;
  for (;;) {
    if (!tok_.next(t)) return tok_.end_error("end_header");
    if (t == "end_header") {
      tok_.skip_line();
      break;
    }
    if (t == "comment" || t == "obj_info") {
      tok_.skip_line();
      continue;
    }
    if (t == "format") {
      std::string_view f, version;
      if (!tok_.next_on_line(f) || !tok_.next_on_line(version)) return tok_.error("format line needs a type and a version");
      if (f == "ascii") {
        ascii_ = true;
      } else if (f == "binary_little_endian" || f == "binary_big_endian") {
        ascii_ = false;
        const bool file_big = f == "binary_big_endian";
        swap_ = file_big != (std::endian::native == std::endian::big);
      } else {
        return tok_.error(fmt::format("unknown format {}", quote_token(f)));
      }
      if (version != "1.0" && version != "1") {
        return tok_.error(fmt::format("unsupported PLY version {}", quote_token(version)));
      }
      have_format = true;
    } else if (t == "element") {
      PlyElement e;
      std::string_view name;
      if (!tok_.next_on_line(name)) return tok_.error("element needs a name and a count");
      e.name = std::string(name);
      e.line = tok_.line();
      Status s = tok_.next_int_on_line(e.count, "element count");
      if (!s) return s;
      if (e.count < 0) return tok_.error(fmt::format("element {} has a negative count {}", e.name, e.count));
      elements_.push_back(std::move(e));
    } else if (t == "property") {
      if (elements_.empty()) return tok_.error("property before any element");
      PlyProperty p;
      std::string_view type, name;
      if (!tok_.next_on_line(type)) return tok_.error("property needs a type and a name");
      if (type == "list") {
        std::string_view count_type;
        if (!tok_.next_on_line(count_type) || !tok_.next_on_line(type)) return tok_.error("list property needs two types and a name");
        if (!parse_ply_type(count_type, p.count_type)) return tok_.error(fmt::format("unknown type {}", quote_token(count_type)));
        if (!is_integer(p.count_type)) return tok_.error("list count type must be an integer type");
        p.is_list = true;
      }
      if (!parse_ply_type(type, p.type)) return tok_.error(fmt::format("unknown type {}", quote_token(type)));
      if (!tok_.next_on_line(name)) return tok_.error("property needs a name");
      p.name = std::string(name);
      elements_.back().props.push_back(std::move(p));
    } else {
      return tok_.error(fmt::format("unknown header keyword {}", quote_token(t)));
    }
    if (!tok_.at_line_end()) {
      std::string_view extra;
      tok_.next_on_line(extra);
      return tok_.error(fmt::format("unexpected {} at the end of a header line", quote_token(extra)));
    }
    tok_.skip_line();
  }
  if (!tok_.status().is_ok()) return tok_.status();
  if (!have_format) return tok_.error("header has no format line");
  body_offset_ = tok_.offset();
  return Status::ok();
}

Status PlyReader::check_header() {
  bool have_vertex = false, have_strips = false;
  int64_t faces = 0;
  uint64_t body_left = tok_.size() > body_offset_ ? tok_.size() - body_offset_ : 0;
  for (PlyElement& e : elements_) {
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
    const auto find = [&](std::string_view name) {
      for (size_t k = 0; k < e.props.size(); ++k) {
        if (e.props[k].name == name) return static_cast<int>(k);
      }
      return -1;
    };
    if (e.name == "vertex") {
      if (have_vertex) return header_error("second vertex element");
      have_vertex = true;
      e.role = PlyElement::Role::Vertex;
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
      e.role = strip ? PlyElement::Role::Strip : PlyElement::Role::Face;
      e.index_prop = find("vertex_indices");
      if (e.index_prop < 0 && !strip) e.index_prop = find("vertex_index");
      if (e.index_prop < 0) return header_error(fmt::format("{} element has no vertex_indices list", e.name));
      const PlyProperty& p = e.props[e.index_prop];
      if (!p.is_list || !is_integer(p.type)) {
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
      end = true;
      return Status::ok();
    }
    const PlyElement& e = elements_[element_];
    switch (e.role) {
      case PlyElement::Role::Vertex: {
        Status s = load_vertices(e);
        if (!s) return s;
        ++element_;
        continue;
      }
      case PlyElement::Role::Other: {
        Status s = skip_element(e);
        if (!s) return s;
        ++element_;
        continue;
      }
      case PlyElement::Role::Face:
      case PlyElement::Role::Strip: {
        if (record_ >= e.count) {
          ++element_;
          record_ = 0;
          continue;
        }
        if (!vertices_ready_) {
          return Status::unsupported(fmt::format("{}: line {}: element {} comes before the vertex element",
                                                 path_, e.line, e.name));
        }
        const bool strip = e.role == PlyElement::Role::Strip;
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
Status PlyReader::read_index_list(const PlyElement& e, bool strip) {
  const auto index_error = [&](int64_t index) {
    std::string msg = fmt::format("{} index {} out of range ({} vertices)", strip ? "strip" : "face", index, vertex_count_);
    return ascii_ ? tok_.error(msg) : byte_error(path_, record_offset_, msg);
  };
  const auto size_error = [&](int64_t n) -> Status {
    std::string bad = strip ? (n < 0 ? fmt::format("strip has a negative length {}", n) : std::string())
                            : check_polygon_size(n, "face");
    if (bad.empty()) return Status::ok();
    return ascii_ ? tok_.error(bad) : byte_error(path_, record_offset_, bad);
  };
  if (ascii_) {
    indices_.clear();
    for (size_t k = 0; k < e.props.size(); ++k) {
      const PlyProperty& p = e.props[k];
      if (static_cast<int>(k) != e.index_prop) {
        if (Status s = skip_ascii_property(p); !s) return s;
        continue;
      }
      int64_t n = 0;
      Status s = tok_.next_int(n, strip ? "strip length" : "face vertex count");
      if (!s) return s;
      s = size_error(n);
      if (!s) return s;
      for (int64_t j = 0; j < n; ++j) {
        int64_t index = 0;
        s = tok_.next_int(index, "vertex index");
        if (!s) return s;
        if (strip && index == -1) {
          indices_.push_back(UINT32_MAX);
          continue;
        }
        if (index < 0 || index >= static_cast<int64_t>(vertex_count_)) return index_error(index);
        indices_.push_back(static_cast<uint32_t>(index));
      }
    }
  } else {
    record_offset_ = stream_.offset();
    for (size_t k = 0; k < e.props.size(); ++k) {
      const PlyProperty& p = e.props[k];
      if (static_cast<int>(k) != e.index_prop) {
        Status s = skip_binary_record_property(p);
        if (!s) return s;
        continue;
      }
      const uint8_t* c = stream_.take(size_of(p.count_type));
      if (c == nullptr) return binary_truncated(strip ? "strip" : "face list");
      const int64_t n = decode_int(c, p.count_type, swap_);
      if (strip ? n < 0 : (n < 3 || n > kMaxPolygonVertices)) return size_error(n);
      const size_t item = size_of(p.type);
      if (static_cast<uint64_t>(n) * item > stream_.remaining()) return binary_truncated(strip ? "strip" : "face list");
      indices_.resize(static_cast<size_t>(n));
      size_t done = 0;
      while (done < static_cast<size_t>(n)) {
        const size_t batch = std::min<size_t>(static_cast<size_t>(n) - done, BinaryStream::kChunk / 8);
        const uint8_t* q = stream_.take(batch * item);
        if (q == nullptr) return binary_truncated(strip ? "strip" : "face list");
        int64_t bad = 0;
        if (!decode_indices(q, p.type, batch, swap_, vertex_count_, strip, indices_.data() + done, bad)) {
          return index_error(bad);
        }
        done += batch;
      }
    }
  }
  if (strip) {
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
  return Status::ok();
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
    for (int k = 0; k < 3; ++k) p[k] = decode_double(r + field_offset_[k], field_type_[k], swap_);
  }
  if (!all_finite(p)) {
    return byte_error(path_, vertex_file_offset_ + static_cast<uint64_t>(i) * vertex_stride_,
                      fmt::format("vertex {} coordinate is not finite", i));
  }
  if (n != nullptr) {
    for (int k = 0; k < 3; ++k) (*n)[k] = decode_double(r + field_offset_[3 + k], field_type_[3 + k], swap_);
    if (!all_finite(*n)) {
      return byte_error(path_, vertex_file_offset_ + static_cast<uint64_t>(i) * vertex_stride_,
                        fmt::format("vertex {} normal is not finite", i));
    }
  }
  return Status::ok();
}

Status PlyReader::load_vertices(const PlyElement& e) {
  const int fields[6] = {x_prop_, y_prop_, z_prop_, nx_prop_, ny_prop_, nz_prop_};
  const int nfields = nx_prop_ >= 0 ? 6 : 3;
  if (!ascii_ && e.fixed_size() > 0) {
    Status s = map_vertices(e);
    if (!s) return s;
    if (vertex_base_ != nullptr || e.count == 0) {
      vertices_ready_ = true;
      return Status::ok();
    }
    // The mapping failed: fall back to reading the records.
  }
  positions_.reserve(static_cast<size_t>(e.count));
  if (nfields == 6) normals_.reserve(static_cast<size_t>(e.count));
  std::array<double, 6> v{};
  for (int64_t r = 0; r < e.count; ++r) {
    if (ascii_) {
      for (size_t k = 0; k < e.props.size(); ++k) {
        const PlyProperty& p = e.props[k];
        if (p.is_list) {
          if (Status s = skip_ascii_property(p); !s) return s;
          continue;
        }
        int f = 0;
        while (f < nfields && fields[f] != static_cast<int>(k)) ++f;
        if (f < nfields) {
          Status s = tok_.next_double(v[f], f < 3 ? "coordinate" : "normal coordinate");
          if (!s) return s;
          continue;
        }
        // Other properties must be numbers, but may be NaN (scanner confidence and the like).
        std::string_view t;
        double value = 0.0;
        bool finite = true;
        if (!tok_.next(t)) return tok_.end_error(p.name);
        if (!parse_double(t, value, finite)) {
          return tok_.error(fmt::format("expected a number ({}), got {}", p.name, quote_token(t)));
        }
      }
    } else {
      const uint64_t at = stream_.offset();
      for (size_t k = 0; k < e.props.size(); ++k) {
        const PlyProperty& p = e.props[k];
        if (p.is_list) {
          Status s = skip_binary_record_property(p);
          if (!s) return s;
          continue;
        }
        const uint8_t* q = stream_.take(size_of(p.type));
        if (q == nullptr) return binary_truncated("vertex");
        int f = 0;
        while (f < nfields && fields[f] != static_cast<int>(k)) ++f;
        if (f < nfields) v[f] = decode_double(q, p.type, swap_);
      }
      if (!all_finite(Vec3(v[0], v[1], v[2])) || !all_finite(Vec3(v[3], v[4], v[5]))) {
        return byte_error(path_, at, fmt::format("vertex {} coordinate is not finite", r));
      }
    }
    positions_.emplace_back(v[0], v[1], v[2]);
    if (nfields == 6) normals_.emplace_back(v[3], v[4], v[5]);
  }
  vertices_ready_ = true;
  return Status::ok();
}

Status PlyReader::map_vertices(const PlyElement& e) {
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
    offset += size_of(e.props[k].type);
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

Status PlyReader::skip_element(const PlyElement& e) {
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

Status PlyReader::skip_ascii_record(const PlyElement& e) {
  for (const PlyProperty& p : e.props) {
    if (Status s = skip_ascii_property(p); !s) return s;
  }
  return Status::ok();
}

Status PlyReader::skip_ascii_property(const PlyProperty& p) {
  std::string_view t;
  if (!p.is_list) return tok_.next(t) ? Status::ok() : tok_.end_error(p.name);
  int64_t n = 0;
  Status s = tok_.next_int(n, "list count");
  if (!s) return s;
  if (n < 0) return tok_.error(fmt::format("negative list count {}", n));
  for (int64_t j = 0; j < n; ++j) {
    if (!tok_.next(t)) return tok_.end_error("list item");
  }
  return Status::ok();
}

Status PlyReader::skip_binary_record(const PlyElement& e) {
  for (const PlyProperty& p : e.props) {
    Status s = skip_binary_record_property(p);
    if (!s) return s;
  }
  return Status::ok();
}

Status PlyReader::skip_binary_record_property(const PlyProperty& p) {
  if (!p.is_list) {
    if (!stream_.skip(size_of(p.type))) return binary_truncated(fmt::format("property {}", p.name));
    return Status::ok();
  }
  const uint64_t at = stream_.offset();
  const uint8_t* c = stream_.take(size_of(p.count_type));
  if (c == nullptr) return binary_truncated(fmt::format("list {}", p.name));
  const int64_t n = decode_int(c, p.count_type, swap_);
  if (n < 0) return byte_error(path_, at, fmt::format("list {} has a negative count {}", p.name, n));
  if (!stream_.skip(static_cast<uint64_t>(n) * size_of(p.type))) {
    return binary_truncated(fmt::format("list {}", p.name));
  }
  return Status::ok();
}

}  // namespace

Result<std::unique_ptr<SceneReader>> open_ply_reader(const std::string& path) {
  return open_format_reader<PlyReader>(path);
}

}  // namespace frontier
