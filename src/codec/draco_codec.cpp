// The Draco cell codec (tag 1; store/FORMAT.md "Draco payload"; contracts: cell_codec.h).
//
// The triangles go into a Draco edgebreaker mesh (draco_stream.h) whose positions are integer
// lattice offsets from a per-cell base; per-triangle sources and materials are stored beside
// it in the order in which Draco decodes the faces, found at encode time by decoding the mesh
// again and matching faces by their lattice coordinates. Every other primitive goes into a raw
// body (raw_body.h) after them. The split into lattice triangles and the rest, the lattice base
// and the source/material streams are shared with the meshopt codec (lattice_cell.h).
//
// Decoding trusts nothing: the header's counts are checked against the bytes left, the Draco
// stream's own counts against the header before Draco sees them, and everything Draco hands
// back is range-checked (draco_stream.h).
#include "src/codec/cell_codec_impl.h"
#include "src/codec/dense_ids.h"
#include "src/codec/draco_stream.h"
#include "src/codec/lattice_cell.h"
#include "src/codec/raw_body.h"

#include <algorithm>
#include <array>
#include <bit>
#include <memory>
#include <string_view>
#include <utility>

namespace frontier::cell_page {
namespace {

constexpr uint8_t kDracoMagic = 0xD1;  // Draco codec, layout version 1
constexpr uint8_t kDracoHasNormals = 1;  // header flag
// Per axis: Draco's entropy coder sizes a histogram by the largest prediction correction, which
// can reach the cell's extent in lattice steps (see check_span).
constexpr int64_t kMaxCellSteps = int64_t{1} << 24;
constexpr std::string_view kCodec = "Draco";

// A Draco point: a vertex id and the bit pattern of its float normal.
using PointKey = std::array<uint32_t, 4>;
// A face's vertex ids rotated to start at the smallest, keeping the cyclic order: equal for
// the same oriented face whatever corner Draco starts it at, different for the flipped one.
using FaceKey = std::array<uint32_t, 3>;

FaceKey face_key(uint32_t a, uint32_t b, uint32_t c) {
  if (b < a && b < c) return {b, c, a};
  if (c < a && c < b) return {c, a, b};
  return {a, b, c};
}

// The fields of a Draco payload, in order (the raw body follows).
struct DracoPage {
  bool normals = false;  // only with faces
  int bits = 0;
  LatticeIndex base{0, 0, 0};
  uint64_t faces = 0;
  uint64_t points = 0;  // of the decoded Draco mesh
  std::span<const uint8_t> blob;
  std::vector<uint32_t> sources, materials;  // per face, in Draco's decoded order
};

// --- encoding --------------------------------------------------------------------------------

Status check_options(const CellCodecOptions& options, bool normals) {
  if (Status s = check_lattice(options.lattice, "encode_cell"); !s) return s;
  if (options.draco_speed < 0 || options.draco_speed > 10) {
    return Status::invalid_argument(fmt::format("encode_cell: Draco speed {} is not 0..10", options.draco_speed));
  }
  if (normals && (options.normal_bits < 2 || options.normal_bits > 30)) {
    return Status::invalid_argument(fmt::format("encode_cell: normal bits {} is not 2..30", options.normal_bits));
  }
  return Status::ok();
}

// Draco's entropy coder sizes a histogram by the largest prediction correction, which can reach
// the cell's extent in lattice steps: measured 74 MB and 0.1 M triangles/s at 2^24 steps, 4 GB
// at 2^30. Refuse before that rather than exhaust memory.
Status check_span(const LatticeCell& cell) {
  for (int a = 0; a < 3; ++a) {
    if (cell.span[a] >= kMaxCellSteps) {
      return Status::invalid_argument(fmt::format(
          "encode_cell: the cell spans {} lattice steps on axis {}; the Draco codec takes at most 2^24 "
          "(use fewer lattice bits or smaller cells)", cell.span[a], a));
    }
  }
  return Status::ok();
}

// The mesh Draco encodes: positions relative to the base; with normals, one Draco point per
// distinct (vertex, float normal), otherwise one per vertex.
DracoInput draco_input(const LatticeCell& cell, const Scene& scene, bool normals) {
  DracoInput in;
  in.normals = normals;
  const std::vector<VertexKey>& vertices = cell.vertex_ids.keys();
  in.positions.resize(vertices.size());
  for (size_t v = 0; v < vertices.size(); ++v) {
    for (int a = 0; a < 3; ++a) in.positions[v][a] = static_cast<int32_t>(vertices[v][a] - cell.base[a]);
  }
  in.faces.resize(cell.faces.size());
  if (!normals) {
    for (size_t f = 0; f < cell.faces.size(); ++f) in.faces[f] = cell.faces[f].vertex;
    return in;
  }
  DenseIds<PointKey> point_ids(vertices.size());
  for (size_t f = 0; f < cell.faces.size(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const Vec3& n = scene.triangle_normals[cell.faces[f].triangle][c];
      in.faces[f][c] = point_ids.insert({cell.faces[f].vertex[c], std::bit_cast<uint32_t>(static_cast<float>(n.x)),
                                         std::bit_cast<uint32_t>(static_cast<float>(n.y)),
                                         std::bit_cast<uint32_t>(static_cast<float>(n.z))});
    }
  }
  for (const PointKey& key : point_ids.keys()) {
    in.point_vertex.push_back(key[0]);
    in.point_normals.push_back({std::bit_cast<float>(key[1]), std::bit_cast<float>(key[2]), std::bit_cast<float>(key[3])});
  }
  return in;
}

// Gives every face of Draco's decoded mesh the source and material of an input face with the
// same oriented vertices (page.sources, page.materials). Input faces are grouped by key (equal
// faces in input order); each decoded face takes the next unused input face of its key, so the
// k-th copy of a face pairs with the k-th (equal faces are interchangeable).
Status pair_faces(const LatticeCell& cell, const DracoMesh& decoded, DracoPage& page) {
  // Draco may decode more points than it was given (it splits non-manifold vertices).
  std::vector<uint32_t> point_vertex(page.points);
  for (size_t p = 0; p < page.points; ++p) {
    const LatticeIndex& q = decoded.offsets[p];
    const LatticeIndex& b = cell.base;
    point_vertex[p] = cell.vertex_ids.find(vertex_key({q[0] + b[0], q[1] + b[1], q[2] + b[2]}));
    if (point_vertex[p] == DenseIds<VertexKey>::kNone) {
      return Status::invalid_argument("encode_cell: Draco round trip invented a vertex");
    }
  }
  const std::vector<LatticeFace>& faces = cell.faces;
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
  page.sources.resize(faces.size());
  page.materials.resize(faces.size());
  for (uint32_t f = 0; f < faces.size(); ++f) {
    const auto& d = decoded.faces[f];
    const uint32_t c = face_ids.find(face_key(point_vertex[d[0]], point_vertex[d[1]], point_vertex[d[2]]));
    if (c == DenseIds<FaceKey>::kNone || next[c] == first[c + 1]) {
      return Status::invalid_argument("encode_cell: Draco changed the cell's faces (a face was lost, added or flipped)");
    }
    const LatticeFace& in = faces[members[next[c]++]];
    page.sources[f] = in.source;
    page.materials[f] = in.material;
  }
  return Status::ok();
}

// Decodes the stream just encoded to learn Draco's face order (page.points, sources and
// materials); `decoded_blob` keeps Draco's decode for the final check of the whole page.
Status round_trip(const LatticeCell& cell, bool normals, DracoPage& page, std::unique_ptr<draco::Mesh>& decoded_blob) {
  auto draco_mesh = run_draco_decoder(page.blob);
  if (!draco_mesh) {
    return Status::invalid_argument(
        fmt::format("encode_cell: Draco round trip failed ({})", draco_mesh.status().message()));
  }
  page.points = (*draco_mesh)->num_points();
  const LatticeIndex extent = {INT32_MAX, INT32_MAX, INT32_MAX};
  auto decoded = read_draco_mesh(**draco_mesh, cell.faces.size(), page.points, normals, extent);
  if (!decoded) {
    return Status::invalid_argument(fmt::format("encode_cell: Draco round trip failed ({})", decoded.status().message()));
  }
  if (Status s = pair_faces(cell, *decoded, page); !s) return s;
  decoded_blob = std::move(draco_mesh).value();
  return Status::ok();
}

void write_payload(const DracoPage& page, const Scene& others, std::vector<uint8_t>& out) {
  GeometryWriter w(out);
  w.u8(kDracoMagic);
  w.u8(page.normals ? kDracoHasNormals : 0);
  write_lattice_base(w, page.bits, page.base);
  w.varint(page.faces);
  w.varint(page.points);
  w.varint(page.blob.size());
  w.bytes(page.blob);
  write_triangle_ids(w, page.sources, page.materials);
  write_raw_body(w, others);
}

// --- decoding --------------------------------------------------------------------------------

// Reads the fields up to and including the Draco stream and checks them against the lattice
// and the bytes left. `extent`: the largest offset from the base each axis allows.
Status read_header(GeometryReader& r, const Lattice& lattice, DracoPage& page, LatticeIndex& extent) {
  if (r.u8() != kDracoMagic || !r.ok()) return corrupt(kCodec, 0, "bad magic or version");
  const uint8_t flags = r.u8();
  if ((flags & ~kDracoHasNormals) != 0 && r.ok()) return corrupt(kCodec, 1, "unknown flags");
  if (Status s = read_lattice_base(r, kCodec, lattice, page.base, extent); !s) return s;
  page.bits = lattice.bits;
  page.faces = r.varint();
  page.points = r.varint();
  const uint64_t blob_size = r.varint();
  if (!r.ok()) return corrupt(kCodec, r.offset(), "truncated header");
  page.normals = (flags & kDracoHasNormals) != 0;
  // A valid Draco stream holds at most 16 faces per byte (check_draco_stream).
  if (blob_size > r.remaining() || page.faces > 16 * blob_size + 1 || page.points > 3 * page.faces ||
      (page.faces == 0) != (blob_size == 0) || (page.normals && page.faces == 0)) {
    return corrupt(kCodec, r.offset(), "face, point or stream size does not fit the payload");
  }
  page.blob = r.bytes(blob_size);
  return Status::ok();
}

// The page's Draco mesh, checked; `decoded_blob` is Draco's decode of page.blob when the
// encoder already has it, else null.
Status read_mesh(const DracoPage& page, const LatticeIndex& extent, const draco::Mesh* decoded_blob, DracoMesh& mesh) {
  if (Status s = check_draco_stream(page.blob, page.faces, page.normals); !s) return s;
  std::unique_ptr<draco::Mesh> own;
  if (decoded_blob == nullptr) {
    auto draco_mesh = run_draco_decoder(page.blob);
    if (!draco_mesh) return draco_mesh.status();
    own = std::move(draco_mesh).value();
    decoded_blob = own.get();
  }
  auto decoded = read_draco_mesh(*decoded_blob, page.faces, page.points, page.normals, extent);
  if (!decoded) return decoded.status();
  mesh = std::move(decoded).value();
  return Status::ok();
}

// Appends the page's triangles to `out`, dequantized once per point, in double, through
// Lattice::point.
void add_triangles(const DracoPage& page, const DracoMesh& mesh, const Lattice& lattice, Scene& out) {
  std::vector<Vec3> positions(page.points);
  for (size_t p = 0; p < page.points; ++p) {
    const LatticeIndex& q = mesh.offsets[p];
    positions[p] = lattice.point({page.base[0] + q[0], page.base[1] + q[1], page.base[2] + q[2]});
  }
  out.triangles.reserve(page.faces);
  out.prims.reserve(page.faces);
  if (page.normals) out.triangle_normals.reserve(page.faces);
  for (uint32_t f = 0; f < page.faces; ++f) {
    const auto& p = mesh.faces[f];
    out.prims.push_back({PrimKind::Triangle, f, page.sources[f], page.materials[f]});
    out.triangles.push_back({positions[p[0]], positions[p[1]], positions[p[2]]});
    if (page.normals) out.triangle_normals.push_back({mesh.normals[p[0]], mesh.normals[p[1]], mesh.normals[p[2]]});
  }
}

// `decoded_blob`, when given, is what run_draco_decoder made of this payload's Draco stream (the
// encoder has just decoded it once already): the rest of the payload is read as always.
Status decode_payload(std::span<const uint8_t> payload, const Lattice& lattice, Scene& out,
                      const draco::Mesh* decoded_blob) {
  GeometryReader r(payload);
  DracoPage page;
  LatticeIndex extent{};
  if (Status s = read_header(r, lattice, page, extent); !s) return s;
  DracoMesh mesh;
  if (page.faces > 0) {
    if (Status s = read_mesh(page, extent, decoded_blob, mesh); !s) return s;
  }
  if (Status s = read_triangle_ids(r, kCodec, page.faces, page.sources, page.materials); !s) return s;
  out = Scene{};
  add_triangles(page, mesh, lattice, out);
  if (Status s = read_raw_body(r, kCodec, false, out); !s) return s;
  if (r.remaining() != 0) return corrupt(kCodec, r.offset(), "trailing bytes");
  return Status::ok();
}

// --- the codec -------------------------------------------------------------------------------

Result<EncodedCell> encode_draco(const Scene& cell, const CellCodecOptions& options) {
  const bool normals = !cell.triangle_normals.empty();
  if (Status s = check_options(options, normals); !s) return s;
  LatticeCell split(cell.triangles.size());
  if (Status s = split_lattice_cell(cell, options.lattice, split); !s) return s;
  if (Status s = check_span(split); !s) return s;

  DracoPage page;
  page.normals = normals && !split.faces.empty();
  page.bits = options.lattice.bits;
  page.base = split.base;
  page.faces = split.faces.size();
  std::vector<uint8_t> blob;
  std::unique_ptr<draco::Mesh> decoded_blob;  // the round trip's decode, reused below
  if (!split.faces.empty()) {
    auto stream = encode_draco_stream(draco_input(split, cell, normals), options.draco_speed, options.normal_bits);
    if (!stream) return stream.status();
    blob = std::move(stream).value();
    page.blob = blob;
    if (Status s = round_trip(split, normals, page, decoded_blob); !s) return s;
  }

  EncodedCell encoded;
  encoded.codec = CellCodec::Draco;
  write_payload(page, split.others, encoded.payload);
  // What a reader gets, by the reader's own code (Draco's decode of the same stream is the one
  // made above: decoding is deterministic, and a second run cost about 4% of a build).
  if (Status s = decode_payload(encoded.payload, options.lattice, encoded.decoded, decoded_blob.get()); !s) {
    return Status::invalid_argument(fmt::format("encode_cell: the page does not decode ({})", s.message()));
  }
  return encoded;
}

Status decode_draco(std::span<const uint8_t> payload, const Lattice& lattice, Scene& out) {
  if (Status s = check_lattice(lattice, "decode_cell"); !s) return s;
  return decode_payload(payload, lattice, out, nullptr);
}

}  // namespace

const CellCodecImpl kDracoCodec = {CellCodec::Draco, "draco", encode_draco, decode_draco};

}  // namespace frontier::cell_page
