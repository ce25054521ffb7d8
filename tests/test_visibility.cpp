// The visibility classes of issue 7: every rasterizing class (exhaustive, frustum culling,
// occlusion culling, cells and portals) is conservative — its id image equals brute-force ray
// casting's at every pixel but ties — in memory on the tessellated SPD scenes, on the SPD
// scenes' own spheres and cones and every other primitive kind (issue 24), from stores that
// keep spheres, and paged along a building walk with a cache too small for the frame; hierarchical frustum culling accepts and
// rejects exactly the subtrees a brute classification of every node says; the classes touch
// what they should (occlusion and portals less than frustum culling, exhaustive everything).
#include "preprocess/build.h"
#include "src/io/camera_path.h"
#include "src/engine/kdtree.h"
#include "src/io/load_scene.h"
#include "src/raster/imr.h"
#include "src/raster/portals.h"
#include "src/engine/ray_walk.h"
#include "src/paging/store_model.h"
#include "src/core/tessellate.h"
#include "src/raster/visibility.h"
#include "src/walk/walkthrough.h"
#include "tests/engine_util.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

constexpr Visibility kRasterizing[] = {Visibility::kExhaustive, Visibility::kFrustumCull,
                                       Visibility::kOcclusionCull};

const fs::path& scratch() { return testing::scratch_dir("frontier_visibility"); }

// Brute force's first-hit ids of a view, with its tie flags.
struct Reference {
  std::vector<uint32_t> ids;
  std::vector<uint8_t> tie;
  Reference(const Scene& scene, const View& view) { testing::brute_reference(scene, view, ids, tie); }
};

// Differing ids that are not ties: where the method and brute force see different primitives,
// the brute-force hit must be as near as the method's depth (1e-9 relative) or brute force
// must itself report a tie there.
size_t mismatches(const Scene& scene, const View& view, const Reference& ref, const std::vector<uint32_t>& ids,
                  const std::vector<double>& depths, std::string& first) {
  size_t bad = 0;
  Counters unused;
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      const size_t i = size_t(y) * size_t(view.width) + size_t(x);
      if (ids[i] == ref.ids[i] || ref.tie[i]) continue;
      const Ray ray = view.ray(x, y);
      const RayHit hit = brute_force_hit(scene, ray, view.tmin(ray), unused);
      if (hit.hit() && ids[i] != kNoPrim && std::abs(depths[i] - hit.t) <= 1e-9 * hit.t) continue;
      if (bad++ == 0) {
        first = "pixel (" + std::to_string(x) + "," + std::to_string(y) + "): brute " +
                std::to_string(int64_t(ref.ids[i] == kNoPrim ? -1 : ref.ids[i])) + " method " +
                std::to_string(int64_t(ids[i] == kNoPrim ? -1 : ids[i]));
      }
    }
  }
  return bad;
}

// Renders `view` with visibility class `v` (2 threads; the other options from `o`) and expects
// its ids to equal brute force's at every pixel but ties; the ids go to *ids when asked.
CullCounters render_exact(const Scene& scene, const View& view, const Reference& ref, CullSource& source, Visibility v,
                          CullOptions o = {}, std::vector<uint32_t>* ids = nullptr) {
  o.visibility = v;
  o.threads = 2;
  CullingRenderer renderer(o);
  const CullCounters c = renderer.render(view, source);
  std::string first;
  EXPECT_EQ(mismatches(scene, view, ref, renderer.ids(), renderer.depths(), first), 0u) << first;
  if (ids != nullptr) *ids = renderer.ids();
  return c;
}

Scene tessellated_spd(const std::string& name) {
  Scene scene;
  EXPECT_TRUE(load_scene(testing::spd(name), scene).is_ok());
  TessellateOptions t;
  t.segments = 6;
  return tessellate(scene, t);
}

View spd_view(const Scene& scene, int size, double advance) {
  Camera cam = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
  cam.eye = cam.eye + advance * (cam.look_at - cam.eye);
  return View(cam, size, size);
}

TEST(Visibility, NamesRoundTrip) {
  for (const Visibility v : {Visibility::kExhaustive, Visibility::kFrustumCull, Visibility::kOcclusionCull,
                             Visibility::kFrustumAdvance, Visibility::kPortals}) {
    ASSERT_TRUE(parse_visibility(visibility_name(v)).has_value());
    EXPECT_EQ(*parse_visibility(visibility_name(v)), v);
  }
  EXPECT_FALSE(parse_visibility("zbuffer").has_value());
}

// Every rasterizing class equals brute force on the tessellated SPD scenes, from the file's
// camera and from one moved into the scene (where frustum and occlusion culling cut most).
// (Back-face culling: Visibility.BackFaceCullingKeepsSpheresExact.)
TEST(Visibility, ClassesEqualBruteForceOnTheSpdScenes) {
  for (const char* name : {"rings", "tree", "shells"}) {
    const Scene scene = tessellated_spd(name);
    const KdTree tree = KdTree::build(scene);
    MemoryCullSource source(scene, tree);
    for (const double advance : {0.0, 0.6}) {
      const View view = spd_view(scene, 49, advance);
      const Reference ref(scene, view);
      uint64_t exhaustive_prims = 0, frustum_prims = 0, occlusion_cells = 0, frustum_cells = 0;
      for (const Visibility v : kRasterizing) {
        SCOPED_TRACE(std::string(name) + " advance " + std::to_string(advance) + " " + visibility_name(v));
        const CullCounters c = render_exact(scene, view, ref, source, v);
        if (v == Visibility::kExhaustive) {
          exhaustive_prims = c.primitives_rasterized;
          EXPECT_EQ(c.primitives_rasterized, scene.size()) << "exhaustive draws every primitive once";
          EXPECT_EQ(c.cells_touched, tree.cells().size());
        }
        if (v == Visibility::kFrustumCull) {
          frustum_prims = c.primitives_rasterized;
          frustum_cells = c.cells_touched;
        }
        if (v == Visibility::kOcclusionCull) occlusion_cells = c.cells_touched;
      }
      EXPECT_LE(frustum_prims, exhaustive_prims);
      EXPECT_LE(occlusion_cells, frustum_cells);
      if (advance > 0.0) {
        EXPECT_LT(frustum_prims, exhaustive_prims) << name << ": the moved camera sees part of it";
      }
    }
  }
}

// Brute classification of every node against the view frustum (the eight corners against the
// four image-border planes and the near plane): the nodes frustum culling tests are the root and
// the children of straddling nodes; it accepts the inside ones and rejects the outside ones.
TEST(Visibility, FrustumCullingAcceptsAndRejectsWholeSubtrees) {
  const Scene scene = tessellated_spd("tree");
  const KdTree tree = KdTree::build(scene);
  const View view = spd_view(scene, 101, 0.5);
  // Planes through the eye and the image border, inside positive.
  auto dir = [&](double x, double y) { return view.base + x * view.step_x + y * view.step_y; };
  const double w = view.width, h = view.height;
  const Vec3 centre = dir(0.5 * (w - 1), 0.5 * (h - 1));
  std::vector<Vec3> normals;
  for (const auto& [a, b] : {std::pair{dir(-0.5, -0.5), dir(-0.5, h - 0.5)}, {dir(w - 0.5, -0.5), dir(w - 0.5, h - 0.5)},
                            {dir(-0.5, -0.5), dir(w - 0.5, -0.5)}, {dir(-0.5, h - 0.5), dir(w - 0.5, h - 0.5)}}) {
    Vec3 n = glm::cross(a, b);
    normals.push_back(glm::dot(n, centre) < 0.0 ? -n : n);
  }
  normals.push_back(view.forward);
  enum Class { kIn, kOut, kStraddle };
  auto classify = [&](const Aabb& b) {
    bool all_in = true;
    for (const Vec3& n : normals) {
      int inside = 0;
      for (int k = 0; k < 8; ++k) {
        const Vec3 p(k & 1 ? b.hi.x : b.lo.x, k & 2 ? b.hi.y : b.lo.y, k & 4 ? b.hi.z : b.lo.z);
        inside += glm::dot(n, p - view.eye) - (&n == &normals.back() ? view.near : 0.0) >= 0.0 ? 1 : 0;
      }
      if (inside == 0) return kOut;
      all_in = all_in && inside == 8;
    }
    return all_in ? kIn : kStraddle;
  };
  uint64_t tested = 0, accepted = 0, rejected = 0, cells = 0;
  struct Item {
    uint32_t node;
    Aabb bounds;
  };
  std::vector<Item> stack{{0, tree.bounds()}};
  std::vector<Item> accepted_subtrees;
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    ++tested;
    const Class c = classify(it.bounds);
    if (c == kOut) {
      ++rejected;
      continue;
    }
    const KdTree::Node& node = tree.nodes()[it.node];
    if (c == kIn) {
      ++accepted;
      accepted_subtrees.push_back(it);
      continue;
    }
    if (node.is_leaf()) {
      ++cells;
      continue;
    }
    Aabb lo = it.bounds, hi = it.bounds;
    lo.hi[int(node.axis_or_leaf)] = node.split;
    hi.lo[int(node.axis_or_leaf)] = node.split;
    stack.push_back({it.node + 1, lo});
    stack.push_back({node.child, hi});
  }
  // Cells of the accepted subtrees are drawn without further node tests.
  for (const Item& a : accepted_subtrees) {
    std::vector<uint32_t> nodes{a.node};
    while (!nodes.empty()) {
      const uint32_t n = nodes.back();
      nodes.pop_back();
      if (tree.nodes()[n].is_leaf()) {
        ++cells;
      } else {
        nodes.push_back(n + 1);
        nodes.push_back(tree.nodes()[n].child);
      }
    }
  }
  ASSERT_GT(accepted, 0u);
  ASSERT_GT(rejected, 0u);
  CullOptions o;
  o.visibility = Visibility::kFrustumCull;
  CullingRenderer renderer(o);
  MemoryCullSource source(scene, tree);
  const CullCounters c = renderer.render(view, source);
  EXPECT_EQ(c.nodes_tested, tested);
  EXPECT_EQ(c.subtrees_accepted, accepted);
  EXPECT_EQ(c.subtrees_rejected, rejected);
  EXPECT_EQ(c.cells_touched, cells);
  EXPECT_LT(c.nodes_tested, c.nodes_touched) << "accepted subtrees are walked without tests";
}

// Curved primitives (issue 24). Scenes as their files keep them: spheres, open cones, polygons.

// A small balls-like scene: frontier-gen's sphere flake of depth 2 (91 spheres) on a floor.
const std::string& flake_path() {
  static const std::string path = [] {
    const std::string out = (scratch() / "flake.nff").string();
    const auto r = run_binary(proc::gen_binary(), {"spheres", "--family", "flake", "--size", "2", "-o", out, "-q"},
                              scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return out;
  }();
  return path;
}

Scene loaded(const std::string& path) {
  Scene scene;
  const Status status = load_scene(path, scene);
  EXPECT_TRUE(status.is_ok()) << status.to_string();
  return scene;
}

size_t curved_count(const Scene& scene) {
  return size_t(std::count_if(scene.prims.begin(), scene.prims.end(),
                              [](const PrimRef& r) { return r.kind != PrimKind::Triangle && r.kind != PrimKind::Box; }));
}

// Every class draws spheres and cones as immediate-mode ray casting does (bound rasterized, a
// ray per fragment that passes depth): ids equal brute force on the SPD scenes and the flake,
// from the file's camera and one moved in; nothing is skipped; portals without a graph fall
// back to frustum culling and draw the same. Before issue 24 the classes skipped every sphere
// and cone (the floor alone was drawn).
TEST(Visibility, ClassesDrawCurvedPrimitivesAsBruteForceSeesThem) {
  for (const std::string& path : {testing::spd("rings"), testing::spd("tree"), testing::spd("shells"), flake_path()}) {
    const Scene scene = loaded(path);
    const KdTree tree = KdTree::build(scene);
    MemoryCullSource source(scene, tree);
    const size_t curved = curved_count(scene);
    ASSERT_GT(curved, 0u) << path;
    for (const double advance : {0.0, 0.6}) {
      const View view = spd_view(scene, 41, advance);
      const Reference ref(scene, view);
      for (const Visibility v : {Visibility::kExhaustive, Visibility::kFrustumCull, Visibility::kOcclusionCull,
                                 Visibility::kPortals}) {
        SCOPED_TRACE(path + " advance " + std::to_string(advance) + " " + visibility_name(v));
        const CullCounters c = render_exact(scene, view, ref, source, v);
        EXPECT_EQ(c.skipped_primitives, 0u);
        EXPECT_EQ(c.degenerate_primitives, 0u);
        EXPECT_GT(c.curved_primitives, 0u);
        EXPECT_GT(c.bound_triangles, c.curved_primitives);
        EXPECT_GT(c.surface_hits, 0u);
        EXPECT_LE(c.surface_hits, c.surface_rays);
        EXPECT_LE(c.surface_rays, c.pixels_rasterized);
        if (v == Visibility::kExhaustive) {
          EXPECT_EQ(c.primitives_rasterized, scene.size()) << "every primitive, curved or not";
          EXPECT_EQ(c.curved_primitives, curved);
        }
        if (v == Visibility::kPortals) {
          EXPECT_TRUE(c.portal_fallback);
        }
      }
    }
  }
}

// Closed spheres seen from outside: back-face culling (back-sample culling of curved surfaces)
// changes nothing seen.
TEST(Visibility, BackFaceCullingKeepsSpheresExact) {
  const Scene scene = loaded(testing::spd("shells"));
  const KdTree tree = KdTree::build(scene);
  MemoryCullSource source(scene, tree);
  const View view = spd_view(scene, 41, 0.3);
  const Reference ref(scene, view);
  for (const Visibility v : kRasterizing) {
    SCOPED_TRACE(visibility_name(v));
    CullOptions o;
    o.cull_back_faces = true;
    render_exact(scene, view, ref, source, v, o);
  }
}

// Every kind at once — triangle, box, sphere, cone, clipped quadric — with the eye inside one
// sphere's bound but outside the sphere (its front faces clipped by the near plane: the near
// cap casts those rays), with and without a near plane. The view looks past the sphere's
// silhouette, at the others on its far side.
TEST(Visibility, EveryPrimitiveKindIsDrawnFromInsideABound) {
  Scene scene;
  scene.materials.push_back(Material{});
  scene.add_triangle(Triangle{Vec3(-6, -6, -3), Vec3(6, -6, -3), Vec3(0, 6, -3)}, 0, 0);
  scene.add_box(Box{Aabb(Vec3(1.5, -1, -2), Vec3(2.5, 0, -1))}, 1, 0);
  scene.add_sphere(Sphere{Vec3(0, 0, 0), 1.0}, 2, 0);
  scene.add_cone(Cone{Vec3(3.5, -1, -2), 0.6, Vec3(3.5, 1, -1), 0.2}, 3, 0);
  // An ellipsoid about (1.5, -3, -1.5) cut by a plane: 4(x-1.5)² + (y+3)² + 4(z+1.5)² = 1,
  // y <= -2.6.
  Quadric q;
  q.coeff = {4, 1, 4, 0, 0, 0, -12, 6, 12, -1.0 + 9.0 + 9.0 + 9.0};
  q.clip[0] = Vec4(0, 1, 0, 2.6);
  q.clip_count = 1;
  q.bounds = Aabb(Vec3(1, -4, -2), Vec3(2, -2.6, -1));
  scene.add_quadric(q, 4, 0);
  scene.input_primitives = 5;
  const KdTree tree = KdTree::build(scene);
  MemoryCullSource source(scene, tree);
  // Between the sphere (radius 1) and its 6-slice bound's vertices (~1.15 out), looking in.
  const Vec3 eye = glm::normalize(Vec3(0.8, -0.6, 0.9)) * 1.08;
  ImrOptions imr_options;
  const CurvedBound bound = curved_bound(scene, 2, [&] {
    ImplicitSurface s;
    EXPECT_TRUE(implicit_surface_of(scene, 2, s));
    return s;
  }(), imr_options.slices, imr_options.slices / 2);
  for (const double near : {0.0, 0.01}) {
    const View view(testing::camera_at(eye, Vec3(2.5, -1.5, -1.5), 100.0, near), 57, 57);
    SCOPED_TRACE("near " + std::to_string(near));
    const Reference ref(scene, view);
    for (const Visibility v : kRasterizing) {
      SCOPED_TRACE(visibility_name(v));
      std::vector<uint32_t> ids;
      const CullCounters c = render_exact(scene, view, ref, source, v, {}, &ids);
      EXPECT_EQ(c.skipped_primitives, 0u);
      for (uint32_t source_id = 0; source_id < 5; ++source_id) {
        EXPECT_NE(std::find(ids.begin(), ids.end(), source_id), ids.end()) << "primitive " << source_id << " unseen";
      }
    }
  }
  EXPECT_TRUE(bound.polyhedron.contains(eye - bound.origin)) << "the eye was meant to be inside the bound";
}

// Occlusion culling with curved fragments: a bound fragment whose ray misses the sphere writes
// no depth, so a small floor tile seen past the sphere's silhouette but behind its bound is not
// hidden by the z-pyramid. The pyramid is updated after every cell, so it does cull.
TEST(Visibility, OcclusionCullingIsNotFooledByBoundFragments) {
  Scene scene;
  scene.materials.push_back(Material{});
  scene.add_sphere(Sphere{Vec3(0, 0, 0), 1.0}, 0, 0);
  uint32_t id = 1;
  const int n = 48;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double x0 = -3.0 + 6.0 * i / n, x1 = -3.0 + 6.0 * (i + 1) / n;
      const double y0 = -3.0 + 6.0 * j / n, y1 = -3.0 + 6.0 * (j + 1) / n;
      scene.add_triangle(Triangle{Vec3(x0, y0, -2), Vec3(x1, y0, -2), Vec3(x1, y1, -2)}, id++, 0);
      scene.add_triangle(Triangle{Vec3(x0, y0, -2), Vec3(x1, y1, -2), Vec3(x0, y1, -2)}, id++, 0);
    }
  }
  scene.input_primitives = id;
  KdBuildOptions kb;
  kb.max_cell_prims = 4;
  const KdTree tree = KdTree::build(scene, kb);
  MemoryCullSource source(scene, tree);
  const View view(testing::camera_at(Vec3(0, 0, 4), Vec3(0, 0, 0), 40.0), 97, 97);
  const Reference ref(scene, view);
  CullOptions o;
  o.pyramid_batch = 1;
  o.bound_slices = 3;  // a loose bound: a wide band of fragments that miss
  const CullCounters c = render_exact(scene, view, ref, source, Visibility::kOcclusionCull, o);
  EXPECT_GT(c.subtrees_occluded, 0u) << "the sphere was meant to hide part of the floor";
  EXPECT_GT(c.surface_rays, c.surface_hits) << "some bound fragments were meant to miss";
}

// Curved hits are lit with the surface normal: the same colour immediate-mode ray casting
// (without shadows) gives the same sample, not one flat colour per sphere.
TEST(Visibility, CurvedHitsAreShadedWithTheSurfaceNormal) {
  const Scene scene = loaded(flake_path());
  const KdTree tree = KdTree::build(scene);
  const View view = spd_view(scene, 61, 0.0);
  CullOptions o;
  o.visibility = Visibility::kFrustumCull;
  o.threads = 2;
  CullingFrameRenderer culling(scene, tree, o);
  auto frame = culling.render(view);
  ASSERT_TRUE(frame.is_ok());
  ImrOptions io;
  io.threads = 2;
  io.shadows = false;
  ImrRenderer imr(scene, io);
  imr.render(view);
  const std::vector<uint32_t>& imr_ids = imr.rasterizer().ids();
  const std::vector<Rgb>& imr_colors = imr.rasterizer().colors();
  size_t compared = 0, differ = 0;
  for (size_t i = 0; i < frame->ids.size(); ++i) {
    if (frame->ids[i] == kNoPrim || imr_ids[i] == kNoPrim || scene.prims[imr_ids[i]].source != frame->ids[i] ||
        scene.prims[imr_ids[i]].kind != PrimKind::Sphere) {
      continue;
    }
    ++compared;
    const Rgb& a = frame->colors[i];
    const Rgb& b = imr_colors[i];
    differ += std::max({std::abs(a.r - b.r), std::abs(a.g - b.g), std::abs(a.b - b.b)}) > 1e-4f ? 1 : 0;
  }
  EXPECT_GT(compared, 200u);
  EXPECT_EQ(differ, 0u) << "of " << compared << " sphere pixels";
}

// A store that keeps spheres (frontier-build without --tessellate), paged: every class's
// frame equals brute force over the model, in the library and through frontier-view's --ids,
// and the report counts the curved primitives drawn.
TEST(Visibility, StoresThatKeepSpheresDrawThem) {
  const std::string model = flake_path();
  const Scene scene = loaded(model);
  ASSERT_TRUE(scene.camera.has_value());
  const std::string store = (scratch() / "flake.frontier").string();
  BuildOptions b;
  b.inputs = {model};
  b.output = store;
  b.codec = CellCodec::Raw;
  b.quiet = true;
  b.threads = 2;
  b.cell_prims = 16;
  auto report = build_store(b);
  ASSERT_TRUE(report.is_ok()) << report.status().to_string();
  const int size = 48;
  const View view(*scene.camera, size, size);
  const Reference ref(scene, view);
  for (const Visibility v : kRasterizing) {
    SCOPED_TRACE(visibility_name(v));
    WalkOptions o;
    o.width = o.height = size;
    o.threads = 2;
    o.visibility = v;
    auto walk = Walkthrough::open(store, o);
    ASSERT_TRUE(walk.is_ok()) << walk.status().to_string();
    const FrameReport r = (*walk)->frame(*scene.camera);
    ASSERT_TRUE(r.cull.has_value());
    EXPECT_EQ(r.cull->skipped_primitives, 0u);
    EXPECT_GT(r.cull->curved_primitives, 0u);
    std::string first;
    EXPECT_EQ(mismatches(scene, (*walk)->view(), ref, (*walk)->ids(), (*walk)->depths(), first), 0u) << first;

    const std::string ids_path = (scratch() / (std::string("flake-") + visibility_name(v) + ".ids")).string();
    const auto run = run_binary(FRONTIER_VIEW_PATH,
                                {store, "--headless", "--visibility", visibility_name(v), "--size",
                                 std::to_string(size) + "x" + std::to_string(size), "--threads", "2", "--ids", ids_path},
                                scratch());
    ASSERT_EQ(run.exit_code, 0) << run.err;
    const std::string bytes = proc::slurp(ids_path);
    ASSERT_EQ(bytes.size(), view.pixels() * sizeof(uint32_t));
    std::vector<uint32_t> ids(view.pixels());
    std::memcpy(ids.data(), bytes.data(), bytes.size());
    size_t differ = 0;
    for (size_t i = 0; i < ids.size(); ++i) differ += ids[i] != ref.ids[i] && !ref.tie[i] ? 1 : 0;
    EXPECT_EQ(differ, 0u) << "frontier-view " << store << " --visibility " << visibility_name(v);
  }
}

// A generated building with its sidecar, built into a store with cells and portals, and a walk
// through it (cached within the run).
struct Building {
  std::string model, store, path;
};
const Building& building() {
  static const Building b = [] {
    Building out;
    out.model = (scratch() / "building.ply").string();
    auto r = run_binary(proc::gen_binary(),
                        {"building", "--floors", "2", "--rooms", "12", "--furniture", "0.6", "-o", out.model, "--quiet"},
                        scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    out.path = (scratch() / "walk.cam").string();
    r = run_binary(proc::gen_binary(),
                   {"path", "--model", out.model, "--kind", "walk", "--frames", "16", "--step", "0.6", "-o", out.path},
                   scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    out.store = (scratch() / "building.frontier").string();
    BuildOptions o;
    o.inputs = {out.model};
    o.output = out.store;
    o.codec = CellCodec::Raw;
    o.quiet = true;
    o.threads = 2;
    o.cell_prims = 512;
    auto report = build_store(o);
    EXPECT_TRUE(report.is_ok()) << report.status().to_string();
    return out;
  }();
  return b;
}

// Paged along the building walk with a cache smaller than the model: every class's frames
// equal brute force over the model (ties aside), resident bytes stay within the budget (cells
// drawn are evicted while the frame goes on), and the classes order as they should: exhaustive
// touches every cell, occlusion culling and portals fewer than frustum culling.
TEST(Visibility, PagedBuildingWalkEqualsBruteForceWithinTheBudget) {
  const Building& b = building();
  Scene scene;
  ASSERT_TRUE(load_scene(b.model, scene).is_ok());
  auto cams = read_camera_path(b.path);
  ASSERT_TRUE(cams.is_ok());
  auto model = StoreModel::open(b.store);
  ASSERT_TRUE(model.is_ok());
  ASSERT_NE((*model)->portals(), nullptr) << "the store should carry the sidecar's cells and portals";
  const size_t store_cells = (*model)->cells().size();
  std::map<Visibility, uint64_t> touched;
  // Brute force once per frame (the views are the same for every class).
  std::map<size_t, Reference> references;
  for (size_t f = 0; f < cams->size(); f += 3) references.emplace(f, Reference(scene, View((*cams)[f], 64, 64)));
  for (const Visibility v : {Visibility::kExhaustive, Visibility::kFrustumCull, Visibility::kOcclusionCull,
                             Visibility::kPortals}) {
    SCOPED_TRACE(visibility_name(v));
    WalkOptions o;
    o.width = o.height = 64;
    o.threads = 2;
    o.cache_bytes = 3u << 20;
    o.visibility = v;
    o.cull_back_faces = true;
    auto walk = Walkthrough::open(b.store, o);
    ASSERT_TRUE(walk.is_ok()) << walk.status().to_string();
    uint64_t evicted = 0;
    for (size_t f = 0; f < cams->size(); f += 3) {
      const FrameReport r = (*walk)->frame((*cams)[f]);
      SCOPED_TRACE(r.to_json().dump());
      EXPECT_TRUE(r.complete);
      EXPECT_LE(r.resident_bytes, r.cache_budget);
      ASSERT_TRUE(r.cull.has_value());
      if (v == Visibility::kExhaustive) {
        EXPECT_EQ(r.cells_touched, store_cells);
      }
      if (v == Visibility::kPortals) {
        EXPECT_FALSE(r.cull->portal_fallback) << "the walk stays inside";
      }
      touched[v] += r.cells_touched;
      evicted += r.cells_evicted;
      const std::vector<uint32_t> ids = (*walk)->ids();
      const std::vector<double> depth = (*walk)->depths();
      ASSERT_EQ(depth.size(), ids.size());
      std::string first;
      const View& view = (*walk)->view();
      EXPECT_EQ(mismatches(scene, view, references.at(f), ids, depth, first), 0u) << "frame " << f << ": " << first;
    }
    if (v == Visibility::kExhaustive) {
      EXPECT_GT(evicted, 0u) << "the budget was meant to force eviction mid-frame";
    }
  }
  EXPECT_LT(touched[Visibility::kFrustumCull], touched[Visibility::kExhaustive]);
  EXPECT_LT(touched[Visibility::kOcclusionCull], touched[Visibility::kFrustumCull]);
  EXPECT_LT(touched[Visibility::kPortals], touched[Visibility::kFrustumCull]);
}

}  // namespace
}  // namespace frontier
