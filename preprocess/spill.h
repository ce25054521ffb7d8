// Spill files: the out-of-core builder's temporary lists of primitives. One record per primitive,
// written and read strictly sequentially through a large buffer:
//
//   u8 kind | u8 has_normals | u16 0 | u32 source | u32 material | geometry (f64, per kind)
//
// geometry: triangle 9 (+9 normals), sphere 4, box 6, cone 8, quadric 10 + 48 + 6 + 1 (clip
// count). Host byte order: a spill file never leaves the build that wrote it.
#pragma once

#include "src/core/scene.h"
#include "src/core/status.h"

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace frontier {

class SpillWriter {
 public:
  explicit SpillWriter(size_t buffer_bytes = size_t{4} << 20) : buffer_bytes_(buffer_bytes) {}
  ~SpillWriter();
  SpillWriter(const SpillWriter&) = delete;
  SpillWriter& operator=(const SpillWriter&) = delete;

  Status open(const std::string& path);
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
};

class SpillReader {
 public:
  SpillReader() = default;
  ~SpillReader();
  SpillReader(const SpillReader&) = delete;
  SpillReader& operator=(const SpillReader&) = delete;

  Status open(const std::string& path);
  // Appends up to `max` records to `batch` (through Scene's adders); `end` when the file is
  // exhausted. Corruption for a torn record (a spill file cut short by a full disk).
  Status read(Scene& batch, size_t max, bool& end);

 private:
  Status fill();

  std::string path_;
  std::FILE* file_ = nullptr;
  std::vector<uint8_t> buffer_;
  size_t begin_ = 0, end_ = 0;
  bool eof_ = false;
};

}  // namespace frontier
