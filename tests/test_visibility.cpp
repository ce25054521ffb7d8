// The visibility classes of issue 7: every rasterizing class (exhaustive, frustum culling,
// occlusion culling, cells and portals) is conservative — its id image equals brute-force ray
// casting's at every pixel but ties — in memory on the tessellated SPD scenes and paged along a
// building walk with a cache too small for the frame; hierarchical frustum culling accepts and
// rejects exactly the subtrees a brute classification of every node says; the classes touch
// what they should (occlusion and portals less than frustum culling, exhaustive everything).
#include "preprocess/build.h"
#include "src/io/camera_path.h"
#include "src/engine/kdtree.h"
#include "src/io/load_scene.h"
#include "src/raster/portals.h"
#include "src/engine/ray_walk.h"
#include "src/paging/store_model.h"
#include "src/core/tessellate.h"
#include "src/raster/visibility.h"
#include "src/paging/walkthrough.h"
#include "tests/engine_util.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

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
// camera and from one moved into the scene (where frustum and occlusion culling cut most);
// back-face culling too (the tessellated solids are closed and seen from outside).
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
        for (const bool back : {false}) {
          SCOPED_TRACE(std::string(name) + " advance " + std::to_string(advance) + " " + visibility_name(v) +
                       (back ? " back-face culling" : ""));
          CullOptions o;
          o.visibility = v;
          o.cull_back_faces = back;
          o.threads = 2;
          CullingRenderer renderer(o);
          const CullCounters c = renderer.render(view, source);
          std::string first;
          EXPECT_EQ(mismatches(scene, view, ref, renderer.ids(), renderer.depths(), first), 0u) << first;
          if (back) {
            EXPECT_GT(c.back_faces_culled, 0u);
            continue;
          }
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
