// The Draco stream of a Draco cell page (contracts: draco_stream.h).
#include "src/codec/draco_stream.h"

#include "store/byte_stream.h"

#include <draco/compression/config/compression_shared.h>
#include <draco/compression/decode.h>
#include <draco/compression/expert_encode.h>
#include <draco/core/decoder_buffer.h>
#include <draco/core/encoder_buffer.h>
#include <fmt/format.h>

#include <cstring>
#include <exception>
#include <utility>

namespace frontier::cell_page {
namespace {

using store::ByteReader;

// Fills `mesh` with the input's points, attributes and faces; returns the normal attribute's id
// (-1 without normals).
int build_draco_mesh(const DracoInput& in, draco::Mesh& mesh) {
  const size_t num_points = in.normals ? in.point_vertex.size() : in.positions.size();
  mesh.set_num_points(static_cast<uint32_t>(num_points));
  // Positions are integers: Draco predicts and entropy-codes them losslessly (its float
  // quantization would dequantize in float32 and lose far-from-origin coordinates).
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_INT32, false, 3 * sizeof(int32_t), 0);
  const int position_id = mesh.AddAttribute(position, !in.normals, static_cast<uint32_t>(in.positions.size()));
  draco::PointAttribute* position_att = mesh.attribute(position_id);
  for (uint32_t v = 0; v < in.positions.size(); ++v) {
    position_att->SetAttributeValue(draco::AttributeValueIndex(v), in.positions[v].data());
  }
  int normal_id = -1;
  if (in.normals) {
    draco::GeometryAttribute normal;
    normal.Init(draco::GeometryAttribute::NORMAL, nullptr, 3, draco::DT_FLOAT32, false, 3 * sizeof(float), 0);
    normal_id = mesh.AddAttribute(normal, true, static_cast<uint32_t>(num_points));
    for (uint32_t p = 0; p < num_points; ++p) {
      position_att->SetPointMapEntry(draco::PointIndex(p), draco::AttributeValueIndex(in.point_vertex[p]));
      mesh.attribute(normal_id)->SetAttributeValue(draco::AttributeValueIndex(p), in.point_normals[p].data());
    }
  }
  for (const auto& ids : in.faces) {
    mesh.AddFace({draco::PointIndex(ids[0]), draco::PointIndex(ids[1]), draco::PointIndex(ids[2])});
  }
  return normal_id;
}

// The Draco stream's header, checked before Draco reads it. Draco sizes its connectivity
// tables from the face and vertex counts at the start of the stream before it knows whether the
// rest exists, so a damaged count would make it allocate gigabytes. The layout (Draco bitstream 2.2, edgebreaker, no metadata) is:
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

}  // namespace

Result<std::vector<uint8_t>> encode_draco_stream(const DracoInput& input, int speed, int normal_bits) {
  draco::Mesh mesh;
  const int normal_id = build_draco_mesh(input, mesh);
  draco::ExpertEncoder encoder(mesh);
  encoder.SetSpeedOptions(speed, speed);
  encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
  // The standard traversal, never the valence one Draco picks below speed 5 for meshes of
  // 1000+ faces: its size bound is what lets the decoder refuse absurd face counts
  // (check_draco_stream). ExpertEncoder::SetEncodingSubmethod does not reach the
  // edgebreaker (it reads "edgebreaker_method"), hence the raw option.
  encoder.options().SetGlobalInt("edgebreaker_method", draco::MESH_EDGEBREAKER_STANDARD_ENCODING);
  if (input.normals) encoder.SetAttributeQuantization(normal_id, normal_bits);
  draco::EncoderBuffer buffer;
  try {
    const draco::Status s = encoder.EncodeToBuffer(&buffer);
    if (!s.ok()) return Status::invalid_argument(fmt::format("encode_cell: Draco: {}", s.error_msg_string()));
  } catch (const std::exception& e) {
    return Status::invalid_argument(fmt::format("encode_cell: Draco failed: {}", e.what()));
  }
  const auto* data = reinterpret_cast<const uint8_t*>(buffer.data());
  return std::vector<uint8_t>(data, data + buffer.size());
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

}  // namespace frontier::cell_page
