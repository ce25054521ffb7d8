// Spill files (layout in spill.h and preprocess/README.md "Spill files").
#include "preprocess/spill.h"

#include "store/byte_stream.h"

#include <fmt/format.h>

#include <bit>
#include <cerrno>
#include <cstring>
#include <span>

namespace frontier {
namespace {

constexpr size_t kBufferBytes = 4 << 20;
constexpr size_t kLargestRecord = 512;  // a quadric: 1 + 15 + 8 * 57 bytes; a triangle at most 163

// The tag byte.
constexpr uint8_t kKindMask = 0x07;
constexpr uint8_t kHasNormals = 0x08;
constexpr uint8_t kNextSource = 0x10;    // source = the previous record's + 1
constexpr uint8_t kSameMaterial = 0x20;  // material = the previous record's
constexpr int kModeShift = 6;            // bits 6-7: how new positions are stored
enum PositionMode : uint8_t { kOnLattice = 0, kFloats = 1, kDoubles = 2 };
// Bit 15 of a triangle's refs: new vertices' normals are doubles (else floats).
constexpr uint16_t kNormalDoubles = 0x8000;
constexpr int kNewVertex = SpillVertexCache::kSlots;

constexpr size_t geometry_doubles(PrimKind kind) {
  switch (kind) {
    case PrimKind::Triangle: return 0;  // coded apart
    case PrimKind::Sphere: return 4;
    case PrimKind::Box: return 6;
    case PrimKind::Cone: return 8;
    case PrimKind::Quadric: return 10 + 4 * Quadric::kMaxClipPlanes + 6 + 1;
  }
  return 0;
}

uint64_t zigzag(int64_t v) { return (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63); }
int64_t unzigzag(uint64_t v) { return static_cast<int64_t>(v >> 1) ^ -static_cast<int64_t>(v & 1); }

bool same_bits(const Vec3& a, const Vec3& b) { return std::memcmp(&a, &b, sizeof(Vec3)) == 0; }
bool float_exact(const Vec3& v) {
  for (int a = 0; a < 3; ++a) {
    if (std::bit_cast<uint64_t>(static_cast<double>(static_cast<float>(v[a]))) != std::bit_cast<uint64_t>(v[a])) {
      return false;
    }
  }
  return true;
}

uint64_t vertex_key(const Vec3& p, const Vec3* n) {
  uint64_t k = std::bit_cast<uint64_t>(p.x) * 0x9e3779b97f4a7c15ull;
  k ^= std::bit_cast<uint64_t>(p.y) * 0xc2b2ae3d27d4eb4full + (k << 6) + (k >> 2);
  k ^= std::bit_cast<uint64_t>(p.z) * 0x165667b19e3779f9ull + (k << 6) + (k >> 2);
  if (n != nullptr) k ^= std::bit_cast<uint64_t>(n->x + 2.0 * n->y + 3.0 * n->z) * 0x27d4eb2f165667c5ull;
  return k;
}

// Appends at `at` (the writer's buffer always has room for one more record).
class Put {
 public:
  explicit Put(uint8_t* at) : at_(at) {}
  uint8_t* at() const { return at_; }
  void u8(uint8_t v) { *at_++ = v; }
  void u16(uint16_t v) { raw(&v, 2); }
  void varint(uint64_t v) {
    while (v >= 0x80) {
      *at_++ = static_cast<uint8_t>(v | 0x80);
      v >>= 7;
    }
    *at_++ = static_cast<uint8_t>(v);
  }
  void f64(const double* v, size_t n) { raw(v, 8 * n); }
  void vec(const Vec3& v, bool doubles) {
    if (doubles) {
      f64(&v.x, 3);
      return;
    }
    const float f[3] = {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
    raw(f, sizeof(f));
  }

 private:
  void raw(const void* p, size_t n) {
    std::memcpy(at_, p, n);
    at_ += n;
  }
  uint8_t* at_;
};

// A triangle's refs and new vertices (tag written by the caller, mode bits filled in here).
void put_triangle(Put& out, uint8_t& tag, SpillCodecState& st, const Triangle& t, const std::array<Vec3, 3>* normals) {
  const Vec3 v[3] = {t.v0, t.v1, t.v2};
  int slot[3];
  bool on_lattice = st.lattice.has_value(), floats = true, normal_floats = true;
  LatticeIndex q[3];
  for (int k = 0; k < 3; ++k) {
    const Vec3* n = normals != nullptr ? &(*normals)[static_cast<size_t>(k)] : nullptr;
    slot[k] = st.cache.find(v[k], n);
    if (slot[k] != kNewVertex) continue;
    if (on_lattice) {
      q[k] = st.lattice->quantize(v[k]);
      on_lattice = same_bits(st.lattice->point(q[k]), v[k]);
    }
    floats = floats && float_exact(v[k]);
    normal_floats = normal_floats && (n == nullptr || float_exact(*n));
  }
  const PositionMode mode = on_lattice ? kOnLattice : floats ? kFloats : kDoubles;
  tag = static_cast<uint8_t>(tag | mode << kModeShift);
  out.u16(static_cast<uint16_t>(slot[0] | slot[1] << 5 | slot[2] << 10 | (normal_floats ? 0 : kNormalDoubles)));
  for (int k = 0; k < 3; ++k) {
    if (slot[k] != kNewVertex) continue;
    if (mode == kOnLattice) {
      for (int a = 0; a < 3; ++a) out.varint(zigzag(q[k][a] - st.last_index[a]));
      st.last_index = q[k];
    } else {
      out.vec(v[k], mode == kDoubles);
    }
    const Vec3* n = normals != nullptr ? &(*normals)[static_cast<size_t>(k)] : nullptr;
    if (n != nullptr) out.vec(*n, !normal_floats);
  }
  for (int k = 0; k < 3; ++k) {
    if (slot[k] == kNewVertex) st.cache.push(v[k], normals != nullptr ? &(*normals)[static_cast<size_t>(k)] : nullptr);
  }
}

// Writes primitive i of `scene` at `at`; returns the end of the record.
uint8_t* put_record(uint8_t* at, SpillCodecState& st, const Scene& scene, uint32_t i) {
  const PrimRef& p = scene.prims[i];
  const bool normals = p.kind == PrimKind::Triangle && !scene.triangle_normals.empty();
  uint8_t& tag = *at;
  tag = static_cast<uint8_t>(static_cast<uint8_t>(p.kind) | (normals ? kHasNormals : 0));
  Put out(at + 1);
  if (p.source == st.source + 1) {
    tag |= kNextSource;
  } else {
    out.varint(zigzag(static_cast<int64_t>(p.source) - static_cast<int64_t>(st.source)));
  }
  if (p.material == st.material) {
    tag |= kSameMaterial;
  } else {
    out.varint(p.material);
  }
  st.source = p.source;
  st.material = p.material;
  switch (p.kind) {
    case PrimKind::Triangle:
      put_triangle(out, tag, st, scene.triangles[p.index], normals ? &scene.triangle_normals[p.index] : nullptr);
      break;
    case PrimKind::Sphere: {
      const Sphere& s = scene.spheres[p.index];
      out.f64(&s.center.x, 3);
      out.f64(&s.radius, 1);
      break;
    }
    case PrimKind::Box:
      out.f64(&scene.boxes[p.index].bounds.lo.x, 3);
      out.f64(&scene.boxes[p.index].bounds.hi.x, 3);
      break;
    case PrimKind::Cone: {
      const Cone& c = scene.cones[p.index];
      out.f64(&c.base.x, 3);
      out.f64(&c.base_radius, 1);
      out.f64(&c.apex.x, 3);
      out.f64(&c.apex_radius, 1);
      break;
    }
    case PrimKind::Quadric: {
      const Quadric& q = scene.quadrics[p.index];
      out.f64(q.coeff.data(), 10);
      for (const Vec4& c : q.clip) out.f64(&c.x, 4);
      out.f64(&q.bounds.lo.x, 3);
      out.f64(&q.bounds.hi.x, 3);
      const double count = q.clip_count;
      out.f64(&count, 1);
      break;
    }
  }
  return out.at();
}

// Reading a record from a bounds-checked span.
double get_f64(store::ByteReader& r) { return std::bit_cast<double>(r.u64()); }
Vec3 get_vec(store::ByteReader& r, bool doubles) {
  if (doubles) {
    const double x = get_f64(r), y = get_f64(r);
    return {x, y, get_f64(r)};
  }
  const float x = std::bit_cast<float>(r.u32()), y = std::bit_cast<float>(r.u32());
  return {x, y, std::bit_cast<float>(r.u32())};
}

// A triangle's refs and new vertices; false for values no writer makes.
bool get_triangle(store::ByteReader& r, uint8_t tag, SpillCodecState& st, Triangle& t, std::array<Vec3, 3>* normals) {
  const auto mode = static_cast<PositionMode>(tag >> kModeShift);
  const uint8_t low = r.u8();
  const auto refs = static_cast<uint16_t>(low | r.u8() << 8);
  if (mode > kDoubles || (mode == kOnLattice && !st.lattice)) return false;
  Vec3 v[3];
  bool fresh[3];
  for (int k = 0; k < 3; ++k) {
    const int slot = refs >> (5 * k) & 31;
    fresh[k] = slot == kNewVertex;
    Vec3* n = normals != nullptr ? &(*normals)[static_cast<size_t>(k)] : nullptr;
    if (!fresh[k]) {
      v[k] = st.cache.position(slot);
      if (n != nullptr) *n = st.cache.normal(slot);
      continue;
    }
    if (mode == kOnLattice) {
      const int64_t last = (int64_t{1} << st.lattice->bits) - 1;
      for (int a = 0; a < 3; ++a) {
        st.last_index[a] = static_cast<int64_t>(static_cast<uint64_t>(st.last_index[a]) +
                                                static_cast<uint64_t>(unzigzag(r.varint())));
        if (st.last_index[a] < 0 || st.last_index[a] > last) return false;
      }
      v[k] = st.lattice->point(st.last_index);
    } else {
      v[k] = get_vec(r, mode == kDoubles);
    }
    if (n != nullptr) *n = get_vec(r, (refs & kNormalDoubles) != 0);
  }
  for (int k = 0; k < 3; ++k) {
    if (fresh[k]) st.cache.push(v[k], normals != nullptr ? &(*normals)[static_cast<size_t>(k)] : nullptr);
  }
  t = {v[0], v[1], v[2]};
  return true;
}

// Appends the record at the reader's position to `batch`; false for a torn or bad record.
bool get_record(store::ByteReader& r, SpillCodecState& st, Scene& batch) {
  const uint8_t tag = r.u8();
  if ((tag & kKindMask) > static_cast<uint8_t>(PrimKind::Quadric)) return false;
  const auto kind = static_cast<PrimKind>(tag & kKindMask);
  st.source = (tag & kNextSource) != 0 ? st.source + 1
                                       : static_cast<uint32_t>(static_cast<int64_t>(st.source) + unzigzag(r.varint()));
  if ((tag & kSameMaterial) == 0) st.material = static_cast<uint32_t>(r.varint());
  if (kind == PrimKind::Triangle) {
    Triangle t;
    std::array<Vec3, 3> normals;
    const bool with_normals = (tag & kHasNormals) != 0;
    if (!get_triangle(r, tag, st, t, with_normals ? &normals : nullptr) || !r.ok()) return false;
    batch.add_triangle(t, st.source, st.material, with_normals ? &normals : nullptr);
    return true;
  }
  double g[geometry_doubles(PrimKind::Quadric)];
  for (size_t k = 0; k < geometry_doubles(kind); ++k) g[k] = get_f64(r);
  if (!r.ok()) return false;
  switch (kind) {
    case PrimKind::Triangle: break;
    case PrimKind::Sphere: batch.add_sphere({{g[0], g[1], g[2]}, g[3]}, st.source, st.material); break;
    case PrimKind::Box: batch.add_box({Aabb({g[0], g[1], g[2]}, {g[3], g[4], g[5]})}, st.source, st.material); break;
    case PrimKind::Cone: batch.add_cone({{g[0], g[1], g[2]}, g[3], {g[4], g[5], g[6]}, g[7]}, st.source, st.material); break;
    case PrimKind::Quadric: {
      Quadric q;
      std::memcpy(q.coeff.data(), g, 10 * 8);
      for (int c = 0; c < Quadric::kMaxClipPlanes; ++c) {
        q.clip[static_cast<size_t>(c)] = Vec4(g[10 + 4 * c], g[11 + 4 * c], g[12 + 4 * c], g[13 + 4 * c]);
      }
      const double* b = g + 10 + 4 * Quadric::kMaxClipPlanes;
      q.bounds = Aabb({b[0], b[1], b[2]}, {b[3], b[4], b[5]});
      q.clip_count = static_cast<int>(b[6]);
      batch.add_quadric(q, st.source, st.material);
      break;
    }
  }
  return true;
}

Status open_file(const std::string& path, const char* mode, std::FILE*& file) {
  file = std::fopen(path.c_str(), mode);
  if (file != nullptr) return Status::ok();
  return Status::io_error(fmt::format("{}: cannot {}: {}", path, mode[0] == 'w' ? "create" : "open", std::strerror(errno)));
}

}  // namespace

int SpillVertexCache::find(const Vec3& p, const Vec3* n) const {
  const uint64_t key = vertex_key(p, n);
  for (int s = 0; s < size_; ++s) {
    const auto i = static_cast<size_t>(s);
    if (key_[i] == key && same_bits(position_[i], p) && (n == nullptr || same_bits(normal_[i], *n))) return s;
  }
  return kSlots;
}

void SpillVertexCache::push(const Vec3& p, const Vec3* n) {
  const auto i = static_cast<size_t>(next_);
  key_[i] = vertex_key(p, n);
  position_[i] = p;
  normal_[i] = n != nullptr ? *n : Vec3(0.0);
  next_ = (next_ + 1) % kSlots;
  size_ = std::min(size_ + 1, kSlots);
}

SpillWriter::~SpillWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

Status SpillWriter::open(const std::string& path, std::optional<Lattice> lattice) {
  path_ = path;
  if (Status s = open_file(path, "wb", file_); !s) return s;
  buffer_.resize(buffer_bytes_ + kLargestRecord);  // once: records are copied in, never appended
  used_ = 0;
  state_ = SpillCodecState(lattice);
  return Status::ok();
}

Status SpillWriter::write(const Scene& scene, uint32_t i) {
  used_ = static_cast<size_t>(put_record(buffer_.data() + used_, state_, scene, i) - buffer_.data());
  ++records_;
  if (used_ >= buffer_bytes_) return flush();
  return Status::ok();
}

Status SpillWriter::flush() {
  if (used_ == 0) return Status::ok();
  if (std::fwrite(buffer_.data(), 1, used_, file_) != used_) {
    return Status::io_error(fmt::format("{}: write failed: {}", path_, std::strerror(errno)));
  }
  bytes_ += used_;
  used_ = 0;
  return Status::ok();
}

Status SpillWriter::close() {
  if (file_ == nullptr) return Status::ok();
  Status s = flush();
  if (std::fclose(file_) != 0 && s) s = Status::io_error(fmt::format("{}: close failed: {}", path_, std::strerror(errno)));
  file_ = nullptr;
  return s;
}

SpillReader::~SpillReader() {
  if (file_ != nullptr) std::fclose(file_);
}

Status SpillReader::open(const std::string& path, std::optional<Lattice> lattice) {
  path_ = path;
  if (Status s = open_file(path, "rb", file_); !s) return s;
  buffer_.resize(kBufferBytes);
  state_ = SpillCodecState(lattice);
  return Status::ok();
}

Status SpillReader::fill() {
  // Keep the unread tail, then top the buffer up.
  std::memmove(buffer_.data(), buffer_.data() + begin_, end_ - begin_);
  end_ -= begin_;
  begin_ = 0;
  while (!eof_ && end_ < buffer_.size()) {
    const size_t got = std::fread(buffer_.data() + end_, 1, buffer_.size() - end_, file_);
    if (got == 0) {
      if (std::ferror(file_)) return Status::io_error(fmt::format("{}: read failed: {}", path_, std::strerror(errno)));
      eof_ = true;
    }
    end_ += got;
  }
  return Status::ok();
}

Status SpillReader::read(Scene& batch, size_t max, bool& end) {
  end = false;
  for (size_t n = 0; n < max; ++n) {
    if (end_ - begin_ < kLargestRecord && !eof_) {
      if (Status s = fill(); !s) return s;
    }
    if (begin_ == end_) {
      end = true;
      return Status::ok();
    }
    store::ByteReader r(std::span<const uint8_t>(buffer_.data() + begin_, end_ - begin_));
    if (!get_record(r, state_, batch)) {
      return Status::corruption(fmt::format("{}: byte {}: {} record", path_, offset_, r.ok() ? "bad" : "torn"));
    }
    begin_ += r.offset();
    offset_ += r.offset();
  }
  return Status::ok();
}

}  // namespace frontier
