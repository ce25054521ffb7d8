// Cell page codecs: the checks every codec shares and the dispatch on the codec tag (contracts:
// cell_codec.h; one file per codec behind the interface of cell_codec_impl.h).
#include "src/codec/cell_codec.h"

#include "src/codec/cell_codec_impl.h"

#include <fmt/format.h>

#include <array>

namespace frontier {
namespace {

using cell_page::CellCodecImpl;

// Every codec this build knows. Adding one: its CellCodecImpl here.
constexpr std::array<const CellCodecImpl*, 3> kCodecs = {&cell_page::kRawCodec, &cell_page::kDracoCodec,
                                                          &cell_page::kMeshoptCodec};

const CellCodecImpl* find_codec(uint8_t tag) {
  for (const CellCodecImpl* codec : kCodecs) {
    if (static_cast<uint8_t>(codec->tag) == tag) return codec;
  }
  return nullptr;
}

// What every codec requires of its input: primitives that refer to existing elements,
// per-vertex normals for all triangles or none, clip counts in range.
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

}  // namespace

bool is_cell_codec(uint8_t tag) { return find_codec(tag) != nullptr; }

std::string_view cell_codec_name(CellCodec codec) {
  const CellCodecImpl* impl = find_codec(static_cast<uint8_t>(codec));
  return impl != nullptr ? impl->name : std::string_view();
}

std::optional<CellCodec> cell_codec_named(std::string_view name) {
  for (const CellCodecImpl* codec : kCodecs) {
    if (codec->name == name) return codec->tag;
  }
  return std::nullopt;
}

bool cell_codec_on_lattice(CellCodec codec) { return codec == CellCodec::Draco || codec == CellCodec::Meshopt; }

Result<EncodedCell> encode_cell(const Scene& cell, const CellCodecOptions& options) {
  if (Status s = check_scene(cell); !s) return s;
  const CellCodecImpl* codec = find_codec(static_cast<uint8_t>(options.codec));
  if (codec == nullptr) {
    return Status::invalid_argument(
        fmt::format("encode_cell: unknown codec {}", static_cast<unsigned>(options.codec)));
  }
  return codec->encode(cell, options);
}

Status decode_cell(std::span<const uint8_t> payload, CellCodec codec, const Lattice& lattice, Scene& out) {
  const CellCodecImpl* impl = find_codec(static_cast<uint8_t>(codec));
  out = Scene{};
  Status s = impl != nullptr ? impl->decode(payload, lattice, out)
                             : Status::corruption(fmt::format("cell page: unknown codec {}", static_cast<unsigned>(codec)));
  if (!s) out = Scene{};
  return s;
}

}  // namespace frontier
