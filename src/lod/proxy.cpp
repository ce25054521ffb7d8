// Proxy meshes: leaf inputs, merges and meshoptimizer simplification with a measured bound
// (contracts and the bound's argument in proxy.h).
#include "src/lod/proxy.h"

#include "src/core/tessellate.h"
#include "src/lod/proxy_distance.h"
#include "src/lod/proxy_shell.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cfloat>
#include <cmath>
#include <unordered_map>
#include <unordered_set>

namespace frontier {
namespace {

struct TriangleKeyHash {
  size_t operator()(const std::array<uint32_t, 3>& k) const {
    return static_cast<size_t>((uint64_t{k[0]} * 0x9e3779b97f4a7c15ull) ^ (uint64_t{k[1]} * 0xc2b2ae3d27d4eb4full) ^
                               (uint64_t{k[2]} * 0x165667b19e3779f9ull));
  }
};

// Builds a ProxyMesh triangle by triangle: vertices welded by exact position, triangles with a
// repeated corner dropped, and (when asked) a triangle already added (same corners in the same
// cyclic order) dropped too.
class MeshWelder {
 public:
  explicit MeshWelder(ProxyMesh& out, size_t triangles_hint) : out_(out) {
    index_.reserve(triangles_hint);
    out_.positions.reserve(triangles_hint);
    out_.indices.reserve(3 * triangles_hint);
    out_.sources.reserve(triangles_hint);
    out_.materials.reserve(triangles_hint);
  }
  // False when the triangle was dropped (degenerate, or a duplicate with `dedupe`).
  bool add(const Vec3& a, const Vec3& b, const Vec3& c, uint32_t source, uint32_t material, bool dedupe) {
    std::array<uint32_t, 3> k = {vertex(a), vertex(b), vertex(c)};
    if (k[0] == k[1] || k[1] == k[2] || k[2] == k[0]) return false;
    if (dedupe) {
      std::array<uint32_t, 3> key = k;  // the smallest index first, orientation kept
      std::rotate(key.begin(), std::min_element(key.begin(), key.end()), key.end());
      if (!seen_.insert(key).second) return false;
    }
    out_.indices.insert(out_.indices.end(), k.begin(), k.end());
    out_.sources.push_back(source);
    out_.materials.push_back(material);
    return true;
  }

 private:
  uint32_t vertex(const Vec3& p) {
    auto [it, fresh] = index_.try_emplace(p, static_cast<uint32_t>(out_.positions.size()));
    if (fresh) out_.positions.push_back(p);
    return it->second;
  }
  ProxyMesh& out_;
  std::unordered_map<Vec3, uint32_t, ExactPositionHash> index_;
  std::unordered_set<std::array<uint32_t, 3>, TriangleKeyHash> seen_;
};

// The largest distance between a curved primitive and its tessellation `tris` (vertices on the
// surface, before snapping). Spheres: every triangle is inscribed, so the sphere's points behind
// it lie within r - sqrt(r^2 - rho^2) of its plane (rho its circumradius). Cones: the chord's
// sagitta at the larger radius. Boxes: exact. Quadrics (drawn as their bounding box surface): half
// the box's smallest extent, the farthest any point inside lies from its surface.
double tessellation_error(const Scene& scene, uint32_t i, const std::vector<Triangle>& tris, int segments) {
  const PrimRef& p = scene.prims[i];
  switch (p.kind) {
    case PrimKind::Sphere: {
      const double r = scene.spheres[p.index].radius;
      double worst = 0.0;
      for (const Triangle& t : tris) {
        const double a = glm::length(t.v1 - t.v0), b = glm::length(t.v2 - t.v1), c = glm::length(t.v0 - t.v2);
        const double area2 = glm::length(glm::cross(t.v1 - t.v0, t.v2 - t.v0));  // twice the area
        const double rho = area2 > 0.0 ? a * b * c / (2.0 * area2) : r;
        worst = std::max(worst, r - std::sqrt(std::max(0.0, r * r - rho * rho)));
      }
      return worst;
    }
    case PrimKind::Cone: {
      const Cone& c = scene.cones[p.index];
      return std::max(c.base_radius, c.apex_radius) * (1.0 - std::cos(M_PI / std::max(3, segments)));
    }
    case PrimKind::Quadric: {
      const Vec3 e = scene.prim_bounds(i).extent();
      return 0.5 * std::min({e.x, e.y, e.z});
    }
    default: return 0.0;
  }
}

// The shell proxy of `input` (proxy_shell.h) simplified towards `target` triangles, each triangle
// named after the input triangle nearest its centroid; empty when no shell could be made.
// `estimate`: the shell's offset from the input (one voxel, plus half a voxel's diagonal for
// where the grid places it) and meshoptimizer's error in simplifying it.
ProxyMesh shell_proxy(const ProxyMesh& input, const ProxyOptions& options, size_t target, const Aabb* region,
                      const TriangleBvh& input_bvh, double& estimate) {
  ProxyMesh out;
  VoxelShell shell = voxel_shell(input.positions, input.indices, options.shell_resolution, region, options.lattice);
  if (shell.indices.empty()) return out;
  Aabb box;
  for (const Vec3& p : shell.positions) box.extend(p);
  const Vec3 centre = box.center();
  std::vector<float> local(3 * shell.positions.size());
  for (size_t v = 0; v < shell.positions.size(); ++v) {
    for (int a = 0; a < 3; ++a) local[3 * v + a] = static_cast<float>(shell.positions[v][a] - centre[a]);
  }
  std::vector<uint32_t> kept(shell.indices.size());
  float error = 0.0f;
  size_t count = 0;
  if (shell.indices.size() > 3 * target) {
    count = meshopt_simplify(kept.data(), shell.indices.data(), shell.indices.size(), local.data(),
                             shell.positions.size(), 3 * sizeof(float), 3 * target, FLT_MAX, 0, &error);
  }
  if (count == 0) {  // already within the target, or nothing simplified it
    kept = shell.indices;
    count = kept.size();
    error = 0.0f;
  }
  estimate = shell.voxel * (1.0 + 0.5 * std::sqrt(3.0)) +
             static_cast<double>(error) *
                 static_cast<double>(meshopt_simplifyScale(local.data(), shell.positions.size(), 3 * sizeof(float)));
  MeshWelder weld(out, count / 3);
  for (size_t i = 0; i < count; i += 3) {
    const Vec3& a = shell.positions[kept[i]];
    const Vec3& b = shell.positions[kept[i + 1]];
    const Vec3& c = shell.positions[kept[i + 2]];
    const uint32_t t = input_bvh.nearest((a + b + c) / 3.0);
    weld.add(a, b, c, input.sources[t], input.materials[t], false);
  }
  return out;
}

// simplify_proxy tries a shell when its simplified mesh lies farther than this many shell voxels
// from the input.
constexpr double kShellTriggerVoxels = 6.0;
// With a ProxyMeasure, simplify_proxy measures the other methods too where its result's bound
// exceeds both this factor times its input's and this many shell voxels. (At 2, bounds could
// double at every level towards the root, and did: a 20 M terrain's root had 242 on a height
// range of 82; at 1.3 with the other candidates below, 60.)
constexpr double kAcceptGrowth = 1.3;
constexpr double kAcceptVoxels = 3.0;

}  // namespace

ProxyMesh proxy_input(const Scene& cell, const ProxyOptions& options) {
  ProxyMesh out;
  MeshWelder weld(out, cell.triangles.size());
  TessellateOptions tess;
  tess.segments = options.segments;
  tess.smooth_normals = false;
  std::vector<Triangle> tris;
  const double snap_error = options.lattice ? options.lattice->step * std::sqrt(3.0) * 0.5 : 0.0;
  for (uint32_t i = 0; i < cell.size(); ++i) {
    const PrimRef& p = cell.prims[i];
    if (p.kind == PrimKind::Triangle) {
      const Triangle& t = cell.triangles[p.index];
      out.subtree_triangles += weld.add(t.v0, t.v1, t.v2, p.source, p.material, false) ? 1 : 0;
      continue;
    }
    tris.clear();
    tessellate_primitive(tris, nullptr, cell, i, tess);
    double error = tessellation_error(cell, i, tris, options.segments);
    for (Triangle& t : tris) {
      if (options.lattice) t = {options.lattice->snap(t.v0), options.lattice->snap(t.v1), options.lattice->snap(t.v2)};
      out.subtree_triangles += weld.add(t.v0, t.v1, t.v2, p.source, p.material, false) ? 1 : 0;
    }
    if (options.lattice) error += snap_error;
    out.error = std::max(out.error, error);
    out.chord_error = out.error;
  }
  return out;
}

ProxyMesh merge_proxies(const ProxyMesh& lower, const ProxyMesh& upper) {
  const ProxyMesh* both[2] = {&lower, &upper};
  return merge_proxies(both);
}

ProxyMesh merge_proxies(std::span<const ProxyMesh* const> meshes) {
  ProxyMesh out;
  size_t triangles = 0;
  for (const ProxyMesh* m : meshes) triangles += m->triangle_count();
  MeshWelder weld(out, triangles);
  uint64_t dropped = 0, total = 0;
  const bool normals = std::any_of(meshes.begin(), meshes.end(), [](const ProxyMesh* m) { return !m->normals.empty(); });
  if (normals) out.normals.reserve(3 * triangles);
  for (const ProxyMesh* m : meshes) {
    for (size_t t = 0; t < m->triangle_count(); ++t) {
      const uint32_t* k = &m->indices[3 * t];
      const Vec3 &a = m->positions[k[0]], &b = m->positions[k[1]], &c = m->positions[k[2]];
      if (!weld.add(a, b, c, m->sources[t], m->materials[t], true)) {
        ++dropped;
        continue;
      }
      if (!normals) continue;
      if (!m->normals.empty()) {
        out.normals.insert(out.normals.end(), m->normals.begin() + std::ptrdiff_t(3 * t),
                           m->normals.begin() + std::ptrdiff_t(3 * t + 3));
      } else {
        const Vec3 n = glm::cross(b - a, c - a);
        const double len = glm::length(n);
        const Vec3 face = len > 0.0 ? n / len : Vec3(0.0, 0.0, 1.0);
        out.normals.insert(out.normals.end(), {face, face, face});
      }
    }
    out.error = std::max(out.error, m->error);
    out.chord_error = std::max(out.chord_error, m->chord_error);
    total += m->subtree_triangles;
  }
  out.subtree_triangles = total - std::min(total, dropped);
  return out;
}

namespace {
// The points where the proxy's side of the distance is sampled: its vertices, edge midpoints and
// centroids.
std::vector<Vec3> proxy_samples(const ProxyMesh& proxy) {
  std::vector<Vec3> out;
  out.reserve(proxy.positions.size() + 4 * proxy.triangle_count());
  out.insert(out.end(), proxy.positions.begin(), proxy.positions.end());
  for (size_t t = 0; t < proxy.triangle_count(); ++t) {
    const Vec3& a = proxy.positions[proxy.indices[3 * t]];
    const Vec3& b = proxy.positions[proxy.indices[3 * t + 1]];
    const Vec3& c = proxy.positions[proxy.indices[3 * t + 2]];
    out.insert(out.end(), {(a + b + c) / 3.0, 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)});
  }
  return out;
}

// measured_distance may exceed the true distance by this fraction of the input's diagonal (what
// it spends on triangles straddling the other mesh's creases and edges; proxy_distance.h).
constexpr double kMeasureSlack = 1e-3;

double measured_distance(const ProxyMesh& input, const TriangleBvh& input_bvh, const ProxyMesh& proxy) {
  const TriangleBvh proxy_bvh(proxy.positions, proxy.indices);
  Aabb box;
  for (const Vec3& p : input.positions) box.extend(p);
  const double slack = kMeasureSlack * glm::length(box.extent());
  const double input_side = farthest_triangle_point(input.positions, input.indices, proxy_bvh, 0.0, slack);
  return std::max(input_side, farthest_sample(proxy_samples(proxy), input_bvh));
}
}  // namespace

double measured_distance(const ProxyMesh& input, const ProxyMesh& proxy) {
  return measured_distance(input, TriangleBvh(input.positions, input.indices), proxy);
}

ProxyMesh simplify_proxy(const ProxyMesh& input, const ProxyOptions& options, ProxySimplifyStats* stats,
                         const Aabb* region, const ProxyMeasure* measure) {
  ProxySimplifyStats local;
  ProxySimplifyStats& st = stats != nullptr ? *stats : local;
  st = {};
  const size_t target = std::max<uint32_t>(options.target_triangles, 1);
  if (input.triangle_count() <= target) {
    st.kept_input = true;
    return input;
  }
  st.simplified = true;

  // meshoptimizer takes floats: positions relative to the mesh's centre keep their precision
  // far from the origin. Its output refers to the input's vertices, which stay exact doubles.
  Aabb box;
  for (const Vec3& p : input.positions) box.extend(p);
  const Vec3 centre = box.center();
  std::vector<float> local_positions(3 * input.positions.size());
  for (size_t v = 0; v < input.positions.size(); ++v) {
    for (int a = 0; a < 3; ++a) local_positions[3 * v + a] = static_cast<float>(input.positions[v][a] - centre[a]);
  }
  const size_t stride = 3 * sizeof(float);
  std::vector<uint32_t> kept(input.indices.size());
  float error = 0.0f;
  size_t count = meshopt_simplify(kept.data(), input.indices.data(), input.indices.size(), local_positions.data(),
                                  input.positions.size(), stride, 3 * target, FLT_MAX, meshopt_SimplifyLockBorder,
                                  &error);
  if (count == 0 || count > 6 * target) {
    // The locked border alone keeps it above twice the target (a big node's long cut edge):
    // unlocked, the simplifier may move border vertices along the border, opening slits between
    // this proxy and its neighbours no wider than its bound, but never a hole in the surface.
    std::vector<uint32_t> unlocked(input.indices.size());
    float unlocked_error = 0.0f;
    const size_t n = meshopt_simplify(unlocked.data(), input.indices.data(), input.indices.size(),
                                      local_positions.data(), input.positions.size(), stride, 3 * target, FLT_MAX, 0,
                                      &unlocked_error);
    if (n > 0 && (count == 0 || n < count)) {
      kept = std::move(unlocked);
      count = n;
      error = unlocked_error;
      st.unlocked = true;
    }
  }
  // A candidate's bound: against the original geometry when the caller measures it, else the
  // measured distance to the input plus the input's bound.
  // The input's BVH, built when first needed (a shell, or measuring against the input).
  std::optional<TriangleBvh> input_bvh_storage;
  auto input_bvh = [&]() -> const TriangleBvh& {
    if (!input_bvh_storage) input_bvh_storage.emplace(input.positions, input.indices);
    return *input_bvh_storage;
  };
  auto bound = [&](ProxyMesh& candidate, double estimate, double measured, MeasuredBound& original) {
    candidate.chord_error = input.chord_error;
    if (measure == nullptr) {
      candidate.error = std::max(estimate, measured) + input.error;
      return;
    }
    original = (*measure)(candidate);
    candidate.error = std::max(input.error, original.distance() + input.chord_error);
  };
  // A voxel shell (proxy_shell.h) with its measured bound; empty when none could be made.
  MeasuredBound shell_bound;
  auto make_shell = [&](double& estimate, double& measured) {
    ProxyMesh shell;
    if (options.shell_resolution <= 0) return shell;
    shell = shell_proxy(input, options, target, region, input_bvh(), estimate);
    if (shell.empty()) return shell;
    shell.subtree_triangles = input.subtree_triangles;
    if (measure == nullptr) measured = measured_distance(input, input_bvh(), shell);
    bound(shell, estimate, measured, shell_bound);
    if (measure != nullptr) measured = shell_bound.distance();
    return shell;
  };
  if (count == 0 || count > 12 * target) {
    // Unlocked still above twelve times the target: a node of disconnected parts (a building's
    // walls and floors), or one whose children's borders moved apart. A voxel shell keeps every
    // surface a distant viewer sees, thin ones too; clustering is the last resort (it reaches
    // any size but collapses whatever is thinner than its grid, opening holes).
    double estimate = 0.0, measured = 0.0;
    if (ProxyMesh shell = make_shell(estimate, measured); !shell.empty()) {
      st.shell = true;
      st.estimate = estimate;
      st.measured = measured;
      st.bound = std::move(shell_bound);
      return shell;
    }
    std::vector<uint32_t> sloppy(input.indices.size());
    float sloppy_error = 0.0f;
    const size_t n = meshopt_simplifySloppy(sloppy.data(), input.indices.data(), input.indices.size(),
                                            local_positions.data(), input.positions.size(), stride, 3 * target,
                                            FLT_MAX, &sloppy_error);
    if (n > 0 && (count == 0 || n < count)) {
      kept = std::move(sloppy);
      count = n;
      error = sloppy_error;
      st.sloppy = true;
    }
  }
  if (count == 0) {  // nothing simplified it: the input is its own proxy
    st.kept_input = true;
    return input;
  }
  st.estimate = static_cast<double>(error) *
                static_cast<double>(meshopt_simplifyScale(local_positions.data(), input.positions.size(), stride));

  // Every input vertex names the first input triangle using it: the source and material of the
  // proxy triangles whose first corner it is.
  std::vector<uint32_t> first_triangle(input.positions.size(), UINT32_MAX);
  for (size_t i = input.indices.size(); i-- > 0;) first_triangle[input.indices[i]] = static_cast<uint32_t>(i / 3);
  // A simplifier's output (indices into the input) as a mesh, each triangle named after the first
  // input triangle of its first corner.
  auto mesh_of = [&](const std::vector<uint32_t>& indices, size_t n) {
    ProxyMesh m;
    MeshWelder weld(m, n / 3);
    for (size_t i = 0; i < n; i += 3) {
      const uint32_t t = first_triangle[indices[i]];
      weld.add(input.positions[indices[i]], input.positions[indices[i + 1]], input.positions[indices[i + 2]],
               input.sources[t], input.materials[t], false);
    }
    m.subtree_triangles = input.subtree_triangles;
    return m;
  };
  ProxyMesh out = mesh_of(kept, count);
  if (out.empty()) {
    st.kept_input = true;
    return input;
  }
  // Measured against the original (which the input is within input.error of) when the caller
  // measures, else against the input.
  if (measure == nullptr) st.measured = measured_distance(input, input_bvh(), out);
  bound(out, st.estimate, st.measured, st.bound);
  if (measure != nullptr) st.measured = st.bound.distance();
  // With an unbounded error the simplifier removes whole small components (a wall, a pillar)
  // before it flattens a big one, and the measured distance shows it: a result farther from its
  // input than a few of the shell's voxels gives way to the shell when that lies nearer.
  const Vec3 extent = box.extent();
  const double voxel = std::max({extent.x, extent.y, extent.z}) / std::max(options.shell_resolution, 1);
  // (Against the original, what the input already was from it does not count.)
  const double added = measure == nullptr ? st.measured : st.measured - input.error;
  const bool try_shell = options.shell_resolution > 0 && added > kShellTriggerVoxels * voxel;
  if (try_shell) {
    double estimate = 0.0, measured = 0.0;
    ProxyMesh shell = make_shell(estimate, measured);
    if (!shell.empty() && shell.error < out.error) {
      st.shell = true;
      st.estimate = estimate;
      st.measured = measured;
      st.bound = std::move(shell_bound);
      out = std::move(shell);
    }
  }
  if (measure == nullptr || out.error <= std::max(kAcceptGrowth * input.error, kAcceptVoxels * voxel)) return out;
  // Its bound against the original grew beyond its input's: the simplifier deleted a component
  // (a wall; a shell a lower node chose, which is not welded to its neighbours), folded the
  // surface, or widened the slits between the merged meshes into holes. The sloppy simplifier,
  // clustering then simplifying, and a shell (an OpenVDB grid, only here) are measured too, and
  // the smallest bound is kept (at no more triangles than twice the target or this result's).
  // Not the unlocked simplifier: it moves border vertices, and the slits it opens between
  // neighbouring proxies showed as holes along a building's walls in pegged frames (2 M building
  // exterior orbit at 1280x720: geometry shown at 0.949-0.960 of the exact frame's pixels in the
  // worst frame with it, 0.965-0.974 without; the 2 M terrain's root bound 19.4 -> 16.8).
  const size_t most = std::max(out.triangle_count(), 2 * target);
  auto consider = [&](ProxyMesh candidate, double estimate, bool unlocked, bool shell, bool sloppy) {
    if (candidate.empty() || candidate.triangle_count() > most) return;
    MeasuredBound b;
    bound(candidate, estimate, 0.0, b);
    if (candidate.error >= out.error) return;
    out = std::move(candidate);
    st.unlocked = unlocked;
    st.shell = shell;
    st.sloppy = sloppy;
    st.estimate = estimate;
    st.measured = b.distance();
    st.bound = std::move(b);
  };
  const double scale =
      static_cast<double>(meshopt_simplifyScale(local_positions.data(), input.positions.size(), stride));
  if (!st.sloppy) {
    std::vector<uint32_t> sloppy(input.indices.size());
    float sloppy_error = 0.0f;
    const size_t n = meshopt_simplifySloppy(sloppy.data(), input.indices.data(), input.indices.size(),
                                            local_positions.data(), input.positions.size(), stride, 3 * target,
                                            FLT_MAX, &sloppy_error);
    consider(mesh_of(sloppy, n), sloppy_error * scale, true, false, true);
  }
  {
    // Clustered first to four times the target, which welds the slits between the merged
    // descendants' meshes (their border vertices fall into the same grid cells), then simplified
    // topologically down to the target.
    std::vector<uint32_t> clustered(input.indices.size());
    float clustered_error = 0.0f;
    const size_t c = meshopt_simplifySloppy(clustered.data(), input.indices.data(), input.indices.size(),
                                            local_positions.data(), input.positions.size(), stride,
                                            std::min(input.indices.size(), 4 * 3 * target), FLT_MAX, &clustered_error);
    size_t n = c;
    float simplified_error = 0.0f;
    if (c > 3 * target) {
      std::vector<uint32_t> simplified(c);
      n = meshopt_simplify(simplified.data(), clustered.data(), c, local_positions.data(), input.positions.size(),
                           stride, 3 * target, FLT_MAX, 0, &simplified_error);
      clustered = std::move(simplified);
    }
    if (n > 0) consider(mesh_of(clustered, n), (clustered_error + simplified_error) * scale, true, false, true);
  }
  if (!st.shell && !try_shell) {  // a shell heals the slits too, and keeps thin walls
    double estimate = 0.0, measured = 0.0;
    ProxyMesh shell = make_shell(estimate, measured);
    if (!shell.empty() && shell.error < out.error && shell.triangle_count() <= most) {
      st.shell = true;
      st.unlocked = st.sloppy = false;
      st.estimate = estimate;
      st.measured = measured;
      st.bound = std::move(shell_bound);
      out = std::move(shell);
    }
  }
  return out;
}

namespace {
// The barycentric coordinates of the point of triangle (a, b, c) nearest p (a third each for a
// degenerate triangle).
Vec3 nearest_barycentric(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 e1 = b - a, e2 = c - a, h = closest_on_triangle(p, a, b, c) - a;
  const double d00 = glm::dot(e1, e1), d01 = glm::dot(e1, e2), d11 = glm::dot(e2, e2);
  const double den = d00 * d11 - d01 * d01;
  if (!(den > 0.0)) return {1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0};
  const double d20 = glm::dot(h, e1), d21 = glm::dot(h, e2);
  const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
  return {1.0 - v - w, v, w};
}
}  // namespace

void shade_proxy(const ProxyMesh& input, ProxyMesh& proxy) {
  proxy.normals.clear();
  const size_t tris = proxy.triangle_count();
  if (tris == 0) return;
  std::vector<Vec3> face(tris);
  for (size_t t = 0; t < tris; ++t) {
    const uint32_t* k = &proxy.indices[3 * t];
    const Vec3 n = glm::cross(proxy.positions[k[1]] - proxy.positions[k[0]], proxy.positions[k[2]] - proxy.positions[k[0]]);
    const double len = glm::length(n);
    face[t] = len > 0.0 ? n / len : Vec3(0.0);
  }
  // Each proxy corner's share of the input's area-weighted normals.
  std::vector<Vec3> corner(3 * tris, Vec3(0.0));
  const TriangleBvh bvh(proxy.positions, proxy.indices);
  for (size_t i = 0; i < input.triangle_count(); ++i) {
    const uint32_t* k = &input.indices[3 * i];
    const Vec3 &a = input.positions[k[0]], &b = input.positions[k[1]], &c = input.positions[k[2]];
    Vec3 m = 0.5 * glm::cross(b - a, c - a);  // length: the area
    if (!input.normals.empty()) {
      const Vec3 mean = input.normals[3 * i] + input.normals[3 * i + 1] + input.normals[3 * i + 2];
      const double len = glm::length(mean);
      if (len > 0.0) m = mean * (glm::length(m) / len);
    }
    const Vec3 centroid = (a + b + c) / 3.0;
    const uint32_t t = bvh.nearest(centroid);
    if (t == UINT32_MAX || !std::isfinite(glm::dot(m, m))) continue;
    if (glm::dot(m, face[t]) < 0.0) m = -m;
    const uint32_t* q = &proxy.indices[3 * t];
    const Vec3 w = nearest_barycentric(centroid, proxy.positions[q[0]], proxy.positions[q[1]], proxy.positions[q[2]]);
    for (int j = 0; j < 3; ++j) corner[3 * t + size_t(j)] += w[j] * m;
  }
  // Per corner, the sum over the corners around its vertex whose faces lie within the crease
  // angle of its own (either way round: a soup's windings disagree), turned to agree with it.
  std::vector<uint32_t> first(proxy.positions.size() + 1, 0), around(3 * tris);
  for (uint32_t v : proxy.indices) ++first[v + 1];
  for (size_t v = 0; v < proxy.positions.size(); ++v) first[v + 1] += first[v];
  std::vector<uint32_t> fill(first.begin(), first.end() - 1);
  for (size_t c = 0; c < 3 * tris; ++c) around[fill[proxy.indices[c]]++] = uint32_t(c);
  const double crease = std::cos(kProxyCreaseDegrees * M_PI / 180.0);
  proxy.normals.resize(3 * tris);
  for (size_t c = 0; c < 3 * tris; ++c) {
    const size_t t = c / 3;
    const uint32_t v = proxy.indices[c];
    Vec3 n(0.0);
    for (uint32_t k = first[v]; k < first[v + 1]; ++k) {
      const uint32_t other = around[k];
      const double agree = glm::dot(face[other / 3], face[t]);
      if (other == c || std::abs(agree) >= crease) n += (agree < 0.0 ? -1.0 : 1.0) * corner[other];
    }
    const double len = glm::length(n);
    n = len > 0.0 && std::isfinite(len) ? n / len : face[t];
    if (face[t] != Vec3(0.0) && glm::dot(n, face[t]) < crease) n = face[t];
    proxy.normals[c] = n == Vec3(0.0) ? Vec3(0.0, 0.0, 1.0) : n;
  }
}

Scene proxy_scene(const ProxyMesh& mesh) {
  Scene scene;
  scene.triangles.reserve(mesh.triangle_count());
  scene.prims.reserve(mesh.triangle_count());
  const bool normals = mesh.normals.size() == 3 * mesh.triangle_count() && !mesh.normals.empty();
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    const uint32_t* k = &mesh.indices[3 * t];
    const std::array<Vec3, 3> n = normals ? std::array<Vec3, 3>{mesh.normals[3 * t], mesh.normals[3 * t + 1],
                                                                mesh.normals[3 * t + 2]}
                                          : std::array<Vec3, 3>{};
    scene.add_triangle({mesh.positions[k[0]], mesh.positions[k[1]], mesh.positions[k[2]]}, mesh.sources[t],
                       mesh.materials[t], normals ? &n : nullptr);
  }
  return scene;
}

}  // namespace frontier
