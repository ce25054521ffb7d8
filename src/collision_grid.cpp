// CollisionGrid: loading the "sdf" section and walking the eye through the distance field.
// The grid is immutable after load; queries build a throwaway, unregistered tree accessor each
// (cheap, and safe from any number of threads because nothing writes the tree).
#include "src/collision_grid.h"

#include "store/page_format.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>
#include <openvdb/tools/Interpolation.h>

#include <atomic>
#include <cassert>
#include <cmath>
#include <cstring>
#include <exception>
#include <mutex>
#include <sstream>
#include <string>

namespace frontier {

namespace sdf_format {

std::vector<uint8_t> frame(std::span<const uint8_t> vdb_stream) {
  std::vector<uint8_t> out(kMagic.begin(), kMagic.end());
  out.reserve(kHeaderSize + vdb_stream.size());
  store::put_u32(out, kVersion);
  store::put_u64(out, vdb_stream.size());
  store::put_u64(out, store::checksum(vdb_stream));
  out.insert(out.end(), vdb_stream.begin(), vdb_stream.end());
  return out;
}

}  // namespace sdf_format

void ensure_openvdb_initialized() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

namespace {

using FloatTree = openvdb::FloatTree;
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

}  // namespace

struct CollisionGrid::Impl {
  openvdb::FloatGrid::ConstPtr grid;
  double voxel = 1.0;
  int band = 3;
  double far = 3.0;  // band * voxel
  mutable std::atomic<uint64_t> queries{0};

  // One accessor serves a whole query: its node cache makes the nearby samples of a gradient
  // or a walk cheap.
  double sample(ConstAccessor& acc, const Vec3& p) const {
    const openvdb::Vec3d index = grid->transform().worldToIndex(openvdb::Vec3d(p.x, p.y, p.z));
    // NaN or beyond any grid (the builder keeps within 2^30 voxels): far, and no int overflow.
    for (int a = 0; a < 3; ++a) {
      if (!(std::abs(index[a]) < kMaxIndex)) return far;
    }
    const double d = openvdb::tools::BoxSampler::sample(acc, index);
    return std::clamp(d, 0.0, far);
  }

  Vec3 gradient(ConstAccessor& acc, const Vec3& p) const {
    const double e = 0.5 * voxel;
    Vec3 g;
    for (int a = 0; a < 3; ++a) {
      Vec3 lo = p, hi = p;
      lo[a] -= e;
      hi[a] += e;
      g[a] = sample(acc, hi) - sample(acc, lo);
    }
    const double len = glm::length(g);
    // Differences below float noise are a flat field, not a direction.
    if (!(len > 1e-6 * voxel)) return Vec3(0.0);
    return g / len;
  }

  // Pushes p (reading d < radius) up the distance field in moves of at most kShortStep voxels.
  // Returns true with p, d updated when it reaches d >= radius; false (p, d at the best point
  // found, d never lower than on entry) when the field is flat or stops rising.
  bool push_out(ConstAccessor& acc, Vec3& p, double& d, double radius, int max_pushes) const {
    for (int i = 0; i < max_pushes && d < radius; ++i) {
      const Vec3 g = gradient(acc, p);
      if (g == Vec3(0.0)) return false;
      const double move = std::min(radius - d + kContactSlack * voxel, kShortStep * voxel);
      const Vec3 q = p + move * g;
      const double dq = sample(acc, q);
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
    ConstAccessor acc(grid->tree());
    Vec3 pos = from;
    double d = sample(acc, pos);
    if (d < radius && !push_out(acc, pos, d, radius, 4 * kMaxPushes)) return pos;

    const double short_step = kShortStep * voxel;
    for (int move = 0; move < kMaxMoves; ++move) {
      const Vec3 delta = to - pos;
      const double remaining = glm::length(delta);
      if (remaining == 0.0) return to;
      const double step = std::max(d - radius, short_step);
      const bool last = step >= remaining;
      Vec3 next = last ? to : pos + (step / remaining) * delta;
      double dn = sample(acc, next);
      if (dn < radius && !push_out(acc, next, dn, radius, kMaxPushes)) return pos;
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

CollisionGrid::CollisionGrid(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
CollisionGrid::CollisionGrid(CollisionGrid&&) noexcept = default;
CollisionGrid& CollisionGrid::operator=(CollisionGrid&&) noexcept = default;
CollisionGrid::~CollisionGrid() = default;

Result<CollisionGrid> CollisionGrid::load(std::span<const uint8_t> bytes) {
  using sdf_format::kHeaderSize;
  const auto corrupt = [](const std::string& what) {
    return Status::corruption("sdf section: " + what);
  };
  if (bytes.size() < kHeaderSize) {
    return corrupt("truncated header (" + std::to_string(bytes.size()) + " bytes)");
  }
  if (std::memcmp(bytes.data(), sdf_format::kMagic.data(), sdf_format::kMagic.size()) != 0) {
    return corrupt("bad magic");
  }
  const uint32_t version = store::get_u32(bytes.data() + 4);
  if (version == 0) return corrupt("bad version 0");
  if (version > sdf_format::kVersion) {
    return Status::unsupported("sdf section: version " + std::to_string(version) +
                               " is newer than this reader (" +
                               std::to_string(sdf_format::kVersion) + ")");
  }
  const uint64_t size = store::get_u64(bytes.data() + 8);
  if (size != bytes.size() - kHeaderSize) {
    return corrupt("payload size " + std::to_string(size) + " but " +
                   std::to_string(bytes.size() - kHeaderSize) + " bytes follow the header");
  }
  const std::span<const uint8_t> payload = bytes.subspan(kHeaderSize);
  if (store::checksum(payload) != store::get_u64(bytes.data() + 16)) {
    return corrupt("checksum mismatch");
  }

  ensure_openvdb_initialized();
  auto impl = std::make_unique<Impl>();
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
    if (!grid) return corrupt(std::string("no float grid named ") + sdf_format::kGridName);
    const auto voxel_meta = grid->getMetadata<openvdb::DoubleMetadata>(sdf_format::kMetaVoxelSize);
    const auto band_meta = grid->getMetadata<openvdb::Int32Metadata>(sdf_format::kMetaBandVoxels);
    const auto kind_meta = grid->getMetadata<openvdb::StringMetadata>(sdf_format::kMetaDistance);
    if (!voxel_meta || !band_meta || !kind_meta) return corrupt("grid metadata missing");
    if (kind_meta->value() != "unsigned") return corrupt("distance kind is not \"unsigned\"");
    const double voxel = voxel_meta->value();
    const int band = band_meta->value();
    if (!(voxel > 0.0) || !std::isfinite(voxel) || band < 1 || band > 1000) {
      return corrupt("bad voxel size or band width");
    }
    const openvdb::math::Transform& xform = grid->transform();
    if (!xform.isLinear() || !xform.hasUniformScale() ||
        std::abs(xform.voxelSize()[0] - voxel) > 1e-9 * voxel) {
      return corrupt("grid transform disagrees with its voxel size");
    }
    impl->voxel = voxel;
    impl->band = band;
    impl->far = band * voxel;
    if (std::abs(double(grid->background()) - impl->far) > 1e-4 * impl->far) {
      return corrupt("grid background is not the band width");
    }
    impl->grid = grid;
  } catch (const std::exception& e) {
    return corrupt(std::string("OpenVDB: ") + e.what());
  } catch (...) {
    return corrupt("OpenVDB: unknown exception");
  }
  return CollisionGrid(std::move(impl));
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
  ConstAccessor acc(impl_->grid->tree());
  return impl_->sample(acc, p);
}

Vec3 CollisionGrid::gradient(const Vec3& p) const {
  impl_->queries.fetch_add(1, std::memory_order_relaxed);
  ConstAccessor acc(impl_->grid->tree());
  return impl_->gradient(acc, p);
}

Vec3 CollisionGrid::resolve(const Vec3& from, const Vec3& to, double radius) const {
  impl_->queries.fetch_add(1, std::memory_order_relaxed);
  assert(check_radius(radius).is_ok());
  // Largest double below the band width: the clamp keeps release builds inside the contract.
  radius = std::clamp(radius, impl_->voxel, std::nextafter(impl_->far, 0.0));
  return impl_->resolve(from, to, radius);
}

uint64_t CollisionGrid::queries() const { return impl_->queries.load(std::memory_order_relaxed); }

uint64_t CollisionGrid::active_voxels() const { return impl_->grid->activeVoxelCount(); }

uint64_t CollisionGrid::memory_bytes() const { return impl_->grid->memUsage(); }

Aabb CollisionGrid::bounds() const {
  const openvdb::CoordBBox box = impl_->grid->evalActiveVoxelBoundingBox();
  if (box.empty()) return Aabb();
  const openvdb::BBoxd world = impl_->grid->transform().indexToWorld(box);
  return Aabb(Vec3(world.min().x(), world.min().y(), world.min().z()),
              Vec3(world.max().x(), world.max().y(), world.max().z()));
}

}  // namespace frontier
