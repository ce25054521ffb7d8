// Spill files: the out-of-core builder's temporary lists of primitives, written and read
// strictly sequentially through a large buffer. Byte layout in preprocess/README.md "Spill
// files"; in short, one variable-length record per primitive:
//
//   tag u8 | [source delta] | [material] | triangle: refs u16, each new vertex's position
//   (lattice index deltas as varints, or 3 f32, or 3 f64) [and normal] | other kinds: f64s
//
// A triangle's vertices are looked up in a cache of the last 31 distinct vertices written: a
// hit costs 5 bits. A position goes on the store's lattice (delta to the previous new vertex's
// index) when the file has the lattice and the position is exactly a lattice point, as every
// snapped triangle is; else as floats when that is exact, else as doubles. Reading gives back
// every primitive bit for bit: the format is lossless, only smaller (a 5 M-triangle terrain:
// 84 bytes a triangle before, about 6 after). Host byte order: a spill file never leaves the
// build that wrote it.
#pragma once

#include "src/codec/lattice.h"
#include "src/core/scene.h"
#include "src/core/status.h"

#include <array>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

namespace frontier {

// The last vertices written (or read) in one spill file, first in first out: writer and reader
// keep identical copies. Internal to the spill codec.
class SpillVertexCache {
 public:
  static constexpr int kSlots = 31;  // slot 31 in a record's refs means "a new vertex"
  // The slot holding p (and n, when the file has normals), or kSlots.
  int find(const Vec3& p, const Vec3* n) const;
  void push(const Vec3& p, const Vec3* n);
  const Vec3& position(int slot) const { return position_[static_cast<size_t>(slot)]; }
  const Vec3& normal(int slot) const { return normal_[static_cast<size_t>(slot)]; }

 private:
  std::array<uint64_t, kSlots> key_{};
  std::array<Vec3, kSlots> position_{};
  std::array<Vec3, kSlots> normal_{};
  int size_ = 0, next_ = 0;
};

// What the records of one file are coded against; identical for its writer and its reader.
struct SpillCodecState {
  explicit SpillCodecState(std::optional<Lattice> lattice) : lattice(lattice) {}
  std::optional<Lattice> lattice;  // positions on it are stored as indices
  SpillVertexCache cache;
  LatticeIndex last_index{};       // of the last new vertex stored on the lattice
  uint32_t source = UINT32_MAX;    // the previous record's: a first source 0 is "the previous + 1"
  uint32_t material = 0;
};

class SpillWriter {
 public:
  explicit SpillWriter(size_t buffer_bytes = size_t{4} << 20) : buffer_bytes_(buffer_bytes) {}
  ~SpillWriter();
  SpillWriter(const SpillWriter&) = delete;
  SpillWriter& operator=(const SpillWriter&) = delete;

  // `lattice`: the store's lattice, when triangles are already snapped to it (or mostly are:
  // a vertex that is not exactly a lattice point is stored exactly anyway).
  Status open(const std::string& path, std::optional<Lattice> lattice = std::nullopt);
  // Appends primitive i of `scene`.
  Status write(const Scene& scene, uint32_t i);
  Status close();

  const std::string& path() const { return path_; }
  uint64_t records() const { return records_; }
  uint64_t bytes() const { return bytes_; }

 private:
  Status flush();

  std::string path_;
  std::FILE* file_ = nullptr;
  size_t buffer_bytes_;
  std::vector<uint8_t> buffer_;  // buffer_bytes_ plus room for the largest record
  size_t used_ = 0;
  uint64_t records_ = 0;
  uint64_t bytes_ = 0;
  SpillCodecState state_{std::nullopt};
};

class SpillReader {
 public:
  SpillReader() = default;
  ~SpillReader();
  SpillReader(const SpillReader&) = delete;
  SpillReader& operator=(const SpillReader&) = delete;

  // `lattice`: the one the file was written with.
  Status open(const std::string& path, std::optional<Lattice> lattice = std::nullopt);
  // Appends up to `max` records to `batch` (through Scene's adders); `end` when the file is
  // exhausted. Corruption naming the file and byte offset for a torn or bad record (a spill
  // file cut short by a full disk).
  Status read(Scene& batch, size_t max, bool& end);

 private:
  Status fill();

  std::string path_;
  std::FILE* file_ = nullptr;
  std::vector<uint8_t> buffer_;
  size_t begin_ = 0, end_ = 0;
  uint64_t offset_ = 0;  // of buffer_[begin_] in the file
  bool eof_ = false;
  SpillCodecState state_{std::nullopt};
};

// Bytes a spill file takes per primitive at most for triangles on the lattice in practice
// (meshes share vertices; see preprocess/README.md), and for anything stored exactly: what the
// build's up-front disk check assumes.
inline constexpr uint64_t kSpillBytesPerLatticeTriangle = 16;
inline constexpr uint64_t kSpillBytesPerExactPrimitive = 48;

}  // namespace frontier
