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
// The "sdf" section (version 2, paged), all integers little-endian:
//   magic "FSDF" (4 B) | version u32 | payload size u64 | xxHash64(payload) u64 | payload
//   payload = voxel size f64 | band voxels i32 | brick voxels u32 (kBrickVoxels) |
//             lattice origin i64 x 3 (in voxels) | brick count u64 | active voxels u64 |
//             brick count x { brick coordinate i32 x 3 | active box min i32 x 3 | max i32 x 3 |
//                             store page u64 | active voxels u64 }            (52 B each)
// Index coordinates are world / voxel - origin; brick (i, j, k) holds the index voxels
// [i, i + 1) * kBrickVoxels (and so on), and its voxels live in one store page (codec tag
// kBrickCodec, checksummed by the store) holding an OpenVDB stream of one FloatGrid named
// kGridName with background W. Bricks without active voxels are not stored: they read as W.
// Version 1 (still read): the payload is one OpenVDB stream of the whole grid, with metadata
// kMetaVoxelSize (double), kMetaBandVoxels (int32) and kMetaDistance ("unsigned"); it is all
// resident once loaded. The checksums are what make loading safe on damaged bytes: OpenVDB's own
// reader is not hardened against arbitrary input, so it only ever sees bytes that passed one.
//
// Memory (version 2): bricks are read on demand, by the first query that needs one of their
// voxels, and kept in an LRU cache with a byte budget (a brick is about 7 bytes per active voxel,
// about 1-2 MiB for a 64^3 brick cut by walls and floors). The budget is exceeded only while a
// query holds more bricks than fit (a query holds the bricks it touches until it returns: a
// resolve() across several bricks). memory_bytes() reports the cached bricks for the working-set
// line, with loads, evictions and load time in the counters. A brick that cannot be read (I/O
// error, checksum, OpenVDB) reads as distance 0 everywhere, so the eye can never enter it: walk
// mode stops there rather than walking through walls, and error() says why.
//
// Thread safety: every const member may be called from any number of threads at once (the brick
// cache is behind a mutex; loads happen under it; each query reads its bricks through its own
// unregistered accessors; the counters are atomic).
#pragma once

#include "src/core/geometry.h"
#include "src/core/status.h"
#include "store/section_frame.h"

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

namespace frontier {

namespace store {
class StoreReader;
}

namespace sdf_format {
inline constexpr store::SectionMagic kMagic = {'F', 'S', 'D', 'F'};
// Versions, oldest first; load() accepts versions <= kVersion and refuses newer ones cleanly.
inline constexpr uint32_t kVersion1 = 1;  // unsigned distance FloatGrid in an OpenVDB stream
inline constexpr uint32_t kVersion2 = 2;  // the grid cut into bricks, one store page each
inline constexpr uint32_t kVersion = kVersion2;
inline constexpr size_t kHeaderSize = store::kSectionHeaderSize;
inline constexpr const char* kGridName = "frontier_collision";
inline constexpr const char* kMetaVoxelSize = "frontier_voxel_size";
inline constexpr const char* kMetaBandVoxels = "frontier_band_voxels";
inline constexpr const char* kMetaDistance = "frontier_distance";  // value "unsigned"

inline constexpr int kBrickLog2 = 6;
inline constexpr int kBrickVoxels = 1 << kBrickLog2;  // a brick is 64^3 voxels
inline constexpr size_t kBrickEntrySize = 52;
// Codec tag of brick pages (the store carries it and never interprets it; cell pages use the
// cell codecs' tags, 0 and 1).
inline constexpr uint8_t kBrickCodec = 0x53;  // 'S'

// Wraps a payload in the section header above (magic, version, size, checksum):
// store::frame_section with kMagic.
std::vector<uint8_t> frame(std::span<const uint8_t> payload, uint32_t version = kVersion);
}  // namespace sdf_format

// A whole collision grid held in memory: the section and the brick pages it names by index,
// each framed as a store block (payload | codec kBrickCodec | checksum, store/page_format.h) so
// that damaged bytes are caught before OpenVDB reads them, as in a store (tests and tools).
struct SdfImage {
  std::vector<uint8_t> section;
  std::vector<std::vector<uint8_t>> pages;
  friend bool operator==(const SdfImage&, const SdfImage&) = default;
};

namespace sdf_format {
}  // namespace sdf_format

// Registers OpenVDB's grid types; safe to call from any thread, any number of times (the work
// happens once). Both the builder and CollisionGrid::load call it.
void ensure_openvdb_initialized();

// Reads one brick page's payload (checked by the store), naming the page in any error.
using BrickSource = std::function<Result<std::vector<uint8_t>>(uint64_t page)>;

class CollisionGrid {
 public:
  static constexpr uint64_t kDefaultBudget = uint64_t{64} << 20;

  // Parses the section; bricks are read through `source` later, on demand, and cached within
  // `budget_bytes`. Corruption (naming what is wrong) for damaged, truncated or foreign bytes;
  // Unsupported for a newer section version. Never throws, never crashes: OpenVDB exceptions are
  // caught. A version 1 section is loaded whole at once (source unused, budget not applied).
  static Result<CollisionGrid> open(std::span<const uint8_t> section, BrickSource source,
                                    uint64_t budget_bytes = kDefaultBudget);
  // The same over an in-memory image (brick pages by index).
  static Result<CollisionGrid> load(SdfImage image, uint64_t budget_bytes = kDefaultBudget);

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

  // Reads every brick once (evicting as it goes) and returns the first that fails, naming its
  // page: frontier-store verify. Does not count as queries or change error().
  Status check_all_bricks() const;
  // The store pages of the bricks, in brick table order (empty for a version 1 grid).
  std::vector<uint64_t> brick_pages() const;

  struct Counters {
    uint64_t bricks = 0;          // bricks in the section (1 for a version 1 grid)
    uint64_t resident = 0;        // bricks in the cache now
    uint64_t resident_bytes = 0;  // their memory (memory_bytes())
    uint64_t budget_bytes = 0;
    uint64_t loads = 0;           // brick pages read and decoded since open
    uint64_t evictions = 0;
    uint64_t largest_brick_bytes = 0;  // the most memory one loaded brick took
    uint64_t errors = 0;          // bricks that could not be read (they read as solid)
    double load_ms = 0.0;         // time spent reading and decoding bricks
  };
  Counters counters() const;
  // The first brick that could not be read (ok while none failed).
  Status error() const;

  // Active voxels (all bricks, from the section) and the memory of the bricks resident now
  // (the viewer's working-set report counts it).
  uint64_t active_voxels() const;
  uint64_t memory_bytes() const;
  // World bounds of the active voxel centres (empty for an empty grid).
  Aabb bounds() const;

 private:
  struct Impl;
  explicit CollisionGrid(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The grid of a store's "sdf" section, its bricks read as the store's checked pages (codec
// kBrickCodec). NotFound without the section; errors name the store file. The reader must
// outlive the grid.
Result<std::unique_ptr<CollisionGrid>> open_collision_grid(const store::StoreReader& reader,
                                                           uint64_t budget_bytes = CollisionGrid::kDefaultBudget);

}  // namespace frontier
