// Frustum casting and ray walking against brute force on random scenes and cameras, plus the
// hard cases: eye on split planes and cell corners, axis-parallel views, extreme field of view,
// far-from-origin coordinates, one-primitive cells, closed meshes that must not leak.
#include "src/core/tessellate.h"
#include "src/engine/packet.h"
#include "src/engine/prim_accel.h"
#include "src/io/load_scene.h"
#include "tests/engine_util.h"

#include <gtest/gtest.h>

#include <tuple>

namespace frontier {
namespace {

using testing::brute_reference;
using testing::compare_ids;
using testing::Comparison;
using testing::render_ids;

// Renders with ray walking and frustum casting, compares both with brute force.
void expect_matches_brute(const Scene& scene, const KdTree& tree, const View& view, const std::string& what,
                          size_t* ties_out = nullptr) {
  std::vector<uint32_t> ref;
  std::vector<uint8_t> tie;
  brute_reference(scene, view, ref, tie);
  // Ray walking, packets and frustum casting with the paper's 2×2 leaves, odd 5×5 leaves and the
  // default, their rays through Embree's BVH (accel) and through the k-d tree.
  const std::tuple<Method, int, bool> runs[] = {{Method::RayWalk, 0, false},
                                                {Method::Packet, 0, true},
                                                {Method::Packet, 0, false},
                                                {Method::Frustum, 2, true},
                                                {Method::Frustum, 5, true},
                                                {Method::Frustum, FrustumCaster::kDefaultLeafPixels, true},
                                                {Method::Frustum, FrustumCaster::kDefaultLeafPixels, false}};
  for (const auto& [m, leaf, accel] : runs) {
    const Comparison c = compare_ids(ref, tie, render_ids(scene, tree, view, m, 2, leaf, accel), view.width);
    EXPECT_EQ(c.mismatches, 0u) << what << " " << method_name(m) << " leaf " << leaf << (accel ? " accel" : " k-d")
                                << ": " << c.first_mismatch;
    if (ties_out) *ties_out += c.ties;
  }
}

using testing::camera_at;

// The counters of one unshaded frustum-casting frame on 2 threads.
Counters frustum_counters(const Scene& scene, const KdTree& tree, const View& view,
                          int leaf = FrustumCaster::kDefaultLeafPixels) {
  Renderer renderer(scene, tree, 2);
  SampleBuffer buffer;
  RenderOptions options;
  options.method = Method::Frustum;
  options.shade = false;
  options.leaf_pixels = leaf;
  return renderer.render(view, options, buffer);
}

// An SPD scene tessellated with `segments` around a circle (empty, with a failure, when it does
// not load).
Scene tessellated_spd(const std::string& name, int segments) {
  Scene loaded;
  const std::string path = std::string(FRONTIER_DATA_DIR) + "/spd/" + name + ".nff";
  if (Status s = load_scene(path, loaded); !s) {
    ADD_FAILURE() << path << ": " << s.to_string();
    return {};
  }
  TessellateOptions tess;
  tess.segments = segments;
  return tessellate(loaded, tess);
}

TEST(EngineRandom, TwoHundredScenesMatchBruteForce) {
  RecordProperty("methods", "ray walking; packets; frustum casting with 2x2, 5x5 and 16x16 leaves: ids against brute force");
  std::mt19937_64 rng(20261122);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  size_t ties = 0, pixels = 0;
  uint64_t packet_rays = 0;
  for (int s = 0; s < 210; ++s) {
    Scene scene = testing::random_scene(rng, 20 + s % 120);
    KdBuildOptions opt;
    opt.max_cell_prims = 1 + uint32_t(s % 5);
    const KdTree tree = KdTree::build(scene, opt);
    const Aabb root = tree.bounds();
    Vec3 eye;
    switch (s % 3) {
      case 0: eye = Vec3(u(rng), u(rng), u(rng)) * 0.9; break;                       // inside
      case 1: eye = Vec3(u(rng), u(rng), u(rng)) * 3.0 + Vec3(0, 0, 3.5); break;    // outside
      default: {                                                                      // on the boundary
        eye = Vec3(u(rng), u(rng), u(rng)) * 0.5;
        eye[s % 3] = (s % 2) ? root.hi[s % 3] : root.lo[s % 3];
      }
    }
    const Vec3 at = Vec3(u(rng), u(rng), u(rng)) * 0.3 + (glm::length(eye) < 1e-3 ? Vec3(0.5, 0, 0) : Vec3(0));
    Camera cam = camera_at(eye, at, 30.0 + 10.0 * (s % 10));
    const View view(cam, 41 + s % 7, 37 + s % 5);
    expect_matches_brute(scene, tree, view, "scene " + std::to_string(s), &ties);
    pixels += 4 * view.pixels();
    if (s % 4 == 0) {
      // The same tessellated: frustum casting traces its leaf frusta as packets only in
      // scenes of triangles alone.
      TessellateOptions tess;
      tess.segments = 6;
      const Scene triangles = tessellate(scene, tess);
      const KdTree triangle_tree = KdTree::build(triangles, opt);
      expect_matches_brute(triangles, triangle_tree, view, "tessellated scene " + std::to_string(s), &ties);
      pixels += 5 * view.pixels();
      packet_rays += frustum_counters(triangles, triangle_tree, view).packet_rays;
    }
    if (HasFailure()) return;
  }
  EXPECT_LT(double(ties), 1e-4 * double(pixels)) << ties << " tie pixels of " << pixels;
  EXPECT_GT(packet_rays, 0u) << "the tessellated scenes' leaf frusta were meant to go as packets";
}

// The three SPD scenes with their own cameras at 129² and 257².
TEST(EngineSpd, RingsTreeShellsMatchBruteForce) {
  RecordProperty("methods", "ray walking; packets; frustum casting with 2x2, 5x5 and 16x16 leaves: ids against brute force");
  for (const char* name : {"rings", "tree", "shells"}) {
    Scene scene;
    const std::string path = std::string(FRONTIER_DATA_DIR) + "/spd/" + name + ".nff";
    ASSERT_TRUE(load_scene(path, scene).is_ok()) << path;
    ASSERT_TRUE(scene.camera.has_value());
    const KdTree tree = KdTree::build(scene, {});
    for (int size : {129, 257}) {
      size_t ties = 0;
      const View view(*scene.camera, size, size);
      expect_matches_brute(scene, tree, view, std::string(name) + " " + std::to_string(size), &ties);
      EXPECT_LT(double(ties), 1e-4 * 4.0 * double(view.pixels())) << name;
    }
  }
}

TEST(EngineHardCases, EyeOnSplitPlanesAndCellCorners) {
  RecordProperty("methods", "ray walking; packets; frustum casting with 2x2, 5x5 and 16x16 leaves: ids against brute force");
  std::mt19937_64 rng(7);
  Scene scene = testing::random_scene(rng, 150);
  const KdTree tree = KdTree::build(scene, {});
  ASSERT_GT(tree.cells().size(), 8u);
  int tried = 0;
  for (size_t n = 0; n < tree.nodes().size() && tried < 12; n += 3) {
    const KdTree::Node& node = tree.nodes()[n];
    if (node.is_leaf()) continue;
    // Eye exactly on this split plane, at the centre of the root in the other axes.
    Vec3 eye = tree.bounds().center();
    eye[int(node.axis_or_leaf)] = node.split;
    for (const Vec3& dir : {Vec3(1, 0.3, 0.2), Vec3(-1, 0.1, -0.3), Vec3(0.2, 1, 0.1)}) {
      expect_matches_brute(scene, tree, View(camera_at(eye, eye + dir), 33, 33), "split plane");
    }
    ++tried;
  }
  // Eye exactly on cell corners.
  for (size_t c = 0; c < tree.cells().size(); c += std::max<size_t>(1, tree.cells().size() / 10)) {
    const Vec3 eye = tree.cell(int32_t(c)).bounds.lo;
    expect_matches_brute(scene, tree, View(camera_at(eye, Vec3(0.0)), 33, 33), "cell corner");
    expect_matches_brute(scene, tree, View(camera_at(eye, eye + Vec3(1, 1, 1)), 33, 33), "cell corner diag");
  }
}

TEST(EngineHardCases, AxisParallelViewDirections) {
  RecordProperty("methods", "ray walking; packets; frustum casting with 2x2, 5x5 and 16x16 leaves: ids against brute force");
  std::mt19937_64 rng(11);
  Scene scene = testing::random_scene(rng, 120);
  const KdTree tree = KdTree::build(scene, {});
  // Odd resolution: the centre pixel's ray is exactly axis-parallel.
  for (int a = 0; a < 3; ++a) {
    for (double sign : {-1.0, 1.0}) {
      Vec3 dir(0.0);
      dir[a] = sign;
      for (const Vec3& eye : {Vec3(0.0), -2.5 * dir, Vec3(0.1, 0.2, 0.3)}) {
        expect_matches_brute(scene, tree, View(camera_at(eye, eye + dir, 50.0), 33, 33), "axis-parallel");
      }
    }
  }
}

TEST(EngineHardCases, WideFieldOfViewAndOneMeshPerCell) {
  RecordProperty("methods", "ray walking; packets; frustum casting with 2x2, 5x5 and 16x16 leaves: ids against brute force");
  std::mt19937_64 rng(13);
  Scene scene = testing::random_scene(rng, 100);
  KdBuildOptions single;
  single.max_cell_prims = 1;
  single.intersection_cost = 100.0;
  const KdTree tree = KdTree::build(scene, single);
  size_t max_count = 0, ones = 0;
  for (const auto& c : tree.cells()) {
    max_count = std::max<size_t>(max_count, c.count);
    ones += c.count <= 1 ? 1 : 0;
  }
  EXPECT_GT(ones, tree.cells().size() / 2) << "most cells should hold at most one primitive";
  expect_matches_brute(scene, tree, View(camera_at(Vec3(0.05, -0.1, 0.0), Vec3(0.3, 1, 0), 170.0), 49, 49), "170 fov");
  expect_matches_brute(scene, tree, View(camera_at(Vec3(0.0, -3.0, 0.0), Vec3(0.0), 170.0), 49, 49), "170 fov out");
}

// Cameras whose centre ray grazes a sphere and a cone (tangent to the surface).
TEST(EngineHardCases, GrazingRaysOnSpheresAndCones) {
  RecordProperty("methods", "ray walking; packets; frustum casting with 2x2, 5x5 and 16x16 leaves: ids against brute force");
  Scene scene;
  scene.materials.push_back({});
  scene.add_sphere({Vec3(0.0), 1.0}, 0, 0);
  scene.add_cone({Vec3(3.0, 0.0, -1.0), 0.8, Vec3(3.0, 0.0, 1.0), 0.3}, 1, 0);
  scene.add_sphere({Vec3(1.2, 0.3, 0.2), 0.25}, 2, 0);
  scene.input_primitives = 3;
  const KdTree tree = KdTree::build(scene, {});
  // Tangent to the unit sphere at (0, 0, 1): the centre pixel's ray touches the top.
  for (double dz : {0.0, 1e-9, -1e-9, 1e-6}) {
    const Vec3 eye(-4.0, 0.0, 1.0 + dz);
    expect_matches_brute(scene, tree, View(camera_at(eye, eye + Vec3(1, 0, 0), 20.0), 65, 65), "sphere tangent");
  }
  // Along the slant of the cone: eye on the line through its surface.
  const Vec3 base(3.0, -0.8, -1.0), apex(3.0, -0.3, 1.0);
  const Vec3 eye = base - 2.0 * (apex - base);
  expect_matches_brute(scene, tree, View(camera_at(eye, apex, 30.0), 65, 65), "cone slant");
  expect_matches_brute(scene, tree, View(camera_at(Vec3(3.0, -0.55, -6.0), Vec3(3.0, -0.55, 0.0), 30.0), 65, 65),
                       "cone axis-parallel graze");
}

TEST(EngineHardCases, FarFromOriginRendersTheSameIds) {
  RecordProperty("methods",
                 "ray walking, packets, frustum casting of the scene moved by 1e6: ids against brute force of the unmoved scene");
  std::mt19937_64 rng(17);
  Scene scene = testing::random_scene(rng, 120);
  Camera cam = camera_at(Vec3(0.3, -2.8, 0.4), Vec3(0.0), 50.0);
  const View view(cam, 65, 65);
  const KdTree tree = KdTree::build(scene, {});
  const auto ids = render_ids(scene, tree, view, Method::Frustum);
  Scene far = scene;
  const Vec3 offset(1e6, -1e6, 1e6);
  far.translate(offset);
  cam.eye += offset;
  cam.look_at += offset;
  const KdTree far_tree = KdTree::build(far, {});
  const View far_view(cam, 65, 65);
  std::vector<uint32_t> ref;
  std::vector<uint8_t> tie;
  brute_reference(scene, view, ref, tie);
  for (Method m : {Method::RayWalk, Method::Packet, Method::Frustum}) {
    const auto far_ids = render_ids(far, far_tree, far_view, m);
    const Comparison c = compare_ids(ref, tie, far_ids, 65);
    // Translation perturbs hit distances at the 1e-10 level: allow only tie pixels to differ.
    EXPECT_EQ(c.mismatches, 0u) << method_name(m) << ": " << c.first_mismatch;
  }
  EXPECT_EQ(compare_ids(ref, tie, ids, 65).mismatches, 0u);
}

// Ray packets (src/engine/packet.h): the edge filter leaves the exact test only a fraction of the
// lane x triangle pairs, every ray is traced by a packet or walked, and the blocks whose rays
// disagree on a direction's sign (an axis-parallel view: the centre row and column) are walked
// and still exact.
TEST(EngineHardCases, PacketsFilterMostTestsAndWalkMixedSigns) {
  RecordProperty("methods", "packets: counters, and ids against brute force with mixed-sign blocks");
  const Scene scene = tessellated_spd("rings", 8);
  ASSERT_GT(scene.size(), 0u);
  const KdTree tree = KdTree::build(scene, {});
  const Camera cam = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
  const View view(cam, 64, 64);
  Renderer renderer(scene, tree, 2);
  SampleBuffer buffer;
  RenderOptions options;
  options.method = Method::Packet;
  options.shade = false;
  options.accel = false;  // the k-d kernel's filter (Embree's BVH: below)
  const Counters c = renderer.render(view, options, buffer);
  EXPECT_EQ(c.packet_rays + c.rays_walked, c.rays);
  EXPECT_EQ(c.rays, 64u * 64u);
  EXPECT_GT(c.packet_filter_tests, 0u);
  EXPECT_LT(c.ray_primitive_tests * 3, c.packet_filter_tests);  // at least two thirds rejected
  EXPECT_GT(c.hits, 0u);

  // Looking down -z at odd size: the centre column and row of blocks mix signs in x and y.
  const Vec3 eye = scene.bounds().center() + Vec3(0.0, 0.0, 2.0 * glm::length(scene.bounds().extent()));
  const View down(camera_at(eye, scene.bounds().center(), 40.0), 33, 33);
  const Counters d = renderer.render(down, options, buffer);
  EXPECT_GT(d.rays_walked, 0u);
  EXPECT_GT(d.packet_rays, 0u);
  expect_matches_brute(scene, tree, down, "packets looking down -z");
  // Through Embree's BVH every block is a packet, mixed signs or not (the ids: just above).
  options.accel = true;
  const Counters e = renderer.render(down, options, buffer);
  EXPECT_EQ(e.rays_walked, 0u);
  EXPECT_EQ(e.packet_rays, 33u * 33u);
  EXPECT_GT(e.accel_rays, 0u);  // those that meet the scene's bounds
}

// The ids of a view's packets traced without a leaf layout (as the paged walk traces them: the
// edge filter per reference); blocks whose lanes mix signs are cast ray by ray.
std::vector<uint32_t> packet_ids_without_layout(const Scene& scene, const KdTree& tree, const View& view) {
  std::vector<uint32_t> ids(view.pixels(), kNoPrim);
  PacketTracer tracer(scene, tree);
  Counters counters;
  for (int by = 0; by < view.height; by += 4) {
    for (int bx = 0; bx < view.width; bx += 4) {
      RayPacket packet;
      int px[kPacketRays], py[kPacketRays];
      for (int y = by; y < std::min(by + 4, view.height); ++y) {
        for (int x = bx; x < std::min(bx + 4, view.width); ++x) {
          const Ray ray = view.ray(x, y);
          px[packet.count] = x;
          py[packet.count] = y;
          packet.add(ray, view.tmin(ray));
        }
      }
      PacketResult result;
      const bool traced = tracer.trace(packet, result, counters);
      for (int l = 0; l < packet.count; ++l) {
        const RayHit hit =
            traced ? result.hit[l] : cast_ray(scene, tree, packet.rays[l], packet.tmin[l], counters, nullptr);
        ids[size_t(py[l]) * size_t(view.width) + size_t(px[l])] = hit.hit() ? scene.prims[hit.prim].source : kNoPrim;
      }
    }
  }
  return ids;
}

// Every instruction set the packet kernel is compiled for that this CPU runs gives the ids of
// brute force: with the leaf layout (in-memory frames: packets, frustum casting) and without it
// (the paged walk), on tessellated rings, and on triangles 1e6 from the origin seen from a
// grazing eye.
TEST(EngineHardCases, EveryPacketKernelTheCpuRunsMatchesBruteForce) {
  RecordProperty("methods", "packets and frustum casting under each packet kernel (baseline, AVX2, AVX-512): ids against brute force");
  struct Case {
    std::string name;
    Scene scene;
    KdTree tree;
    View view;
    std::vector<uint32_t> ref;
    std::vector<uint8_t> tie;
  };
  std::vector<Case> cases;
  {
    Scene rings = tessellated_spd("rings", 6);
    ASSERT_GT(rings.size(), 0u);
    const Camera cam = rings.camera ? *rings.camera : automatic_camera(rings.bounds());
    KdTree tree = KdTree::build(rings, {});
    cases.push_back({"rings", std::move(rings), std::move(tree), View(cam, 40, 40), {}, {}});
  }
  {
    std::mt19937_64 rng(23);
    Scene far;
    far.materials.push_back({});
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const Vec3 offset(1e6, -1e6, 1e6);
    for (uint32_t i = 0; i < 400; ++i) {
      const Vec3 c = offset + Vec3(u(rng), u(rng), 0.05 * u(rng));
      far.add_triangle({c, c + 0.2 * Vec3(u(rng), u(rng), 0.1 * u(rng)), c + 0.2 * Vec3(u(rng), u(rng), 0.1 * u(rng))},
                       i, 0);
    }
    const Vec3 centre = far.bounds().center();
    const Camera grazing = camera_at(centre + Vec3(-2.5, -0.3, 0.08), centre + Vec3(0.0, 0.0, -0.02), 50.0);
    KdTree tree = KdTree::build(far, {});
    cases.push_back({"far and grazing", std::move(far), std::move(tree), View(grazing, 49, 37), {}, {}});
  }
  for (Case& c : cases) brute_reference(c.scene, c.view, c.ref, c.tie);

  const PacketIsa best = packet_isa();
  int kernels = 0;
  for (const PacketIsa isa : {PacketIsa::Baseline, PacketIsa::Avx2, PacketIsa::Avx512}) {
    if (!use_packet_isa(isa)) {
      EXPECT_FALSE(packet_isa_supported(isa));
      continue;
    }
    ++kernels;
    ASSERT_EQ(packet_isa(), isa);
    for (const Case& c : cases) {
      const std::string what = c.name + ", kernel " + std::to_string(int(isa));
      for (const Method m : {Method::Packet, Method::Frustum}) {
        const Comparison r = compare_ids(c.ref, c.tie, render_ids(c.scene, c.tree, c.view, m), c.view.width);
        EXPECT_EQ(r.mismatches, 0u) << what << " " << method_name(m) << ": " << r.first_mismatch;
      }
      const Comparison r = compare_ids(c.ref, c.tie, packet_ids_without_layout(c.scene, c.tree, c.view), c.view.width);
      EXPECT_EQ(r.mismatches, 0u) << what << " without a layout: " << r.first_mismatch;
    }
  }
  EXPECT_TRUE(use_packet_isa(best));
  EXPECT_GE(kernels, 1);  // the baseline runs everywhere
  EXPECT_TRUE(packet_isa_supported(PacketIsa::Baseline));
}

// The edge filter's margin: rays that pass a triangle's edges or corners by 1e-9 to 1e-5 of its
// size, on either side, near the origin and 1e6 from it, get from every packet kernel (with the
// leaf layout and without) exactly what the watertight test gives them alone. A filter whose
// margin did not cover its rounding (single precision in the layout's) rejects rays just inside.
TEST(EngineHardCases, PacketFilterKeepsEveryRayTheExactTestHits) {
  RecordProperty("methods", "packet kernels with and without the leaf layout, and through Embree's BVH (PrimAccel): hit or miss of rays grazing edges and corners, against intersect_triangle");
  std::mt19937_64 rng(41);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const PacketIsa best = packet_isa();
  size_t rays = 0, hits = 0;
  for (const double offset : {0.0, 1e3, 1e6}) {
    Scene scene;
    scene.materials.push_back({});
    const Vec3 o(offset, offset, -offset);
    for (int i = 0; i < 24; ++i) {
      const Vec3 c = o + Vec3(4.0 * u(rng), 4.0 * u(rng), 0.2 * u(rng));
      const Triangle t{c, c + Vec3(0.2 + u(rng), 0.3 * u(rng), 0.1 * u(rng)), c + Vec3(0.3 * u(rng), 0.2 + u(rng), 0.1 * u(rng))};
      scene.add_triangle(t, uint32_t(i), 0);
    }
    const KdTree tree = KdTree::build(scene, {});
    const PacketLayout layout(scene, tree);
    const PrimAccel accel = PrimAccel::build(scene);
    // One eye below and before every triangle: every direction has positive components.
    const Vec3 eye = o + Vec3(-3.0, -2.0, -1.5);
    // The kernels the CPU runs, with and without the layout; then (isa -1) Embree's BVH.
    for (const int isa_or_accel : {int(PacketIsa::Baseline), int(PacketIsa::Avx2), int(PacketIsa::Avx512), -1}) {
      const auto isa = PacketIsa(isa_or_accel);
      const bool with_accel = isa_or_accel < 0;
      if (!with_accel && !use_packet_isa(isa)) continue;
      for (const PacketLayout* l : {&layout, static_cast<const PacketLayout*>(nullptr)}) {
        if (with_accel && l != nullptr) continue;
        PacketTracer tracer(scene, tree, nullptr, nullptr, l, with_accel ? &accel : nullptr);
        Counters counters;
        for (int p = 0; p < 200; ++p) {
          RayPacket packet;
          while (packet.count < kPacketRays) {
            // A point on an edge (or a corner), moved off it within the triangle's plane by a
            // tiny share of the edge, inwards or outwards, and a little along the normal.
            const Triangle& t = scene.triangles[size_t(rng() % scene.triangles.size())];
            const Vec3 v[3] = {t.v0, t.v1, t.v2};
            const int e = int(rng() % 3);
            const Vec3 a = v[e], b = v[(e + 1) % 3], c = v[(e + 2) % 3];
            const double along = rng() % 4 == 0 ? 0.0 : u(rng);
            const Vec3 on_edge = a + along * (b - a);
            const double tiny = std::pow(10.0, -9.0 + 4.0 * u(rng)) * (rng() % 2 == 0 ? 1.0 : -1.0);
            const Vec3 target = on_edge + tiny * (c - on_edge);
            packet.add(Ray(eye, target - eye), 0.0);
          }
          PacketResult result;
          ASSERT_TRUE(tracer.trace(packet, result, counters));
          if (with_accel) {
            ASSERT_EQ(counters.accel_rays, uint64_t(p + 1) * kPacketRays) << "offset " << offset << ": not Embree's";
          }
          for (int k = 0; k < packet.count; ++k) {
            Counters brute;
            const RayHit reference = brute_force_hit(scene, packet.rays[k], 0.0, brute);
            const bool any = reference.hit();
            const double nearest = reference.t;
            ++rays;
            hits += any ? 1 : 0;
            ASSERT_EQ(result.hit[k].hit(), any) << "offset " << offset << ", kernel " << isa_or_accel
                                                << (l ? ", layout" : ", no layout") << ", packet " << p << " lane " << k;
            if (any) {
              EXPECT_EQ(result.hit[k].t, nearest);
              EXPECT_EQ(result.hit[k].prim, reference.prim);
            }
          }
        }
      }
    }
  }
  EXPECT_TRUE(use_packet_isa(best));
  // Both sides of the edges: many rays hit, many miss.
  EXPECT_GT(hits, rays / 5);
  EXPECT_LT(hits, rays * 4 / 5);
}

// A few curved primitives among many triangles: leaf frusta still go as packets (which test the
// spheres exactly per lane), and every method still equals brute force. Each sphere is the
// original of one of rings.nff's tessellated spheres, so its surface bulges out between the
// tessellation's vertices: hits on either lie within a hair of each other.
TEST(EngineHardCases, PacketsWithAFewSpheresAmongTrianglesMatchBruteForce) {
  RecordProperty("methods", "frustum casting with packets over triangles and a few spheres: ids against brute force");
  Scene loaded;
  const std::string path = std::string(FRONTIER_DATA_DIR) + "/spd/rings.nff";
  ASSERT_TRUE(load_scene(path, loaded)) << path;
  Scene scene = tessellated_spd("rings", 6);
  ASSERT_GT(scene.size(), 0u);
  for (uint32_t i = 0, added = 0; i < loaded.size() && added < 6; ++i) {
    if (loaded.prims[i].kind != PrimKind::Sphere) continue;
    scene.add_sphere(loaded.spheres[loaded.prims[i].index], uint32_t(scene.size()), loaded.prims[i].material);
    ++added;
  }
  ASSERT_GT(scene.spheres.size(), 0u);
  ASSERT_LE(64 * scene.spheres.size(), scene.size()) << "a few curved primitives among many triangles";
  const KdTree tree = KdTree::build(scene, {});
  const Camera cam = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
  const View view(cam, 48, 48);
  EXPECT_GT(frustum_counters(scene, tree, view).packet_rays, 0u) << "leaf frusta were meant to go as packets";
  expect_matches_brute(scene, tree, view, "rings tessellated, with six of its spheres");
  // Close to the first sphere, which then fills much of the view.
  const Sphere& s = scene.spheres.front();
  const View near(camera_at(s.center + Vec3(0.0, -4.0 * s.radius, 1.5 * s.radius), s.center, 40.0), 32, 32);
  expect_matches_brute(scene, tree, near, "close to one of the spheres");
}

// Walls and floors that cover whole frusta are filled without a ray per pixel (fill_plane):
// a floor of two triangles, a wall, and spheres, cones and small triangles standing on and in
// front of them (occluders, some within a hair of the floor), seen from high, from a grazing
// eye just above the floor, from below it, and all of it moved 1e6 from the origin.
TEST(EngineHardCases, FilledFloorsAndWallsMatchBruteForce) {
  RecordProperty("methods", "frustum casting with plane fills, ray walking: ids against brute force; fills counted");
  std::mt19937_64 rng(31);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const Vec3& offset : {Vec3(0.0), Vec3(1e6, -1e6, 1e6)}) {
    Scene scene;
    scene.materials.push_back({});
    uint32_t source = 0;
    auto quad = [&](const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
      scene.add_triangle({a, b, c}, source, 0);
      scene.add_triangle({a, c, d}, source++, 0);
    };
    quad(Vec3(-8, -8, 0), Vec3(8, -8, 0), Vec3(8, 8, 0), Vec3(-8, 8, 0));      // floor
    quad(Vec3(-8, 6, 0), Vec3(8, 6, 0), Vec3(8, 6, 4), Vec3(-8, 6, 4));        // wall
    for (int i = 0; i < 40; ++i) {
      const Vec3 c(4.0 * u(rng), 4.0 * u(rng), 0.0);
      const double r = 0.1 + 0.3 * std::abs(u(rng));
      switch (i % 4) {
        case 0: scene.add_sphere({c + Vec3(0, 0, r), r}, source++, 0); break;             // touching
        case 1: scene.add_sphere({c + Vec3(0, 0, r + 1e-9), r}, source++, 0); break;      // a hair above
        case 2: scene.add_cone({c, r, c + Vec3(0, 0, 1.5), 0.5 * r}, source++, 0); break;
        default: scene.add_triangle({c + Vec3(0, 0, 0.5), c + Vec3(r, 0, 0.8), c + Vec3(0, r, 1.2)}, source++, 0);
      }
    }
    scene.input_primitives = source;
    scene.translate(offset);
    const KdTree tree = KdTree::build(scene, {});
    const Vec3 eyes[] = {Vec3(-6, -7, 5), Vec3(-7, -7, 1e-3), Vec3(0.3, -7.5, 0.05), Vec3(2, -6, -2)};
    const Vec3 ats[] = {Vec3(0, 0, 0), Vec3(5, 5, 0.2), Vec3(0.2, 5, 0.5), Vec3(0, 2, 1)};
    uint64_t fills = 0;
    for (size_t k = 0; k < 4; ++k) {
      // Odd views have a near plane: the floor reaches behind the eye and is clipped there
      // (View::project), so its screen rectangles shrink to where it is seen.
      const double near = k % 2 ? 0.7 : 0.0;
      const View view(camera_at(eyes[k] + offset, ats[k] + offset, 60.0, near), 97, 89);
      expect_matches_brute(scene, tree, view, "floor view " + std::to_string(k) + (offset.x != 0.0 ? " far" : ""));
      fills += frustum_counters(scene, tree, view).frustum_fills;
    }
    EXPECT_GT(fills, 20u) << "the floor and wall should fill whole frusta";
  }
}

// Frusta that cannot advance through a fine tree ask it which few elements lie ahead
// (gather_ahead) and test only those: a floor under a sparse "tree" of slanted cones and
// spheres, with sky around it, seen from the side, from inside the crown, straight down (the
// view's directions change sign on two axes), grazing the floor, from outside the root, and
// moved 1e6 from the origin.
TEST(EngineHardCases, LookAheadMatchesBruteForce) {
  RecordProperty("methods", "frustum casting with look-ahead, ray walking: ids against brute force; look-aheads counted");
  std::mt19937_64 rng(77);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const Vec3& offset : {Vec3(0.0), Vec3(-1e6, 1e6, 1e6)}) {
    Scene scene;
    scene.materials.push_back({});
    uint32_t source = 0;
    scene.add_triangle({Vec3(-20, -20, 0), Vec3(20, -20, 0), Vec3(20, 20, 0)}, source, 0);
    scene.add_triangle({Vec3(-20, -20, 0), Vec3(20, 20, 0), Vec3(-20, 20, 0)}, source++, 0);
    for (int i = 0; i < 60; ++i) {
      const Vec3 base(1.5 * u(rng), 1.5 * u(rng), 1.0 + 2.0 * std::abs(u(rng)));
      const Vec3 tip = base + Vec3(u(rng), u(rng), 0.5 * u(rng));
      const double r = 0.02 + 0.05 * std::abs(u(rng));
      scene.add_cone({base, r, tip, 0.5 * r}, source++, 0);
      scene.add_sphere({tip, 1.5 * r}, source++, 0);
    }
    scene.add_cone({Vec3(0, 0, 0), 0.2, Vec3(0, 0, 2), 0.1}, source++, 0);  // trunk, standing on the floor
    scene.input_primitives = source;
    scene.translate(offset);
    KdBuildOptions opt;
    opt.max_cell_prims = 2;
    const KdTree tree = KdTree::build(scene, opt);
    const Vec3 eyes[] = {Vec3(6, 1, 2), Vec3(0.3, 0.2, 2.0), Vec3(0.01, 0.02, 12), Vec3(7, -6, 1e-3), Vec3(30, 25, 9)};
    const Vec3 ats[] = {Vec3(0, 0, 1.8), Vec3(2, 1, 2.5), Vec3(0.01, 0.02, 0), Vec3(0, 0, 0.3), Vec3(0, 0, 1)};
    uint64_t lookaheads = 0;
    for (size_t k = 0; k < 5; ++k) {
      const double near = k == 0 || k == 3 ? 0.5 : 0.0;  // clips the floor behind the eye
      const View view(camera_at(eyes[k] + offset, ats[k] + offset, k == 1 ? 100.0 : 50.0, near), 129, 121);
      expect_matches_brute(scene, tree, view, "look-ahead view " + std::to_string(k) + (offset.x != 0.0 ? " far" : ""));
      // At this image size the default leaf makes every frustum start small: count with 5.
      lookaheads += frustum_counters(scene, tree, view, 5).frustum_lookaheads;
    }
    EXPECT_GT(lookaheads, 50u) << "frusta over the floor and the sky should resolve by looking ahead";
  }
}

// A box's screen rectangle holds every pixel whose ray hits the box beyond the near plane,
// also for boxes reaching behind the eye (clipped at the near plane). Floors under the eye get
// rectangles smaller than the view.
TEST(EngineHardCases, ScreenRectanglesHoldEveryHitBeyondTheNearPlane) {
  RecordProperty("methods", "View::project against ray-box intersection at every pixel");
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  size_t clipped = 0, smaller = 0, hits = 0;
  for (int s = 0; s < 600; ++s) {
    const Vec3 offset = s % 3 == 2 ? Vec3(1e6, -1e6, 1e6) : Vec3(0.0);
    const double near = s % 4 == 0 ? 0.0 : 0.05 + std::abs(u(rng));
    const Vec3 eye = Vec3(u(rng), u(rng), u(rng)) + offset;
    const View view(camera_at(eye, eye + Vec3(u(rng), u(rng), 0.3 * u(rng)) + Vec3(0.1, 0, 0), 30.0 + 40.0 * std::abs(u(rng)), near), 40, 33);
    Aabb box;
    const Vec3 c = eye + 2.0 * Vec3(u(rng), u(rng), u(rng));
    const Vec3 h = s % 2 ? Vec3(3.0 * std::abs(u(rng)), 3.0 * std::abs(u(rng)), 1e-3)  // a floor
                         : Vec3(std::abs(u(rng)), std::abs(u(rng)), std::abs(u(rng)));
    box.lo = c - h;
    box.hi = c + h;
    int x0, y0, x1, y1;
    if (!view.project(box, x0, y0, x1, y1)) continue;
    bool behind = false;
    for (int k = 0; k < 8; ++k) {
      const Vec3 p(k & 1 ? box.hi.x : box.lo.x, k & 2 ? box.hi.y : box.lo.y, k & 4 ? box.hi.z : box.lo.z);
      behind = behind || glm::dot(p - eye, view.forward) < near;
    }
    clipped += behind ? 1 : 0;
    if (behind && (x1 - x0 + 1) * (y1 - y0 + 1) < view.width * view.height / 2) ++smaller;
    for (int y = 0; y < view.height; ++y) {
      for (int x = 0; x < view.width; ++x) {
        const Ray ray = view.ray(x, y);
        double t0, t1;
        if (!ray_box_interval(ray, box, t0, t1) || t1 < view.tmin(ray)) continue;
        ++hits;
        ASSERT_TRUE(x >= x0 && x <= x1 && y >= y0 && y <= y1)
            << "box " << s << " pixel " << x << "," << y << " outside [" << x0 << "," << x1 << "]x[" << y0 << "," << y1
            << "] near " << near;
      }
    }
  }
  EXPECT_GT(clipped, 100u) << "boxes reaching behind the near plane should be bounded";
  EXPECT_GT(smaller, 20u) << "clipped boxes should cover less than the view";
  EXPECT_GT(hits, 10000u);
}

// A closed UV sphere of triangles: no background pixel may appear inside its silhouette.
TEST(EngineHardCases, ClosedTessellatedSphereLeaksNothing) {
  RecordProperty("methods",
                 "frustum casting, ray walking, packets: no background pixel inside the silhouette, 100 directions");
  Scene scene;
  scene.materials.push_back({});
  const int stacks = 24, slices = 48;
  auto point = [&](int i, int j) {
    const double th = 3.14159265358979323846 * i / stacks, ph = 2 * 3.14159265358979323846 * (j % slices) / slices;
    return Vec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th));
  };
  uint32_t id = 0;
  for (int i = 0; i < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      const Vec3 a = point(i, j), b = point(i + 1, j), c = point(i + 1, j + 1), d = point(i, j + 1);
      if (i != stacks - 1) scene.add_triangle({a, b, c}, id++, 0);
      if (i != 0) scene.add_triangle({a, c, d}, id++, 0);
    }
  }
  scene.input_primitives = id;
  KdBuildOptions opt;
  opt.max_cell_prims = 4;
  const KdTree tree = KdTree::build(scene, opt);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g;
  // The inscribed radius of the tessellation: rays passing closer than this must hit.
  const double inner = std::cos(3.14159265358979323846 / stacks) * std::cos(3.14159265358979323846 / slices) * 0.98;
  for (int k = 0; k < 100; ++k) {
    Vec3 dir = glm::normalize(Vec3(g(rng), g(rng), g(rng)));
    Camera cam = camera_at(3.0 * dir, Vec3(0.0), 45.0);
    const View view(cam, 65, 65);
    const auto ids = render_ids(scene, tree, view, Method::Frustum);
    const auto walk_ids = render_ids(scene, tree, view, Method::RayWalk);
    const auto packet_ids = render_ids(scene, tree, view, Method::Packet);
    size_t leaks = 0;
    for (int y = 0; y < view.height; ++y) {
      for (int x = 0; x < view.width; ++x) {
        const Ray r = view.ray(x, y);
        const double dist = glm::length(glm::cross(r.dir, -r.origin));  // distance of the ray to the centre
        const size_t i = size_t(y) * 65 + size_t(x);
        if (dist < inner && (ids[i] == kNoPrim || walk_ids[i] == kNoPrim || packet_ids[i] == kNoPrim)) ++leaks;
      }
    }
    ASSERT_EQ(leaks, 0u) << "direction " << k;
  }
}

// Primitives that no plane separates: shells.nff's stacks of overlapping spheres, tessellated
// coarsely (138 k triangles). The cell-size cap must not force splits that copy nearly every
// primitive into both children, which doubles the references at every level down to max_depth:
// before forced splits were limited this build took 24 GB (8 segments: 21 GB).
TEST(EngineHardCases, InseparableClustersKeepTheTreeSmall) {
  RecordProperty("methods", "k-d tree build: references per primitive; frustum casting ids against brute force");
  const Scene scene = tessellated_spd("shells", 6);
  ASSERT_GT(scene.size(), 0u);
  const KdTree tree = KdTree::build(scene, {});
  EXPECT_LT(double(tree.reference_count()), 40.0 * double(scene.size()))
      << tree.reference_count() << " references for " << scene.size() << " primitives in " << tree.cells().size()
      << " cells";
  expect_matches_brute(scene, tree, View(camera_at(Vec3(4.5, -6.0, 3.0), Vec3(4.5, 0.0, 0.0), 50.0), 65, 65),
                       "clusters");
}


// An eye so far from the scene that Embree's float rays could stray past the boxes' margin
// (PrimAccel::usable): the packet goes through the k-d tree instead, with the same hits; an
// eye nearby goes through Embree's BVH.
TEST(EngineHardCases, EmbreeBvhHandsFarEyesToTheKdTree) {
  RecordProperty("methods", "packets through Embree's BVH (PrimAccel) against brute force, eye near and 1e4 scene sizes away");
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Scene scene;
  scene.materials.push_back({});
  for (int i = 0; i < 200; ++i) {
    const Vec3 c(u(rng), u(rng), 0.1 * u(rng));
    scene.add_triangle(Triangle{c, c + Vec3(0.05, 0.01, 0.0), c + Vec3(0.0, 0.05, 0.01)}, uint32_t(i), 0);
  }
  const KdTree tree = KdTree::build(scene, {});
  const PrimAccel accel = PrimAccel::build(scene);
  ASSERT_FALSE(accel.empty());
  for (const double distance : {2.0, 2e4}) {
    PacketTracer tracer(scene, tree, nullptr, nullptr, nullptr, &accel);
    Counters counters;
    const Vec3 eye(-1.0, -1.0, -distance);  // every direction positive: the k-d kernel takes them all
    size_t hits = 0;
    for (int p = 0; p < 64; ++p) {
      RayPacket packet;
      while (packet.count < kPacketRays) {
        const Vec3 target(u(rng), u(rng), 0.05);
        packet.add(Ray(eye, target - eye), 0.0);
      }
      PacketResult result;
      ASSERT_TRUE(tracer.trace(packet, result, counters));
      for (int k = 0; k < packet.count; ++k) {
        Counters brute;
        const RayHit reference = brute_force_hit(scene, packet.rays[k], 0.0, brute);
        ASSERT_EQ(result.hit[k].prim, reference.prim) << "distance " << distance << ", packet " << p << " lane " << k;
        if (reference.hit()) {
          EXPECT_EQ(result.hit[k].t, reference.t);
        }
        hits += reference.hit() ? 1 : 0;
      }
    }
    EXPECT_GT(hits, 64u * kPacketRays / 10);
    if (distance < 10.0) {
      EXPECT_EQ(counters.accel_rays, 64u * kPacketRays);
    } else {
      EXPECT_EQ(counters.accel_rays, 0u);  // the k-d kernel's
    }
  }
}


// KernelChoice: packets alternate until both kernels have traced enough rays, then the faster
// (per ray) takes every packet but one in kExplore, and the choice follows new measurements.
TEST(EngineKernelChoice, TakesTheFasterKernelAndKeepsMeasuringTheOther) {
  KernelChoice choice;
  bool timed = false;
  EXPECT_TRUE(choice.use_accel(0, timed));
  EXPECT_TRUE(timed);
  EXPECT_FALSE(choice.use_accel(1, timed));
  EXPECT_TRUE(timed);
  const uint64_t n = KernelChoice::kMeasureRays;
  choice.record(true, 300 * n, n);  // Embree's BVH: 300 ns a ray
  choice.record(false, 100 * n, n);  // the k-d tree: 100
  EXPECT_FALSE(choice.prefers_accel());
  uint64_t accel = 0, timings = 0;
  for (uint64_t p = 0; p < 64 * KernelChoice::kExplore; ++p) {
    accel += choice.use_accel(p, timed) ? 1 : 0;
    timings += timed ? 1 : 0;
  }
  EXPECT_EQ(accel, 64u);      // exploring, once in kExplore
  EXPECT_EQ(timings, 128u);   // those and as many of the chosen kernel's
  // Embree's BVH turns out faster where the view went: the choice follows.
  choice.record(true, 10 * 64 * n, 64 * n);
  EXPECT_TRUE(choice.prefers_accel());
  accel = 0;
  for (uint64_t p = 0; p < 64 * KernelChoice::kExplore; ++p) accel += choice.use_accel(p, timed) ? 1 : 0;
  EXPECT_EQ(accel, 64u * (KernelChoice::kExplore - 1));
}

}  // namespace
}  // namespace frontier
