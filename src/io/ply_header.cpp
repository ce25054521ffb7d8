// read_ply_header: the PLY header, line by line (see ply_header.h).
#include "src/io/ply_header.h"

#include <fmt/format.h>

#include <array>

namespace frontier {

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

int64_t PlyElement::fixed_size() const {
  int64_t n = 0;
  for (const PlyProperty& p : props) {
    if (p.is_list) return -1;
    n += static_cast<int64_t>(ply_type_size(p.type));
  }
  return n;
}

int64_t PlyElement::min_size() const {
  int64_t n = 0;
  for (const PlyProperty& p : props) n += static_cast<int64_t>(ply_type_size(p.is_list ? p.count_type : p.type));
  return n;
}

int PlyElement::find(std::string_view name) const {
  for (size_t k = 0; k < props.size(); ++k) {
    if (props[k].name == name) return static_cast<int>(k);
  }
  return -1;
}

namespace {

// The rest of a `format` line: ascii or a binary byte order, version 1.0.
Status parse_format(TextTokenizer& tok, PlyHeader& header) {
  std::string_view f, version;
  if (!tok.next_on_line(f) || !tok.next_on_line(version)) return tok.error("format line needs a type and a version");
  if (f == "ascii") {
    header.ascii = true;
  } else if (f == "binary_little_endian" || f == "binary_big_endian") {
    header.ascii = false;
    const bool file_big = f == "binary_big_endian";
    header.swap = file_big != (std::endian::native == std::endian::big);
  } else {
    return tok.error(fmt::format("unknown format {}", quote_token(f)));
  }
  if (version != "1.0" && version != "1") return tok.error(fmt::format("unsupported PLY version {}", quote_token(version)));
  return Status::ok();
}

// The rest of an `element` line: a name and a count.
Status parse_element(TextTokenizer& tok, PlyHeader& header) {
  PlyElement e;
  std::string_view name;
  if (!tok.next_on_line(name)) return tok.error("element needs a name and a count");
  e.name = std::string(name);
  e.line = tok.line();
  if (Status s = tok.next_int_on_line(e.count, "element count"); !s) return s;
  if (e.count < 0) return tok.error(fmt::format("element {} has a negative count {}", e.name, e.count));
  header.elements.push_back(std::move(e));
  return Status::ok();
}

// The rest of a `property` line: "TYPE NAME" or "list COUNT_TYPE ITEM_TYPE NAME".
Status parse_property(TextTokenizer& tok, PlyHeader& header) {
  if (header.elements.empty()) return tok.error("property before any element");
  PlyProperty p;
  std::string_view type, name;
  if (!tok.next_on_line(type)) return tok.error("property needs a type and a name");
  if (type == "list") {
    std::string_view count_type;
    if (!tok.next_on_line(count_type) || !tok.next_on_line(type)) return tok.error("list property needs two types and a name");
    if (!parse_ply_type(count_type, p.count_type)) return tok.error(fmt::format("unknown type {}", quote_token(count_type)));
    if (!ply_is_integer(p.count_type)) return tok.error("list count type must be an integer type");
    p.is_list = true;
  }
  if (!parse_ply_type(type, p.type)) return tok.error(fmt::format("unknown type {}", quote_token(type)));
  if (!tok.next_on_line(name)) return tok.error("property needs a name");
  p.name = std::string(name);
  header.elements.back().props.push_back(std::move(p));
  return Status::ok();
}

}  // namespace

Status read_ply_header(TextTokenizer& tok, PlyHeader& header) {
  std::string_view t;
  if (!tok.next(t) || t != "ply") {
    if (!tok.status().is_ok()) return tok.status();
    return tok.error("not a PLY file (no 'ply' magic)");
  }
  tok.skip_line();
  bool have_format = false;
  for (;;) {
    if (!tok.next(t)) return tok.end_error("end_header");
    if (t == "end_header") {
      tok.skip_line();
      break;
    }
    Status s;
    if (t == "format") {
      s = parse_format(tok, header);
      have_format = true;
    } else if (t == "element") {
      s = parse_element(tok, header);
    } else if (t == "property") {
      s = parse_property(tok, header);
    } else {
      // comment and obj_info by the standard; anything else by exporters that do not follow it.
      if (t != "comment" && t != "obj_info") {
        header.warnings.push_back(fmt::format("{}: line {}: skipped a header line with the unknown keyword {}",
                                              tok.path(), tok.line(), quote_token(t)));
      }
      tok.skip_line();
      continue;
    }
    if (!s) return s;
    if (!tok.at_line_end()) {
      std::string_view extra;
      tok.next_on_line(extra);
      return tok.error(fmt::format("unexpected {} at the end of a header line", quote_token(extra)));
    }
    tok.skip_line();
  }
  if (!tok.status().is_ok()) return tok.status();
  if (!have_format) return tok.error("header has no format line");
  header.body_offset = tok.offset();
  return Status::ok();
}

}  // namespace frontier
