// WalkableGridBuilder: per partition, turn every primitive into triangles (tessellating other
// shapes) and rasterize each triangle's exact distance into the voxels of its narrow band that lie
// in the partition's padded region, keeping the minimum per voxel in the one accumulated grid.
//
// Exact rather than openvdb::tools::meshToUnsignedDistanceField: see walkable_grid.h. Each
// triangle costs a column of at most 2 sqrt(3) band + 1 voxels per band voxel it owns.
#include "preprocess/walkable_grid.h"

#include "src/collision_grid.h"
#include "src/tessellate.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <exception>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>

namespace frontier {

namespace {

constexpr double kMaxIndex = double(1 << 30);  // voxels from the origin: Coord is int32
double segment_distance(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = glm::dot(ab, ab);
  const double t = len2 > 0.0 ? std::clamp(glm::dot(p - a, ab) / len2, 0.0, 1.0) : 0.0;
  return glm::length(p - (a + t * ab));
}

// Exact distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5), robust
// to degenerate triangles (they fall back to their edges).
double triangle_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0.0 && d2 <= 0.0) return glm::length(ap);
  const Vec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0.0 && d4 <= d3) return glm::length(bp);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return glm::length(ap - (d1 / (d1 - d3)) * ab);
  const Vec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0.0 && d5 <= d6) return glm::length(cp);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return glm::length(ap - (d2 / (d2 - d6)) * ac);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    return glm::length(bp - ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b));
  }
  const double sum = va + vb + vc;
  if (!(sum > 0.0)) {  // degenerate: no interior
    return std::min({segment_distance(p, a, b), segment_distance(p, b, c), segment_distance(p, c, a)});
  }
  return glm::length(ap - (vb / sum) * ab - (vc / sum) * ac);
}

struct IndexTriangle {
  Vec3 a, b, c;
};

using Accessor = openvdb::tree::ValueAccessor<openvdb::FloatTree>;

}  // namespace

struct WalkableGridBuilder::Impl {
  double voxel;
  int band;
  openvdb::FloatGrid::Ptr grid;  // the accumulated band, world transform
  bool have_origin = false;
  // The lattice origin in voxels (integers): index coordinates are p / h - origin_index, which is
  // exact in the subtraction, so every partition (whichever came first) computes bit-identical
  // distances for a voxel.
  Vec3 origin_index{0.0};
  Stats stats;

  // Per partition: the voxels it may write and its triangles, in index space (voxel centres at
  // integer points), gathered first so that slabs of the write box can be filled in parallel.
  openvdb::CoordBBox write;
  std::vector<IndexTriangle> tris;

  Impl(double voxel_size, int band_voxels) : voxel(voxel_size), band(band_voxels) {
    ensure_openvdb_initialized();
    grid = openvdb::FloatGrid::create(float(band * voxel));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(voxel));
  }

  void set_origin(const Vec3& center) {
    origin_index = glm::round(center / voxel);
    const Vec3 origin = origin_index * voxel;
    have_origin = true;
    openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(voxel);
    xform->postTranslate(openvdb::Vec3d(origin.x, origin.y, origin.z));
    grid->setTransform(xform);
  }

  // Voxels of `box` the band of triangle t can reach; false when there are none.
  bool band_range(const IndexTriangle& t, const openvdb::CoordBBox& box, int lo[3], int hi[3]) const {
    for (int k = 0; k < 3; ++k) {
      const double tlo = std::min({t.a[k], t.b[k], t.c[k]}) - band;
      const double thi = std::max({t.a[k], t.b[k], t.c[k]}) + band;
      // Clamped before converting, so a triangle far outside never overflows an int.
      const double wlo = box.min()[k] - 1.0, whi = box.max()[k] + 1.0;
      lo[k] = std::max(box.min()[k], int(std::ceil(std::clamp(tlo, wlo, whi))));
      hi[k] = std::min(box.max()[k], int(std::floor(std::clamp(thi, wlo, whi))));
      if (lo[k] > hi[k]) return false;
    }
    return true;
  }

  void add_triangle(const Vec3& aw, const Vec3& bw, const Vec3& cw) {
    const IndexTriangle t{aw / voxel - origin_index, bw / voxel - origin_index,
                          cw / voxel - origin_index};
    int lo[3], hi[3];
    if (band_range(t, write, lo, hi)) tris.push_back(t);
  }

  // Writes the exact distance to t (in voxels, stored in world units) into every voxel of `box`
  // closer than the band, keeping the minimum. The triangle's plane is walked along its dominant
  // normal axis, so each (u, v) column visits only the 2 band / |n_axis| <= 2 sqrt(3) band
  // voxels that can lie within the band of the plane. Returns the voxels written.
  uint64_t rasterize(const IndexTriangle& t, const openvdb::CoordBBox& box, Accessor& out) const {
    int lo[3], hi[3];
    if (!band_range(t, box, lo, hi)) return 0;
    const Vec3 &a = t.a, &b = t.b, &c = t.c;
    // Any unit vector orthogonal to the triangle's plane bounds the band as a slab; for a
    // degenerate triangle (a segment or a point) any plane through it will do.
    Vec3 n = glm::cross(b - a, c - a);
    if (!(glm::dot(n, n) > 1e-24)) {
      Vec3 e = b - a;
      if (glm::dot(c - a, c - a) > glm::dot(e, e)) e = c - a;
      if (glm::dot(c - b, c - b) > glm::dot(e, e)) e = c - b;
      n = glm::dot(e, e) > 0.0
              ? glm::cross(e, std::abs(e.x) < std::abs(e.y) ? Vec3(1, 0, 0) : Vec3(0, 1, 0))
              : Vec3(0, 0, 1);
    }
    n = glm::normalize(n);
    int ax = 0;
    if (std::abs(n.y) > std::abs(n[ax])) ax = 1;
    if (std::abs(n.z) > std::abs(n[ax])) ax = 2;
    const int u = (ax + 1) % 3, v = (ax + 2) % 3;
    const double half = band / std::abs(n[ax]);
    uint64_t written = 0;
    openvdb::Coord ijk;
    for (int iu = lo[u]; iu <= hi[u]; ++iu) {
      for (int iv = lo[v]; iv <= hi[v]; ++iv) {
        // The plane's coordinate along ax above (iu, iv).
        const double on_plane = a[ax] - (n[u] * (iu - a[u]) + n[v] * (iv - a[v])) / n[ax];
        const int a0 = std::max(lo[ax], int(std::ceil(on_plane - half)));
        const int a1 = std::min(hi[ax], int(std::floor(on_plane + half)));
        ijk[u] = iu;
        ijk[v] = iv;
        for (int ia = a0; ia <= a1; ++ia) {
          ijk[ax] = ia;
          const double d = triangle_distance(Vec3(ijk.x(), ijk.y(), ijk.z()), a, b, c);
          if (!(d < band)) continue;
          const float value = float(d * voxel);
          float old;
          if (!out.probeValue(ijk, old) || value < old) out.setValue(ijk, value);
          ++written;
        }
      }
    }
    return written;
  }

  // Min-merges a slab's tree into the accumulated band. REQUIRES: the caller holds the lock.
  void merge(const openvdb::FloatTree& slab) {
    openvdb::FloatTree& dst_tree = grid->tree();
    for (auto leaf = slab.cbeginLeaf(); leaf; ++leaf) {
      openvdb::FloatTree::LeafNodeType* dst = dst_tree.touchLeaf(leaf->origin());
      for (auto v = leaf->cbeginValueOn(); v; ++v) {
        const openvdb::Index i = v.pos();
        if (!dst->isValueOn(i) || *v < dst->getValue(i)) dst->setValueOn(i, *v);
      }
    }
  }

  // Fills the write box slab by slab (leaf-aligned along its longest axis), in parallel; each
  // slab is rasterized into its own tree and merged as soon as it is done, so the extra memory
  // is a few slabs' worth of band.
  void rasterize_all() {
    const openvdb::Coord dim = write.dim();
    int axis = 0;
    if (dim[1] > dim[axis]) axis = 1;
    if (dim[2] > dim[axis]) axis = 2;
    constexpr int kLeaf = int(openvdb::FloatTree::LeafNodeType::DIM);
    const int first = write.min()[axis] & ~(kLeaf - 1);
    const int leaves = (write.max()[axis] - first) / kLeaf + 1;
    const int slabs = std::min(leaves, 16 * int(std::max(1u, std::thread::hardware_concurrency())));
    // Slab s covers [start[s], start[s + 1]) along the axis, whole leaves each.
    std::vector<double> start(static_cast<size_t>(slabs) + 1);
    for (int i = 0; i <= slabs; ++i) {
      start[size_t(i)] = first + double(kLeaf) * double((int64_t(i) * leaves) / slabs);
    }
    const auto slab_of = [&](double coord) {
      const auto it = std::upper_bound(start.begin() + 1, start.end() - 1, coord);
      return int(it - start.begin()) - 1;
    };
    std::vector<std::vector<uint32_t>> buckets(static_cast<size_t>(slabs));
    for (uint32_t i = 0; i < tris.size(); ++i) {
      const IndexTriangle& t = tris[i];
      const int s0 = slab_of(std::min({t.a[axis], t.b[axis], t.c[axis]}) - band);
      const int s1 = slab_of(std::max({t.a[axis], t.b[axis], t.c[axis]}) + band);
      for (int s = s0; s <= s1; ++s) buckets[size_t(s)].push_back(i);
    }
    std::mutex merge_lock;
    tbb::parallel_for(0, slabs, [&](int s) {
      if (buckets[size_t(s)].empty()) return;
      openvdb::CoordBBox box = write;
      box.min()[axis] = std::max(write.min()[axis], int(start[size_t(s)]));
      box.max()[axis] = std::min(write.max()[axis], int(start[size_t(s) + 1]) - 1);
      if (box.empty()) return;
      openvdb::FloatTree local(grid->background());
      Accessor out(local);
      uint64_t written = 0;
      for (uint32_t i : buckets[size_t(s)]) written += rasterize(tris[i], box, out);
      const std::lock_guard<std::mutex> lock(merge_lock);
      merge(local);
      stats.voxels_written += written;
    });
  }

  // Curved primitives become triangles within a chord error of h/16 (segments capped at 256);
  // quadrics become their bounding box surface (tessellate.h).
  Status gather(const Scene& part) {
    TessellateOptions options;
    options.max_chord_error = voxel / 16.0;
    options.min_segments = 6;
    options.max_segments = 256;
    std::vector<Triangle> mesh;
    for (uint32_t i = 0; i < part.size(); ++i) {
      if (part.prims[i].kind == PrimKind::Quadric) ++stats.quadrics_as_boxes;
      mesh.clear();
      tessellate_primitive(mesh, nullptr, part, i, options);
      for (const Triangle& t : mesh) add_triangle(t.v0, t.v1, t.v2);
    }
    return Status::ok();
  }

  // Index-space box of voxel centres lying in the world box.
  openvdb::CoordBBox index_box(const Aabb& world) const {
    const Vec3 lo = glm::ceil(world.lo / voxel - origin_index);
    const Vec3 hi = glm::floor(world.hi / voxel - origin_index);
    return openvdb::CoordBBox(openvdb::Coord(int(lo.x), int(lo.y), int(lo.z)),
                              openvdb::Coord(int(hi.x), int(hi.y), int(hi.z)));
  }

  Status add_partition(const Scene& part, const Aabb& region) {
    ++stats.partitions;
    stats.primitives += part.size();
    for (int a = 0; a < 3; ++a) {
      if (std::isnan(region.lo[a]) || std::isnan(region.hi[a])) {
        return Status::invalid_argument("walkable grid: partition region has NaN bounds");
      }
    }
    if (part.size() == 0 || region.empty()) return Status::ok();

    // Where this partition may write: its region padded by the band, but no farther from its
    // content than the band either (regions may be unbounded).
    const double pad = (band + 1) * voxel;
    const Aabb content = part.bounds();
    Aabb write_world = region;
    write_world.lo -= Vec3(pad);
    write_world.hi += Vec3(pad);
    write_world = write_world.intersection(Aabb(content.lo - Vec3(pad), content.hi + Vec3(pad)));
    if (write_world.empty()) return Status::ok();
    for (int a = 0; a < 3; ++a) {
      if (!std::isfinite(write_world.lo[a]) || !std::isfinite(write_world.hi[a])) {
        return Status::invalid_argument("walkable grid: partition content is not finite");
      }
    }
    if (!have_origin) set_origin(write_world.center());
    const double reach = std::max(glm::length(write_world.lo / voxel - origin_index),
                                  glm::length(write_world.hi / voxel - origin_index));
    if (!(reach < kMaxIndex)) {
      return Status::invalid_argument(
          "walkable grid: the model spans more than 2^30 voxels of " + std::to_string(voxel) +
          " from its first partition; choose a larger voxel size");
    }
    write = index_box(write_world);
    if (write.empty()) return Status::ok();
    tris.clear();
    Status st = gather(part);
    if (!st.is_ok()) return st;
    stats.triangles_meshed += tris.size();
    rasterize_all();
    std::vector<IndexTriangle>().swap(tris);  // only the band survives the partition
    return Status::ok();
  }
};

Status WalkableGridBuilder::check_options(double voxel_size, int band_voxels) {
  if (!(voxel_size > 0.0) || !std::isfinite(voxel_size)) {
    return Status::invalid_argument("--voxel-size must be a positive number, not " +
                                    std::to_string(voxel_size));
  }
  if (band_voxels < 1 || band_voxels > 64) {
    return Status::invalid_argument("--band must be between 1 and 64 voxels, not " +
                                    std::to_string(band_voxels));
  }
  return Status::ok();
}

double WalkableGridBuilder::default_voxel_size(const Aabb& model_bounds) {
  // 10 cm: a walker's clearance (~0.25 m) spans a few voxels; 5 cm quadrupled the band's
  // memory (about 7 bytes per voxel) for no gain in collision accuracy that a walker notices.
  constexpr double kPreferred = 0.1;
  if (model_bounds.empty()) return kPreferred;
  const Vec3 e = model_bounds.extent();
  const double longest = std::max({e.x, e.y, e.z});
  if (!(longest > 0.0) || !std::isfinite(longest)) return kPreferred;
  return std::clamp(kPreferred, longest / 4096.0, longest / 256.0);
}

int WalkableGridBuilder::band_voxels_for_radius(double radius, double voxel_size) {
  assert(voxel_size > 0.0);
  if (!(radius > 0.0)) return kDefaultBandVoxels;
  int band = kDefaultBandVoxels;
  // A voxel of slack, so that the stopping distance reads real band values, not the far value.
  while (band < 64 && !(band * voxel_size >= radius + voxel_size * (1.0 - 1e-9))) ++band;
  return band;
}

WalkableGridBuilder::WalkableGridBuilder(double voxel_size, int band_voxels) {
  assert(check_options(voxel_size, band_voxels).is_ok());
  impl_ = std::make_unique<Impl>(voxel_size, band_voxels);
}
WalkableGridBuilder::WalkableGridBuilder(WalkableGridBuilder&&) noexcept = default;
WalkableGridBuilder& WalkableGridBuilder::operator=(WalkableGridBuilder&&) noexcept = default;
WalkableGridBuilder::~WalkableGridBuilder() = default;

Status WalkableGridBuilder::add_partition(const Scene& part, const Aabb& region) {
  try {
    return impl_->add_partition(part, region);
  } catch (const std::exception& e) {
    return Status::invalid_argument(std::string("walkable grid: OpenVDB: ") + e.what());
  }
}

Result<std::vector<uint8_t>> WalkableGridBuilder::finish() {
  try {
    openvdb::FloatGrid& grid = *impl_->grid;
    grid.tree().prune();
    grid.setName(sdf_format::kGridName);
    grid.setGridClass(openvdb::GRID_UNKNOWN);  // not a level set: the distance is unsigned
    grid.insertMeta(sdf_format::kMetaVoxelSize, openvdb::DoubleMetadata(impl_->voxel));
    grid.insertMeta(sdf_format::kMetaBandVoxels, openvdb::Int32Metadata(impl_->band));
    grid.insertMeta(sdf_format::kMetaDistance, openvdb::StringMetadata("unsigned"));
    std::ostringstream out(std::ios::binary);
    openvdb::io::Stream stream(out);
    stream.setCompression(openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
    stream.write(openvdb::GridCPtrVec{impl_->grid});
    std::string bytes = std::move(out).str();
    // The archive header carries a random UUID per write; the nil UUID instead makes the same
    // model give byte-identical sections (OpenVDB uses it only to recognise reopened files).
    const std::string tag = stream.getUniqueTag();
    const size_t at = bytes.find(tag);
    if (!tag.empty() && at != std::string::npos && at < 64) {
      bytes.replace(at, tag.size(), "00000000-0000-0000-0000-000000000000");
    }
    return sdf_format::frame(
        std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()));
  } catch (const std::exception& e) {
    return Status::invalid_argument(std::string("walkable grid: OpenVDB: ") + e.what());
  }
}

double WalkableGridBuilder::voxel_size() const { return impl_->voxel; }
int WalkableGridBuilder::band_voxels() const { return impl_->band; }
const WalkableGridBuilder::Stats& WalkableGridBuilder::stats() const { return impl_->stats; }
uint64_t WalkableGridBuilder::active_voxels() const { return impl_->grid->activeVoxelCount(); }
uint64_t WalkableGridBuilder::memory_bytes() const { return impl_->grid->memUsage(); }

}  // namespace frontier
