// Voxel shells around triangle soups (contract in proxy_shell.h).
#include "src/lod/proxy_shell.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <unordered_map>

namespace frontier {
namespace {

constexpr float kBandVoxels = 2.0f;  // the distance field is exact this far out (in voxels; > the 1-voxel iso)
constexpr int kPadVoxels = 2;        // the dense region reaches this far beyond the input's box

}  // namespace

VoxelShell voxel_shell(std::span<const Vec3> positions, std::span<const uint32_t> indices, int resolution,
                       const Aabb* region, const std::optional<Lattice>& lattice) {
  VoxelShell shell;
  if (indices.size() < 3 || positions.empty()) return shell;
  Aabb box;
  for (const Vec3& p : positions) box.extend(p);
  const Vec3 extent = box.extent();
  const double longest = std::max({extent.x, extent.y, extent.z});
  if (!(longest > 0.0) || !std::isfinite(longest)) return shell;
  const double voxel = longest / std::max(resolution, 4);
  const Vec3 centre = box.center();

  // OpenVDB works in floats: the input relative to its centre keeps its precision far from the origin.
  std::vector<openvdb::Vec3s> points(positions.size());
  for (size_t v = 0; v < positions.size(); ++v) {
    const Vec3 d = positions[v] - centre;
    points[v] = openvdb::Vec3s(static_cast<float>(d.x), static_cast<float>(d.y), static_cast<float>(d.z));
  }
  std::vector<openvdb::Vec3I> triangles(indices.size() / 3);
  for (size_t t = 0; t < triangles.size(); ++t) {
    triangles[t] = openvdb::Vec3I(indices[3 * t], indices[3 * t + 1], indices[3 * t + 2]);
  }
  const openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(voxel);
  const openvdb::FloatGrid::Ptr distance = openvdb::tools::meshToUnsignedDistanceField<openvdb::FloatGrid>(
      *xform, points, triangles, std::vector<openvdb::Vec4I>(), kBandVoxels);
  if (!distance) return shell;

  // The dense region: the input's box in index space, padded so its faces lie outside.
  const Vec3 lo = (box.lo - centre) / voxel, hi = (box.hi - centre) / voxel;
  const openvdb::CoordBBox dense_box(
      openvdb::Coord(static_cast<int>(std::floor(lo.x)) - kPadVoxels, static_cast<int>(std::floor(lo.y)) - kPadVoxels,
                     static_cast<int>(std::floor(lo.z)) - kPadVoxels),
      openvdb::Coord(static_cast<int>(std::ceil(hi.x)) + kPadVoxels, static_cast<int>(std::ceil(hi.y)) + kPadVoxels,
                     static_cast<int>(std::ceil(hi.z)) + kPadVoxels));
  openvdb::tools::Dense<float, openvdb::tools::LayoutZYX> field(dense_box);
  openvdb::tools::copyToDense(*distance, field);
  const openvdb::Coord dim = dense_box.dim();
  const size_t count = field.valueCount();
  const size_t sx = field.xStride(), sy = field.yStride(), sz = field.zStride();
  float* value = field.data();

  // Outside: voxels farther than `iso` from the input that a path of such voxels joins to the
  // region's faces (6-connected flood from every face voxel).
  const float iso = static_cast<float>(voxel);
  std::vector<uint8_t> outside(count, 0);
  std::vector<uint32_t> queue;
  auto visit = [&](size_t i) {
    if (!outside[i] && value[i] > iso) {
      outside[i] = 1;
      queue.push_back(static_cast<uint32_t>(i));
    }
  };
  for (int x = 0; x < dim.x(); ++x) {
    for (int y = 0; y < dim.y(); ++y) {
      for (int z = 0; z < dim.z(); ++z) {
        if (x == 0 || y == 0 || z == 0 || x == dim.x() - 1 || y == dim.y() - 1 || z == dim.z() - 1) {
          visit(x * sx + y * sy + z * sz);
        }
      }
    }
  }
  while (!queue.empty()) {
    const size_t i = queue.back();
    queue.pop_back();
    const int x = static_cast<int>(i / sx), y = static_cast<int>((i / sy) % dim.y()), z = static_cast<int>(i % dim.z());
    if (x > 0) visit(i - sx);
    if (x + 1 < dim.x()) visit(i + sx);
    if (y > 0) visit(i - sy);
    if (y + 1 < dim.y()) visit(i + sy);
    if (z > 0) visit(i - sz);
    if (z + 1 < dim.z()) visit(i + sz);
  }

  // The field the shell is the zero set of: distance - iso outside, at most 0 inside (closed
  // cavities a constant -voxel, so they draw no surface).
  const float background = 2.0f * iso;
  for (size_t i = 0; i < count; ++i) {
    if (outside[i]) {
      value[i] = std::min(value[i] - iso, background);
    } else {
      value[i] = value[i] > iso ? -iso : value[i] - iso;
    }
  }
  const openvdb::FloatGrid::Ptr solid = openvdb::FloatGrid::create(background);
  solid->setTransform(xform);
  openvdb::tools::copyFromDense(field, *solid, 0.0f);

  std::vector<openvdb::Vec3s> shell_points;
  std::vector<openvdb::Vec3I> shell_triangles;
  std::vector<openvdb::Vec4I> shell_quads;
  openvdb::tools::volumeToMesh(*solid, shell_points, shell_triangles, shell_quads, 0.0, 0.0);

  // Welded by exact (snapped) position; corners that snap together drop their triangle. Kept half
  // a lattice step inside the region, so that snapping cannot carry a vertex out of it.
  Vec3 keep_lo(0.0), keep_hi(0.0);
  if (region != nullptr) {
    const Vec3 margin = glm::min(Vec3(lattice ? 0.5 * lattice->step : 0.0), 0.5 * region->extent());
    keep_lo = region->lo + margin;
    keep_hi = region->hi - margin;
  }
  std::unordered_map<Vec3, uint32_t, ExactPositionHash> welded;
  std::vector<uint32_t> remap(shell_points.size());
  for (size_t v = 0; v < shell_points.size(); ++v) {
    Vec3 p = centre + Vec3(shell_points[v].x(), shell_points[v].y(), shell_points[v].z());
    if (region != nullptr) p = glm::clamp(p, keep_lo, keep_hi);
    if (lattice) p = lattice->snap(p);
    auto [it, fresh] = welded.try_emplace(p, static_cast<uint32_t>(shell.positions.size()));
    if (fresh) shell.positions.push_back(p);
    remap[v] = it->second;
  }
  auto add = [&](uint32_t a, uint32_t b, uint32_t c) {
    a = remap[a], b = remap[b], c = remap[c];
    if (a == b || b == c || c == a) return;
    shell.indices.insert(shell.indices.end(), {a, b, c});
  };
  for (const openvdb::Vec3I& t : shell_triangles) add(t[0], t[1], t[2]);
  for (const openvdb::Vec4I& q : shell_quads) {
    add(q[0], q[1], q[2]);
    add(q[0], q[2], q[3]);
  }
  // Outward-facing: a closed surface around its inside has positive signed volume.
  double volume = 0.0;
  for (size_t i = 0; i < shell.indices.size(); i += 3) {
    const Vec3 a = shell.positions[shell.indices[i]] - centre, b = shell.positions[shell.indices[i + 1]] - centre,
               c = shell.positions[shell.indices[i + 2]] - centre;
    volume += glm::dot(a, glm::cross(b, c));
  }
  if (volume < 0.0) {
    for (size_t i = 0; i < shell.indices.size(); i += 3) std::swap(shell.indices[i + 1], shell.indices[i + 2]);
  }
  // Vertices no triangle kept are dropped (the contract: every position used).
  std::vector<uint32_t> used(shell.positions.size(), UINT32_MAX);
  std::vector<Vec3> kept;
  for (uint32_t& k : shell.indices) {
    if (used[k] == UINT32_MAX) {
      used[k] = static_cast<uint32_t>(kept.size());
      kept.push_back(shell.positions[k]);
    }
    k = used[k];
  }
  shell.positions = std::move(kept);
  shell.voxel = voxel;
  return shell;
}

}  // namespace frontier
