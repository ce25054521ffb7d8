// Immediate-mode ray casting: the same first hit as brute-force ray casting at every pixel but
// ties (SPD scenes at 129² and 513², a random scene, a camera inside a bound), bounds that
// enclose their surfaces, and clip planes, capping, back-sample culling and texture coordinates
// changing exactly the pixels they should.
#include "src/io/load_scene.h"
#include "src/raster/imr.h"
#include "src/core/scene.h"
#include "src/core/view.h"
#include "tests/engine_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <random>

namespace frontier {
namespace {

// IMR ids against brute force: differing pixels must be ties.
testing::Comparison compare_with_brute_force(const Scene& scene, const View& view, ImrRenderer& imr,
                                             ImrCounters* counters = nullptr) {
  std::vector<uint32_t> reference;
  std::vector<uint8_t> tie;
  testing::brute_reference(scene, view, reference, tie);
  const ImrCounters c = imr.render(view);
  if (counters != nullptr) *counters = c;
  return testing::compare_ids(reference, tie, source_ids(scene, imr.rasterizer().ids()), view.width);
}

View scene_view(const Scene& scene, int size) {
  return View(scene.camera ? *scene.camera : automatic_camera(scene.bounds()), size, size);
}

// At 129² and 513², unordered and front to back.
void expect_spd_equals_brute_force(const char* name) {
  Scene scene;
  ASSERT_TRUE(load_scene(testing::spd(name), scene).is_ok()) << name;
  ImrOptions options;
  options.order = IssueOrder::kRandom;
  ImrRenderer unordered(scene, options);
  options.order = IssueOrder::kFrontToBack;
  ImrRenderer ordered(scene, options);
  for (const int size : {129, 513}) {
    const View view = scene_view(scene, size);
    std::vector<uint32_t> reference;
    std::vector<uint8_t> tie;
    testing::brute_reference(scene, view, reference, tie);
    for (ImrRenderer* imr : {&unordered, &ordered}) {
      const ImrCounters c = imr->render(view);
      const char* order = issue_order_name(imr->options().order);
      const testing::Comparison cmp =
          testing::compare_ids(reference, tie, source_ids(scene, imr->rasterizer().ids()), view.width);
      EXPECT_EQ(cmp.mismatches, 0u) << name << " " << size << " " << order << ": " << cmp.first_mismatch;
      EXPECT_LT(cmp.ties, cmp.pixels / 1000 + 1) << name << " " << size;
      // Rays are cast only where bounds pass the depth test, and most of them hit.
      EXPECT_GT(c.ray_object_tests, 0u);
      EXPECT_LE(c.ray_object_hits, c.ray_object_tests);
      EXPECT_GT(double(c.ray_object_hits), 0.5 * double(c.ray_object_tests)) << name << " " << order;
      EXPECT_EQ(c.texture_fetches, 0u);  // no scene declares textures
    }
  }
}

// Separate tests (and a suite of their own, left out of the sanitizer run) so CTest spreads
// the brute-force references over the cores.
TEST(ImrSpd, RingsEqualBruteForce) { expect_spd_equals_brute_force("rings"); }
TEST(ImrSpd, TreeEqualsBruteForce) { expect_spd_equals_brute_force("tree"); }
TEST(ImrSpd, ShellsEqualBruteForce) { expect_spd_equals_brute_force("shells"); }

TEST(Imr, EqualsBruteForceOnRandomScenesFromAnywhere) {
  std::mt19937_64 rng(7);
  for (int round = 0; round < 4; ++round) {
    Scene scene = testing::random_scene(rng, 60);
    ImrRenderer imr(scene);
    std::uniform_real_distribution<double> u(-2.5, 2.5);
    for (int v = 0; v < 3; ++v) {
      Camera cam;
      cam.eye = Vec3(u(rng), u(rng), u(rng));
      cam.look_at = Vec3(u(rng), u(rng), u(rng)) * 0.2;
      cam.vfov_deg = 60.0;
      const View view(cam, 97, 83);
      const testing::Comparison cmp = compare_with_brute_force(scene, view, imr);
      EXPECT_EQ(cmp.mismatches, 0u) << "round " << round << " view " << v << ": " << cmp.first_mismatch;
    }
  }
}

TEST(Imr, CameraInsideABoundStillSeesTheSurface) {
  Scene scene;
  ASSERT_TRUE(load_scene(testing::spd("shells"), scene).is_ok());
  // The largest sphere, eyed from between its surface and its bound's outermost vertex.
  uint32_t largest = 0;
  for (uint32_t i = 0; i < scene.size(); ++i) {
    if (scene.prims[i].kind == PrimKind::Sphere &&
        (scene.prims[largest].kind != PrimKind::Sphere ||
         scene.spheres[scene.prims[i].index].radius > scene.spheres[scene.prims[largest].index].radius)) {
      largest = i;
    }
  }
  const Sphere& s = scene.spheres[scene.prims[largest].index];
  ImrOptions options;
  options.slices = 6;
  ImrRenderer imr(scene, options);
  const BoundingPolyhedron bound = bounding_polyhedron(scene, largest, 6, 3);
  Vec3 far_vertex = bound.vertices[0];
  for (const Vec3& v : bound.vertices) {
    if (glm::length(v) > glm::length(far_vertex)) far_vertex = v;
  }
  const Vec3 dir = glm::normalize(far_vertex);
  const double between = 0.5 * (s.radius + glm::length(far_vertex));
  ASSERT_TRUE(bound.contains(dir * between));
  for (const double near : {0.0, 0.01 * s.radius}) {
    Camera cam;
    cam.eye = s.center + dir * between;
    cam.look_at = s.center;
    cam.up = std::abs(dir.z) < 0.9 ? Vec3(0, 0, 1) : Vec3(1, 0, 0);
    cam.vfov_deg = 90.0;
    cam.near = near;
    const View view(cam, 65, 65);
    ImrCounters c;
    const testing::Comparison cmp = compare_with_brute_force(scene, view, imr, &c);
    EXPECT_EQ(cmp.mismatches, 0u) << cmp.first_mismatch;
    EXPECT_GE(c.near_caps, 1u);
    const std::vector<uint32_t>& ids = imr.rasterizer().ids();
    EXPECT_GT(std::count(ids.begin(), ids.end(), largest), 100) << "the sphere in front of the eye is drawn";
  }
}

// Surface points of every curved kind lie inside their bounds, at every tessellation level.
TEST(Imr, BoundsEncloseTheirSurfaces) {
  Scene scene;
  scene.materials.push_back({});
  scene.add_sphere({Vec3(1e6, -2e5, 3.0), 2.7}, 0, 0);
  scene.add_cone({Vec3(0, 0, 0), 0.5, Vec3(1, 2, 3), 0.2}, 1, 0);
  scene.add_cone({Vec3(5, 5, 5), 0.0, Vec3(4, 5, 5.5), 1.3}, 2, 0);  // pointed at the base
  scene.add_cone({Vec3(-3, 1, 0), 0.4, Vec3(-3, 1, 9), 0.4}, 3, 0);  // a cylinder
  Quadric ellipsoid;  // x²/4 + y² + z²/9 = 1, kept where x <= 1
  ellipsoid.coeff = {0.25, 1, 1.0 / 9.0, 0, 0, 0, 0, 0, 0, -1};
  ellipsoid.clip[0] = Vec4(1, 0, 0, -1);
  ellipsoid.clip_count = 1;
  ellipsoid.bounds = Aabb(Vec3(-2, -1, -3), Vec3(1, 1, 3));
  scene.add_quadric(ellipsoid, 4, 0);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const int slices : {3, 4, 5, 7, 8, 12, 25}) {
    for (uint32_t i = 0; i < scene.size(); ++i) {
      ImplicitSurface s;
      ASSERT_TRUE(implicit_surface_of(scene, i, s));
      const BoundingPolyhedron b = bounding_polyhedron(scene, i, slices, std::max(2, slices / 2));
      ASSERT_FALSE(b.faces.empty());
      const double tolerance = 1e-9 * s.scale();
      for (const Vec3& v : b.vertices) ASSERT_TRUE(b.contains(v, tolerance)) << "convex, slices " << slices;
      for (size_t f = 0; f < b.faces.size(); ++f) {
        for (const uint32_t v : b.faces[f]) {
          ASSERT_LE(std::abs(glm::dot(Vec3(b.planes[f]), b.vertices[v]) + b.planes[f].w), tolerance) << "face plane";
        }
      }
      int sampled = 0;
      for (int k = 0; k < 4000; ++k) {
        // A point on the surface: a random ray from inside the bounds' centre region.
        const Vec3 inner = s.bounds.center() + 0.05 * (Vec3(u(rng), u(rng), u(rng)) - 0.5) * (s.bounds.hi - s.bounds.lo);
        const double theta = 2.0 * M_PI * u(rng), z = 2.0 * u(rng) - 1.0;
        const Vec3 dir(std::sqrt(1 - z * z) * std::cos(theta), std::sqrt(1 - z * z) * std::sin(theta), z);
        SurfaceSample hit;
        if (!cast_surface(s, Ray(inner + s.origin, dir), 0.0, kInfinity, false, hit)) continue;
        const Vec3 p = inner + hit.t * dir;
        ++sampled;
        ASSERT_TRUE(b.contains(p)) << "prim " << i << " slices " << slices << " point " << p.x << "," << p.y << ","
                                   << p.z;
      }
      EXPECT_GT(sampled, 500) << "prim " << i;
    }
  }
}

// A unit sphere at the origin, cut to z <= 0 (a bowl), looked at from above: the clip plane
// removes exactly the pixels whose first root has z > 0; they then see the bowl's inside
// (back samples), nothing with back-sample culling, and the flat cap when capped.
TEST(Imr, ClipPlanesCappingAndBackSampleCullingChangeExactlyTheirPixels) {
  auto make = [](bool clipped) {
    Scene scene;
    scene.materials.push_back({});
    Quadric q;
    q.coeff = {1, 1, 1, 0, 0, 0, 0, 0, 0, -1};
    q.bounds = Aabb(Vec3(-1), Vec3(1));
    if (clipped) {
      q.clip[0] = Vec4(0, 0, 1, 0);  // z <= 0
      q.clip_count = 1;
      q.bounds.hi.z = 0.0;
    }
    scene.add_quadric(q, 0, 0);
    return scene;
  };
  Camera cam;
  cam.eye = Vec3(0.3, 0.2, 4.0);
  cam.look_at = Vec3(0, 0, 0);
  cam.vfov_deg = 40.0;
  const View view(cam, 101, 101);
  const Scene whole = make(false), bowl = make(true);
  struct Variant {
    bool clipped, capped, cull;
  };
  auto render = [&](const Variant& v, ImrCounters& c, std::vector<double>& depth) {
    const Scene& scene = v.clipped ? bowl : whole;
    ImrOptions options;
    options.back_sample_culling = v.cull;
    ImrRenderer imr(scene, options);
    if (v.capped) imr.surface(0)->capped = true;
    c = imr.render(view);
    depth = imr.rasterizer().depth_image();
    return imr.rasterizer().ids();
  };
  ImrCounters c_whole, c_bowl, c_culled, c_capped;
  std::vector<double> d_whole, d_bowl, d_culled, d_capped;
  const auto ids_whole = render({false, false, false}, c_whole, d_whole);
  const auto ids_bowl = render({true, false, false}, c_bowl, d_bowl);
  const auto ids_culled = render({true, false, true}, c_culled, d_culled);
  const auto ids_capped = render({true, true, false}, c_capped, d_capped);
  size_t changed = 0, checked = 0;
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      const size_t i = size_t(y) * size_t(view.width) + size_t(x);
      const Ray ray = view.ray(x, y);
      // Analytic answers: the sphere's roots and the plane z = 0.
      const double b = glm::dot(ray.origin, ray.dir), c = glm::dot(ray.origin, ray.origin) - 1.0;
      const double disc = b * b - c;
      if (disc < 1e-6) {  // misses or grazes the sphere: no clip plane matters
        if (disc < -1e-6) {
          EXPECT_EQ(ids_whole[i], kNoPrim);
          EXPECT_EQ(ids_bowl[i], kNoPrim);
        }
        continue;
      }
      const double t0 = -b - std::sqrt(disc), t1 = -b + std::sqrt(disc);
      const double z0 = ray.at(t0).z, z1 = ray.at(t1).z;
      if (std::abs(z0) < 1e-6 || std::abs(z1) < 1e-6) continue;  // on the rim
      ++checked;
      EXPECT_EQ(ids_whole[i], 0u);
      EXPECT_NEAR(d_whole[i], t0, 1e-9);
      const bool first_clipped = z0 > 0.0;
      changed += first_clipped;
      if (!first_clipped) {  // the outside of the bowl: same sample in every variant
        EXPECT_NEAR(d_bowl[i], t0, 1e-9);
        EXPECT_NEAR(d_culled[i], t0, 1e-9);
        EXPECT_NEAR(d_capped[i], t0, 1e-9);
        continue;
      }
      if (z1 < 0.0) {
        // Through the opening onto the inside: a back sample, culled, or the cap at z = 0.
        EXPECT_EQ(ids_bowl[i], 0u);
        EXPECT_NEAR(d_bowl[i], t1, 1e-9);
        EXPECT_EQ(ids_culled[i], kNoPrim);
        EXPECT_EQ(ids_capped[i], 0u);
        EXPECT_NEAR(d_capped[i], -ray.origin.z / ray.dir.z, 1e-9);
      } else {
        EXPECT_EQ(ids_bowl[i], kNoPrim);  // both roots cut away
      }
    }
  }
  EXPECT_GT(checked, 2000u);
  EXPECT_GT(changed, 1000u);
  EXPECT_EQ(c_whole.back_samples_culled, 0u);
  EXPECT_GT(c_culled.back_samples_culled, 1000u);
  EXPECT_EQ(c_bowl.back_samples_culled, 0u);
}

// An open cylinder seen along its axis: its inside shows as back samples, which back-sample
// culling removes — exactly the pixels whose brute-force first hit is back-facing.
TEST(Imr, BackSampleCullingRemovesExactlyTheBackFacingFirstHits) {
  Scene scene;
  scene.materials.push_back({});
  scene.add_cone({Vec3(0, 0, 0), 1.0, Vec3(0, 0, 3), 1.0}, 0, 0);
  scene.add_triangle({Vec3(-5, -5, -2), Vec3(5, -5, -2), Vec3(0, 5, -2)}, 1, 0);  // a floor behind
  Camera cam;
  cam.eye = Vec3(0.4, 0.1, 8.0);
  cam.look_at = Vec3(0, 0, 0);
  cam.vfov_deg = 35.0;
  const View view(cam, 91, 91);
  ImrOptions options;
  options.back_sample_culling = true;
  ImrRenderer culled(scene, options);
  culled.render(view);
  const std::vector<uint32_t> ids = culled.rasterizer().ids();
  size_t back = 0;
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      const size_t i = size_t(y) * size_t(view.width) + size_t(x);
      const Ray ray = view.ray(x, y);
      double t = kInfinity;
      const bool hits = scene.intersect(0, ray, 0.0, kInfinity, t);
      if (!hits) continue;
      const Vec3 n = normal_of(scene.cones[0], ray.at(t));
      const double facing = glm::dot(n, ray.dir);
      if (std::abs(facing) < 1e-3) continue;  // grazing
      if (facing > 0.0) {
        ++back;
        // Behind the inside wall: the floor (through the open far end) or nothing.
        EXPECT_NE(ids[i], 0u) << x << "," << y;
      } else {
        EXPECT_EQ(ids[i], 0u) << x << "," << y;
      }
    }
  }
  EXPECT_GT(back, 200u);
}

// Every order issues each primitive exactly once, and the ordered ones issue nearer objects
// first: along a row of spheres seen end-on, the order is the row's.
TEST(Imr, IssueOrdersArePermutationsAndNearestComesFirst) {
  Scene scene;
  scene.materials.push_back({});
  for (int i = 0; i < 40; ++i) scene.add_sphere({Vec3(0, 0, -3.0 * i), 1.0}, uint32_t(39 - i), 0);
  std::reverse(scene.prims.begin(), scene.prims.end());  // input order: farthest first
  const KdTree tree = KdTree::build(scene);
  const Vec3 eye(0.3, 0.2, 10.0);
  for (const IssueOrder kind : {IssueOrder::kInput, IssueOrder::kRandom, IssueOrder::kFrontToBack, IssueOrder::kNearestFirst}) {
    std::vector<uint32_t> order = issue_order(scene, tree, eye, kind, 5);
    ASSERT_EQ(order.size(), scene.size()) << issue_order_name(kind);
    if (kind == IssueOrder::kFrontToBack || kind == IssueOrder::kNearestFirst) {
      for (size_t k = 1; k < order.size(); ++k) {
        const double a = scene.spheres[scene.prims[order[k - 1]].index].center.z;
        const double b = scene.spheres[scene.prims[order[k]].index].center.z;
        EXPECT_GT(a, b) << issue_order_name(kind) << " at " << k;
      }
    }
    std::sort(order.begin(), order.end());
    for (uint32_t i = 0; i < order.size(); ++i) ASSERT_EQ(order[i], i);
    bool ok = false;
    EXPECT_EQ(parse_issue_order(issue_order_name(kind), ok), kind);
    EXPECT_TRUE(ok);
  }
}

TEST(Imr, TextureCoordinatesComeFromPlanesAndAreFetchedOnlyWhenDeclared) {
  Scene scene;
  scene.materials.push_back({});
  scene.lights.push_back({Vec3(0, 0, 10), Vec3(1.0)});
  scene.add_sphere({Vec3(0), 1.0}, 0, 0);
  Camera cam;
  cam.eye = Vec3(0, 0, 5);
  cam.look_at = Vec3(0);
  const View view(cam, 64, 64);
  ImrRenderer plain(scene);
  const ImrCounters c0 = plain.render(view);
  EXPECT_EQ(c0.texture_fetches, 0u);
  ImrRenderer textured(scene);
  ImplicitSurface* s = textured.surface(0);
  s->textured = true;
  s->texgen = {Vec4(4, 0, 0, 0), Vec4(0, 4, 0, 0)};  // a checker of 0.25-unit squares
  const ImrCounters c1 = textured.render(view);
  EXPECT_EQ(c1.texture_fetches, c1.lit_pixels);
  // Left and right of x = 0.25 the checker alternates: colours differ by the factor 2.
  const auto& a = plain.rasterizer().colors();
  const auto& b = textured.rasterizer().colors();
  size_t darker = 0, same = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (plain.rasterizer().ids()[i] == kNoPrim) continue;
    if (std::abs(b[i].g - 0.5f * a[i].g) < 1e-6f && a[i].g > 1e-3f) ++darker;
    if (b[i].g == a[i].g) ++same;
  }
  EXPECT_GT(darker, 300u);
  EXPECT_GT(same, 300u);
}

}  // namespace
}  // namespace frontier
