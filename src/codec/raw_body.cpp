// The raw body (layout: store/FORMAT.md "Raw body"; contracts: raw_body.h). Decoding checks
// before it allocates: counts against the bytes left, then the streams, then the doubles, then
// the primitives' references into the arrays just read.
#include "src/codec/raw_body.h"

#include "src/codec/cell_codec_impl.h"
#include "src/codec/value_stream.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

namespace frontier::cell_page {
namespace {

// Flags byte.
constexpr uint8_t kRawHasNormals = 1;
constexpr uint8_t kRawExplicitIndices = 2;

constexpr int kPrimKinds = 5;
// Bytes of one primitive's doubles in a raw body (a quadric's clip planes come on top).
constexpr size_t kTriangleBytes = 9 * 8;
constexpr size_t kSphereBytes = 4 * 8;
constexpr size_t kBoxBytes = 6 * 8;
constexpr size_t kConeBytes = 8 * 8;
constexpr size_t kQuadricMinBytes = 10 * 8 + 1 + 6 * 8;

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

void write_geometry(GeometryWriter& w, const Scene& s) {
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

// What the counts at the start of a body announce, checked against the bytes after them.
struct BodyCounts {
  uint64_t prims = 0;
  std::array<uint64_t, kPrimKinds> elements{};  // triangles, spheres, boxes, cones, quadrics
  bool normals = false;
  bool explicit_indices = false;
};

Status read_counts(GeometryReader& r, std::string_view codec, bool triangles_allowed, BodyCounts& c) {
  c.prims = r.varint();
  for (uint64_t& n : c.elements) n = r.varint();
  const uint8_t flags = r.u8();
  if (!r.ok()) return corrupt(codec, r.offset(), "truncated primitive counts");
  if ((flags & ~(kRawHasNormals | kRawExplicitIndices)) != 0) return corrupt(codec, r.offset(), "unknown flags");
  c.normals = (flags & kRawHasNormals) != 0;
  c.explicit_indices = (flags & kRawExplicitIndices) != 0;
  // Cap every count by the bytes left before multiplying or allocating: a triangle costs 72
  // bytes (144 with normals), a sphere 32, and so on; with implicit indices there is one
  // primitive per element, with explicit ones each costs at least a byte of index.
  const size_t left = r.remaining();
  const auto& e = c.elements;
  if (c.prims > left || std::any_of(e.begin(), e.end(), [&](uint64_t n) { return n > left; })) {
    return corrupt(codec, r.offset(), "primitive counts exceed the payload");
  }
  const uint64_t geometry = e[0] * kTriangleBytes * (c.normals ? 2 : 1) + e[1] * kSphereBytes + e[2] * kBoxBytes +
                            e[3] * kConeBytes + e[4] * kQuadricMinBytes;
  const uint64_t elements = e[0] + e[1] + e[2] + e[3] + e[4];
  if (geometry > left || (!c.explicit_indices && c.prims != elements)) {
    return corrupt(codec, r.offset(), "primitive counts exceed the payload");
  }
  if (c.normals && e[0] == 0) return corrupt(codec, r.offset(), "normals flag without triangles");
  if (e[0] > 0 && !triangles_allowed) return corrupt(codec, r.offset(), "triangles outside the Draco mesh");
  return Status::ok();
}

// Per primitive, in order: its kind, its index into that kind's array, source and material.
struct BodyPrims {
  std::vector<uint32_t> kinds, indices, sources, materials;
};

Status read_prims(GeometryReader& r, std::string_view codec, const BodyCounts& c, BodyPrims& p) {
  if (!read_values(r, c.prims, kPrimKinds - 1, p.kinds)) return corrupt(codec, r.offset(), "bad primitive kinds");
  p.indices.resize(c.prims);
  if (c.explicit_indices) {
    if (c.prims > r.remaining()) return corrupt(codec, r.offset(), "truncated primitive indices");
    for (size_t i = 0; i < c.prims; ++i) {
      const uint64_t index = r.varint();
      if (!r.ok() || index >= c.elements[p.kinds[i]]) return corrupt(codec, r.offset(), "bad primitive index");
      p.indices[i] = static_cast<uint32_t>(index);
    }
  } else {
    // Implicit indices: the k-th primitive of a kind is element k, and all elements are used.
    std::array<uint64_t, kPrimKinds> seen{};
    for (size_t i = 0; i < c.prims; ++i) p.indices[i] = static_cast<uint32_t>(seen[p.kinds[i]]++);
    if (seen != c.elements) return corrupt(codec, r.offset(), "primitive kinds do not match the counts");
  }
  if (!read_sources(r, c.prims, p.sources)) return corrupt(codec, r.offset(), "bad primitive sources");
  if (!read_values(r, c.prims, UINT32_MAX, p.materials)) return corrupt(codec, r.offset(), "bad primitive materials");
  return Status::ok();
}

// Appends the body's doubles to out's arrays.
Status read_geometry(GeometryReader& r, std::string_view codec, const BodyCounts& c, Scene& out) {
  const auto& e = c.elements;
  for (uint64_t i = 0; i < e[0]; ++i) {
    const Vec3 v0 = r.vec3(), v1 = r.vec3();
    out.triangles.push_back({v0, v1, r.vec3()});
  }
  if (c.normals) {
    for (uint64_t i = 0; i < e[0]; ++i) {
      const Vec3 n0 = r.vec3(), n1 = r.vec3();
      out.triangle_normals.push_back({n0, n1, r.vec3()});
    }
  }
  for (uint64_t i = 0; i < e[1]; ++i) {
    Sphere s;
    s.center = r.vec3();
    s.radius = r.f64();
    out.spheres.push_back(s);
  }
  for (uint64_t i = 0; i < e[2]; ++i) {
    Box b;
    b.bounds = r.box();
    out.boxes.push_back(b);
  }
  for (uint64_t i = 0; i < e[3]; ++i) {
    Cone k;
    k.base = r.vec3();
    k.base_radius = r.f64();
    k.apex = r.vec3();
    k.apex_radius = r.f64();
    out.cones.push_back(k);
  }
  for (uint64_t i = 0; i < e[4]; ++i) {
    Quadric q;
    for (double& coeff : q.coeff) coeff = r.f64();
    const uint8_t clip_count = r.u8();
    if (!r.ok() || clip_count > Quadric::kMaxClipPlanes) return corrupt(codec, r.offset(), "bad quadric clip count");
    q.clip_count = clip_count;
    for (int k = 0; k < q.clip_count; ++k) {
      const double x = r.f64(), y = r.f64(), z = r.f64();
      q.clip[static_cast<size_t>(k)] = Vec4(x, y, z, r.f64());
    }
    q.bounds = r.box();
    out.quadrics.push_back(q);
  }
  if (!r.ok()) return corrupt(codec, r.offset(), "truncated primitive geometry");
  return Status::ok();
}

}  // namespace

void write_raw_body(GeometryWriter& w, const Scene& s) {
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
  write_geometry(w, s);
}

Status read_raw_body(GeometryReader& r, std::string_view codec, bool triangles_allowed, Scene& out) {
  BodyCounts counts;
  if (Status s = read_counts(r, codec, triangles_allowed, counts); !s) return s;
  BodyPrims prims;
  if (Status s = read_prims(r, codec, counts, prims); !s) return s;
  // Where this body's elements start in out's arrays, per kind.
  const std::array<size_t, kPrimKinds> base = {out.triangles.size(), out.spheres.size(), out.boxes.size(),
                                               out.cones.size(), out.quadrics.size()};
  if (Status s = read_geometry(r, codec, counts, out); !s) return s;
  out.prims.reserve(out.prims.size() + counts.prims);
  for (size_t i = 0; i < counts.prims; ++i) {
    const uint32_t kind = prims.kinds[i];
    out.prims.push_back({static_cast<PrimKind>(kind), static_cast<uint32_t>(base[kind] + prims.indices[i]),
                         prims.sources[i], prims.materials[i]});
  }
  return Status::ok();
}

}  // namespace frontier::cell_page
