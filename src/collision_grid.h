// The viewer's side of walk-mode collision: a sparse OpenVDB distance grid, read from the store's
// "sdf" section, answering "how far is the nearest geometry" and "how far may the eye move".
//
// What the grid holds (written by WalkableGridBuilder, preprocess/walkable_grid.h, which explains
// the choices): the exact *unsigned* distance from each voxel centre to the nearest primitive,
// in world units, for the voxels closer than the band width W = band_voxels * voxel_size h;
// every other voxel is inactive and reads as W ("at least W away"). Because distance is
// 1-Lipschitz, trilinear interpolation of the exact voxel-centre values errs by at most
// sqrt(3)/2 * h anywhere (exactly 0 where the field is locally linear, e.g. near the middle of a
// flat wall, more at edges and corners), and the clamping at W only ever underestimates. Curved primitives were tessellated with a chord
// error of at most h/16 (see walkable_grid.h), so
//
//     |distance(p) - true distance(p)| <= sqrt(3)/2 * h + h/16 < 0.94 h    whenever both are < W.
//
// The "sdf" section layout (version 1), all integers little-endian:
//   magic "FSDF" (4 B) | version u32 | payload size u64 | xxHash64(payload) u64 | payload
// where payload is an OpenVDB stream (openvdb::io::Stream) holding one FloatGrid named
// kGridName with metadata kMetaVoxelSize (double), kMetaBandVoxels (int32) and kMetaDistance
// ("unsigned"). The checksum is what makes load() safe on damaged bytes: OpenVDB's own reader
// is not hardened against arbitrary input, so it only ever sees bytes that passed the checksum.
//
// Memory: the whole grid is resident once loaded, about 7 bytes per active voxel (measured:
// 67 MiB for a 100 k-triangle building at 5 cm voxels, 533 MiB for 1 M triangles); memory_bytes()
// reports it for the working-set line.
//
// Thread safety: a loaded CollisionGrid is immutable; every const member may be called from any
// number of threads at once (each query uses its own unregistered tree accessor; the query
// counter is atomic).
#pragma once

#include "src/geometry.h"
#include "src/status.h"

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace frontier {

namespace sdf_format {
inline constexpr std::array<uint8_t, 4> kMagic = {'F', 'S', 'D', 'F'};
// Versions, oldest first; load() accepts versions <= kVersion and refuses newer ones cleanly.
inline constexpr uint32_t kVersion1 = 1;  // unsigned distance FloatGrid in an OpenVDB stream
inline constexpr uint32_t kVersion = kVersion1;
inline constexpr size_t kHeaderSize = 24;
inline constexpr const char* kGridName = "frontier_collision";
inline constexpr const char* kMetaVoxelSize = "frontier_voxel_size";
inline constexpr const char* kMetaBandVoxels = "frontier_band_voxels";
inline constexpr const char* kMetaDistance = "frontier_distance";  // value "unsigned"

// Wraps an OpenVDB stream in the section header above (magic, version, size, checksum).
std::vector<uint8_t> frame(std::span<const uint8_t> vdb_stream);
}  // namespace sdf_format

// Registers OpenVDB's grid types; safe to call from any thread, any number of times (the work
// happens once). Both the builder and CollisionGrid::load call it.
void ensure_openvdb_initialized();

class CollisionGrid {
 public:
  // Corruption (naming what is wrong) for damaged, truncated or foreign bytes; Unsupported for a
  // newer section version. Never throws, never crashes: OpenVDB exceptions are caught.
  static Result<CollisionGrid> load(std::span<const uint8_t> bytes);

  CollisionGrid(CollisionGrid&&) noexcept;
  CollisionGrid& operator=(CollisionGrid&&) noexcept;
  ~CollisionGrid();

  double voxel_size() const;
  int band_voxels() const;
  // W = band_voxels * voxel_size: the largest distance the grid can tell apart; "far" reads as W.
  double band_width() const;
  // The radii resolve() supports: voxel_size() <= radius < band_width(). Above W the grid cannot
  // see the clearance; below h interpolation (which overestimates by up to sqrt(3)/2 h right at a
  // surface) could let a thin wall slip between two steps. InvalidArgument otherwise (the viewer
  // checks its --radius once, at start-up, and the preprocessor sizes the band to fit it).
  Status check_radius(double radius) const;

  // Unsigned distance from p to the nearest geometry, trilinearly interpolated, in [0, W];
  // exactly W farther than the band, anywhere outside the model's grid, and for a NaN p.
  // Error bound above.
  double distance(const Vec3& p) const;
  // Unit vector pointing away from the nearest geometry (central differences of distance() at
  // +-h/2), or (0,0,0) where the field is flat (outside the band, on a medial plane).
  Vec3 gradient(const Vec3& p) const;

  // Moves from `from` towards `to`, sliding along surfaces, and returns where the eye ends up.
  // REQUIRES: check_radius(radius) is ok (asserted; release builds clamp radius into [h, W)).
  // Guarantees, with d = distance() (the interpolated grid value):
  //  * If d(from) >= radius, then d(result) >= radius, so the true clearance is at least
  //    radius - 0.94 h (the error bound above). The result is `to` itself when every point tried
  //    on the way keeps d >= radius.
  //  * The path is walked in steps no longer than max(d - radius, h / 20), each one checked, so
  //    it never passes through a surface, not even a zero-thickness wall: a point that reads d
  //    is truly at least d - 0.94 h from every surface, more than such a step (d >= radius >= h).
  //    Cost: O(length / max(W - radius, h / 20)) samples, so a far jump should be a teleport.
  //  * Blocked motion slides: a step that would end closer than radius is projected back out
  //    along the gradient (moves of at most h / 20, each up the distance field, so away from the
  //    nearest surface), so walking into a wall at an angle moves along it; walking straight
  //    at it stops where d = radius (within 1e-3 h), i.e. at radius +- 0.94 h from the true wall.
  //  * If d(from) < radius (spawned inside the clearance), the eye is first pushed out along the
  //    gradient, best effort: d(result) >= d(from), never less.
  //  * A non-finite from or to returns from.
  // Counts as one query, however many grid samples it takes.
  Vec3 resolve(const Vec3& from, const Vec3& to, double radius) const;

  // Public calls to distance(), gradient() and resolve() since load (each counts one). A store
  // without walk mode never loads a grid, so its viewer reports zero.
  uint64_t queries() const;

  // Active voxels and the grid's memory (the viewer's working-set report counts it).
  uint64_t active_voxels() const;
  uint64_t memory_bytes() const;
  // World bounds of the active voxel centres (empty for an empty grid).
  Aabb bounds() const;

 private:
  struct Impl;
  explicit CollisionGrid(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace frontier
