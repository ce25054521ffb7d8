// The raw cell codec (tag 0; store/FORMAT.md "Raw payload"): one magic/version byte, then a raw
// body of every primitive, bit for bit, on or off a lattice. It ignores the lattice.
#include "src/codec/cell_codec_impl.h"
#include "src/codec/raw_body.h"

#include <string_view>

namespace frontier::cell_page {
namespace {

constexpr uint8_t kRawMagic = 0xA1;  // raw codec, layout version 1
constexpr std::string_view kCodec = "raw";

Status decode_raw(std::span<const uint8_t> payload, const Lattice& /*lattice*/, Scene& out) {
  GeometryReader r(payload);
  if (r.u8() != kRawMagic || !r.ok()) return corrupt(kCodec, 0, "bad magic or version");
  out = Scene{};
  if (Status s = read_raw_body(r, kCodec, true, out); !s) return s;
  if (r.remaining() != 0) return corrupt(kCodec, r.offset(), "trailing bytes");
  return Status::ok();
}

Result<EncodedCell> encode_raw(const Scene& cell, const CellCodecOptions& /*options*/) {
  EncodedCell encoded;
  encoded.codec = CellCodec::Raw;
  GeometryWriter w(encoded.payload);
  w.u8(kRawMagic);
  write_raw_body(w, cell);
  if (Status s = decode_raw(encoded.payload, Lattice{}, encoded.decoded); !s) {
    return Status::invalid_argument(fmt::format("encode_cell: the page does not decode ({})", s.message()));
  }
  return encoded;
}

}  // namespace

const CellCodecImpl kRawCodec = {CellCodec::Raw, kCodec, encode_raw, decode_raw};

}  // namespace frontier::cell_page
