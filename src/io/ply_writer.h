// Streaming writer of binary little-endian PLY triangle meshes too large to hold in memory.
//
// Layout written: `element vertex V` with float x y z, then optionally float nx ny nz and
// uchar red green blue; `element face F` with `property list uchar uint vertex_indices`
// (always 3 indices). The caller declares V and F exactly before the first byte (frontier-gen
// obtains them from a cheap counting pass over its deterministic generator), so the header is
// final from the start and is never patched.
//
// Pieces arrive in order. A piece's indices are local to the piece (0-based); the writer
// rebases them onto the number of vertices written before it, so vertex sharing (dedup) only
// ever happens inside a piece. Memory is two fixed output buffers, whatever the model size.
//
// Seekable outputs (regular files, /dev/null) take one pass: vertices go to the vertex section
// and faces straight to their own section at header + V * vertex_bytes, each through its own
// buffer with positional writes. A non-seekable output (a pipe; "-" means stdout) takes the
// pieces twice, in the same order: first for vertices, then, after begin_face_pass(), for faces.
//
// A regular file is written as PATH.tmp and renamed to PATH by finish(); a writer destroyed
// before finish() removes PATH.tmp, so a failed run never leaves a truncated model under the
// real name. Not thread-safe: one thread calls add().
#pragma once

#include "src/core/status.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace frontier {

struct PlyVertexLayout {
  bool normals = false;  // float nx ny nz
  bool colors = false;   // uchar red green blue
  size_t vertex_bytes() const { return 12 + (normals ? 12 : 0) + (colors ? 3 : 0); }
};

inline constexpr size_t kPlyFaceBytes = 13;  // uchar 3 + 3 x uint32

// A piece of mesh with piece-local indices. `normals` and `colors` are either empty or hold
// 3 entries per vertex, matching the writer's layout.
struct MeshPiece {
  std::vector<float> positions;   // x y z per vertex
  std::vector<float> normals;     // nx ny nz per vertex (layout.normals)
  std::vector<uint8_t> colors;    // r g b per vertex (layout.colors)
  std::vector<uint32_t> indices;  // 3 per triangle, counter-clockwise seen from outside

  size_t vertex_count() const { return positions.size() / 3; }
  size_t triangle_count() const { return indices.size() / 3; }
  void clear() {
    positions.clear();
    normals.clear();
    colors.clear();
    indices.clear();
  }
};

class PlyWriter {
 public:
  // Creates the output and writes the header declaring exactly `vertices` and `triangles`.
  // `comments` become `comment` lines (no newlines allowed). Fails with IoError when the file
  // cannot be created and InvalidArgument when `vertices` does not fit 32-bit indices.
  static Result<std::unique_ptr<PlyWriter>> create(const std::string& path,
                                                   const PlyVertexLayout& layout,
                                                   uint64_t vertices, uint64_t triangles,
                                                   const std::vector<std::string>& comments = {});
  ~PlyWriter();
  PlyWriter(const PlyWriter&) = delete;
  PlyWriter& operator=(const PlyWriter&) = delete;

  // True when the output cannot seek: feed the pieces once for vertices, call
  // begin_face_pass(), and feed the same pieces again for faces.
  bool needs_two_passes() const { return !seekable_; }
  // REQUIRES needs_two_passes() and every declared vertex written.
  Status begin_face_pass();

  // Appends a piece. Returns InvalidArgument (and writes nothing) for a malformed piece:
  // arrays of the wrong size, an index outside the piece, a NaN/Inf coordinate, or more
  // vertices/triangles than declared. Returns IoError when the disk write fails.
  Status add(const MeshPiece& piece);

  // Flushes, checks that exactly the declared counts were written, closes and renames.
  Status finish();

  // The header text for these counts (used by tests and by create()).
  static std::string header(const PlyVertexLayout& layout, uint64_t vertices, uint64_t triangles,
                            const std::vector<std::string>& comments);

 private:
  struct Section {
    std::vector<char> buffer;
    size_t used = 0;
    uint64_t offset = 0;  // file offset of buffer[0] (seekable outputs)
  };
  PlyWriter() = default;
  Status write_at(Section& s);
  Status reserve(Section& s, size_t bytes);
  // Appends `count` records of `record_bytes` to `s` in runs of as many as its buffer holds:
  // encode(out, first, n) writes records first .. first + n - 1 at `out`.
  template <class Encode>
  Status append_records(Section& s, size_t record_bytes, size_t count, Encode&& encode);
  // add()'s two halves: the piece's vertices, and its triangles with indices rebased by `base`.
  Status add_vertices(const MeshPiece& piece);
  Status add_faces(const MeshPiece& piece, uint64_t base);
  Status check_piece(const MeshPiece& piece) const;

  PlyVertexLayout layout_;
  std::string path_;       // the name the user asked for
  std::string temp_path_;  // PATH.tmp for regular files, else empty
  int fd_ = -1;
  bool owns_fd_ = false;
  bool seekable_ = true;
  bool face_pass_ = false;  // two-pass mode: now writing faces
  bool finished_ = false;
  uint64_t header_bytes_ = 0;
  uint64_t vertices_declared_ = 0, triangles_declared_ = 0;
  uint64_t vertices_done_ = 0, triangles_done_ = 0;
  uint64_t face_pass_vertex_base_ = 0;  // two-pass mode: vertices seen again in the face pass
  Section vertex_section_, face_section_;
};

}  // namespace frontier
