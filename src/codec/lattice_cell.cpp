// The parts the lattice codecs share (contracts: lattice_cell.h).
#include "src/codec/lattice_cell.h"

#include "src/codec/cell_codec_impl.h"
#include "src/codec/value_stream.h"

#include <fmt/format.h>

#include <algorithm>

namespace frontier::cell_page {

Status split_lattice_cell(const Scene& cell, const Lattice& lattice, LatticeCell& out) {
  for (size_t i = 0; i < cell.prims.size(); ++i) {
    const PrimRef& p = cell.prims[i];
    switch (p.kind) {
      case PrimKind::Sphere: out.others.add_sphere(cell.spheres[p.index], p.source, p.material); continue;
      case PrimKind::Box: out.others.add_box(cell.boxes[p.index], p.source, p.material); continue;
      case PrimKind::Cone: out.others.add_cone(cell.cones[p.index], p.source, p.material); continue;
      case PrimKind::Quadric: out.others.add_quadric(cell.quadrics[p.index], p.source, p.material); continue;
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
    // A face with a repeated vertex (zero area on the lattice) is dropped here, and `decoded`
    // shows it.
    if (q[0] == q[1] || q[1] == q[2] || q[0] == q[2]) continue;
    out.faces.push_back({{out.vertex_ids.insert(vertex_key(q[0])), out.vertex_ids.insert(vertex_key(q[1])),
                          out.vertex_ids.insert(vertex_key(q[2]))},
                         p.index, p.source, p.material});
  }
  const std::vector<VertexKey>& vertices = out.vertex_ids.keys();
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
  out.base = base;
  for (int a = 0; a < 3; ++a) out.span[a] = top[a] - base[a];
  return Status::ok();
}

void write_lattice_base(GeometryWriter& w, int bits, const LatticeIndex& base) {
  w.u8(static_cast<uint8_t>(bits));
  for (int64_t b : base) w.varint(static_cast<uint64_t>(b));
}

Status read_lattice_base(GeometryReader& r, std::string_view codec, const Lattice& lattice, LatticeIndex& base,
                         LatticeIndex& extent) {
  const size_t bits_at = r.offset();
  const int bits = r.u8();
  for (int64_t& b : base) b = static_cast<int64_t>(std::min<uint64_t>(r.varint(), INT64_MAX));
  if (!r.ok()) return corrupt(codec, r.offset(), "truncated header");
  if (bits != lattice.bits) {
    return corrupt(codec, bits_at, fmt::format("page lattice has {} bits, the model's {}", bits, lattice.bits));
  }
  const int64_t last = (int64_t{1} << bits) - 1;
  for (int a = 0; a < 3; ++a) {
    if (base[a] > last) return corrupt(codec, r.offset(), "base off the lattice");
    extent[a] = last - base[a];
  }
  return Status::ok();
}

void write_triangle_ids(GeometryWriter& w, const std::vector<uint32_t>& sources,
                        const std::vector<uint32_t>& materials) {
  write_sources(w, sources);
  write_values(w, materials);
}

Status read_triangle_ids(GeometryReader& r, std::string_view codec, size_t triangles, std::vector<uint32_t>& sources,
                         std::vector<uint32_t>& materials) {
  if (!read_sources(r, triangles, sources)) return corrupt(codec, r.offset(), "bad triangle sources");
  if (!read_values(r, triangles, UINT32_MAX, materials)) return corrupt(codec, r.offset(), "bad triangle materials");
  return Status::ok();
}

}  // namespace frontier::cell_page
