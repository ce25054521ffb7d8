// The meshopt cell codec (tag 2; store/FORMAT.md "Meshopt payload"; contracts: cell_codec.h).
//
// The triangles (split on the global lattice as the Draco codec splits them, lattice_cell.h)
// become an indexed mesh whose vertices are integer lattice offsets from the cell's base, three
// uint32 each, compressed by meshoptimizer's vertex codec; with normals, a second vertex stream
// holds each vertex's normal in meshoptimizer's 16-bit octahedral filter. The index buffer goes
// through meshoptimizer's index codec, which keeps the triangle order (it may rotate a
// triangle's corners: normals live on the vertices, so they rotate with them). Before encoding,
// triangles are reordered for the vertex cache and vertices for first use (meshoptimizer's
// optimizers), which is what the codecs are tuned for; the per-triangle sources and materials
// are stored in that order. Every other primitive goes into a raw body after them.
//
// Decoding trusts nothing: counts are checked against the bytes left before anything is
// allocated (meshoptimizer's streams cannot hold more than a fixed number of vertices or
// triangles per byte), meshoptimizer's decoders are documented safe on untrusted input, and
// every index and offset they return is range-checked before use.
#include "src/codec/cell_codec_impl.h"
#include "src/codec/lattice_cell.h"
#include "src/codec/raw_body.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <mutex>
#include <numeric>
#include <string_view>
#include <tuple>

namespace frontier::cell_page {
namespace {

constexpr uint8_t kMeshoptMagic = 0xE1;  // meshopt codec, layout version 1
constexpr uint8_t kMeshoptHasNormals = 1;  // header flag
constexpr std::string_view kCodec = "meshopt";
constexpr size_t kPositionBytes = 3 * sizeof(uint32_t);
constexpr size_t kNormalBytes = 4 * sizeof(int16_t);  // octahedral x, y, the filter's 1.0, unused w
// meshoptimizer's vertex codec spends at least 4 bytes of group headers per 256-vertex block and
// vertex byte (and a tail), its index codec at least one byte per triangle: a stream of n bytes
// holds at most 64 n bytes of vertices and n triangles.
constexpr uint64_t kVertexBytesPerStreamByte = 64;

// An oct-encoded normal as the filter writes it (its x, y; the rest is constant).
using OctNormal = std::array<int16_t, 4>;

// The fields of a meshopt payload, in order (the raw body follows).
struct MeshoptPage {
  bool normals = false;  // only with faces
  LatticeIndex base{0, 0, 0};
  uint64_t faces = 0, vertices = 0;
  std::span<const uint8_t> positions, normal_stream, indices;
  std::vector<uint32_t> sources, materials;  // per face, in the stored order
};

// --- encoding --------------------------------------------------------------------------------

Status check_options(const CellCodecOptions& options, bool normals) {
  if (Status s = check_lattice(options.lattice, "encode_cell"); !s) return s;
  if (normals && (options.normal_bits < 2 || options.normal_bits > 16)) {
    return Status::invalid_argument(
        fmt::format("encode_cell: normal bits {} is not 2..16 (meshopt codec)", options.normal_bits));
  }
  return Status::ok();
}

// The indexed mesh before compression: vertices (lattice offset, and with normals the
// oct-encoded normal; one vertex per distinct pair) and per face its three vertices, faces in
// the cell's order.
struct IndexedMesh {
  std::vector<std::array<uint32_t, 3>> positions;
  std::vector<OctNormal> normals;
  std::vector<uint32_t> indices;  // 3 per face
};

IndexedMesh indexed_mesh(const LatticeCell& cell, const Scene& scene, bool normals, int normal_bits) {
  IndexedMesh mesh;
  const std::vector<VertexKey>& vertices = cell.vertex_ids.keys();
  auto offset = [&](uint32_t v) {
    std::array<uint32_t, 3> o;
    for (int a = 0; a < 3; ++a) o[a] = static_cast<uint32_t>(vertices[v][a] - cell.base[a]);
    return o;
  };
  mesh.indices.resize(3 * cell.faces.size());
  if (!normals) {
    mesh.positions.resize(vertices.size());
    for (uint32_t v = 0; v < vertices.size(); ++v) mesh.positions[v] = offset(v);
    for (size_t f = 0; f < cell.faces.size(); ++f) {
      for (int c = 0; c < 3; ++c) mesh.indices[3 * f + c] = cell.faces[f].vertex[c];
    }
    return mesh;
  }
  // Every corner's normal through the octahedral filter, then one vertex per distinct
  // (lattice vertex, encoded normal).
  std::vector<float> corner_normals(4 * mesh.indices.size(), 0.0f);
  for (size_t f = 0; f < cell.faces.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      Vec3 n = scene.triangle_normals[cell.faces[f].triangle][c];
      const double length = glm::length(n);
      n = std::isfinite(length) && length > 0.0 ? n / length : Vec3(0, 0, 1);
      for (int a = 0; a < 3; ++a) corner_normals[4 * (3 * f + c) + a] = static_cast<float>(n[a]);
    }
  }
  std::vector<OctNormal> encoded(mesh.indices.size());
  meshopt_encodeFilterOct(encoded.data(), encoded.size(), kNormalBytes, normal_bits, corner_normals.data());
  DenseIds<std::array<uint32_t, 3>> vertex_ids(vertices.size());
  for (size_t f = 0; f < cell.faces.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const OctNormal& n = encoded[3 * f + c];
      const uint32_t key_normal = std::bit_cast<uint32_t>(std::array<int16_t, 2>{n[0], n[1]});
      const uint32_t key_rest = std::bit_cast<uint32_t>(std::array<int16_t, 2>{n[2], n[3]});
      const uint32_t id = vertex_ids.insert({cell.faces[f].vertex[c], key_normal, key_rest});
      if (id == mesh.positions.size()) {
        mesh.positions.push_back(offset(cell.faces[f].vertex[c]));
        mesh.normals.push_back(n);
      }
      mesh.indices[3 * f + c] = id;
    }
  }
  return mesh;
}

// Reorders the faces for the vertex cache (`order[k]`: the cell face stored k-th) and the
// vertices by first use. meshopt_optimizeVertexCache permutes whole triangles without rotating
// them; equal triangles are interchangeable, so the k-th copy of a triangle pairs with the k-th.
Status optimize(IndexedMesh& mesh, std::vector<uint32_t>& order) {
  const size_t faces = mesh.indices.size() / 3;
  std::vector<uint32_t> optimized(mesh.indices.size());
  meshopt_optimizeVertexCache(optimized.data(), mesh.indices.data(), mesh.indices.size(), mesh.positions.size());
  auto by_corners = [](const std::vector<uint32_t>& indices) {
    std::vector<uint32_t> faces_sorted(indices.size() / 3);
    std::iota(faces_sorted.begin(), faces_sorted.end(), 0u);
    std::stable_sort(faces_sorted.begin(), faces_sorted.end(), [&](uint32_t a, uint32_t b) {
      return std::tie(indices[3 * a], indices[3 * a + 1], indices[3 * a + 2]) <
             std::tie(indices[3 * b], indices[3 * b + 1], indices[3 * b + 2]);
    });
    return faces_sorted;
  };
  const std::vector<uint32_t> before = by_corners(mesh.indices), after = by_corners(optimized);
  order.assign(faces, 0);
  for (size_t k = 0; k < faces; ++k) {
    if (!std::equal(&mesh.indices[3 * before[k]], &mesh.indices[3 * before[k]] + 3, &optimized[3 * after[k]])) {
      return Status::invalid_argument("encode_cell: meshoptimizer's vertex cache optimizer changed a triangle");
    }
    order[after[k]] = before[k];
  }
  std::vector<uint32_t> remap(mesh.positions.size());
  const size_t used = meshopt_optimizeVertexFetchRemap(remap.data(), optimized.data(), optimized.size(),
                                                       mesh.positions.size());
  std::vector<std::array<uint32_t, 3>> positions(used);
  std::vector<OctNormal> normals(mesh.normals.empty() ? 0 : used);
  for (size_t v = 0; v < mesh.positions.size(); ++v) {
    if (remap[v] == ~0u) continue;
    positions[remap[v]] = mesh.positions[v];
    if (!normals.empty()) normals[remap[v]] = mesh.normals[v];
  }
  for (uint32_t& i : optimized) i = remap[i];
  mesh.positions = std::move(positions);
  mesh.normals = std::move(normals);
  mesh.indices = std::move(optimized);
  return Status::ok();
}

// meshoptimizer's index format version 1 (0.14+; smaller than 0). The setting is global in
// meshoptimizer: set once, before the first encode on any thread.
void use_index_version_1() {
  static std::once_flag once;
  std::call_once(once, [] { meshopt_encodeIndexVersion(1); });
}

std::vector<uint8_t> vertex_stream(const void* vertices, size_t count, size_t size) {
  std::vector<uint8_t> out(meshopt_encodeVertexBufferBound(count, size));
  out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), vertices, count, size));
  return out;
}

std::vector<uint8_t> index_stream(const std::vector<uint32_t>& indices, size_t vertices) {
  use_index_version_1();
  std::vector<uint8_t> out(meshopt_encodeIndexBufferBound(indices.size(), vertices));
  out.resize(meshopt_encodeIndexBuffer(out.data(), out.size(), indices.data(), indices.size()));
  return out;
}

void write_payload(const MeshoptPage& page, int bits, const Scene& others, std::vector<uint8_t>& out) {
  GeometryWriter w(out);
  w.u8(kMeshoptMagic);
  w.u8(page.normals ? kMeshoptHasNormals : 0);
  write_lattice_base(w, bits, page.base);
  w.varint(page.faces);
  w.varint(page.vertices);
  for (std::span<const uint8_t> stream : {page.positions, page.normal_stream, page.indices}) {
    w.varint(stream.size());
    w.bytes(stream);
  }
  write_triangle_ids(w, page.sources, page.materials);
  write_raw_body(w, others);
}

// --- decoding --------------------------------------------------------------------------------

// Reads the fields up to and including the index stream and checks the counts against the
// stream sizes (so that what the decoders allocate stays within a constant times the payload).
// `extent`: the largest offset from the base each axis allows.
Status read_header(GeometryReader& r, const Lattice& lattice, MeshoptPage& page, LatticeIndex& extent) {
  if (r.u8() != kMeshoptMagic || !r.ok()) return corrupt(kCodec, 0, "bad magic or version");
  const uint8_t flags = r.u8();
  if ((flags & ~kMeshoptHasNormals) != 0 && r.ok()) return corrupt(kCodec, 1, "unknown flags");
  page.normals = (flags & kMeshoptHasNormals) != 0;
  if (Status s = read_lattice_base(r, kCodec, lattice, page.base, extent); !s) return s;
  page.faces = r.varint();
  page.vertices = r.varint();
  std::span<const uint8_t>* streams[3] = {&page.positions, &page.normal_stream, &page.indices};
  for (std::span<const uint8_t>* stream : streams) {
    const size_t at = r.offset();
    const uint64_t size = r.varint();
    if (r.ok() && size > r.remaining()) return corrupt(kCodec, at, "stream longer than the payload");
    *stream = r.bytes(size);
  }
  if (!r.ok()) return corrupt(kCodec, r.offset(), "truncated header");
  const bool empty = page.faces == 0;
  const uint64_t limit = kVertexBytesPerStreamByte;
  if (page.faces > page.indices.size() || page.vertices > 3 * page.faces || empty != (page.vertices == 0) ||
      empty != page.positions.empty() || empty != page.indices.empty() || (page.normals && empty) ||
      page.normals == page.normal_stream.empty() || page.vertices * kPositionBytes > limit * page.positions.size() ||
      (page.normals && page.vertices * kNormalBytes > limit * page.normal_stream.size())) {
    return corrupt(kCodec, r.offset(), "face, vertex or stream size does not fit the payload");
  }
  return Status::ok();
}

// Appends the page's triangles to `out`, dequantized once per vertex, in double, through
// Lattice::point; every index and offset checked first.
Status add_triangles(const MeshoptPage& page, const Lattice& lattice, const LatticeIndex& extent, size_t at,
                     Scene& out) {
  std::vector<std::array<uint32_t, 3>> offsets(page.vertices);
  if (meshopt_decodeVertexBuffer(offsets.data(), offsets.size(), kPositionBytes, page.positions.data(),
                                 page.positions.size()) != 0) {
    return corrupt(kCodec, at, "bad vertex stream");
  }
  std::vector<OctNormal> normals(page.normals ? page.vertices : 0);
  if (page.normals) {
    if (meshopt_decodeVertexBuffer(normals.data(), normals.size(), kNormalBytes, page.normal_stream.data(),
                                   page.normal_stream.size()) != 0) {
      return corrupt(kCodec, at, "bad normal stream");
    }
    meshopt_decodeFilterOct(normals.data(), normals.size(), kNormalBytes);
  }
  std::vector<uint32_t> indices(3 * page.faces);
  if (meshopt_decodeIndexBuffer(indices.data(), indices.size(), sizeof(uint32_t), page.indices.data(),
                                page.indices.size()) != 0) {
    return corrupt(kCodec, at, "bad index stream");
  }
  for (uint32_t i : indices) {
    if (i >= page.vertices) return corrupt(kCodec, at, "triangle refers to a missing vertex");
  }
  std::vector<Vec3> positions(page.vertices), vertex_normals(normals.size());
  for (size_t v = 0; v < page.vertices; ++v) {
    const std::array<uint32_t, 3>& q = offsets[v];
    for (int a = 0; a < 3; ++a) {
      if (q[a] > extent[a]) return corrupt(kCodec, at, "vertex off the lattice");
    }
    positions[v] = lattice.point({page.base[0] + q[0], page.base[1] + q[1], page.base[2] + q[2]});
    if (!normals.empty()) {
      vertex_normals[v] = Vec3(normals[v][0], normals[v][1], normals[v][2]) / 32767.0;
    }
  }
  out.triangles.reserve(page.faces);
  out.prims.reserve(page.faces);
  if (page.normals) out.triangle_normals.reserve(page.faces);
  for (uint32_t f = 0; f < page.faces; ++f) {
    const uint32_t* p = &indices[3 * f];
    out.prims.push_back({PrimKind::Triangle, f, page.sources[f], page.materials[f]});
    out.triangles.push_back({positions[p[0]], positions[p[1]], positions[p[2]]});
    if (page.normals) out.triangle_normals.push_back({vertex_normals[p[0]], vertex_normals[p[1]], vertex_normals[p[2]]});
  }
  return Status::ok();
}

Status decode_meshopt(std::span<const uint8_t> payload, const Lattice& lattice, Scene& out) {
  if (Status s = check_lattice(lattice, "decode_cell"); !s) return s;
  GeometryReader r(payload);
  MeshoptPage page;
  LatticeIndex extent{};
  if (Status s = read_header(r, lattice, page, extent); !s) return s;
  const size_t mesh_end = r.offset();
  if (Status s = read_triangle_ids(r, kCodec, page.faces, page.sources, page.materials); !s) return s;
  if (page.faces > 0) {
    if (Status s = add_triangles(page, lattice, extent, mesh_end, out); !s) return s;
  }
  if (Status s = read_raw_body(r, kCodec, false, out); !s) return s;
  if (r.remaining() != 0) return corrupt(kCodec, r.offset(), "trailing bytes");
  return Status::ok();
}

// --- the codec -------------------------------------------------------------------------------

Result<EncodedCell> encode_meshopt(const Scene& cell, const CellCodecOptions& options) {
  const bool normals = !cell.triangle_normals.empty();
  if (Status s = check_options(options, normals); !s) return s;
  LatticeCell split(cell.triangles.size());
  if (Status s = split_lattice_cell(cell, options.lattice, split); !s) return s;

  MeshoptPage page;
  page.normals = normals && !split.faces.empty();
  page.base = split.base;
  page.faces = split.faces.size();
  IndexedMesh mesh = indexed_mesh(split, cell, page.normals, options.normal_bits);
  std::vector<uint32_t> order;
  if (page.faces > 0) {
    if (Status s = optimize(mesh, order); !s) return s;
  }
  page.vertices = mesh.positions.size();
  page.sources.resize(order.size());
  page.materials.resize(order.size());
  for (size_t k = 0; k < order.size(); ++k) {
    page.sources[k] = split.faces[order[k]].source;
    page.materials[k] = split.faces[order[k]].material;
  }
  std::vector<uint8_t> positions, normal_stream, indices;
  if (page.faces > 0) {
    positions = vertex_stream(mesh.positions.data(), mesh.positions.size(), kPositionBytes);
    if (page.normals) normal_stream = vertex_stream(mesh.normals.data(), mesh.normals.size(), kNormalBytes);
    indices = index_stream(mesh.indices, mesh.positions.size());
    if (positions.empty() || (page.normals && normal_stream.empty()) || indices.empty()) {
      return Status::invalid_argument("encode_cell: meshoptimizer's encoder failed");
    }
  }
  page.positions = positions;
  page.normal_stream = normal_stream;
  page.indices = indices;

  EncodedCell encoded;
  encoded.codec = CellCodec::Meshopt;
  write_payload(page, options.lattice.bits, split.others, encoded.payload);
  // What a reader gets, by the reader's own code.
  if (Status s = decode_meshopt(encoded.payload, options.lattice, encoded.decoded); !s) {
    return Status::invalid_argument(fmt::format("encode_cell: the page does not decode ({})", s.message()));
  }
  return encoded;
}

}  // namespace

const CellCodecImpl kMeshoptCodec = {CellCodec::Meshopt, kCodec, encode_meshopt, decode_meshopt};

}  // namespace frontier::cell_page
