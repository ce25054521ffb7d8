// CollisionGrid: parsing the "sdf" section, paging its bricks in on demand within a byte budget,
// and walking the eye through the distance field. A query reads voxels through a Cursor that
// pins the bricks it touches (shared pointers: eviction never frees a brick a query still reads)
// and keeps one unregistered accessor per brick, so the nearby samples of a gradient or a walk
// cost a tree lookup each and the cache's mutex only once per brick per query.
#include "src/walk/collision_grid.h"

#include "src/core/byte_io.h"

#include "store/byte_lru.h"
#include "store/page_format.h"
#include "store/section_frame.h"
#include "store/store_file.h"
#include "store/store_page_source.h"

#include <fmt/format.h>
#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>

#include <atomic>
#include <chrono>
#include <cassert>
#include <cmath>
#include <exception>
#include <mutex>
#include <sstream>
#include <string>
#include <unordered_map>

namespace frontier {

namespace sdf_format {

std::vector<uint8_t> frame(std::span<const uint8_t> payload, uint32_t version) {
  return store::frame_section(kMagic, version, payload);
}

}  // namespace sdf_format

void ensure_openvdb_initialized() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

namespace {

using FloatTree = openvdb::FloatTree;
using TreePtr = std::shared_ptr<const FloatTree>;
// Unregistered accessor: no bookkeeping in the tree, so constructing one per query is cheap and
// concurrent queries never contend.
using ConstAccessor = openvdb::tree::ValueAccessor<const FloatTree, /*IsSafe=*/false>;

// The interpolant is not exactly 1-Lipschitz and the far value is clamped, so steps and pushes
// use these fractions of a voxel (see the header's guarantees).
constexpr double kShortStep = 1.0 / 20.0;   // longest move near a surface, in voxels
constexpr double kContactSlack = 1e-3;      // how far past radius a push-out aims, in voxels
constexpr double kNoProgress = 1e-4;        // progress below this (voxels) ends a walk
constexpr int kMaxPushes = 40;              // push-out moves per blocked step
constexpr int kMaxMoves = 100000;           // hard cap on steps per resolve()
constexpr double kMaxIndex = double(1 << 30);  // no voxel lies farther from the grid origin

struct CoordHash {
  size_t operator()(const openvdb::Coord& c) const {
    const uint64_t h = uint64_t(uint32_t(c.x())) * 0x9E3779B97F4A7C15ull ^
                       uint64_t(uint32_t(c.y())) * 0xC2B2AE3D27D4EB4Full ^
                       uint64_t(uint32_t(c.z())) * 0x165667B19E3779F9ull;
    return size_t(h ^ (h >> 29));
  }
};

openvdb::CoordBBox brick_box(const openvdb::Coord& brick) {
  using sdf_format::kBrickVoxels;
  const openvdb::Coord lo(brick.x() * kBrickVoxels, brick.y() * kBrickVoxels, brick.z() * kBrickVoxels);
  return openvdb::CoordBBox(lo, lo.offsetBy(kBrickVoxels - 1));
}

// The one FloatGrid named kGridName in an OpenVDB stream; Corruption otherwise (never throws).
Result<openvdb::FloatGrid::Ptr> read_grid(std::span<const uint8_t> payload) {
  try {
    std::istringstream in(std::string(reinterpret_cast<const char*>(payload.data()), payload.size()),
                          std::ios::binary);
    openvdb::io::Stream stream(in, /*delayLoad=*/false);
    openvdb::GridPtrVecPtr grids = stream.getGrids();
    openvdb::FloatGrid::Ptr grid;
    if (grids) {
      for (const openvdb::GridBase::Ptr& g : *grids) {
        if (g && g->getName() == sdf_format::kGridName) grid = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
      }
    }
    if (!grid) return Status::corruption(std::string("no float grid named ") + sdf_format::kGridName);
    return grid;
  } catch (const std::exception& e) {
    return Status::corruption(std::string("OpenVDB: ") + e.what());
  } catch (...) {
    return Status::corruption("OpenVDB: unknown exception");
  }
}

}  // namespace

struct CollisionGrid::Impl {
  struct Brick {
    openvdb::Coord coord;       // brick coordinate: index voxels [coord, coord + 1) * kBrickVoxels
    openvdb::CoordBBox active;  // index box of its active voxels
    uint64_t page = 0;
    uint64_t active_voxels = 0;
  };

  double voxel = 1.0;
  int band = 3;
  double far = 3.0;  // band * voxel
  Vec3 origin{0.0};  // version 2: index = world / voxel - origin
  // Version 1: the whole grid, resident; version 2: null, and the bricks below.
  openvdb::FloatGrid::ConstPtr whole;
  std::vector<Brick> bricks;
  std::unordered_map<openvdb::Coord, uint32_t, CoordHash> brick_index;
  uint64_t total_active = 0;
  BrickSource source;
  uint64_t budget = 0;

  mutable std::atomic<uint64_t> queries{0};
  mutable std::mutex mu;  // guards everything below
  // Resident bricks by index, with their memory; a null tree: the brick could not be read, and
  // reads as solid. Bricks that cost nothing (failed ones) are pinned: they stay.
  mutable store::ByteLru<uint32_t, TreePtr> cache;
  mutable Counters stats;
  mutable Status first_error;

  // Reads and checks brick b's page: a tree whose active voxels lie in the brick, as many as the
  // section says, with the band width as background.
  Result<TreePtr> read_brick(const Brick& b) const {
    const std::string where = fmt::format("sdf brick ({}, {}, {}) in page {}: ", b.coord.x(), b.coord.y(),
                                          b.coord.z(), b.page);
    auto bytes = source(b.page);
    if (!bytes) return bytes.status().prefixed(where);
    auto grid = read_grid(*bytes);
    if (!grid) return Status::corruption(where + grid.status().message());
    try {
      const FloatTree& tree = (*grid)->tree();
      if (std::abs(double(tree.background()) - far) > 1e-4 * far) {
        return Status::corruption(where + "background is not the band width");
      }
      openvdb::CoordBBox box;
      tree.evalActiveVoxelBoundingBox(box);
      const uint64_t count = tree.activeVoxelCount();
      if (count != b.active_voxels || (count > 0 && (box != b.active || !brick_box(b.coord).isInside(box)))) {
        return Status::corruption(where + "active voxels disagree with the section's directory");
      }
      return TreePtr((*grid)->treePtr());
    } catch (const std::exception& e) {
      return Status::corruption(where + "OpenVDB: " + e.what());
    }
  }

  // The tree of brick `coord` for a query (loaded and cached if need be), or null with the value
  // every voxel of it reads: the band width for a brick with no active voxels, 0 for one that
  // could not be read.
  TreePtr fetch(const openvdb::Coord& coord, float& constant) const {
    const auto at = brick_index.find(coord);
    if (at == brick_index.end()) {
      constant = float(far);
      return nullptr;
    }
    const uint32_t index = at->second;
    const std::lock_guard<std::mutex> lock(mu);
    constant = 0.0f;
    if (const TreePtr* hit = cache.find(index)) {
      cache.touch(index);
      return *hit;
    }
    const auto start = std::chrono::steady_clock::now();
    Result<TreePtr> tree = read_brick(bricks[index]);
    stats.load_ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    ++stats.loads;
    TreePtr resident;
    uint64_t bytes = 0;
    if (tree) {
      resident = *tree;
      bytes = resident->memUsage();
      stats.largest_brick_bytes = std::max(stats.largest_brick_bytes, bytes);
    } else {
      ++stats.errors;
      if (first_error.is_ok()) first_error = tree.status();
    }
    cache.insert(index, bytes, resident);
    if (bytes == 0) cache.pin(index);
    // Least recently used first, never the brick just read (the newest).
    while (cache.over_budget()) {
      const std::optional<uint32_t> victim = cache.oldest();
      if (!victim || *victim == index) break;
      cache.erase(*victim);
      ++stats.evictions;
    }
    stats.resident_bytes = cache.resident_bytes();
    return resident;
  }

  // Reads voxels for one query, holding every brick it has touched until it is destroyed.
  class Cursor {
   public:
    explicit Cursor(const Impl& grid) : g_(grid) {
      if (g_.whole) {
        held_.push_back({openvdb::Coord(), g_.whole->treePtr(), 0.0f, nullptr});
        held_.back().acc = std::make_unique<ConstAccessor>(*held_.back().tree);
        last_ = 0;
      }
    }

    float value(const openvdb::Coord& ijk) {
      if (g_.whole) return held_[0].acc->getValue(ijk);
      using sdf_format::kBrickLog2;
      const openvdb::Coord brick(ijk.x() >> kBrickLog2, ijk.y() >> kBrickLog2, ijk.z() >> kBrickLog2);
      if (last_ < 0 || held_[size_t(last_)].brick != brick) {
        last_ = -1;
        for (size_t i = 0; i < held_.size(); ++i) {
          if (held_[i].brick == brick) last_ = int(i);
        }
        if (last_ < 0) {
          Held h{brick, nullptr, 0.0f, nullptr};
          h.tree = g_.fetch(brick, h.constant);
          if (h.tree) h.acc = std::make_unique<ConstAccessor>(*h.tree);
          held_.push_back(std::move(h));
          last_ = int(held_.size()) - 1;
        }
      }
      const Held& h = held_[size_t(last_)];
      return h.acc ? h.acc->getValue(ijk) : h.constant;
    }

   private:
    struct Held {
      openvdb::Coord brick;
      TreePtr tree;
      float constant;  // what every voxel reads when tree is null
      std::unique_ptr<ConstAccessor> acc;
    };
    const Impl& g_;
    std::vector<Held> held_;
    int last_ = -1;
  };

  // Trilinear interpolation of the voxel-centre values, clamped to [0, W].
  double sample(Cursor& cur, const Vec3& p) const {
    Vec3 index;
    if (whole) {
      const openvdb::Vec3d i = whole->transform().worldToIndex(openvdb::Vec3d(p.x, p.y, p.z));
      index = Vec3(i.x(), i.y(), i.z());
    } else {
      index = p / voxel - origin;
    }
    // NaN or beyond any grid (the builder keeps within 2^30 voxels): far, and no int overflow.
    for (int a = 0; a < 3; ++a) {
      if (!(std::abs(index[a]) < kMaxIndex)) return far;
    }
    const Vec3 base = glm::floor(index);
    const Vec3 f = index - base;
    const openvdb::Coord c(int(base.x), int(base.y), int(base.z));
    double v[2][2][2];
    for (int i = 0; i < 2; ++i) {
      for (int j = 0; j < 2; ++j) {
        for (int k = 0; k < 2; ++k) v[i][j][k] = cur.value(c.offsetBy(i, j, k));
      }
    }
    const auto lerp = [](double a, double b, double t) { return a + t * (b - a); };
    const double d = lerp(lerp(lerp(v[0][0][0], v[0][0][1], f.z), lerp(v[0][1][0], v[0][1][1], f.z), f.y),
                          lerp(lerp(v[1][0][0], v[1][0][1], f.z), lerp(v[1][1][0], v[1][1][1], f.z), f.y), f.x);
    return std::clamp(d, 0.0, far);
  }

  Vec3 gradient(Cursor& cur, const Vec3& p) const {
    const double e = 0.5 * voxel;
    Vec3 g;
    for (int a = 0; a < 3; ++a) {
      Vec3 lo = p, hi = p;
      lo[a] -= e;
      hi[a] += e;
      g[a] = sample(cur, hi) - sample(cur, lo);
    }
    const double len = glm::length(g);
    // Differences below float noise are a flat field, not a direction.
    if (!(len > 1e-6 * voxel)) return Vec3(0.0);
    return g / len;
  }

  // Pushes p (reading d < radius) up the distance field in moves of at most kShortStep voxels.
  // Returns true with p, d updated when it reaches d >= radius; false (p, d at the best point
  // found, d never lower than on entry) when the field is flat or stops rising.
  bool push_out(Cursor& cur, Vec3& p, double& d, double radius, int max_pushes) const {
    for (int i = 0; i < max_pushes && d < radius; ++i) {
      const Vec3 g = gradient(cur, p);
      if (g == Vec3(0.0)) return false;
      const double move = std::min(radius - d + kContactSlack * voxel, kShortStep * voxel);
      const Vec3 q = p + move * g;
      const double dq = sample(cur, q);
      if (!(dq > d)) return false;
      p = q;
      d = dq;
    }
    return d >= radius;
  }

  Vec3 resolve(const Vec3& from, const Vec3& to, double radius) const {
    const auto finite = [](const Vec3& v) {
      return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
    };
    if (!finite(from) || !finite(to)) return from;  // a caller's bug; never walk into NaN
    Cursor cur(*this);
    Vec3 pos = from;
    double d = sample(cur, pos);
    if (d < radius && !push_out(cur, pos, d, radius, 4 * kMaxPushes)) return pos;

    const double short_step = kShortStep * voxel;
    for (int move = 0; move < kMaxMoves; ++move) {
      const Vec3 delta = to - pos;
      const double remaining = glm::length(delta);
      if (remaining == 0.0) return to;
      const double step = std::max(d - radius, short_step);
      const bool last = step >= remaining;
      Vec3 next = last ? to : pos + (step / remaining) * delta;
      double dn = sample(cur, next);
      if (dn < radius && !push_out(cur, next, dn, radius, kMaxPushes)) return pos;
      // Blocked (pushed back to where we were) or sliding into a corner: stop when the target
      // comes no closer.
      if (!last || next != to) {
        if (glm::length(to - next) > remaining - kNoProgress * voxel) return pos;
      }
      pos = next;
      d = dn;
      if (pos == to) return to;
    }
    return pos;
  }
};

CollisionGrid::CollisionGrid(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {
  impl_->cache.set_budget(impl_->budget);
}
CollisionGrid::CollisionGrid(CollisionGrid&&) noexcept = default;
CollisionGrid& CollisionGrid::operator=(CollisionGrid&&) noexcept = default;
CollisionGrid::~CollisionGrid() = default;

namespace {

Status corrupt_section(const std::string& what) { return Status::corruption("sdf section: " + what); }

bool usable_sizes(double voxel, int band) {
  return voxel > 0.0 && std::isfinite(voxel) && band >= 1 && band <= 1000;
}

// The fixed fields of a version 2 payload, before its brick table.
struct BrickTableHeader {
  double voxel = 1.0;
  int band = 3;
  Vec3 origin{0.0};
  uint64_t bricks = 0;
  uint64_t active = 0;
};

// Reads and checks the fixed fields, and that exactly `bricks` entries follow them.
Status read_brick_table_header(GeometryReader& r, BrickTableHeader& h) {
  h.voxel = r.f64();
  h.band = int(int32_t(r.u32()));
  const uint32_t brick_voxels = r.u32();
  int64_t origin[3];
  for (int64_t& o : origin) o = int64_t(r.u64());
  h.bricks = r.u64();
  h.active = r.u64();
  if (!r.ok()) return corrupt_section("truncated brick table");
  if (!usable_sizes(h.voxel, h.band)) return corrupt_section("bad voxel size or band width");
  if (brick_voxels != uint32_t(sdf_format::kBrickVoxels)) return corrupt_section("unknown brick size");
  for (int a = 0; a < 3; ++a) {
    if (!(std::abs(double(origin[a])) < kMaxIndex)) return corrupt_section("lattice origin out of range");
    h.origin[a] = double(origin[a]);
  }
  if (h.bricks > r.remaining() / sdf_format::kBrickEntrySize || r.remaining() != h.bricks * sdf_format::kBrickEntrySize) {
    return corrupt_section("brick table size does not match its " + std::to_string(h.bricks) + " bricks");
  }
  return Status::ok();
}

// One brick table entry on its own: within the index range the builder keeps to, with a
// non-empty active box inside the brick and a count a brick can hold.
Status check_brick(uint64_t i, const openvdb::Coord& coord, const openvdb::CoordBBox& active, uint64_t active_voxels) {
  const int64_t limit = int64_t(1) << (30 - sdf_format::kBrickLog2);
  for (int a = 0; a < 3; ++a) {
    if (std::abs(int64_t(coord[a])) > limit) return corrupt_section("brick " + std::to_string(i) + " out of range");
  }
  const uint64_t cap = uint64_t(sdf_format::kBrickVoxels) * sdf_format::kBrickVoxels * sdf_format::kBrickVoxels;
  if (active_voxels == 0 || active_voxels > cap || active.empty() || !brick_box(coord).isInside(active)) {
    return corrupt_section("brick " + std::to_string(i) + ": bad active voxels");
  }
  return Status::ok();
}

// A version 1 payload: one OpenVDB stream of the whole grid, its sizes in its metadata.
struct WholeGrid {
  openvdb::FloatGrid::Ptr grid;
  double voxel = 1.0;
  int band = 3;
  uint64_t active = 0;
};

Result<WholeGrid> read_whole_grid(std::span<const uint8_t> payload) {
  auto grid = read_grid(payload);
  if (!grid) return corrupt_section(grid.status().message());
  try {
    const auto voxel_meta = (*grid)->getMetadata<openvdb::DoubleMetadata>(sdf_format::kMetaVoxelSize);
    const auto band_meta = (*grid)->getMetadata<openvdb::Int32Metadata>(sdf_format::kMetaBandVoxels);
    const auto kind_meta = (*grid)->getMetadata<openvdb::StringMetadata>(sdf_format::kMetaDistance);
    if (!voxel_meta || !band_meta || !kind_meta) return corrupt_section("grid metadata missing");
    if (kind_meta->value() != "unsigned") return corrupt_section("distance kind is not \"unsigned\"");
    WholeGrid whole{*grid, voxel_meta->value(), band_meta->value(), 0};
    if (!usable_sizes(whole.voxel, whole.band)) return corrupt_section("bad voxel size or band width");
    const double far = whole.band * whole.voxel;
    const openvdb::math::Transform& xform = (*grid)->transform();
    if (!xform.isLinear() || !xform.hasUniformScale() ||
        std::abs(xform.voxelSize()[0] - whole.voxel) > 1e-9 * whole.voxel) {
      return corrupt_section("grid transform disagrees with its voxel size");
    }
    if (std::abs(double((*grid)->background()) - far) > 1e-4 * far) {
      return corrupt_section("grid background is not the band width");
    }
    whole.active = whole.grid->activeVoxelCount();
    return whole;
  } catch (const std::exception& e) {
    return corrupt_section(std::string("OpenVDB: ") + e.what());
  }
}

}  // namespace

Result<CollisionGrid> CollisionGrid::open(std::span<const uint8_t> bytes, BrickSource source,
                                          uint64_t budget_bytes) {
  auto section = store::unframe_section(bytes, sdf_format::kMagic, sdf_format::kVersion, "sdf section");
  if (!section) return section.status();

  ensure_openvdb_initialized();
  auto impl = std::make_unique<Impl>();
  impl->source = std::move(source);
  impl->budget = budget_bytes;
  if (section->version == sdf_format::kVersion2) {
    GeometryReader r(section->payload);
    BrickTableHeader h;
    if (Status s = read_brick_table_header(r, h); !s) return s;
    impl->voxel = h.voxel;
    impl->band = h.band;
    impl->far = h.band * h.voxel;
    impl->origin = h.origin;
    impl->total_active = h.active;
    uint64_t active = 0;
    impl->bricks.reserve(h.bricks);
    for (uint64_t i = 0; i < h.bricks; ++i) {
      int32_t v[9];
      for (int32_t& x : v) x = int32_t(r.u32());
      Impl::Brick b;
      b.coord = openvdb::Coord(v[0], v[1], v[2]);
      b.active = openvdb::CoordBBox(openvdb::Coord(v[3], v[4], v[5]), openvdb::Coord(v[6], v[7], v[8]));
      b.page = r.u64();
      b.active_voxels = r.u64();
      if (Status s = check_brick(i, b.coord, b.active, b.active_voxels); !s) return s;
      if (!impl->brick_index.emplace(b.coord, uint32_t(i)).second) {
        return corrupt_section("brick " + std::to_string(i) + " appears twice");
      }
      active += b.active_voxels;
      impl->bricks.push_back(b);
    }
    if (active != impl->total_active) return corrupt_section("brick voxel counts do not add up");
    return CollisionGrid(std::move(impl));
  }

  // Version 1: the whole grid in the section.
  auto whole = read_whole_grid(section->payload);
  if (!whole) return whole.status();
  impl->voxel = whole->voxel;
  impl->band = whole->band;
  impl->far = whole->band * whole->voxel;
  impl->whole = whole->grid;
  impl->total_active = whole->active;
  impl->stats.resident_bytes = impl->whole->memUsage();
  return CollisionGrid(std::move(impl));
}

Result<CollisionGrid> CollisionGrid::load(SdfImage image, uint64_t budget_bytes) {
  auto pages = std::make_shared<const std::vector<std::vector<uint8_t>>>(std::move(image.pages));
  BrickSource source = [pages](uint64_t page) -> Result<std::vector<uint8_t>> {
    if (page >= pages->size()) return Status::corruption("page " + std::to_string(page) + " does not exist");
    const std::vector<uint8_t>& block = (*pages)[page];
    auto decoded = store::decode_page(block, store::Handle{0, block.size()});
    if (!decoded) return decoded.status();
    if (decoded->codec != sdf_format::kBrickCodec) return Status::corruption("page " + std::to_string(page) + " is not a collision brick");
    return std::vector<uint8_t>(decoded->payload.begin(), decoded->payload.end());
  };
  return open(image.section, std::move(source), budget_bytes);
}

double CollisionGrid::voxel_size() const { return impl_->voxel; }
int CollisionGrid::band_voxels() const { return impl_->band; }
double CollisionGrid::band_width() const { return impl_->far; }

Status CollisionGrid::check_radius(double radius) const {
  if (!(radius >= impl_->voxel) || !(radius < impl_->far)) {
    return Status::invalid_argument("collision radius " + std::to_string(radius) +
                                    " must lie in [voxel size " + std::to_string(impl_->voxel) +
                                    ", band width " + std::to_string(impl_->far) +
                                    "): rebuild the store with a wider band or finer voxels");
  }
  return Status::ok();
}

double CollisionGrid::distance(const Vec3& p) const {
  impl_->queries.fetch_add(1, std::memory_order_relaxed);
  Impl::Cursor cur(*impl_);
  return impl_->sample(cur, p);
}

Vec3 CollisionGrid::gradient(const Vec3& p) const {
  impl_->queries.fetch_add(1, std::memory_order_relaxed);
  Impl::Cursor cur(*impl_);
  return impl_->gradient(cur, p);
}

Vec3 CollisionGrid::resolve(const Vec3& from, const Vec3& to, double radius) const {
  impl_->queries.fetch_add(1, std::memory_order_relaxed);
  assert(check_radius(radius).is_ok());
  // Largest double below the band width: the clamp keeps release builds inside the contract.
  radius = std::clamp(radius, impl_->voxel, std::nextafter(impl_->far, 0.0));
  return impl_->resolve(from, to, radius);
}

uint64_t CollisionGrid::queries() const { return impl_->queries.load(std::memory_order_relaxed); }

Status CollisionGrid::check_all_bricks() const {
  for (const Impl::Brick& b : impl_->bricks) {
    Result<TreePtr> tree = impl_->read_brick(b);
    if (!tree) return tree.status();
  }
  return Status::ok();
}

std::vector<uint64_t> CollisionGrid::brick_pages() const {
  std::vector<uint64_t> pages;
  for (const Impl::Brick& b : impl_->bricks) pages.push_back(b.page);
  return pages;
}

CollisionGrid::Counters CollisionGrid::counters() const {
  const std::lock_guard<std::mutex> lock(impl_->mu);
  Counters c = impl_->stats;
  c.bricks = impl_->whole ? 1 : impl_->bricks.size();
  c.resident = impl_->whole ? 1 : impl_->cache.size();
  c.budget_bytes = impl_->budget;
  return c;
}

Status CollisionGrid::error() const {
  const std::lock_guard<std::mutex> lock(impl_->mu);
  return impl_->first_error;
}

uint64_t CollisionGrid::active_voxels() const { return impl_->total_active; }

uint64_t CollisionGrid::memory_bytes() const { return counters().resident_bytes; }

Aabb CollisionGrid::bounds() const {
  openvdb::CoordBBox box;
  if (impl_->whole) {
    box = impl_->whole->evalActiveVoxelBoundingBox();
    if (box.empty()) return Aabb();
    const openvdb::BBoxd world = impl_->whole->transform().indexToWorld(box);
    return Aabb(Vec3(world.min().x(), world.min().y(), world.min().z()),
                Vec3(world.max().x(), world.max().y(), world.max().z()));
  }
  for (const Impl::Brick& b : impl_->bricks) box.expand(b.active);
  if (box.empty()) return Aabb();
  const auto world = [&](const openvdb::Coord& c) {
    return (Vec3(c.x(), c.y(), c.z()) + impl_->origin) * impl_->voxel;
  };
  return Aabb(world(box.min()), world(box.max()));
}

Result<std::unique_ptr<CollisionGrid>> open_collision_grid(const store::StoreReader& reader,
                                                           uint64_t budget_bytes) {
  auto section = reader.read_section("sdf");
  if (!section) return section.status();
  // Bricks come through the store's page source, as cells do (it is thread-safe, as the
  // queries that fetch bricks need).
  auto pages = std::make_shared<store::StorePageSource>(reader);
  BrickSource source = [&reader, pages](uint64_t page) -> Result<std::vector<uint8_t>> {
    if (page >= reader.page_count()) {
      return Status::corruption(reader.name() + ": page " + std::to_string(page) + " does not exist");
    }
    auto block = pages->load(page);
    if (!block) return block.status();
    if (block->codec != sdf_format::kBrickCodec) {
      return Status::corruption(reader.name() + ": page " + std::to_string(page) + " is not a collision brick");
    }
    return std::move(block->bytes);
  };
  auto grid = CollisionGrid::open(*section, std::move(source), budget_bytes);
  if (!grid) return grid.status().prefixed(reader.name() + ": ");
  return std::make_unique<CollisionGrid>(std::move(*grid));
}

}  // namespace frontier
