// Proxies: coarse triangle stand-ins for whole subtrees of the store's top tree, each with an
// object-space error bound (DESIGN.md "The k-d tree, in two levels, with a proxy at every interior
// node"; the section and pages: store/FORMAT.md "proxies").
//
// A ProxyMesh is an indexed triangle mesh whose vertices are distinct (welded by exact position)
// and whose triangles each keep a source id and a material, so a viewer can shade and name them.
// The builder makes them bottom-up:
//   leaf   proxy_input(cell): the cell's triangles, curved primitives tessellated (for proxies
//          only) with their measured chord error as the bound, snapped to the store's lattice.
//   node   merge_proxies(meshes): the node's descendants three levels down (leaves above that
//          standing for themselves; the builder's kProxyInputLevels) welded, exact duplicate
//          triangles (a primitive straddling cells is stored in each) dropped; the bound is the
//          largest, and at least the children's. (From the children's proxies instead, the error
//          compounded level by level and slits between them widened into holes.)
//          simplify_proxy(merged): meshoptimizer's simplifier with locked borders (so sibling
//          proxies meet), unlocked when the border alone keeps it above six times the target (no
//          hole; the border may move within the bound). Where even that stays above twelve times
//          the target (disconnected parts), or its result lies farther than six shell voxels from
//          its input (with its error unbounded the simplifier deletes whole small components —
//          walls, pillars — first), a voxel shell (proxy_shell.h: OpenVDB's distance field and
//          mesher, rooms filled, kept inside the node's region, then simplified) is made, and
//          kept when its bound is the smaller; sloppy clustering only when no shell can be made
//          (it opens holes a viewer shows as background).
// A proxy's vertices are vertices of its input (meshoptimizer only removes vertices), so they
// stay on the global lattice; a shell's are new points, snapped to the lattice. Both encode with
// the store's cell codecs.
//
// The bound of a node (the builder's, with a ProxyMeasure): the larger of its children's bounds
// (so bounds are monotone: a parent's >= its children's) and the measured two-sided distance
// between its proxy and the subtree's ORIGINAL geometry (the leaf cells' triangles, curved
// primitives as their tessellation) plus the curved primitives' chord error. Bounds are not
// summed down the tree: the original side is a rigorous upper bound over every point of the
// original triangles (TriangleBvh::farthest_point: convexity at the corners, splitting where the
// corners' nearest triangles differ; at most 0.1% of the originals' diagonal, or 1/1800 of a
// triangle's longest edge, above the true distance), reached by branch and bound through the
// descendants' proxies (proxy_bound.h, which also says what the nodes above the external build's
// parts measure through); the proxy's side is sampled at its vertices, edge midpoints and
// centroids (its few large triangles would need splitting to the bound's size to be bounded
// everywhere). Candidates are compared by that bound: a shell replaces the simplifier's result
// when it is the smaller, and where the result's bound exceeds both 1.3 times its input's and
// three shell voxels, the unlocked and sloppy simplifiers, clustering to four times the target
// then simplifying (which welds the slits between the merged meshes), and a shell are measured
// too and the smallest kept.
// Without a ProxyMeasure (tests of simplify_proxy alone) a node's bound is relative to its input:
// max(meshoptimizer's estimate, the measured distance to the input) + the input's bound; a
// shell's estimate is its offset (a voxel and half a voxel's diagonal) plus meshoptimizer's.
//
// All functions are pure and may run on any number of threads at once.
#pragma once

#include "src/codec/lattice.h"
#include "src/core/scene.h"
#include "src/lod/proxy_bound.h"

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <vector>

namespace frontier {

struct ProxyMesh {
  std::vector<Vec3> positions;      // distinct, every one used by a triangle
  std::vector<uint32_t> indices;    // three per triangle, into positions
  std::vector<uint32_t> sources;    // per triangle: the input primitive it stands for
  std::vector<uint32_t> materials;  // per triangle
  // Empty (flat shading: the original triangles themselves), or three per triangle: unit shading
  // normals at its corners (shade_proxy), what the original surface's normals average to there.
  std::vector<Vec3> normals;
  double error = 0.0;               // object-space bound on the distance to the original geometry
  double chord_error = 0.0;         // the largest tessellation (and snapping) error of the curved
                                    // primitives beneath: original geometry is their surface
  uint64_t subtree_triangles = 0;   // triangles of the subtree (tessellated; duplicates dropped
                                    // where a merge still saw both copies)

  size_t triangle_count() const { return sources.size(); }
  bool empty() const { return sources.empty(); }
};

struct ProxyOptions {
  // Simplify a node's input to about this many triangles (a node with fewer keeps them all).
  uint32_t target_triangles = 128;
  // Tessellated curved primitives are snapped to it (the Draco codec requires lattice positions).
  std::optional<Lattice> lattice;
  // Segments around a circle for curved primitives (src/core/tessellate.h).
  int segments = 6;
  // Voxels along the longest side of a voxel shell (proxy_shell.h), made where the unlocked
  // simplifier stays above twelve times the target; 0: meshopt_simplifySloppy there instead.
  int shell_resolution = 32;
};

// What simplify_proxy did, for the build's report.
struct ProxySimplifyStats {
  bool simplified = false;   // the input had more triangles than the target
  bool kept_input = false;   // the proxy is the input itself (its bound is the input's)
  bool unlocked = false;     // the locked border kept meshopt_simplify above twice the target: unlocked
  bool shell = false;        // a voxel shell replaced meshopt_simplify's result (unlocked too far)
  bool sloppy = false;       // meshopt_simplifySloppy did (unlocked too far, and no shell)
  double estimate = 0.0;     // meshoptimizer's absolute error (result_error x simplifyScale)
  double measured = 0.0;     // measured two-sided distance between proxy and input (with a
                             // ProxyMeasure: and the original)
  MeasuredBound bound;       // with a ProxyMeasure: the kept proxy's distances to the original
};

// Measures a candidate proxy against the original geometry it replaces (proxy_bound.h).
using ProxyMeasure = std::function<MeasuredBound(const ProxyMesh& candidate)>;

// A leaf's input: `cell`'s primitives as one welded mesh. Triangles are taken as they are (they
// already lie on the lattice in a Draco store); spheres, cones, boxes and quadrics (as their
// bounding box surface) are tessellated and snapped; `error` is the largest distance between a
// curved primitive and its tessellation (plus the snapping), 0 when there are only triangles.
// Zero-area triangles (after welding) are dropped.
ProxyMesh proxy_input(const Scene& cell, const ProxyOptions& options);

// Both meshes in one, welded by exact position; a triangle that appears in both (same corners,
// same orientation) is kept once. error = max of both; subtree_triangles = sum less duplicates.
// When either has normals the result has them (a mesh without: its face normals).
ProxyMesh merge_proxies(const ProxyMesh& lower, const ProxyMesh& upper);
// The same for any number of meshes (a node's descendants some levels down).
ProxyMesh merge_proxies(std::span<const ProxyMesh* const> meshes);

// The proxy of `input`: a copy when it has at most options.target_triangles triangles (same
// error), else simplified (at most twice the target unless even sloppy clustering cannot get
// there; borders locked when that gets there, else unlocked, else sloppy clustering, which
// opens holes) with the bound described above. Never empty for a non-empty input.
// `region`: the node's region, which a voxel shell is kept inside (none: the shell may reach a
// voxel beyond the input).
// `measure` (the builder's): each candidate's bound is max(input.error, its measured distance to
// the original + input.chord_error), and the candidates are compared by it; without it, the
// bound is relative to `input` (see above).
ProxyMesh simplify_proxy(const ProxyMesh& input, const ProxyOptions& options, ProxySimplifyStats* stats = nullptr,
                         const Aabb* region = nullptr, const ProxyMeasure* measure = nullptr);

// The two-sided distance between a proxy and its input (see above): an upper bound over every
// point of the input, the largest over the proxy's samples.
double measured_distance(const ProxyMesh& input, const ProxyMesh& proxy);

// Gives `proxy` shading normals (ProxyMesh::normals) that make it look like `input`, the mesh it
// was simplified from: each input triangle's normal, weighted by its area (its corner normals'
// mean where `input` has normals), goes to the proxy triangle nearest its centroid, shared among
// that triangle's corners by the barycentric coordinates of the nearest point; a corner's normal
// is the sum at its vertex over the triangles around it (turned to agree in orientation), unless
// that lies more than kProxyCreaseDegrees from its triangle's own normal (a crease: a box's edge,
// a wall's two sides), where the face normal stays. A proxy with few large triangles so shades
// like the many small ones it replaces, instead of in flat facets; flat parts stay flat.
constexpr double kProxyCreaseDegrees = 40.0;
void shade_proxy(const ProxyMesh& input, ProxyMesh& proxy);

// The mesh as a Scene of triangles (source, material and normals kept), to encode as a page.
Scene proxy_scene(const ProxyMesh& mesh);

}  // namespace frontier
