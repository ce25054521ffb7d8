// Private to the scene readers: the per-format factories behind open_scene_reader() and the
// limits and message helpers they share. Not for use outside the reader files.
#pragma once

#include "src/scene_reader.h"

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

namespace frontier {

// The most vertices one polygon (NFF p/pp, PLY/OBJ/OFF face) may have. Larger counts are
// rejected as corrupt: they would cost O(n²) to triangulate and a garbled count must never
// turn into a huge allocation.
inline constexpr int64_t kMaxPolygonVertices = int64_t{1} << 16;

Result<std::unique_ptr<SceneReader>> open_nff_reader(const std::string& path);
Result<std::unique_ptr<SceneReader>> open_ply_reader(const std::string& path);
Result<std::unique_ptr<SceneReader>> open_obj_reader(const std::string& path);
Result<std::unique_ptr<SceneReader>> open_off_reader(const std::string& path);

// "path: byte N: message" as a Corruption status (binary formats).
Status byte_error(const std::string& path, uint64_t offset, std::string_view message);

// Validates a polygon vertex count read from a file: at least 3, at most kMaxPolygonVertices.
// Returns an empty string when fine, else the complaint ("face has 2 vertices (needs 3)").
std::string check_polygon_size(int64_t count, std::string_view what);

// True when x, y and z are all finite (no NaN, no Inf).
inline bool all_finite(const Vec3& p) { return (p.x - p.x) + (p.y - p.y) + (p.z - p.z) == 0.0; }

}  // namespace frontier
