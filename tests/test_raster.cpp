// The z-buffer rasterizer against brute-force ray casting: same ids at every pixel (ties
// aside) and the same depth, on random triangle scenes seen from outside and inside (triangles
// crossing the near plane and reaching behind the eye), a closed sphere and a room. Plus the
// properties of the fill rule (a mesh covers each pixel exactly once, counted in fragments),
// back-face culling (exactly the back faces) and determinism across threads and tilings.
#include "src/raster/raster.h"
#include "src/engine/shading.h"
#include "tests/engine_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace frontier {
namespace {

using testing::brute_reference;
using testing::compare_ids;
using testing::Comparison;

using testing::camera_at;

// Random triangles in [-1,1]^3; about one in eight is large (up to 3 units), so seen from
// inside some cross the near plane and reach behind the eye.
Scene random_triangles(std::mt19937_64& rng, int count) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), size(0.05, 0.5);
  std::uniform_int_distribution<int> large(0, 7);
  Scene scene;
  scene.materials.push_back({});
  for (int i = 0; i < count; ++i) {
    const Vec3 c(u(rng), u(rng), u(rng));
    const double s = large(rng) == 0 ? 3.0 : size(rng);
    scene.add_triangle({c, c + s * Vec3(u(rng), u(rng), u(rng)), c + s * Vec3(u(rng), u(rng), u(rng))}, uint32_t(i), 0);
  }
  scene.input_primitives = uint32_t(count);
  return scene;
}

// Source ids of a rasterized frame (kNoPrim for background).
std::vector<uint32_t> source_ids(const Scene& scene, Rasterizer& r) { return frontier::source_ids(scene, r.ids()); }

struct Frame {
  std::vector<uint32_t> ids;  // scene primitive indices
  std::vector<double> inverse_depth;
  RasterCounters counters;
};

Frame rasterize(const Scene& scene, const View& view, const RasterOptions& options = {}) {
  Rasterizer r(view, options);
  Frame f;
  f.counters = rasterize_scene(scene, r);
  f.ids = r.ids();
  f.inverse_depth = r.inverse_depth();
  return f;
}

// Ids equal brute force at every pixel but ties; where both see the same primitive, the
// depth equals the ray-cast t to 1e-9 relative. Returns the rasterizer's counters.
RasterCounters expect_matches_brute(const Scene& scene, const View& view, const std::string& what,
                                    RasterOptions options = {}) {
  std::vector<uint32_t> ref;
  std::vector<uint8_t> tie;
  brute_reference(scene, view, ref, tie);
  options.threads = 2;
  Rasterizer r(view, options);
  const RasterCounters counters = rasterize_scene(scene, r);
  const std::vector<uint32_t> ids = source_ids(scene, r);
  const Comparison c = compare_ids(ref, tie, ids, view.width);
  // compare_ids takes the brute-force caster's word for ties; it finds one hit on a pixel
  // centre exactly on a shared edge (a symmetric view puts whole rows of centres there), so a
  // differing id at the same distance to 1e-9 is a tie too.
  size_t mismatches = 0;
  std::string first;
  Counters unused;
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      const size_t i = size_t(y) * size_t(view.width) + size_t(x);
      if (ids[i] == ref[i] || tie[i]) continue;
      const Ray ray = view.ray(x, y);
      const RayHit hit = brute_force_hit(scene, ray, view.tmin(ray), unused);
      if (hit.hit() && ids[i] != kNoPrim && std::abs(r.depth(x, y) - hit.t) <= 1e-9 * hit.t) continue;
      if (mismatches++ == 0) first = c.first_mismatch;
    }
  }
  EXPECT_EQ(mismatches, 0u) << what << ": " << first;
  size_t compared = 0, off = 0;
  double worst = 0.0;
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      const uint32_t id = r.id(x, y);
      if (id == kNoPrim) {
        EXPECT_EQ(r.depth(x, y), kInfinity);
        continue;
      }
      const Ray ray = view.ray(x, y);
      const RayHit hit = brute_force_hit(scene, ray, view.tmin(ray), unused);
      if (hit.prim != id) continue;
      const double error = std::abs(r.depth(x, y) - hit.t) / hit.t;
      worst = std::max(worst, error);
      ++compared;
      off += error > 1e-9 ? 1 : 0;
    }
  }
  EXPECT_EQ(off, 0u) << what << ": worst relative depth error " << worst;
  EXPECT_GT(compared, view.pixels() / 20) << what << ": too few pixels to compare";
  return counters;
}

TEST(Raster, RandomTrianglesMatchBruteForceFromOutside) {
  std::mt19937_64 rng(7);
  for (int round = 0; round < 4; ++round) {
    const Scene scene = random_triangles(rng, 150);
    const View view(camera_at(Vec3(2.5, 1.5 - round, 3.0), Vec3(0.0), 50.0), 96, 72);
    const RasterCounters c = expect_matches_brute(scene, view, "outside round " + std::to_string(round));
    EXPECT_EQ(c.submitted, 150u);
    EXPECT_GT(c.depth_passes, 0u);
    EXPECT_LE(c.depth_passes, c.fragments);
  }
}

TEST(Raster, RandomTrianglesMatchBruteForceFromInside) {
  std::mt19937_64 rng(11);
  uint64_t near_clipped = 0, outside = 0;
  for (int round = 0; round < 6; ++round) {
    const Scene scene = random_triangles(rng, 150);
    const Vec3 eye(0.1 * round - 0.2, -0.15, 0.05);
    const Vec3 at = eye + Vec3(std::cos(round * 1.1), std::sin(round * 1.1), 0.3 - 0.1 * round);
    for (double near : {0.0, 0.05}) {
      const View view(camera_at(eye, at, 75.0, near), 88, 66);
      const RasterCounters c =
          expect_matches_brute(scene, view, "inside round " + std::to_string(round) + " near " + std::to_string(near));
      near_clipped += c.near_clipped;
      outside += c.culled_outside;
    }
  }
  EXPECT_GT(near_clipped, 0u) << "no triangle crossed the near plane: the test tests nothing";
  EXPECT_GT(outside, 0u);
}

TEST(Raster, FarFromOriginMatchesBruteForce) {
  std::mt19937_64 rng(5);
  Scene scene = random_triangles(rng, 100);
  const Vec3 offset(1e5, -2e5, 3e5);
  scene.translate(offset);
  const View view(camera_at(offset + Vec3(0.2, 0.1, 0.0), offset + Vec3(1.0, 0.5, 0.2), 70.0, 0.01), 80, 60);
  expect_matches_brute(scene, view, "far from origin");
}

// A plane mesh (vertices snapped to pixel centres, or jittered) across the whole screen
// covers every pixel exactly once: fragments == pixels, no background, at any cell size
// (small cells take the per-pixel path, large ones the span path).
Scene plane_mesh(const View& view, double distance, int cell, double jitter, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-jitter, jitter);
  const int nx = (view.width + 2 * cell) / cell + 1, ny = (view.height + 2 * cell) / cell + 1;
  std::vector<Vec3> vertices;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      const bool border = i == 0 || j == 0 || i == nx || j == ny;
      const double x = -cell + i * cell + (border ? 0.0 : u(rng));
      const double y = -cell + j * cell + (border ? 0.0 : u(rng));
      vertices.push_back(view.eye + distance * (view.base + x * view.step_x + y * view.step_y));
    }
  }
  Scene scene;
  scene.materials.push_back({});
  auto at = [&](int i, int j) { return vertices[size_t(j) * size_t(nx + 1) + size_t(i)]; };
  uint32_t id = 0;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const Vec3 a = at(i, j), b = at(i + 1, j), c = at(i + 1, j + 1), d = at(i, j + 1);
      // Counter-clockwise as seen from the eye (screen y points down): front faces.
      if ((i + j) % 2 == 0) {
        scene.add_triangle({a, c, b}, id, 0), ++id;
        scene.add_triangle({a, d, c}, id, 0), ++id;
      } else {
        scene.add_triangle({a, d, b}, id, 0), ++id;
        scene.add_triangle({b, d, c}, id, 0), ++id;
      }
    }
  }
  scene.input_primitives = id;
  return scene;
}

TEST(Raster, PlaneMeshCoversEachPixelExactlyOnce) {
  std::mt19937_64 rng(3);
  const View view(camera_at(Vec3(0.3, -0.2, 0.5), Vec3(1.0, 2.0, 0.0), 60.0), 131, 97);
  for (int cell : {1, 3, 40}) {
    for (double jitter : {0.0, 0.2}) {
      const Scene scene = plane_mesh(view, 5.0, cell, jitter * cell, rng);  // jitter < 0.25: no folds
      for (bool cull : {false, true}) {
        RasterOptions options;
        options.cull_back_faces = cull;
        options.threads = 2;
        const Frame f = rasterize(scene, view, options);
        const std::string what = "cell " + std::to_string(cell) + " jitter " + std::to_string(jitter) +
                                 (cull ? " culled" : "");
        EXPECT_EQ(f.counters.fragments, view.pixels()) << what;
        EXPECT_EQ(f.counters.depth_passes, view.pixels()) << what;
        EXPECT_EQ(std::count(f.ids.begin(), f.ids.end(), kNoPrim), 0) << what;
        EXPECT_EQ(f.counters.culled_back, 0u) << what;
      }
    }
  }
}

// The same mesh seen from its back: with culling nothing is left.
TEST(Raster, PlaneMeshSeenFromBehindIsCulled) {
  std::mt19937_64 rng(4);
  const View view(camera_at(Vec3(0.0), Vec3(0.0, 0.0, -1.0), 45.0), 64, 48);
  Scene scene = plane_mesh(view, 3.0, 5, 1.0, rng);
  for (Triangle& t : scene.triangles) std::swap(t.v1, t.v2);
  RasterOptions options;
  options.cull_back_faces = true;
  const Frame f = rasterize(scene, view, options);
  EXPECT_EQ(f.counters.culled_back + f.counters.culled_outside, scene.size());
  EXPECT_EQ(f.counters.fragments, 0u);
  options.cull_back_faces = false;
  EXPECT_EQ(rasterize(scene, view, options).counters.fragments, view.pixels());
}

// A closed latitude/longitude sphere, outward-facing, vertices shared bit-identically.
Scene sphere_mesh(const Vec3& centre, double radius, int meridians, int parallels) {
  std::vector<Vec3> v;
  for (int j = 0; j <= parallels; ++j) {
    const double theta = 3.14159265358979323846 * j / parallels;
    for (int i = 0; i < meridians; ++i) {
      const double phi = 2.0 * 3.14159265358979323846 * i / meridians;
      v.push_back(j == 0 ? centre + Vec3(0, 0, radius)
                  : j == parallels ? centre - Vec3(0, 0, radius)
                                   : centre + radius * Vec3(std::sin(theta) * std::cos(phi),
                                                            std::sin(theta) * std::sin(phi), std::cos(theta)));
    }
  }
  Scene scene;
  scene.materials.push_back({});
  auto at = [&](int i, int j) { return v[size_t(j) * size_t(meridians) + size_t(i % meridians)]; };
  uint32_t id = 0;
  for (int j = 0; j < parallels; ++j) {
    for (int i = 0; i < meridians; ++i) {
      const Vec3 a = at(i, j), b = at(i, j + 1), c = at(i + 1, j + 1), d = at(i + 1, j);
      if (j != parallels - 1) scene.add_triangle({a, b, c}, id, 0), ++id;  // outward: counter-clockwise
      if (j != 0) scene.add_triangle({a, c, d}, id, 0), ++id;
    }
  }
  scene.input_primitives = id;
  return scene;
}

TEST(Raster, ClosedSphereIsWatertightAndCullsItsBackHalf) {
  const Scene scene = sphere_mesh(Vec3(0.1, -0.2, 0.05), 1.0, 48, 24);
  for (const Vec3& eye : {Vec3(0.3, 0.2, 3.5), Vec3(-2.0, 2.2, 1.0), Vec3(0.1, -0.2, 4.0)}) {
    const View view(camera_at(eye, Vec3(0.1, -0.2, 0.05), 45.0), 120, 100);
    const RasterCounters c = expect_matches_brute(scene, view, "sphere");
    RasterOptions options;
    options.cull_back_faces = true;
    const Frame all = rasterize(scene, view), front = rasterize(scene, view, options);
    const size_t covered = view.pixels() - size_t(std::count(all.ids.begin(), all.ids.end(), kNoPrim));
    EXPECT_GT(covered, view.pixels() / 10);
    // Front faces partition the silhouette, back faces too.
    EXPECT_EQ(front.counters.fragments, covered);
    EXPECT_EQ(all.counters.fragments, 2 * covered);
    EXPECT_EQ(front.ids, all.ids);
    EXPECT_EQ(front.inverse_depth, all.inverse_depth);
    EXPECT_EQ(c.culled_back, 0u);
    // Exactly the back faces are culled: a bit over half, as a sphere seen from a finite
    // distance shows less than a hemisphere.
    size_t back = 0;
    for (const Triangle& t : scene.triangles) {
      back += glm::dot(t.v0 - eye, glm::cross(t.v1 - t.v0, t.v2 - t.v0)) > 0.0 ? 1 : 0;
    }
    EXPECT_EQ(front.counters.culled_back, back);
    EXPECT_GT(double(back) / double(scene.size()), 0.5);
    EXPECT_LT(double(back) / double(scene.size()), 0.75);
    // No background pixel inside the silhouette: none with all four neighbours covered.
    size_t holes = 0;
    for (int y = 1; y + 1 < view.height; ++y) {
      for (int x = 1; x + 1 < view.width; ++x) {
        auto id = [&](int px, int py) { return all.ids[size_t(py) * size_t(view.width) + size_t(px)]; };
        holes += id(x, y) == kNoPrim && id(x - 1, y) != kNoPrim && id(x + 1, y) != kNoPrim &&
                 id(x, y - 1) != kNoPrim && id(x, y + 1) != kNoPrim;
      }
    }
    EXPECT_EQ(holes, 0u);
  }
}

// A closed room (two triangles per wall, normals inward) with the eye inside, plus a
// triangle crossing the near plane right beside the eye.
TEST(Raster, EyeInsideRoomWithNearPlaneCrossing) {
  Scene scene;
  scene.materials.push_back({});
  const Vec3 lo(-2.0, -3.0, -1.0), hi(4.0, 2.0, 1.5);
  auto corner = [&](int k) { return Vec3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z); };
  const int faces[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
  uint32_t id = 0;
  for (const auto& f : faces) {
    scene.add_triangle({corner(f[0]), corner(f[1]), corner(f[2])}, id, 0), ++id;
    scene.add_triangle({corner(f[0]), corner(f[2]), corner(f[3])}, id, 0), ++id;
  }
  const Vec3 eye(0.2, -0.3, 0.1);
  scene.add_triangle({eye + Vec3(-0.5, 0.05, -0.4), eye + Vec3(2.0, 0.3, -0.2), eye + Vec3(0.3, -0.2, 0.6)}, id, 0),
      ++id;
  scene.input_primitives = id;
  for (double near : {0.0, 0.02, 0.3}) {
    for (const Vec3& dir : {Vec3(1.0, 0.2, 0.0), Vec3(-0.3, 1.0, -0.2), Vec3(0.1, -0.2, 1.0)}) {
      const View view(camera_at(eye, eye + dir, 90.0, near), 100, 80);
      const RasterCounters c = expect_matches_brute(scene, view, "room near " + std::to_string(near));
      EXPECT_GT(c.clipped, 0u);
      // Walls face inwards: culling keeps every visible one, so only the crossing triangle's
      // pixels may change (it may be a back face from here).
      RasterOptions options;
      options.cull_back_faces = true;
      const Frame culled = rasterize(scene, view, options), all = rasterize(scene, view);
      size_t changed = 0;
      for (size_t i = 0; i < view.pixels(); ++i) changed += all.ids[i] != 12 && culled.ids[i] != all.ids[i];
      EXPECT_EQ(changed, 0u) << "room near " << near;
    }
  }
  // The crossing triangle is near-clipped when the camera looks along it.
  const View view(camera_at(eye, eye + Vec3(1.0, 0.2, 0.0), 90.0, 0.3), 100, 80);
  EXPECT_GT(rasterize(scene, view).counters.near_clipped, 0u);
}

TEST(Raster, SameResultForAnyThreadCountTilingAndOrder) {
  std::mt19937_64 rng(21);
  Scene scene = random_triangles(rng, 3000);
  // Coplanar duplicates: equal depth everywhere, the lower id must win.
  for (uint32_t i = 0; i < 50; ++i) scene.add_triangle(scene.triangles[i * 7], 3000 + i, 0);
  const View view(camera_at(Vec3(0.2, 0.1, 0.3), Vec3(1.0, 0.0, 0.0), 80.0, 0.01), 200, 150);
  RasterOptions one;
  one.threads = 1;
  const Frame reference = rasterize(scene, view, one);
  for (int threads : {1, 2}) {
    for (int tile : {8, 64, 100}) {
      RasterOptions options;
      options.threads = threads;
      options.tile_size = tile;
      const Frame f = rasterize(scene, view, options);
      EXPECT_EQ(f.ids, reference.ids) << threads << " threads, tile " << tile;
      EXPECT_EQ(f.inverse_depth, reference.inverse_depth);
      EXPECT_EQ(f.counters.fragments, reference.counters.fragments);
      EXPECT_EQ(f.counters.depth_passes, reference.counters.depth_passes) << threads << " threads, tile " << tile;
    }
  }
  // Reverse order, and in batches with flushes in between.
  Rasterizer r(view, one);
  for (size_t i = scene.size(); i-- > 0;) {
    r.submit(scene.triangles[scene.prims[i].index], uint32_t(i));
    if (i % 500 == 0) r.flush();
  }
  EXPECT_EQ(r.ids(), reference.ids);
  EXPECT_EQ(r.inverse_depth(), reference.inverse_depth);
  // The duplicates lose to their lower-id originals wherever they are visible.
  for (uint32_t id : reference.ids) EXPECT_TRUE(id == kNoPrim || id < 3000u);
}

TEST(Raster, CountsOutsideBehindAndSkipped) {
  std::mt19937_64 rng(8);
  Scene scene = testing::random_scene(rng, 60);
  const size_t triangles = scene.triangles.size();
  // Behind the eye, and outside the frustum.
  scene.add_triangle({Vec3(0, 0, 10), Vec3(1, 0, 10), Vec3(0, 1, 10)}, 60, 0);
  scene.add_triangle({Vec3(50, 0, -3), Vec3(51, 0, -3), Vec3(50, 1, -3)}, 61, 0);
  const View view(camera_at(Vec3(0, 0, 5), Vec3(0.0), 40.0), 64, 64);
  Rasterizer r(view);
  const RasterCounters c = rasterize_scene(scene, r);
  EXPECT_EQ(c.submitted, triangles + 2);
  EXPECT_EQ(c.skipped_primitives, scene.size() - triangles - 2);
  EXPECT_GE(c.culled_outside, 2u);
}

// Shading the rasterized frame gives the ray caster's colours.
TEST(Raster, ShadingHookMatchesRayCaster) {
  std::mt19937_64 rng(9);
  Scene scene = random_triangles(rng, 120);
  scene.lights.push_back({Vec3(3.0, 2.0, 4.0), Vec3(1.0)});
  scene.materials[0].ks = 0.4;
  scene.materials[0].shine = 20.0;
  const KdTree tree = KdTree::build(scene);
  const View view(camera_at(Vec3(2.0, -2.5, 1.5), Vec3(0.0), 50.0), 80, 60);
  RenderOptions ray_options;
  ray_options.method = Method::Brute;
  ray_options.threads = 2;
  SampleBuffer cast;
  render_frame(scene, tree, view, ray_options, cast);

  Rasterizer r(view);
  rasterize_scene(scene, r);
  const Shader shader(scene, tree);
  const Counters c = r.shade(shader, true);
  EXPECT_GT(c.shading_ops, 0u);
  EXPECT_GT(c.shadow_rays, 0u);
  SampleBuffer raster;
  r.to_sample_buffer(raster);
  size_t same = 0;
  for (size_t i = 0; i < view.pixels(); ++i) {
    if (raster.prim(i) != cast.prim(i)) continue;
    ++same;
    const Rgb a = raster.color(i), b = cast.color(i);
    EXPECT_NEAR(a.r, b.r, 1e-4);
    EXPECT_NEAR(a.g, b.g, 1e-4);
    EXPECT_NEAR(a.b, b.b, 1e-4);
  }
  EXPECT_GT(same, view.pixels() * 9 / 10);
}

}  // namespace
}  // namespace frontier
