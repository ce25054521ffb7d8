// WalkableGridBuilder: per partition, turn every primitive into triangles (tessellating other
// shapes) and rasterize each triangle's exact distance into the voxels of its narrow band that lie
// in the partition's padded region, keeping the minimum per voxel in the one accumulated grid.
//
// Exact rather than openvdb::tools::meshToUnsignedDistanceField: see walkable_grid.h. Each
// triangle costs a column of at most 2 sqrt(3) band + 1 voxels per band voxel it owns.
#include "preprocess/walkable_grid.h"

#include "src/core/byte_io.h"
#include "src/walk/collision_grid.h"
#include "src/core/tessellate.h"
#include "store/page_format.h"

#include <openvdb/openvdb.h>
#include <openvdb/io/Stream.h>

#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <map>
#include <cmath>
#include <exception>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>

namespace frontier {

namespace {

constexpr double kMaxIndex = double(1 << 30);  // voxels from the origin: Coord is int32
struct IndexTriangle {
  Vec3 a, b, c;
};

using Accessor = openvdb::tree::ValueAccessor<openvdb::FloatTree>;

// One slab's voxels of one brick, as leaf records in the spill file.
struct Chunk {
  uint64_t offset;
  uint64_t size;
};
using BrickKey = std::array<int32_t, 3>;

// Leaf records: origin i32 x 3 | active mask u64 x 8 | the active values in mask order (float).
void put_leaf(std::vector<uint8_t>& out, const openvdb::FloatTree::LeafNodeType& leaf) {
  const auto put = [&](const void* p, size_t n) {
    const auto* b = static_cast<const uint8_t*>(p);
    out.insert(out.end(), b, b + n);
  };
  const openvdb::Coord o = leaf.origin();
  const int32_t origin[3] = {o.x(), o.y(), o.z()};
  put(origin, sizeof origin);
  const auto& mask = leaf.getValueMask();
  for (openvdb::Index w = 0; w < openvdb::FloatTree::LeafNodeType::NodeMaskType::WORD_COUNT; ++w) {
    const uint64_t word = mask.getWord<uint64_t>(w);
    put(&word, sizeof word);
  }
  for (auto v = leaf.cbeginValueOn(); v; ++v) {
    const float value = *v;
    put(&value, sizeof value);
  }
}

}  // namespace

struct WalkableGridBuilder::Impl {
  double voxel;
  int band;
  float far;  // band * voxel, the background
  openvdb::math::Transform::Ptr xform;  // index -> world
  bool have_origin = false;
  // The lattice origin in voxels (integers): index coordinates are p / h - origin_index, which is
  // exact in the subtraction, so every partition (whichever came first) computes bit-identical
  // distances for a voxel.
  Vec3 origin_index{0.0};
  Stats stats;

  // The spill: every slab's band, cut by brick, appended as it is rasterized; the index says where
  // each brick's pieces are. An unlinked temporary file: it vanishes with the process.
  std::FILE* spill = nullptr;
  uint64_t spill_size = 0;
  std::map<BrickKey, std::vector<Chunk>> index;
  Status spill_error;
  uint64_t finished_active = 0;  // active voxels of the last finish()
  uint64_t peak_brick_bytes = 0;

  // Per partition: the voxels it may write and its triangles, in index space (voxel centres at
  // integer points), gathered first so that slabs of the write box can be filled in parallel.
  openvdb::CoordBBox write;
  std::vector<IndexTriangle> tris;

  Impl(double voxel_size, int band_voxels, const std::string& spill_dir)
      : voxel(voxel_size), band(band_voxels), far(float(band_voxels * voxel_size)) {
    ensure_openvdb_initialized();
    xform = openvdb::math::Transform::createLinearTransform(voxel);
    if (spill_dir.empty()) {
      spill = std::tmpfile();
    } else {
      std::string name = spill_dir + "/sdf-spill-XXXXXX";
      const int fd = ::mkstemp(name.data());
      if (fd >= 0) {
        ::unlink(name.c_str());
        spill = ::fdopen(fd, "w+b");
        if (spill == nullptr) ::close(fd);
      }
    }
    if (spill == nullptr) {
      spill_error = Status::io_error("walkable grid: cannot create a spill file in " +
                                     (spill_dir.empty() ? std::string("the temporary directory") : spill_dir) +
                                     ": " + std::strerror(errno));
    }
  }
  ~Impl() {
    if (spill != nullptr) std::fclose(spill);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  void set_origin(const Vec3& center) {
    origin_index = glm::round(center / voxel);
    const Vec3 origin = origin_index * voxel;
    have_origin = true;
    xform = openvdb::math::Transform::createLinearTransform(voxel);
    xform->postTranslate(openvdb::Vec3d(origin.x, origin.y, origin.z));
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
          const double d = point_triangle_distance(Vec3(ijk.x(), ijk.y(), ijk.z()), a, b, c);
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

  // Appends a slab's tree to the spill, one chunk per brick it touches.
  // REQUIRES: the caller holds the lock.
  void spill_slab(const std::map<BrickKey, std::vector<uint8_t>>& pieces) {
    for (const auto& [key, bytes] : pieces) {
      if (!spill_error.is_ok()) return;
      if (std::fwrite(bytes.data(), 1, bytes.size(), spill) != bytes.size()) {
        spill_error = Status::io_error(std::string("walkable grid: writing the spill file failed: ") +
                                       std::strerror(errno));
        return;
      }
      index[key].push_back(Chunk{spill_size, bytes.size()});
      spill_size += bytes.size();
    }
  }

  // A slab's leaves as leaf records, grouped by the brick each leaf lies in.
  static std::map<BrickKey, std::vector<uint8_t>> cut_into_bricks(const openvdb::FloatTree& slab) {
    std::map<BrickKey, std::vector<uint8_t>> pieces;
    using sdf_format::kBrickLog2;
    for (auto leaf = slab.cbeginLeaf(); leaf; ++leaf) {
      const openvdb::Coord o = leaf->origin();
      put_leaf(pieces[BrickKey{o.x() >> kBrickLog2, o.y() >> kBrickLog2, o.z() >> kBrickLog2}], *leaf);
    }
    return pieces;
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
      openvdb::FloatTree local(far);
      Accessor out(local);
      uint64_t written = 0;
      for (uint32_t i : buckets[size_t(s)]) written += rasterize(tris[i], box, out);
      const std::map<BrickKey, std::vector<uint8_t>> pieces = cut_into_bricks(local);
      const std::lock_guard<std::mutex> lock(merge_lock);
      spill_slab(pieces);
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
    if (!spill_error.is_ok()) return spill_error;
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
    std::vector<IndexTriangle>().swap(tris);  // only the spilled band survives the partition
    return spill_error;
  }

  // Reads brick `key`'s chunks back and merges them by minimum into one tree.
  Status assemble(const std::vector<Chunk>& pieces, openvdb::FloatTree& tree) const {
    using LeafT = openvdb::FloatTree::LeafNodeType;
    constexpr size_t kWords = LeafT::NodeMaskType::WORD_COUNT;
    std::vector<uint8_t> buf;
    for (const Chunk& c : pieces) {
      buf.resize(c.size);
      size_t done = 0;
      while (done < c.size) {
        const ssize_t n = ::pread(::fileno(spill), buf.data() + done, c.size - done, off_t(c.offset + done));
        if (n <= 0) {
          return Status::io_error(std::string("walkable grid: reading the spill file failed: ") +
                                  (n < 0 ? std::strerror(errno) : "unexpected end"));
        }
        done += size_t(n);
      }
      size_t at = 0;
      while (at < buf.size()) {
        int32_t origin[3];
        uint64_t words[kWords];
        assert(at + sizeof origin + sizeof words <= buf.size());
        std::memcpy(origin, buf.data() + at, sizeof origin);
        std::memcpy(words, buf.data() + at + sizeof origin, sizeof words);
        at += sizeof origin + sizeof words;
        LeafT* leaf = tree.touchLeaf(openvdb::Coord(origin[0], origin[1], origin[2]));
        for (size_t w = 0; w < kWords; ++w) {
          for (uint64_t bits = words[w]; bits != 0; bits &= bits - 1) {
            const openvdb::Index i = openvdb::Index(64 * w + size_t(std::countr_zero(bits)));
            float v;
            assert(at + sizeof v <= buf.size());
            std::memcpy(&v, buf.data() + at, sizeof v);
            at += sizeof v;
            if (!leaf->isValueOn(i) || v < leaf->getValue(i)) leaf->setValueOn(i, v);
          }
        }
      }
    }
    return Status::ok();
  }

  // One brick's tree as an OpenVDB stream (zip), deterministic bytes.
  std::vector<uint8_t> brick_stream(openvdb::FloatTree::Ptr tree) const {
    openvdb::FloatGrid::Ptr grid = openvdb::FloatGrid::create(tree);
    grid->setName(sdf_format::kGridName);
    grid->setGridClass(openvdb::GRID_UNKNOWN);  // not a level set: the distance is unsigned
    grid->setTransform(xform->copy());
    std::ostringstream out(std::ios::binary);
    openvdb::io::Stream stream(out);
    stream.setCompression(openvdb::io::COMPRESS_ZIP | openvdb::io::COMPRESS_ACTIVE_MASK);
    stream.write(openvdb::GridCPtrVec{grid});
    std::string bytes = std::move(out).str();
    // The archive header carries a random UUID per write; the nil UUID instead makes the same
    // model give byte-identical pages (OpenVDB uses it only to recognise reopened files).
    const std::string tag = stream.getUniqueTag();
    const size_t at = bytes.find(tag);
    if (!tag.empty() && at != std::string::npos && at < 64) {
      bytes.replace(at, tag.size(), "00000000-0000-0000-0000-000000000000");
    }
    return std::vector<uint8_t>(bytes.begin(), bytes.end());
  }

  Result<std::vector<uint8_t>> finish(const BrickSink& sink) {
    if (!spill_error.is_ok()) return spill_error;
    if (std::fflush(spill) != 0) {
      return Status::io_error(std::string("walkable grid: writing the spill file failed: ") + std::strerror(errno));
    }
    // Bricks are assembled and compressed in parallel, a few at a time, and handed to the sink
    // in coordinate order.
    struct Brick {
      const BrickKey* key = nullptr;
      const std::vector<Chunk>* pieces = nullptr;
      Status status;
      std::vector<uint8_t> stream;
      uint64_t count = 0, bytes = 0;
      openvdb::CoordBBox box;
    };
    using BrickPtr = std::shared_ptr<Brick>;
    const size_t in_flight = 2 * size_t(std::max(1u, std::thread::hardware_concurrency()));
    std::vector<uint8_t> table;
    uint64_t bricks = 0, active = 0;
    Status failed;
    auto next = index.begin();
    tbb::parallel_pipeline(
        in_flight,
        tbb::make_filter<void, BrickPtr>(tbb::filter_mode::serial_in_order,
                                         [&](tbb::flow_control& fc) -> BrickPtr {
                                           if (next == index.end() || !failed.is_ok()) {
                                             fc.stop();
                                             return nullptr;
                                           }
                                           auto b = std::make_shared<Brick>();
                                           b->key = &next->first;
                                           b->pieces = &next->second;
                                           ++next;
                                           return b;
                                         }) &
            tbb::make_filter<BrickPtr, BrickPtr>(tbb::filter_mode::parallel,
                                                 [&](BrickPtr b) {
                                                   try {
                                                     auto tree = std::make_shared<openvdb::FloatTree>(far);
                                                     b->status = assemble(*b->pieces, *tree);
                                                     if (!b->status.is_ok()) return b;
                                                     tree->prune();
                                                     b->count = tree->activeVoxelCount();
                                                     if (b->count == 0) return b;
                                                     tree->evalActiveVoxelBoundingBox(b->box);
                                                     b->bytes = tree->memUsage();
                                                     b->stream = brick_stream(tree);
                                                   } catch (const std::exception& e) {
                                                     b->status = Status::invalid_argument(
                                                         std::string("walkable grid: OpenVDB: ") + e.what());
                                                   }
                                                   return b;
                                                 }) &
            tbb::make_filter<BrickPtr, void>(tbb::filter_mode::serial_in_order, [&](BrickPtr b) {
              if (!failed.is_ok()) return;
              if (!b->status.is_ok()) {
                failed = b->status;
                return;
              }
              if (b->count == 0) return;
              peak_brick_bytes = std::max(peak_brick_bytes, b->bytes);
              auto page = sink(std::move(b->stream));
              if (!page) {
                failed = page.status();
                return;
              }
              const BrickKey& key = *b->key;
              store::ByteWriter entry(table);
              for (int32_t v : {key[0], key[1], key[2], b->box.min().x(), b->box.min().y(), b->box.min().z(),
                                b->box.max().x(), b->box.max().y(), b->box.max().z()}) {
                entry.u32(uint32_t(v));
              }
              entry.u64(*page);
              entry.u64(b->count);
              ++bricks;
              active += b->count;
            }));
    if (!failed.is_ok()) return failed;
    std::vector<uint8_t> payload;
    GeometryWriter w(payload);
    w.f64(voxel);
    w.u32(uint32_t(band));
    w.u32(uint32_t(sdf_format::kBrickVoxels));
    for (int a = 0; a < 3; ++a) w.u64(uint64_t(int64_t(origin_index[a])));
    w.u64(bricks);
    w.u64(active);
    w.bytes(table);
    finished_active = active;
    return sdf_format::frame(payload);
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

WalkableGridBuilder::WalkableGridBuilder(double voxel_size, int band_voxels, const std::string& spill_dir) {
  assert(check_options(voxel_size, band_voxels).is_ok());
  impl_ = std::make_unique<Impl>(voxel_size, band_voxels, spill_dir);
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

Result<std::vector<uint8_t>> WalkableGridBuilder::finish(const BrickSink& sink) {
  try {
    return impl_->finish(sink);
  } catch (const std::exception& e) {
    return Status::invalid_argument(std::string("walkable grid: OpenVDB: ") + e.what());
  }
}

Result<SdfImage> WalkableGridBuilder::finish() {
  SdfImage image;
  auto section = finish([&](std::vector<uint8_t> page) -> Result<uint64_t> {
    image.pages.push_back(store::encode_page(sdf_format::kBrickCodec, page));
    return uint64_t(image.pages.size() - 1);
  });
  if (!section) return section.status();
  image.section = std::move(*section);
  return image;
}

double WalkableGridBuilder::voxel_size() const { return impl_->voxel; }
int WalkableGridBuilder::band_voxels() const { return impl_->band; }
const WalkableGridBuilder::Stats& WalkableGridBuilder::stats() const { return impl_->stats; }
uint64_t WalkableGridBuilder::active_voxels() const { return impl_->finished_active; }
uint64_t WalkableGridBuilder::memory_bytes() const {
  // The spill index (a map node per brick, a chunk record per piece) and the largest brick.
  // finish() holds up to two bricks per hardware thread at once.
  const uint64_t in_flight = 2 * uint64_t(std::max(1u, std::thread::hardware_concurrency()));
  uint64_t chunks = 0;
  for (const auto& [key, pieces] : impl_->index) chunks += pieces.size();
  return impl_->index.size() * 96 + chunks * sizeof(Chunk) + in_flight * impl_->peak_brick_bytes;
}
uint64_t WalkableGridBuilder::spill_bytes() const { return impl_->spill_size; }

}  // namespace frontier
