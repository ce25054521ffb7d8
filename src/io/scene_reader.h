// Pull-based model readers: each call to next() hands out one input primitive, so a caller
// (the in-memory loader, the out-of-core preprocessor) never needs the whole model at once.
//
// What each reader must hold in memory: NFF and STL nothing but the current primitive; binary PLY
// with fixed-size vertex records maps the vertex section and indexes into it; ASCII PLY, OBJ
// and OFF keep the vertex positions (24 bytes each) because faces may refer to any of them.
//
// Errors: a malformed file yields a Status whose message starts with the file name and names
// the line (text formats) or byte offset (binary PLY and STL). NaN/Inf coordinates are errors
// naming their position. Readers never crash on garbage or truncated input. What a reader can
// read past is a warning instead (warnings()): an unknown PLY header line, data after the last
// record of a PLY, OFF or STL file.
#pragma once

#include "src/core/primitives.h"
#include "src/core/scene.h"
#include "src/core/status.h"

#include <memory>
#include <string>
#include <vector>

namespace frontier {

// One primitive as it appears in the file, before triangulation.
struct InputPrimitive {
  enum class Kind { Polygon, Sphere, Cone, Box, Quadric };
  Kind kind = Kind::Polygon;
  uint32_t material = 0;               // index into SceneHeader::materials
  std::vector<Vec3> vertices;          // Polygon: n >= 3 vertices, in order (may be concave)
  std::vector<Vec3> normals;           // Polygon: empty or one per vertex
  Sphere sphere;
  Cone cone;
  Box box;
  Quadric quadric;
};

// Everything a file says besides its primitives. NFF may interleave materials and lights with
// primitives, so the header grows as the file is read; it is complete once next() reports the
// end. Meshes get one default material (index 0).
struct SceneHeader {
  std::optional<Camera> camera;
  Vec3 background{0.0, 0.0, 0.0};
  std::vector<PointLight> lights;
  std::vector<Material> materials;
};

class SceneReader {
 public:
  virtual ~SceneReader() = default;
  // Writes the next primitive into `out` and returns ok with `end == false`; at the end of the
  // file returns ok with `end == true`. On malformed input returns the error (and keeps
  // returning it).
  virtual Status next(InputPrimitive& out, bool& end) = 0;
  virtual const SceneHeader& header() const = 0;
  // Total number of input primitives when the format states it up front (PLY, OFF), else -1.
  virtual int64_t declared_primitives() const { return -1; }
  // True when the body is binary records (binary PLY): parsing it again costs little next to
  // writing and reading back a copy (frontier-build reads such inputs twice).
  virtual bool binary() const { return false; }
  // Problems read past so far, one message each naming the file and the line or byte offset
  // (an unknown PLY header line at open; data after the last record once next() reports the
  // end). Each is reported once, however often it is asked for.
  virtual const std::vector<std::string>& warnings() const = 0;
  // Bytes consumed so far and the file size, for progress reports.
  virtual uint64_t bytes_read() const = 0;
  virtual uint64_t bytes_total() const = 0;
};

// Opens a reader chosen by extension (.nff, .ply, .obj, .off, .stl; case-insensitive). Errors:
// NotFound (no such file), IoError (unreadable, a directory), Unsupported (another extension),
// or the format's own header errors; each message starts with the path.
Result<std::unique_ptr<SceneReader>> open_scene_reader(const std::string& path);

}  // namespace frontier
