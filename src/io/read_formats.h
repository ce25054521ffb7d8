// Private to the scene readers: the per-format factories behind open_scene_reader() and the
// limits and message helpers they share. Not for use outside the reader files.
#pragma once

#include "src/io/scene_reader.h"
#include "src/io/text_tokenizer.h"

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

namespace frontier {

// The most vertices one polygon (NFF p/pp, PLY/OBJ/OFF face) may have. Larger counts are
// rejected as corrupt: they would cost O(n²) to triangulate and a garbled count must never
// turn into a huge allocation.
inline constexpr int64_t kMaxPolygonVertices = int64_t{1} << 16;

// Base of the format readers: owns the header, keeps the first error and returns it from
// every later next() call (the SceneReader contract), so a reader only writes read_next().
class FormatReader : public SceneReader {
 public:
  Status next(InputPrimitive& out, bool& end) final {
    end = false;
    if (!status_.is_ok()) return status_;
    status_ = read_next(out, end);
    return status_;
  }
  const SceneHeader& header() const final { return header_; }
  const std::vector<std::string>& warnings() const final { return warnings_; }

 protected:
  virtual Status read_next(InputPrimitive& out, bool& end) = 0;
  void warn(std::string message) { warnings_.push_back(std::move(message)); }
  // Call once, after the last record of a text file: warns when anything but blanks (and
  // comments, where the format has them) is left.
  void warn_trailing_text(TextTokenizer& tok);
  SceneHeader header_;

 private:
  Status status_;
  std::vector<std::string> warnings_;
};

// Constructs a reader and opens `path` with its `Status open(const std::string&)`.
template <class Reader>
Result<std::unique_ptr<SceneReader>> open_format_reader(const std::string& path) {
  auto reader = std::make_unique<Reader>();
  if (Status s = reader->open(path); !s) return s;
  return std::unique_ptr<SceneReader>(std::move(reader));
}

Result<std::unique_ptr<SceneReader>> open_nff_reader(const std::string& path);
Result<std::unique_ptr<SceneReader>> open_ply_reader(const std::string& path);
Result<std::unique_ptr<SceneReader>> open_obj_reader(const std::string& path);
Result<std::unique_ptr<SceneReader>> open_off_reader(const std::string& path);
Result<std::unique_ptr<SceneReader>> open_stl_reader(const std::string& path);

// "path: byte N: message" as a Corruption status (binary formats).
Status byte_error(const std::string& path, uint64_t offset, std::string_view message);

// The warning about `bytes` bytes after the last record, from `offset` to the end of the file.
std::string trailing_data_warning(const std::string& path, uint64_t offset, uint64_t bytes);

// Validates a polygon vertex count read from a file: at least 3, at most kMaxPolygonVertices.
// Returns an empty string when fine, else the complaint ("face has 2 vertices (needs 3)").
std::string check_polygon_size(int64_t count, std::string_view what);

// True when x, y and z are all finite (no NaN, no Inf).
inline bool all_finite(const Vec3& p) { return (p.x - p.x) + (p.y - p.y) + (p.z - p.z) == 0.0; }

}  // namespace frontier
