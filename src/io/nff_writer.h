// Streaming writer of NFF scenes (Eric Haines' Neutral File Format, as read by frontier's NFF
// reader): camera `v` block, background `b`, lights `l`, materials `f`, spheres `s`, cones and
// cylinders `c`, polygons `p`. Each call appends text to a bounded buffer that is flushed as it
// fills, so scenes of any size are written in constant memory.
//
// Numbers are printed with 9 significant digits ("{:.9g}"), which is deterministic: the same
// calls give byte-identical files. A NaN/Inf argument or a non-positive radius is not written;
// the first such error is kept and returned by finish(), which then leaves no file behind.
// Regular files are written as PATH.tmp and renamed by finish(); "-" writes to stdout.
// Not thread-safe.
#pragma once

#include "src/core/geometry.h"
#include "src/core/scene.h"
#include "src/core/status.h"

#include <cstdint>
#include <cstdio>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace frontier {

class NffWriter {
 public:
  // Fails with IoError when the file cannot be created.
  static Result<std::unique_ptr<NffWriter>> create(const std::string& path);
  ~NffWriter();
  NffWriter(const NffWriter&) = delete;
  NffWriter& operator=(const NffWriter&) = delete;

  void comment(std::string_view text);  // one `# text` line per line of text
  // `v` block; `cam.vfov_deg` is NFF's full vertical angle.
  void view(const Camera& cam, double hither, int width, int height);
  void background(const Vec3& rgb);
  void light(const Vec3& position, const Vec3& rgb);
  void material(const Material& m);
  void sphere(const Vec3& center, double radius);
  // Truncated cone from base to apex (a cylinder when the radii are equal), open-ended.
  void cone(const Vec3& base, double base_radius, const Vec3& apex, double apex_radius);
  void polygon(std::span<const Vec3> vertices);  // REQUIRES at least 3 vertices

  // Flushes, closes, renames; returns the first error seen.
  Status finish();

  uint64_t primitives() const { return primitives_; }

 private:
  NffWriter() = default;
  void flush_if_full();
  bool check(bool ok, std::string_view what);
  bool finite(const Vec3& v) const {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
  }

  std::string path_, temp_path_;
  std::FILE* file_ = nullptr;
  bool owns_file_ = false;
  bool finished_ = false;
  std::string buffer_;
  Status error_;
  uint64_t primitives_ = 0;
};

}  // namespace frontier
