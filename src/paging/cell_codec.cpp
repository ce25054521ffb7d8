// Cell page codecs (byte layout: store/FORMAT.md "Cell pages"; contracts: cell_codec.h).
//
// Both payloads start with one magic/version byte and end exactly at the payload's end. The
// non-triangle primitives (and, for the raw codec, the triangles) are a "raw body": counts,
// the per-primitive kind/source/material streams, then fixed-size little-endian doubles.
// The Draco payload puts the triangles in a Draco edgebreaker mesh whose positions are
// integer lattice offsets from a per-cell base; per-triangle sources and materials are stored
// beside it in the order in which Draco decodes the faces (found at encode time by decoding
// the mesh again and matching faces by their lattice coordinates).
//
// Decoding trusts nothing: every count is capped by the bytes that remain before anything is
// allocated, the Draco stream's own face count is checked against ours before Draco sees it
// (Draco sizes its tables from it), and everything Draco hands back is range-checked.
#include "src/paging/cell_codec.h"

#include <draco/compression/config/compression_shared.h>
#include <draco/compression/decode.h>
#include <draco/compression/entropy/symbol_decoding.h>
#include <draco/compression/entropy/symbol_encoding.h>
#include <draco/compression/expert_encode.h>
#include <draco/core/decoder_buffer.h>
#include <draco/core/encoder_buffer.h>
#include <draco/mesh/mesh.h>
#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <string_view>
#include <utility>

namespace frontier {

// --- the lattice -----------------------------------------------------------------------------

Lattice Lattice::covering(const Aabb& bounds, int bits) {
  Lattice lattice;
  lattice.bits = bits;
  if (bounds.empty() || bits < 1) return lattice;
  lattice.origin = bounds.lo;
  const Vec3 e = bounds.extent();
  const double extent = std::max({e.x, e.y, e.z});
  const double last = std::ldexp(1.0, bits) - 1.0;
  if (!(extent > 0.0)) return lattice;  // a single point (or non-finite bounds: caught later)
  lattice.step = extent / last;
  // Division rounding may leave the last lattice point a hair short of bounds.hi; widen the step
  // by ulps until it covers, so that max_error() holds everywhere inside `bounds`.
  for (int a = 0; a < 3 && std::isfinite(lattice.step); ++a) {
    while (lattice.origin[a] + lattice.step * last < bounds.hi[a]) {
      lattice.step = std::nextafter(lattice.step, kInfinity);
    }
  }
  return lattice;
}

namespace {

// std::round (halves away from zero) without the library call, bit for bit: adding and
// removing 1.5 * 2^52 rounds to the nearest integer (ties to even) for |x| < 2^51, and a tie
// is then moved away from zero. Anything else (huge, infinite, NaN) goes to std::round.
inline double round_half_away(double x) {
  if (!(std::abs(x) < 0x1p51)) return std::round(x);
  double r = (x + 0x1.8p52) - 0x1.8p52;  // IEEE arithmetic: not reassociated without -ffast-math
  if (std::abs(x - r) == 0.5) r = x + std::copysign(0.5, x);
  return std::copysign(r, x);  // -0.4 rounds to -0, as std::round does
}

}  // namespace

std::array<int64_t, 3> Lattice::quantize(const Vec3& p) const {
  const double last = bits >= 1 && bits <= 62 ? static_cast<double>((int64_t{1} << bits) - 1) : std::ldexp(1.0, bits) - 1.0;
  std::array<int64_t, 3> q{};
  for (int a = 0; a < 3; ++a) {
    const double t = round_half_away((p[a] - origin[a]) / step);
    // !(t > 0) also sends NaN to 0; clamping before the conversion keeps it defined.
    q[a] = !(t > 0.0) ? 0 : t >= last ? static_cast<int64_t>(last) : static_cast<int64_t>(t);
  }
  return q;
}

// Out of line on purpose: every decoder dequantizes through this one function, so a vertex
// shared by two cells gets bit-identical doubles in both.
Vec3 Lattice::point(const std::array<int64_t, 3>& q) const {
  return {origin.x + step * static_cast<double>(q[0]), origin.y + step * static_cast<double>(q[1]),
          origin.z + step * static_cast<double>(q[2])};
}

namespace {

// --- payload constants -----------------------------------------------------------------------

constexpr uint8_t kRawMagic = 0xA1;    // raw codec, layout version 1
constexpr uint8_t kDracoMagic = 0xD1;  // Draco codec, layout version 1
constexpr int kMaxLatticeBits = 30;    // Draco's integer prediction needs differences in int32
constexpr int64_t kMaxCellSteps = int64_t{1} << 24;  // per axis, Draco codec (see encode_draco)

// Raw body flags.
constexpr uint8_t kRawHasNormals = 1;
constexpr uint8_t kRawExplicitIndices = 2;
// Draco header flags.
constexpr uint8_t kDracoHasNormals = 1;

constexpr int kPrimKinds = 5;
// Bytes of one primitive's doubles in a raw body (a quadric's clip planes come on top).
constexpr size_t kTriangleBytes = 9 * 8;
constexpr size_t kSphereBytes = 4 * 8;
constexpr size_t kBoxBytes = 6 * 8;
constexpr size_t kConeBytes = 8 * 8;
constexpr size_t kQuadricMinBytes = 10 * 8 + 1 + 6 * 8;

// --- bytes -----------------------------------------------------------------------------------

class ByteWriter {
 public:
  explicit ByteWriter(std::vector<uint8_t>& out) : out_(out) {}
  void u8(uint8_t v) { out_.push_back(v); }
  void varint(uint64_t v) {
    while (v >= 0x80) {
      out_.push_back(static_cast<uint8_t>(v | 0x80));
      v >>= 7;
    }
    out_.push_back(static_cast<uint8_t>(v));
  }
  void f64(double v) {
    const uint64_t bits = std::bit_cast<uint64_t>(v);
    uint8_t b[8];  // little endian, appended at once
    for (int i = 0; i < 8; ++i) b[i] = static_cast<uint8_t>(bits >> (8 * i));
    out_.insert(out_.end(), b, b + 8);
  }
  void reserve(size_t more) { out_.reserve(out_.size() + more); }
  void vec3(const Vec3& v) { f64(v.x); f64(v.y); f64(v.z); }
  void bytes(const uint8_t* data, size_t n) { out_.insert(out_.end(), data, data + n); }

 private:
  std::vector<uint8_t>& out_;
};

// Reads a payload front to back. Every read checks the bytes left; the first failure is kept
// and all later reads fail too, so a decoder may check ok() once after a group of reads.
class ByteReader {
 public:
  explicit ByteReader(std::span<const uint8_t> bytes) : bytes_(bytes) {}
  bool ok() const { return ok_; }
  void fail() { ok_ = false; }
  size_t offset() const { return pos_; }
  size_t remaining() const { return bytes_.size() - pos_; }

  uint8_t u8() {
    if (!take(1)) return 0;
    return bytes_[pos_ - 1];
  }
  uint64_t varint() {
    uint64_t v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      if (!take(1)) return 0;
      const uint8_t b = bytes_[pos_ - 1];
      if (shift == 63 && b > 1) break;  // would overflow 64 bits
      v |= static_cast<uint64_t>(b & 0x7f) << shift;
      if ((b & 0x80) == 0) return v;
    }
    ok_ = false;
    return 0;
  }
  double f64() {
    if (!take(8)) return 0.0;
    uint64_t bits = 0;
    for (int i = 7; i >= 0; --i) bits = (bits << 8) | bytes_[pos_ - 8 + static_cast<size_t>(i)];
    return std::bit_cast<double>(bits);
  }
  Vec3 vec3() {
    const double x = f64(), y = f64();
    return {x, y, f64()};
  }
  std::span<const uint8_t> bytes(size_t n) {
    if (!take(n)) return {};
    return bytes_.subspan(pos_ - n, n);
  }

 private:
  bool take(size_t n) {
    if (!ok_ || n > remaining()) {
      ok_ = false;
      return false;
    }
    pos_ += n;
    return true;
  }
  std::span<const uint8_t> bytes_;
  size_t pos_ = 0;
  bool ok_ = true;
};

Status corrupt(std::string_view codec, size_t offset, std::string_view what) {
  return Status::corruption(fmt::format("{} cell page: {} (at byte {})", codec, what, offset));
}

uint64_t zigzag(int64_t v) { return (static_cast<uint64_t>(v) << 1) ^ static_cast<uint64_t>(v >> 63); }
int64_t unzigzag(uint64_t v) { return static_cast<int64_t>(v >> 1) ^ -static_cast<int64_t>(v & 1); }

// --- value streams ---------------------------------------------------------------------------
// A stream of n > 0 values (n known to the reader; no bytes at all when n = 0) is a mode byte,
// then either
//   runs:    varint run count, then per run varint value, varint length  (few runs), or
//   symbols: varint byte length, Draco's entropy coder (draco::EncodeSymbols, rANS) over
//            min(value, kEscape), then one varint (value - kEscape) per escaped value, in order.
// The writer keeps the shorter. The escape exists because draco::EncodeSymbols sizes a
// histogram by the largest value (it crashes on 2^32 - 1 and allocates gigabytes near it).
// Sources are stored as zigzag differences to the previous source (the first to 0): Draco's
// face order mostly follows the input order, so most differences are +1 and entropy-code to a
// fraction of a bit.

constexpr uint8_t kStreamRuns = 0;
constexpr uint8_t kStreamSymbols = 1;
constexpr uint32_t kEscape = 1023;

void write_stream(ByteWriter& w, const std::vector<uint64_t>& values) {
  if (values.empty()) return;  // nothing at all, not even the mode byte
  std::vector<uint8_t> runs;
  ByteWriter rw(runs);
  std::vector<std::pair<uint64_t, uint64_t>> list;
  for (uint64_t v : values) {
    if (list.empty() || list.back().first != v) list.emplace_back(v, 0);
    ++list.back().second;
  }
  rw.varint(list.size());
  for (const auto& [value, length] : list) {
    rw.varint(value);
    rw.varint(length);
  }
  if (list.size() > 2 && values.size() <= INT32_MAX) {
    std::vector<uint32_t> symbols;
    std::vector<uint8_t> escaped;
    ByteWriter ew(escaped);
    symbols.reserve(values.size());
    for (uint64_t v : values) {
      symbols.push_back(static_cast<uint32_t>(std::min<uint64_t>(v, kEscape)));
      if (v >= kEscape) ew.varint(v - kEscape);
    }
    draco::EncoderBuffer buffer;
    if (draco::EncodeSymbols(symbols.data(), static_cast<int>(symbols.size()), 1, nullptr, &buffer) &&
        buffer.size() + escaped.size() + 4 < runs.size()) {
      w.u8(kStreamSymbols);
      w.varint(buffer.size());
      w.bytes(reinterpret_cast<const uint8_t*>(buffer.data()), buffer.size());
      w.bytes(escaped.data(), escaped.size());
      return;
    }
  }
  w.u8(kStreamRuns);
  w.bytes(runs.data(), runs.size());
}

// Reads n values, each at most max_value. REQUIRES: n was capped by the caller (it is
// allocated before the stream is known to hold that many).
bool read_stream(ByteReader& r, size_t n, uint64_t max_value, std::vector<uint64_t>& values) {
  values.clear();
  if (n == 0) return true;
  values.reserve(n);
  const uint8_t mode = r.u8();
  if (!r.ok()) return false;
  if (mode == kStreamRuns) {
    const uint64_t count = r.varint();
    if (!r.ok() || count > n || count > r.remaining() / 2) return false;
    for (uint64_t i = 0; i < count; ++i) {
      const uint64_t value = r.varint();
      const uint64_t length = r.varint();
      if (!r.ok() || value > max_value || length == 0 || length > n - values.size()) return false;
      values.insert(values.end(), length, value);
    }
    return values.size() == n;
  }
  if (mode != kStreamSymbols || n == 0 || n > INT32_MAX) return false;
  const uint64_t size = r.varint();
  if (!r.ok() || size > r.remaining()) return false;
  const std::span<const uint8_t> bytes = r.bytes(size);
  std::vector<uint32_t> symbols(n);
  try {
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(bytes.data()), bytes.size(), draco::kDracoMeshBitstreamVersion);
    if (!draco::DecodeSymbols(static_cast<uint32_t>(n), 1, &buffer, symbols.data())) return false;
  } catch (const std::exception&) {  // std::bad_alloc from a damaged table size
    return false;
  }
  for (uint32_t symbol : symbols) {
    if (symbol > kEscape) return false;
    uint64_t v = symbol;
    if (symbol == kEscape) {
      const uint64_t extra = r.varint();
      if (!r.ok() || extra > UINT64_MAX - kEscape) return false;
      v += extra;
    }
    if (v > max_value) return false;
    values.push_back(v);
  }
  return true;
}

void write_sources(ByteWriter& w, const std::vector<uint32_t>& sources) {
  std::vector<uint64_t> deltas;
  deltas.reserve(sources.size());
  int64_t previous = 0;
  for (uint32_t v : sources) {
    deltas.push_back(zigzag(static_cast<int64_t>(v) - previous));
    previous = v;
  }
  write_stream(w, deltas);
}

bool read_sources(ByteReader& r, size_t n, std::vector<uint32_t>& sources) {
  std::vector<uint64_t> deltas;
  if (!read_stream(r, n, UINT64_MAX, deltas)) return false;
  sources.resize(n);
  int64_t previous = 0;
  for (size_t i = 0; i < n; ++i) {
    const int64_t d = unzigzag(deltas[i]);
    if (d > int64_t{UINT32_MAX} || d < -int64_t{UINT32_MAX}) return false;
    const int64_t v = previous + d;
    if (v < 0 || v > int64_t{UINT32_MAX}) return false;
    sources[i] = static_cast<uint32_t>(v);
    previous = v;
  }
  return true;
}

void write_values(ByteWriter& w, const std::vector<uint32_t>& values) {
  write_stream(w, std::vector<uint64_t>(values.begin(), values.end()));
}

bool read_values(ByteReader& r, size_t n, uint32_t max_value, std::vector<uint32_t>& values) {
  std::vector<uint64_t> wide;
  if (!read_stream(r, n, max_value, wide)) return false;
  values.assign(wide.begin(), wide.end());
  return true;
}

// --- raw body: a Scene's primitives, bit-exact ---------------------------------------------

Status check_scene(const Scene& cell) {
  if (!cell.triangle_normals.empty() && cell.triangle_normals.size() != cell.triangles.size()) {
    return Status::invalid_argument(fmt::format("encode_cell: {} triangle normals for {} triangles",
                                                cell.triangle_normals.size(), cell.triangles.size()));
  }
  for (size_t i = 0; i < cell.prims.size(); ++i) {
    const PrimRef& p = cell.prims[i];
    size_t size = 0;
    switch (p.kind) {
      case PrimKind::Triangle: size = cell.triangles.size(); break;
      case PrimKind::Sphere: size = cell.spheres.size(); break;
      case PrimKind::Box: size = cell.boxes.size(); break;
      case PrimKind::Cone: size = cell.cones.size(); break;
      case PrimKind::Quadric: size = cell.quadrics.size(); break;
      default: return Status::invalid_argument(fmt::format("encode_cell: primitive {} has an unknown kind", i));
    }
    if (p.index >= size) {
      return Status::invalid_argument(fmt::format("encode_cell: primitive {} refers past its array", i));
    }
  }
  for (size_t i = 0; i < cell.quadrics.size(); ++i) {
    if (cell.quadrics[i].clip_count < 0 || cell.quadrics[i].clip_count > Quadric::kMaxClipPlanes) {
      return Status::invalid_argument(fmt::format("encode_cell: quadric {} has {} clip planes", i,
                                                  cell.quadrics[i].clip_count));
    }
  }
  return Status::ok();
}

// Whether every primitive's index is the number of earlier primitives of its kind and every
// array element is referenced: then the indices need not be stored.
bool sequential_indices(const Scene& s) {
  std::array<size_t, kPrimKinds> next{};
  for (const PrimRef& p : s.prims) {
    if (p.index != next[static_cast<size_t>(p.kind)]++) return false;
  }
  return next == std::array<size_t, kPrimKinds>{s.triangles.size(), s.spheres.size(), s.boxes.size(),
                                                s.cones.size(), s.quadrics.size()};
}

// REQUIRES: check_scene(s) is ok.
void write_raw_body(ByteWriter& w, const Scene& s) {
  const bool normals = !s.triangle_normals.empty();
  const bool explicit_indices = !sequential_indices(s);
  w.varint(s.prims.size());
  w.varint(s.triangles.size());
  w.varint(s.spheres.size());
  w.varint(s.boxes.size());
  w.varint(s.cones.size());
  w.varint(s.quadrics.size());
  w.u8(static_cast<uint8_t>((normals ? kRawHasNormals : 0) | (explicit_indices ? kRawExplicitIndices : 0)));
  // Geometry dominates: 72 bytes a triangle (twice that with normals), a few per reference.
  w.reserve(s.triangles.size() * (normals ? 144 : 72) + s.prims.size() * 8 + s.spheres.size() * 32 +
            s.boxes.size() * 48 + s.cones.size() * 64 + s.quadrics.size() * 512);

  std::vector<uint32_t> kinds, sources, materials;
  for (const PrimRef& p : s.prims) {
    kinds.push_back(static_cast<uint32_t>(p.kind));
    sources.push_back(p.source);
    materials.push_back(p.material);
  }
  write_values(w, kinds);
  if (explicit_indices) {
    for (const PrimRef& p : s.prims) w.varint(p.index);
  }
  write_sources(w, sources);
  write_values(w, materials);

  for (const Triangle& t : s.triangles) { w.vec3(t.v0); w.vec3(t.v1); w.vec3(t.v2); }
  for (const auto& n : s.triangle_normals) { w.vec3(n[0]); w.vec3(n[1]); w.vec3(n[2]); }
  for (const Sphere& sp : s.spheres) { w.vec3(sp.center); w.f64(sp.radius); }
  for (const Box& b : s.boxes) { w.vec3(b.bounds.lo); w.vec3(b.bounds.hi); }
  for (const Cone& c : s.cones) { w.vec3(c.base); w.f64(c.base_radius); w.vec3(c.apex); w.f64(c.apex_radius); }
  for (const Quadric& q : s.quadrics) {
    for (double c : q.coeff) w.f64(c);
    w.u8(static_cast<uint8_t>(q.clip_count));
    for (int k = 0; k < q.clip_count; ++k) {
      const Vec4& p = q.clip[static_cast<size_t>(k)];
      w.f64(p.x); w.f64(p.y); w.f64(p.z); w.f64(p.w);
    }
    w.vec3(q.bounds.lo);
    w.vec3(q.bounds.hi);
  }
}

// Appends the primitives of a raw body to `out`, whose per-kind arrays may already hold
// elements (the Draco codec's triangles). The Draco codec's body must hold no triangles
// (`triangles_allowed` false). Leaves `r` after the body.
Status read_raw_body(ByteReader& r, std::string_view codec, bool triangles_allowed, Scene& out) {
  const uint64_t prim_count = r.varint();
  std::array<uint64_t, kPrimKinds> counts{};
  for (uint64_t& c : counts) c = r.varint();
  const uint8_t flags = r.u8();
  if (!r.ok()) return corrupt(codec, r.offset(), "truncated primitive counts");
  if ((flags & ~(kRawHasNormals | kRawExplicitIndices)) != 0) return corrupt(codec, r.offset(), "unknown flags");
  const bool normals = (flags & kRawHasNormals) != 0;
  const bool explicit_indices = (flags & kRawExplicitIndices) != 0;
  // Cap every count by the bytes left before multiplying or allocating: a triangle costs 72
  // bytes (144 with normals), a sphere 32, and so on; with implicit indices there is one
  // primitive per element, with explicit ones each costs at least a byte of index.
  const size_t left = r.remaining();
  if (prim_count > left || std::any_of(counts.begin(), counts.end(), [&](uint64_t c) { return c > left; })) {
    return corrupt(codec, r.offset(), "primitive counts exceed the payload");
  }
  const uint64_t geometry = counts[0] * kTriangleBytes * (normals ? 2 : 1) + counts[1] * kSphereBytes +
                            counts[2] * kBoxBytes + counts[3] * kConeBytes + counts[4] * kQuadricMinBytes;
  const uint64_t elements = counts[0] + counts[1] + counts[2] + counts[3] + counts[4];
  if (geometry > left || (!explicit_indices && prim_count != elements)) {
    return corrupt(codec, r.offset(), "primitive counts exceed the payload");
  }
  if (normals && counts[0] == 0) return corrupt(codec, r.offset(), "normals flag without triangles");
  if (counts[0] > 0 && !triangles_allowed) return corrupt(codec, r.offset(), "triangles outside the Draco mesh");

  std::vector<uint32_t> kinds, indices, sources, materials;
  if (!read_values(r, prim_count, kPrimKinds - 1, kinds)) return corrupt(codec, r.offset(), "bad primitive kinds");
  if (explicit_indices) {
    if (prim_count > r.remaining()) return corrupt(codec, r.offset(), "truncated primitive indices");
    indices.resize(prim_count);
    for (size_t i = 0; i < prim_count; ++i) {
      const uint64_t index = r.varint();
      if (!r.ok() || index >= counts[kinds[i]]) return corrupt(codec, r.offset(), "bad primitive index");
      indices[i] = static_cast<uint32_t>(index);
    }
  } else {
    // Implicit indices: the k-th primitive of a kind is element k, and all elements are used.
    std::array<uint64_t, kPrimKinds> seen{};
    indices.resize(prim_count);
    for (size_t i = 0; i < prim_count; ++i) indices[i] = static_cast<uint32_t>(seen[kinds[i]]++);
    if (seen != counts) return corrupt(codec, r.offset(), "primitive kinds do not match the counts");
  }
  if (!read_sources(r, prim_count, sources)) return corrupt(codec, r.offset(), "bad primitive sources");
  if (!read_values(r, prim_count, UINT32_MAX, materials)) return corrupt(codec, r.offset(), "bad primitive materials");

  const size_t triangle_base = out.triangles.size();
  for (uint64_t i = 0; i < counts[0]; ++i) {
    const Vec3 v0 = r.vec3(), v1 = r.vec3();
    out.triangles.push_back({v0, v1, r.vec3()});
  }
  if (normals) {
    for (uint64_t i = 0; i < counts[0]; ++i) {
      const Vec3 n0 = r.vec3(), n1 = r.vec3();
      out.triangle_normals.push_back({n0, n1, r.vec3()});
    }
  }
  const size_t sphere_base = out.spheres.size(), box_base = out.boxes.size(), cone_base = out.cones.size(),
               quadric_base = out.quadrics.size();
  for (uint64_t i = 0; i < counts[1]; ++i) {
    Sphere s;
    s.center = r.vec3();
    s.radius = r.f64();
    out.spheres.push_back(s);
  }
  for (uint64_t i = 0; i < counts[2]; ++i) {
    Box b;
    b.bounds.lo = r.vec3();
    b.bounds.hi = r.vec3();
    out.boxes.push_back(b);
  }
  for (uint64_t i = 0; i < counts[3]; ++i) {
    Cone c;
    c.base = r.vec3();
    c.base_radius = r.f64();
    c.apex = r.vec3();
    c.apex_radius = r.f64();
    out.cones.push_back(c);
  }
  for (uint64_t i = 0; i < counts[4]; ++i) {
    Quadric q;
    for (double& c : q.coeff) c = r.f64();
    const uint8_t clip_count = r.u8();
    if (!r.ok() || clip_count > Quadric::kMaxClipPlanes) return corrupt(codec, r.offset(), "bad quadric clip count");
    q.clip_count = clip_count;
    for (int k = 0; k < q.clip_count; ++k) {
      const double x = r.f64(), y = r.f64(), z = r.f64();
      q.clip[static_cast<size_t>(k)] = Vec4(x, y, z, r.f64());
    }
    q.bounds.lo = r.vec3();
    q.bounds.hi = r.vec3();
    out.quadrics.push_back(q);
  }
  if (!r.ok()) return corrupt(codec, r.offset(), "truncated primitive geometry");

  const std::array<size_t, kPrimKinds> base = {triangle_base, sphere_base, box_base, cone_base, quadric_base};
  out.prims.reserve(out.prims.size() + prim_count);
  for (size_t i = 0; i < prim_count; ++i) {
    out.prims.push_back({static_cast<PrimKind>(kinds[i]), static_cast<uint32_t>(base[kinds[i]] + indices[i]),
                         sources[i], materials[i]});
  }
  return Status::ok();
}

// --- the lattice, checked ------------------------------------------------------------------

Status check_lattice(const Lattice& lattice, std::string_view who) {
  if (lattice.bits < 1 || lattice.bits > kMaxLatticeBits || !(lattice.step > 0.0) ||
      !std::isfinite(lattice.step) || !std::isfinite(lattice.origin.x) || !std::isfinite(lattice.origin.y) ||
      !std::isfinite(lattice.origin.z)) {
    return Status::invalid_argument(fmt::format("{}: unusable lattice (bits {}, step {}; bits must be 1..{})", who,
                                                lattice.bits, lattice.step, kMaxLatticeBits));
  }
  return Status::ok();
}

using LatticeIndex = std::array<int64_t, 3>;
// Lattice indices fit in 32 bits (bits <= 30): the key of a vertex.
using VertexKey = std::array<int32_t, 3>;
// A Draco point: a vertex id and the bit pattern of its float normal (zero without normals).
using PointKey = std::array<uint32_t, 4>;

VertexKey vertex_key(const LatticeIndex& q) {
  return {static_cast<int32_t>(q[0]), static_cast<int32_t>(q[1]), static_cast<int32_t>(q[2])};
}

uint64_t mix64(uint64_t h) {  // MurmurHash3's finalizer
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ull;
  return h ^ (h >> 33);
}

// Dense ids 0, 1, 2, ... for distinct keys (arrays of 3 or 4 32-bit values) in the order they
// are first seen: an open-addressing table of ids into the key list. Several times faster
// than std::unordered_map here, which dominated encoding time.
template <typename Key>
class DenseIds {
 public:
  static constexpr uint32_t kNone = UINT32_MAX;
  explicit DenseIds(size_t expected) { rehash(expected); }

  uint32_t insert(const Key& key) {
    size_t i = hash(key) & mask_;
    for (;; i = (i + 1) & mask_) {
      const uint32_t slot = slots_[i];
      if (slot == 0) break;
      if (keys_[slot - 1] == key) return slot - 1;
    }
    keys_.push_back(key);
    slots_[i] = static_cast<uint32_t>(keys_.size());
    if (2 * keys_.size() > slots_.size()) rehash(keys_.size());
    return static_cast<uint32_t>(keys_.size() - 1);
  }
  uint32_t find(const Key& key) const {
    for (size_t i = hash(key) & mask_;; i = (i + 1) & mask_) {
      const uint32_t slot = slots_[i];
      if (slot == 0) return kNone;
      if (keys_[slot - 1] == key) return slot - 1;
    }
  }
  const std::vector<Key>& keys() const { return keys_; }

 private:
  static uint64_t hash(const Key& key) {
    const auto u = [&](size_t k) { return k < key.size() ? static_cast<uint64_t>(static_cast<uint32_t>(key[k])) : 0; };
    return mix64((u(0) | u(1) << 32) ^ mix64(u(2) | u(3) << 32));
  }
  void rehash(size_t keys) {
    size_t capacity = 16;
    while (capacity < 4 * keys) capacity *= 2;  // load factor <= 1/4 after growing
    slots_.assign(capacity, 0);
    mask_ = capacity - 1;
    for (uint32_t id = 0; id < keys_.size(); ++id) {
      size_t i = hash(keys_[id]) & mask_;
      while (slots_[i] != 0) i = (i + 1) & mask_;
      slots_[i] = id + 1;
    }
  }
  std::vector<uint32_t> slots_;  // 0: empty, else id + 1
  std::vector<Key> keys_;
  size_t mask_ = 0;
};

// --- the Draco stream's header, checked before Draco reads it -------------------------------
// Draco sizes its connectivity tables from the face and vertex counts at the start of the
// stream before it knows whether the rest exists, so a damaged count would make it allocate
// gigabytes. The layout (Draco bitstream 2.2, edgebreaker, no metadata) is:
//   "DRACO" | major 2 | minor 2 | encoder type 1 (mesh) | method 1 (edgebreaker) | flags u16 0 |
//   traversal u8 (0: standard) | varint encoded vertices | varint faces | u8 attribute data |
//   varint symbols | varint split symbols | ...
// The encoder always uses the standard edgebreaker traversal, which spends at least one bit
// per symbol, and every connected component has at least one symbol per two faces (the first
// face of a closed component is implicit). So a valid stream has
//   faces <= 2 * symbols + 1  and  symbols <= 8 * stream bytes,
// which bounds everything Draco allocates by a constant times the page size.

// Draco reads a 32-bit varint from at most 5 bytes; anything this accepts, Draco reads the
// same way (same value, same length).
uint64_t draco_varint(ByteReader& r) {
  const size_t start = r.offset();
  const uint64_t v = r.varint();
  if (v > UINT32_MAX || r.offset() - start > 5) r.fail();
  return v;
}

Status check_draco_stream(std::span<const uint8_t> blob, uint64_t faces, bool normals) {
  static constexpr uint8_t kHead[] = {'D', 'R', 'A', 'C', 'O', 2, 2, 1, 1, 0, 0};
  if (blob.size() < sizeof(kHead) || std::memcmp(blob.data(), kHead, sizeof(kHead)) != 0) {
    return Status::corruption("Draco cell page: not a Draco 2.2 edgebreaker mesh stream");
  }
  ByteReader r(blob.subspan(sizeof(kHead)));
  const uint8_t traversal = r.u8();
  const uint64_t vertices = draco_varint(r);
  const uint64_t stream_faces = draco_varint(r);
  const uint8_t attribute_data = r.u8();
  const uint64_t symbols = draco_varint(r);
  const uint64_t split_symbols = draco_varint(r);
  if (!r.ok() || traversal != draco::MESH_EDGEBREAKER_STANDARD_ENCODING || stream_faces != faces ||
      vertices > 3 * faces || attribute_data > (normals ? 1 : 0) || symbols > faces || faces > 2 * symbols + 1 ||
      symbols > 8 * blob.size() || split_symbols > symbols) {
    return Status::corruption("Draco cell page: Draco stream header does not match the page");
  }
  return Status::ok();
}

// --- Draco mesh <-> lattice corners -----------------------------------------------------------

// Runs Draco's decoder on a stream that passed check_draco_stream. Its failures (a Status, or
// an exception from an allocation) become Corruption.
Result<std::unique_ptr<draco::Mesh>> run_draco_decoder(std::span<const uint8_t> blob) {
  try {
    draco::DecoderBuffer buffer;
    buffer.Init(reinterpret_cast<const char*>(blob.data()), blob.size());
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
    if (!decoded.ok()) {
      return Status::corruption(fmt::format("Draco cell page: Draco: {}", decoded.status().error_msg_string()));
    }
    std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
    if (mesh == nullptr) return Status::corruption("Draco cell page: Draco returned no mesh");
    return mesh;
  } catch (const std::exception& e) {  // std::bad_alloc, length_error: Draco throws nothing else
    return Status::corruption(fmt::format("Draco cell page: Draco failed: {}", e.what()));
  }
}

// A decoded Draco mesh, range-checked: per point its lattice offset from the page's base and
// its normal (when the page has normals), and per face its three points, in Draco's order.
struct DracoMesh {
  std::vector<LatticeIndex> offsets;
  std::vector<Vec3> normals;
  std::vector<std::array<uint32_t, 3>> faces;
};

// Checks a decoded mesh against the page header (`faces`, `points`, `normals`) and reads it.
// `extent` is the largest offset allowed per axis (base + offset must stay on the lattice).
Result<DracoMesh> read_draco_mesh(const draco::Mesh& mesh, uint64_t faces, uint64_t points, bool normals,
                                  const LatticeIndex& extent) {
  if (mesh.num_faces() != faces || mesh.num_points() != points) {
    return Status::corruption(fmt::format("Draco cell page: decoded mesh has {} faces and {} points, the page "
                                          "says {} and {}", mesh.num_faces(), mesh.num_points(), faces, points));
  }
  const draco::PointAttribute* position = mesh.GetNamedAttribute(draco::GeometryAttribute::POSITION);
  const draco::PointAttribute* normal = mesh.GetNamedAttribute(draco::GeometryAttribute::NORMAL);
  auto usable = [&](const draco::PointAttribute* a, draco::DataType type) {
    return a != nullptr && a->data_type() == type && a->num_components() == 3 && a->size() <= points &&
           (a->is_mapping_identity() || a->indices_map_size() >= points);
  };
  if (!usable(position, draco::DT_INT32) || (normals && !usable(normal, draco::DT_FLOAT32)) ||
      mesh.num_attributes() != (normals ? 2 : 1)) {
    return Status::corruption("Draco cell page: decoded mesh has unexpected attributes");
  }
  DracoMesh out;
  out.offsets.resize(points);
  if (normals) out.normals.resize(points);
  for (uint32_t p = 0; p < points; ++p) {
    const draco::AttributeValueIndex v = position->mapped_index(draco::PointIndex(p));
    if (v.value() >= position->size()) return Status::corruption("Draco cell page: bad position mapping");
    const auto q = position->GetValue<int32_t, 3>(v);
    for (int a = 0; a < 3; ++a) {
      if (q[a] < 0 || q[a] > extent[a]) return Status::corruption("Draco cell page: vertex off the lattice");
      out.offsets[p][a] = q[a];
    }
    if (normals) {
      const draco::AttributeValueIndex n = normal->mapped_index(draco::PointIndex(p));
      if (n.value() >= normal->size()) return Status::corruption("Draco cell page: bad normal mapping");
      const auto f = normal->GetValue<float, 3>(n);
      out.normals[p] = Vec3(f[0], f[1], f[2]);
    }
  }
  out.faces.resize(faces);
  for (uint32_t f = 0; f < faces; ++f) {
    const draco::Mesh::Face& face = mesh.face(draco::FaceIndex(f));
    for (int c = 0; c < 3; ++c) {
      out.faces[f][c] = face[c].value();
      if (out.faces[f][c] >= points) return Status::corruption("Draco cell page: face refers to a missing point");
    }
  }
  return out;
}

// A face's vertex ids rotated to start at the smallest, keeping the cyclic order: equal for
// the same oriented face whatever corner Draco starts it at, different for the flipped one.
using FaceKey = std::array<uint32_t, 3>;
FaceKey face_key(uint32_t a, uint32_t b, uint32_t c) {
  if (b < a && b < c) return {b, c, a};
  if (c < a && c < b) return {c, a, b};
  return {a, b, c};
}

// --- the Draco codec -------------------------------------------------------------------------

// `decoded`, when given, is what run_draco_decoder made of this payload's Draco stream (the
// encoder has just decoded it once already): the rest of the payload is read as always.
Status decode_draco_payload(std::span<const uint8_t> payload, const Lattice& lattice, Scene& out,
                            const draco::Mesh* decoded = nullptr);

Result<EncodedCell> encode_draco(const Scene& cell, const CellCodecOptions& options) {
  const Lattice& lattice = options.lattice;
  if (Status s = check_lattice(lattice, "encode_cell"); !s) return s;
  if (options.draco_speed < 0 || options.draco_speed > 10) {
    return Status::invalid_argument(fmt::format("encode_cell: Draco speed {} is not 0..10", options.draco_speed));
  }
  const bool normals = !cell.triangle_normals.empty();
  if (normals && (options.normal_bits < 2 || options.normal_bits > 30)) {
    return Status::invalid_argument(fmt::format("encode_cell: normal bits {} is not 2..30", options.normal_bits));
  }

  // The triangles on the lattice, in primitive order, as distinct-vertex ids; everything else
  // goes to the raw body.
  struct Face {
    std::array<uint32_t, 3> vertex;
    uint32_t triangle, source, material;
  };
  std::vector<Face> faces;
  faces.reserve(cell.triangles.size());
  DenseIds<VertexKey> vertex_ids(cell.triangles.size());
  Scene others;
  for (size_t i = 0; i < cell.prims.size(); ++i) {
    const PrimRef& p = cell.prims[i];
    switch (p.kind) {
      case PrimKind::Sphere: others.add_sphere(cell.spheres[p.index], p.source, p.material); continue;
      case PrimKind::Box: others.add_box(cell.boxes[p.index], p.source, p.material); continue;
      case PrimKind::Cone: others.add_cone(cell.cones[p.index], p.source, p.material); continue;
      case PrimKind::Quadric: others.add_quadric(cell.quadrics[p.index], p.source, p.material); continue;
      case PrimKind::Triangle: break;
    }
    const Triangle& t = cell.triangles[p.index];
    const Vec3* v[3] = {&t.v0, &t.v1, &t.v2};
    LatticeIndex q[3];
    for (int c = 0; c < 3; ++c) {
      q[c] = lattice.quantize(*v[c]);
      if (lattice.point(q[c]) != *v[c]) {
        return Status::invalid_argument(fmt::format(
            "encode_cell: primitive {} (triangle {}, source {}) vertex {} ({}, {}, {}) is not on the lattice", i,
            p.index, p.source, c, v[c]->x, v[c]->y, v[c]->z));
      }
    }
    // Draco cannot hold a face with a repeated vertex: such triangles (zero area on the
    // lattice) are dropped here, and `decoded` shows it.
    if (q[0] == q[1] || q[1] == q[2] || q[0] == q[2]) continue;
    faces.push_back({{vertex_ids.insert(vertex_key(q[0])), vertex_ids.insert(vertex_key(q[1])),
                      vertex_ids.insert(vertex_key(q[2]))},
                     p.index, p.source, p.material});
  }
  const std::vector<VertexKey>& vertices = vertex_ids.keys();

  LatticeIndex base{0, 0, 0}, top{0, 0, 0};
  if (!vertices.empty()) {
    base = {INT64_MAX, INT64_MAX, INT64_MAX};
    for (const VertexKey& q : vertices) {
      for (int a = 0; a < 3; ++a) {
        base[a] = std::min<int64_t>(base[a], q[a]);
        top[a] = std::max<int64_t>(top[a], q[a]);
      }
    }
  }
  // Draco's entropy coder sizes a histogram by the largest prediction correction, which can
  // reach the cell's extent in lattice steps: measured 74 MB and 0.1 M triangles/s at 2^24
  // steps, 4 GB at 2^30. Refuse before that rather than exhaust memory.
  for (int a = 0; a < 3; ++a) {
    if (top[a] - base[a] >= kMaxCellSteps) {
      return Status::invalid_argument(fmt::format(
          "encode_cell: the cell spans {} lattice steps on axis {}; the Draco codec takes at most 2^24 "
          "(use fewer lattice bits or smaller cells)", top[a] - base[a], a));
    }
  }

  std::vector<uint8_t> blob;
  uint64_t points = 0;
  std::vector<uint32_t> sources, materials;  // in Draco's face order
  std::unique_ptr<draco::Mesh> decoded_blob;  // the round trip's decode, reused below
  if (!faces.empty()) {
    // One Draco point per distinct (vertex, float normal); without normals, per vertex.
    std::vector<std::array<uint32_t, 3>> face_points(faces.size());
    DenseIds<PointKey> point_ids(normals ? vertices.size() : 0);
    for (size_t f = 0; f < faces.size(); ++f) {
      for (int c = 0; c < 3; ++c) {
        if (!normals) {
          face_points[f][c] = faces[f].vertex[c];
          continue;
        }
        const Vec3& n = cell.triangle_normals[faces[f].triangle][c];
        face_points[f][c] = point_ids.insert({faces[f].vertex[c], std::bit_cast<uint32_t>(static_cast<float>(n.x)),
                                              std::bit_cast<uint32_t>(static_cast<float>(n.y)),
                                              std::bit_cast<uint32_t>(static_cast<float>(n.z))});
      }
    }
    const size_t num_points = normals ? point_ids.keys().size() : vertices.size();

    draco::Mesh mesh;
    mesh.set_num_points(static_cast<uint32_t>(num_points));
    // Positions are integers: Draco predicts and entropy-codes them losslessly (its float
    // quantization would dequantize in float32 and lose far-from-origin coordinates).
    draco::GeometryAttribute position;
    position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_INT32, false, 3 * sizeof(int32_t), 0);
    const int position_id = mesh.AddAttribute(position, !normals, static_cast<uint32_t>(vertices.size()));
    draco::PointAttribute* position_att = mesh.attribute(position_id);
    for (uint32_t v = 0; v < vertices.size(); ++v) {
      const std::array<int32_t, 3> q = {static_cast<int32_t>(vertices[v][0] - base[0]),
                                        static_cast<int32_t>(vertices[v][1] - base[1]),
                                        static_cast<int32_t>(vertices[v][2] - base[2])};
      position_att->SetAttributeValue(draco::AttributeValueIndex(v), q.data());
    }
    int normal_id = -1;
    if (normals) {
      const std::vector<PointKey>& keys = point_ids.keys();
      draco::GeometryAttribute normal;
      normal.Init(draco::GeometryAttribute::NORMAL, nullptr, 3, draco::DT_FLOAT32, false, 3 * sizeof(float), 0);
      normal_id = mesh.AddAttribute(normal, true, static_cast<uint32_t>(keys.size()));
      for (uint32_t p = 0; p < keys.size(); ++p) {
        position_att->SetPointMapEntry(draco::PointIndex(p), draco::AttributeValueIndex(keys[p][0]));
        const std::array<float, 3> n = {std::bit_cast<float>(keys[p][1]), std::bit_cast<float>(keys[p][2]),
                                        std::bit_cast<float>(keys[p][3])};
        mesh.attribute(normal_id)->SetAttributeValue(draco::AttributeValueIndex(p), n.data());
      }
    }
    for (const auto& ids : face_points) {
      mesh.AddFace({draco::PointIndex(ids[0]), draco::PointIndex(ids[1]), draco::PointIndex(ids[2])});
    }

    draco::ExpertEncoder encoder(mesh);
    encoder.SetSpeedOptions(options.draco_speed, options.draco_speed);
    encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
    // The standard traversal, never the valence one Draco picks below speed 5 for meshes of
    // 1000+ faces: its size bound is what lets the decoder refuse absurd face counts
    // (check_draco_stream). ExpertEncoder::SetEncodingSubmethod does not reach the
    // edgebreaker (it reads "edgebreaker_method"), hence the raw option.
    encoder.options().SetGlobalInt("edgebreaker_method", draco::MESH_EDGEBREAKER_STANDARD_ENCODING);
    if (normals) encoder.SetAttributeQuantization(normal_id, options.normal_bits);
    draco::EncoderBuffer buffer;
    try {
      const draco::Status s = encoder.EncodeToBuffer(&buffer);
      if (!s.ok()) return Status::invalid_argument(fmt::format("encode_cell: Draco: {}", s.error_msg_string()));
    } catch (const std::exception& e) {
      return Status::invalid_argument(fmt::format("encode_cell: Draco failed: {}", e.what()));
    }
    blob.assign(reinterpret_cast<const uint8_t*>(buffer.data()),
                reinterpret_cast<const uint8_t*>(buffer.data()) + buffer.size());

    // Decode it again to learn Draco's face order, then give every decoded face the source and
    // material of an input face with the same oriented vertices. Sorting both lists by key
    // pairs them up, duplicates included (equal faces are interchangeable).
    auto draco_mesh = run_draco_decoder(blob);
    if (!draco_mesh) {
      return Status::invalid_argument(
          fmt::format("encode_cell: Draco round trip failed ({})", draco_mesh.status().message()));
    }
    // Draco may decode more points than it was given (it splits non-manifold vertices): the
    // page records the decoded count.
    points = (*draco_mesh)->num_points();
    const LatticeIndex extent = {INT32_MAX, INT32_MAX, INT32_MAX};
    auto decoded = read_draco_mesh(**draco_mesh, faces.size(), points, normals, extent);
    if (!decoded) {
      return Status::invalid_argument(
          fmt::format("encode_cell: Draco round trip failed ({})", decoded.status().message()));
    }
    std::vector<uint32_t> point_vertex(points);
    for (size_t p = 0; p < points; ++p) {
      const LatticeIndex& q = decoded->offsets[p];
      point_vertex[p] = vertex_ids.find(vertex_key({q[0] + base[0], q[1] + base[1], q[2] + base[2]}));
      if (point_vertex[p] == DenseIds<VertexKey>::kNone) {
        return Status::invalid_argument("encode_cell: Draco round trip invented a vertex");
      }
    }
    // Input faces grouped by key (equal faces in input order), then each decoded face takes the
    // next unused input face of its key: the k-th copy of a face pairs with the k-th.
    DenseIds<FaceKey> face_ids(faces.size());
    std::vector<uint32_t> face_class(faces.size());
    for (uint32_t f = 0; f < faces.size(); ++f) {
      const auto& v = faces[f].vertex;
      face_class[f] = face_ids.insert(face_key(v[0], v[1], v[2]));
    }
    const size_t classes = face_ids.keys().size();
    std::vector<uint32_t> first(classes + 1, 0), members(faces.size());
    for (uint32_t c : face_class) ++first[c + 1];
    for (size_t c = 0; c < classes; ++c) first[c + 1] += first[c];
    std::vector<uint32_t> next(first.begin(), first.end() - 1);
    for (uint32_t f = 0; f < faces.size(); ++f) members[next[face_class[f]]++] = f;
    next.assign(first.begin(), first.end() - 1);
    sources.resize(faces.size());
    materials.resize(faces.size());
    for (uint32_t f = 0; f < faces.size(); ++f) {
      const auto& d = decoded->faces[f];
      const uint32_t c = face_ids.find(face_key(point_vertex[d[0]], point_vertex[d[1]], point_vertex[d[2]]));
      if (c == DenseIds<FaceKey>::kNone || next[c] == first[c + 1]) {
        return Status::invalid_argument(
            "encode_cell: Draco changed the cell's faces (a face was lost, added or flipped)");
      }
      const Face& in = faces[members[next[c]++]];
      sources[f] = in.source;
      materials[f] = in.material;
    }
    decoded_blob = std::move(draco_mesh).value();
  }

  EncodedCell encoded;
  encoded.codec = CellCodec::Draco;
  ByteWriter w(encoded.payload);
  w.u8(kDracoMagic);
  w.u8(normals && !faces.empty() ? kDracoHasNormals : 0);
  w.u8(static_cast<uint8_t>(lattice.bits));
  for (int64_t b : base) w.varint(static_cast<uint64_t>(b));
  w.varint(faces.size());
  w.varint(points);
  w.varint(blob.size());
  w.bytes(blob.data(), blob.size());
  write_sources(w, sources);
  write_values(w, materials);
  write_raw_body(w, others);

  // What a reader gets, by the reader's own code (Draco's decode of the same stream is the one
  // made above: decoding is deterministic, and a second run cost about 4% of a build).
  if (Status s = decode_draco_payload(encoded.payload, lattice, encoded.decoded, decoded_blob.get()); !s) {
    return Status::invalid_argument(fmt::format("encode_cell: the page does not decode ({})", s.message()));
  }
  return encoded;
}

Status decode_draco_payload(std::span<const uint8_t> payload, const Lattice& lattice, Scene& out,
                            const draco::Mesh* decoded_blob) {
  constexpr std::string_view kCodec = "Draco";
  ByteReader r(payload);
  if (r.u8() != kDracoMagic || !r.ok()) return corrupt(kCodec, 0, "bad magic or version");
  const uint8_t flags = r.u8();
  const uint8_t bits = r.u8();
  LatticeIndex base{};
  for (int64_t& b : base) b = static_cast<int64_t>(std::min<uint64_t>(r.varint(), INT64_MAX));
  const uint64_t faces = r.varint();
  const uint64_t points = r.varint();
  const uint64_t blob_size = r.varint();
  if (!r.ok()) return corrupt(kCodec, r.offset(), "truncated header");
  if ((flags & ~kDracoHasNormals) != 0) return corrupt(kCodec, 1, "unknown flags");
  if (bits != lattice.bits) {
    return corrupt(kCodec, 2, fmt::format("page lattice has {} bits, the model's {}", bits, lattice.bits));
  }
  const int64_t last = (int64_t{1} << bits) - 1;
  LatticeIndex extent{};
  for (int a = 0; a < 3; ++a) {
    if (base[a] > last) return corrupt(kCodec, r.offset(), "base off the lattice");
    extent[a] = last - base[a];
  }
  const bool normals = (flags & kDracoHasNormals) != 0;
  // A valid Draco stream holds at most 16 faces per byte (check_draco_stream).
  if (blob_size > r.remaining() || faces > 16 * blob_size + 1 || points > 3 * faces ||
      (faces == 0) != (blob_size == 0) || (normals && faces == 0)) {
    return corrupt(kCodec, r.offset(), "face, point or stream size does not fit the payload");
  }
  const std::span<const uint8_t> blob = r.bytes(blob_size);
  DracoMesh mesh;
  if (faces > 0) {
    if (Status s = check_draco_stream(blob, faces, normals); !s) return s;
    std::unique_ptr<draco::Mesh> own;
    if (decoded_blob == nullptr) {
      auto draco_mesh = run_draco_decoder(blob);
      if (!draco_mesh) return draco_mesh.status();
      own = std::move(draco_mesh).value();
      decoded_blob = own.get();
    }
    auto decoded = read_draco_mesh(*decoded_blob, faces, points, normals, extent);
    if (!decoded) return decoded.status();
    mesh = std::move(decoded).value();
  }
  std::vector<uint32_t> sources, materials;
  if (!read_sources(r, faces, sources)) return corrupt(kCodec, r.offset(), "bad triangle sources");
  if (!read_values(r, faces, UINT32_MAX, materials)) return corrupt(kCodec, r.offset(), "bad triangle materials");

  // Dequantize once per point, in double, through Lattice::point.
  std::vector<Vec3> positions(points);
  for (size_t p = 0; p < points; ++p) {
    const LatticeIndex& q = mesh.offsets[p];
    positions[p] = lattice.point({base[0] + q[0], base[1] + q[1], base[2] + q[2]});
  }
  out = Scene{};
  out.triangles.reserve(faces);
  out.prims.reserve(faces);
  if (normals) out.triangle_normals.reserve(faces);
  for (uint32_t f = 0; f < faces; ++f) {
    const auto& p = mesh.faces[f];
    out.prims.push_back({PrimKind::Triangle, f, sources[f], materials[f]});
    out.triangles.push_back({positions[p[0]], positions[p[1]], positions[p[2]]});
    if (normals) out.triangle_normals.push_back({mesh.normals[p[0]], mesh.normals[p[1]], mesh.normals[p[2]]});
  }
  if (Status s = read_raw_body(r, kCodec, false, out); !s) return s;
  if (r.remaining() != 0) return corrupt(kCodec, r.offset(), "trailing bytes");
  return Status::ok();
}

// --- the raw codec ---------------------------------------------------------------------------

Result<EncodedCell> encode_raw(const Scene& cell) {
  EncodedCell encoded;
  encoded.codec = CellCodec::Raw;
  ByteWriter w(encoded.payload);
  w.u8(kRawMagic);
  write_raw_body(w, cell);
  if (Status s = decode_cell(encoded.payload, CellCodec::Raw, Lattice{}, encoded.decoded); !s) {
    return Status::invalid_argument(fmt::format("encode_cell: the page does not decode ({})", s.message()));
  }
  return encoded;
}

Status decode_raw_payload(std::span<const uint8_t> payload, Scene& out) {
  constexpr std::string_view kCodec = "raw";
  ByteReader r(payload);
  if (r.u8() != kRawMagic || !r.ok()) return corrupt(kCodec, 0, "bad magic or version");
  out = Scene{};
  if (Status s = read_raw_body(r, kCodec, true, out); !s) return s;
  if (r.remaining() != 0) return corrupt(kCodec, r.offset(), "trailing bytes");
  return Status::ok();
}

}  // namespace

Result<EncodedCell> encode_cell(const Scene& cell, const CellCodecOptions& options) {
  if (Status s = check_scene(cell); !s) return s;
  switch (options.codec) {
    case CellCodec::Raw: return encode_raw(cell);
    case CellCodec::Draco: return encode_draco(cell, options);
  }
  return Status::invalid_argument(
      fmt::format("encode_cell: unknown codec {}", static_cast<unsigned>(options.codec)));
}

Status decode_cell(std::span<const uint8_t> payload, CellCodec codec, const Lattice& lattice, Scene& out) {
  Status s;
  switch (codec) {
    case CellCodec::Raw: s = decode_raw_payload(payload, out); break;
    case CellCodec::Draco:
      s = check_lattice(lattice, "decode_cell");
      if (s) s = decode_draco_payload(payload, lattice, out);
      break;
    default: s = Status::corruption(fmt::format("cell page: unknown codec {}", static_cast<unsigned>(codec)));
  }
  if (!s) out = Scene{};
  return s;
}

}  // namespace frontier
