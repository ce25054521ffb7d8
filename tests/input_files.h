// Model files for the tests/test_input_*.cpp tests: one small triangle mesh written as ASCII
// and binary PLY, OFF and ASCII and binary STL, byte for byte the way exporters write them, so
// that every format holds the same triangles in the same order. Coordinates are multiples of
// 1/8 (exact as float32 and in text), so every format reads back the same doubles.
#pragma once

#include "src/core/geometry.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

namespace frontier::testing {

struct TriangleMesh {
  std::vector<Vec3> vertices;
  std::vector<std::array<uint32_t, 3>> triangles;
};

// An n x n grid of vertices (two triangles per square) over a gently bent surface.
inline TriangleMesh grid_mesh(int n) {
  TriangleMesh m;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) m.vertices.emplace_back(x * 0.125, y * 0.125, ((x * y) % 3) * 0.125);
  }
  for (int y = 0; y + 1 < n; ++y) {
    for (int x = 0; x + 1 < n; ++x) {
      const auto a = static_cast<uint32_t>(y * n + x), b = a + 1, c = a + static_cast<uint32_t>(n), d = c + 1;
      m.triangles.push_back({a, b, d});
      m.triangles.push_back({a, d, c});
    }
  }
  return m;
}

template <typename T>
void append_le(std::string& out, T v) {
  char bytes[sizeof(T)];
  std::memcpy(bytes, &v, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes, bytes + sizeof(T));
  out.append(bytes, sizeof(T));
}

inline std::string ply_header(const TriangleMesh& m, std::string_view format, std::string_view extra_header) {
  return fmt::format("ply\nformat {} 1.0\n{}element vertex {}\nproperty float x\nproperty float y\n"
                     "property float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
                     format, extra_header, m.vertices.size(), m.triangles.size());
}

// One record a line; `extra_header` goes right after the format line.
inline std::string ply_ascii(const TriangleMesh& m, std::string_view extra_header = "") {
  std::string out = ply_header(m, "ascii", extra_header);
  for (const Vec3& v : m.vertices) out += fmt::format("{} {} {}\n", v.x, v.y, v.z);
  for (const auto& t : m.triangles) out += fmt::format("3 {} {} {}\n", t[0], t[1], t[2]);
  return out;
}

inline std::string ply_binary(const TriangleMesh& m, std::string_view extra_header = "") {
  std::string out = ply_header(m, "binary_little_endian", extra_header);
  for (const Vec3& v : m.vertices) {
    for (int k = 0; k < 3; ++k) append_le(out, static_cast<float>(v[k]));
  }
  for (const auto& t : m.triangles) {
    out += '\3';
    for (uint32_t i : t) append_le(out, static_cast<int32_t>(i));
  }
  return out;
}

// The byte offset where face record `face` starts in ply_binary(m).
inline uint64_t ply_binary_face_offset(const TriangleMesh& m, size_t face) {
  return ply_header(m, "binary_little_endian", "").size() + 12 * m.vertices.size() + 13 * face;
}

inline std::string off_text(const TriangleMesh& m) {
  std::string out = fmt::format("OFF\n{} {} 0\n", m.vertices.size(), m.triangles.size());
  for (const Vec3& v : m.vertices) out += fmt::format("{} {} {}\n", v.x, v.y, v.z);
  for (const auto& t : m.triangles) out += fmt::format("3 {} {} {}\n", t[0], t[1], t[2]);
  return out;
}

inline std::string stl_ascii(const TriangleMesh& m) {
  std::string out = "solid grid\n";
  for (const auto& t : m.triangles) {
    out += "  facet normal 0 0 1\n    outer loop\n";
    for (uint32_t i : t) out += fmt::format("      vertex {} {} {}\n", m.vertices[i].x, m.vertices[i].y, m.vertices[i].z);
    out += "    endloop\n  endfacet\n";
  }
  return out + "endsolid grid\n";
}

// `header` fills the 80-byte header (padded with spaces): exporters may start it with "solid".
inline std::string stl_binary(const TriangleMesh& m, std::string_view header = "binary STL written by the tests") {
  std::string out(header.substr(0, 80));
  out.resize(80, ' ');
  append_le(out, static_cast<uint32_t>(m.triangles.size()));
  for (const auto& t : m.triangles) {
    for (float n : {0.0f, 0.0f, 1.0f}) append_le(out, n);
    for (uint32_t i : t) {
      for (int k = 0; k < 3; ++k) append_le(out, static_cast<float>(m.vertices[i][k]));
    }
    append_le(out, uint16_t{0});
  }
  return out;
}

inline std::string write_file(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return path.string();
}

}  // namespace frontier::testing
