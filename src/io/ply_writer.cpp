// Streaming binary PLY writer: two buffered sections written at known offsets (see header).
#include "src/io/ply_writer.h"

#include "src/io/staging_path.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>

#include <fcntl.h>
#include <unistd.h>

namespace frontier {
namespace {

static_assert(std::endian::native == std::endian::little,
              "PlyWriter writes native floats/ints as little-endian");

constexpr size_t kSectionBuffer = size_t{4} << 20;

std::string errno_text() { return std::strerror(errno); }

// True when no value is NaN or Inf (exponent bits all ones). Fixed-size blocks let GCC's
// cheap -O2 vectorizer handle the loops: validation runs in the writer's serial stage.
bool all_finite(const std::vector<float>& v) {
  uint32_t bad = 0;
  size_t i = 0;
  for (; i + 16 <= v.size(); i += 16) {
    uint32_t block = 0;
    for (size_t k = 0; k < 16; ++k)
      block |= static_cast<uint32_t>((std::bit_cast<uint32_t>(v[i + k]) & 0x7f800000u) == 0x7f800000u);
    bad |= block;
  }
  for (; i < v.size(); ++i)
    bad |= static_cast<uint32_t>((std::bit_cast<uint32_t>(v[i]) & 0x7f800000u) == 0x7f800000u);
  return bad == 0;
}

uint32_t max_of(const std::vector<uint32_t>& v) {
  uint32_t m = 0;
  size_t i = 0;
  for (; i + 16 <= v.size(); i += 16) {
    uint32_t block = 0;
    for (size_t k = 0; k < 16; ++k) block = v[i + k] > block ? v[i + k] : block;
    m = block > m ? block : m;
  }
  for (; i < v.size(); ++i) m = v[i] > m ? v[i] : m;
  return m;
}

}  // namespace

std::string PlyWriter::header(const PlyVertexLayout& layout, uint64_t vertices,
                              uint64_t triangles, const std::vector<std::string>& comments) {
  std::string h = "ply\nformat binary_little_endian 1.0\n";
  for (const std::string& c : comments) h += "comment " + c + "\n";
  h += fmt::format("element vertex {}\n", vertices);
  h += "property float x\nproperty float y\nproperty float z\n";
  if (layout.normals) h += "property float nx\nproperty float ny\nproperty float nz\n";
  if (layout.colors) h += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  h += fmt::format("element face {}\n", triangles);
  h += "property list uchar uint vertex_indices\nend_header\n";
  return h;
}

Result<std::unique_ptr<PlyWriter>> PlyWriter::create(const std::string& path,
                                                     const PlyVertexLayout& layout,
                                                     uint64_t vertices, uint64_t triangles,
                                                     const std::vector<std::string>& comments) {
  if (vertices > 0xffffffffull)
    return Status::invalid_argument(fmt::format(
        "{}: {} vertices do not fit the 32-bit indices of the PLY face list", path, vertices));
  for (const std::string& c : comments)
    if (c.find('\n') != std::string::npos)
      return Status::invalid_argument("PLY comment contains a newline");

  std::unique_ptr<PlyWriter> w(new PlyWriter());
  w->layout_ = layout;
  w->path_ = path;
  w->vertices_declared_ = vertices;
  w->triangles_declared_ = triangles;

  if (path == "-") {
    w->fd_ = STDOUT_FILENO;
    w->seekable_ = false;
  } else {
    const std::string staging = staging_path(path);
    const std::string& target = staging.empty() ? path : staging;
    w->fd_ = ::open(target.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (w->fd_ < 0)
      return Status::io_error(fmt::format("cannot create '{}': {}", target, errno_text()));
    w->owns_fd_ = true;
    w->temp_path_ = staging;
    w->seekable_ = ::lseek(w->fd_, 0, SEEK_CUR) != static_cast<off_t>(-1);
  }

  const std::string head = header(layout, vertices, triangles, comments);
  w->header_bytes_ = head.size();
  for (Section* s : {&w->vertex_section_, &w->face_section_}) s->buffer.resize(kSectionBuffer);
  w->vertex_section_.offset = 0;
  std::memcpy(w->vertex_section_.buffer.data(), head.data(), head.size());
  w->vertex_section_.used = head.size();
  w->face_section_.offset = w->header_bytes_ + vertices * layout.vertex_bytes();
  return w;
}

PlyWriter::~PlyWriter() {
  if (owns_fd_ && fd_ >= 0) ::close(fd_);
  if (!finished_ && !temp_path_.empty()) ::unlink(temp_path_.c_str());
}

Status PlyWriter::write_at(Section& s) {
  const char* p = s.buffer.data();
  size_t left = s.used;
  while (left > 0) {
    const ssize_t n = seekable_ ? ::pwrite(fd_, p, left, static_cast<off_t>(s.offset))
                                : ::write(fd_, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Status::io_error(fmt::format("writing '{}': {}", path_, errno_text()));
    }
    p += n;
    left -= static_cast<size_t>(n);
    s.offset += static_cast<uint64_t>(n);
  }
  s.used = 0;
  return Status::ok();
}

Status PlyWriter::reserve(Section& s, size_t bytes) {
  if (s.used + bytes <= s.buffer.size()) return Status::ok();
  Status st = write_at(s);
  if (!st) return st;
  if (bytes > s.buffer.size()) s.buffer.resize(bytes);
  return Status::ok();
}

Status PlyWriter::check_piece(const MeshPiece& piece) const {
  const size_t nv = piece.vertex_count();
  if (piece.positions.size() % 3 != 0 || piece.indices.size() % 3 != 0)
    return Status::invalid_argument("PLY piece: array length is not a multiple of 3");
  if (layout_.normals != !piece.normals.empty() && nv > 0)
    return Status::invalid_argument("PLY piece: normals do not match the declared layout");
  if (layout_.normals && piece.normals.size() != piece.positions.size())
    return Status::invalid_argument("PLY piece: one normal per vertex required");
  if (layout_.colors != !piece.colors.empty() && nv > 0)
    return Status::invalid_argument("PLY piece: colours do not match the declared layout");
  if (layout_.colors && piece.colors.size() != piece.positions.size())
    return Status::invalid_argument("PLY piece: one colour per vertex required");
  const uint32_t max_index = max_of(piece.indices);
  if (!piece.indices.empty() && max_index >= nv)
    return Status::invalid_argument(
        fmt::format("PLY piece: index {} outside the piece's {} vertices", max_index, nv));
  if (!all_finite(piece.positions) || !all_finite(piece.normals))
    return Status::invalid_argument(
        fmt::format("PLY piece starting at vertex {}: NaN or Inf coordinate", vertices_done_));
  return Status::ok();
}

template <class Encode>
Status PlyWriter::append_records(Section& s, size_t record_bytes, size_t count, Encode&& encode) {
  size_t i = 0;
  while (i < count) {
    if (Status st = reserve(s, record_bytes); !st) return st;
    // As many whole records as the buffer holds, in one tight loop.
    const size_t room = (s.buffer.size() - s.used) / record_bytes;
    const size_t n = std::min(room, count - i);
    encode(s.buffer.data() + s.used, i, n);
    s.used += n * record_bytes;
    i += n;
  }
  return Status::ok();
}

Status PlyWriter::add(const MeshPiece& piece) {
  if (finished_) return Status::invalid_argument("PLY writer: add() after finish()");
  Status st = check_piece(piece);
  if (!st) return st;
  const size_t nv = piece.vertex_count();
  const bool write_vertices = seekable_ || !face_pass_;
  const bool write_faces = seekable_ || face_pass_;

  uint64_t base = vertices_done_;
  if (write_vertices) {
    st = add_vertices(piece);
    if (!st) return st;
  } else {
    base = face_pass_vertex_base_;
    face_pass_vertex_base_ += nv;
    if (face_pass_vertex_base_ > vertices_declared_)
      return Status::invalid_argument("PLY writer: face pass saw more vertices than declared");
  }
  if (write_faces) return add_faces(piece, base);
  return Status::ok();
}

Status PlyWriter::add_vertices(const MeshPiece& piece) {
  const size_t nv = piece.vertex_count();
  if (vertices_done_ + nv > vertices_declared_)
    return Status::invalid_argument(
        fmt::format("PLY writer: more vertices than the {} declared", vertices_declared_));
  const Status st = append_records(vertex_section_, layout_.vertex_bytes(), nv, [&](char* out, size_t i, size_t n) {
    if (!layout_.normals && !layout_.colors) {
      std::memcpy(out, &piece.positions[3 * i], 12 * n);
      return;
    }
    for (size_t k = i; k < i + n; ++k) {
      std::memcpy(out, &piece.positions[3 * k], 12);
      out += 12;
      if (layout_.normals) {
        std::memcpy(out, &piece.normals[3 * k], 12);
        out += 12;
      }
      if (layout_.colors) {
        std::memcpy(out, &piece.colors[3 * k], 3);
        out += 3;
      }
    }
  });
  if (!st) return st;
  vertices_done_ += nv;
  return Status::ok();
}

Status PlyWriter::add_faces(const MeshPiece& piece, uint64_t base) {
  const size_t nt = piece.triangle_count();
  if (triangles_done_ + nt > triangles_declared_)
    return Status::invalid_argument(
        fmt::format("PLY writer: more triangles than the {} declared", triangles_declared_));
  const uint32_t b32 = static_cast<uint32_t>(base);
  const Status st = append_records(face_section_, kPlyFaceBytes, nt, [&](char* out, size_t t, size_t n) {
    const uint32_t* idx = &piece.indices[3 * t];
    for (size_t k = 0; k < n; ++k, out += kPlyFaceBytes, idx += 3) {
      const uint32_t g[3] = {b32 + idx[0], b32 + idx[1], b32 + idx[2]};
      out[0] = 3;
      std::memcpy(out + 1, g, 12);
    }
  });
  if (!st) return st;
  triangles_done_ += nt;
  return Status::ok();
}

Status PlyWriter::begin_face_pass() {
  if (seekable_ || face_pass_)
    return Status::invalid_argument("PLY writer: begin_face_pass() needs a two-pass output");
  if (vertices_done_ != vertices_declared_)
    return Status::invalid_argument(fmt::format(
        "PLY writer: {} vertices written, {} declared", vertices_done_, vertices_declared_));
  Status st = write_at(vertex_section_);
  if (!st) return st;
  face_pass_ = true;
  return Status::ok();
}

Status PlyWriter::finish() {
  if (finished_) return Status::ok();
  if (vertices_done_ != vertices_declared_ || triangles_done_ != triangles_declared_)
    return Status::invalid_argument(
        fmt::format("PLY writer: wrote {} vertices and {} triangles, declared {} and {}",
                    vertices_done_, triangles_done_, vertices_declared_, triangles_declared_));
  Status st = write_at(vertex_section_);
  if (st) st = write_at(face_section_);
  if (!st) return st;
  if (owns_fd_) {
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0)
      return Status::io_error(fmt::format("closing '{}': {}", path_, errno_text()));
  }
  if (!temp_path_.empty() && ::rename(temp_path_.c_str(), path_.c_str()) != 0)
    return Status::io_error(
        fmt::format("renaming '{}' to '{}': {}", temp_path_, path_, errno_text()));
  finished_ = true;
  return Status::ok();
}

}  // namespace frontier
