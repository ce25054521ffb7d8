// frontier-gen's fly path keeps clear of the ground (issue 25: it used to dip under the terrain).
// The generated terrains here are small but made by the same height function as the big ones;
// the reference is brute force: a vertical ray down at the eye (and at points around it) against
// every triangle of the model as load_scene reads it. Also the ground map it relies on
// (data_gen/ground.h): conservative for random, steep, vertical and far-from-origin triangles.
#include "data_gen/ground.h"
#include "src/core/primitives.h"
#include "src/io/camera_path.h"
#include "src/io/load_scene.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace frontier {
namespace {

namespace fs = std::filesystem;

const fs::path& scratch() { return testing::scratch_dir("frontier_fly"); }

proc::RunResult run_gen(const std::vector<std::string>& args) {
  return proc::run_binary(proc::gen_binary(), args, scratch());
}

// The highest surface of `scene` on the vertical line through (x, y), or -infinity.
double ground_under(const Scene& scene, double x, double y) {
  const double top = scene.bounds().hi.z + 1.0;
  const Ray down{Vec3(x, y, top), Vec3(0.0, 0.0, -1.0)};
  double best = -kInfinity;
  for (uint32_t i = 0; i < scene.size(); ++i) {
    double t = 0.0;
    if (scene.intersect(i, down, 0.0, kInfinity, t)) best = std::max(best, top - t);
  }
  return best;
}

struct Fly {
  Scene scene;
  std::vector<Camera> cameras;
};

// A terrain of 2 grid^2 triangles and a fly path over it.
Fly fly_over_terrain(int grid, int seed, int frames, const std::vector<std::string>& extra = {}) {
  Fly f;
  const std::string name = "terrain_" + std::to_string(grid) + "_" + std::to_string(seed);
  const std::string ply = (scratch() / (name + ".ply")).string(), cam = (scratch() / (name + ".cam")).string();
  auto r = run_gen({"terrain", "--grid", std::to_string(grid), "--seed", std::to_string(seed), "-q", "-o", ply});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  std::vector<std::string> args = {"path", "--model", ply, "--kind", "fly", "--frames", std::to_string(frames),
                                   "--seed", std::to_string(seed), "-o", cam};
  args.insert(args.end(), extra.begin(), extra.end());
  r = run_gen(args);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(load_scene(ply, f.scene).is_ok());
  auto cams = read_camera_path(cam);
  EXPECT_TRUE(cams.is_ok()) << cams.status().to_string();
  if (cams.is_ok()) f.cameras = *cams;
  return f;
}

// frontier-gen's documented default: 1% of the larger horizontal side of the bounds.
double default_clearance(const Scene& scene) {
  const Vec3 e = scene.bounds().extent();
  return 0.01 * std::max(e.x, e.y);
}

// The least height of the eyes over the ground under them and at 8 points `radius` around them.
double least_clearance(const Fly& f, double radius, size_t& worst) {
  double least = kInfinity;
  for (size_t i = 0; i < f.cameras.size(); ++i) {
    const Vec3& e = f.cameras[i].eye;
    for (int k = 0; k <= 8; ++k) {
      const double a = 2.0 * std::numbers::pi * k / 8.0, r = k == 8 ? 0.0 : radius;
      const double g = ground_under(f.scene, e.x + r * std::cos(a), e.y + r * std::sin(a));
      if (std::isfinite(g) && e.z - g < least) {
        least = e.z - g;
        worst = i;
      }
    }
  }
  return least;
}

// Every eye keeps the default clearance over the ground under it and around it, on terrains of
// several seeds (the old path went under the surface on each of them).
TEST(FlyPath, StaysAboveTheTerrainByTheClearance) {
  for (int seed : {1, 2, 3}) {
    SCOPED_TRACE(seed);
    const Fly f = fly_over_terrain(48, seed, 240);
    ASSERT_EQ(f.cameras.size(), 240u);
    const double clearance = default_clearance(f.scene);
    size_t worst = 0;
    const double least = least_clearance(f, 0.99 * clearance, worst);
    // Positions are rounded to micrometres.
    EXPECT_GE(least, clearance - 2e-6) << "frame " << worst << " eye " << f.cameras[worst].eye.z;
  }
}

// --clearance is honoured: the default path comes closer than 5 m to the ground, the one with
// --clearance 5 does not.
TEST(FlyPath, ClearanceOptionLiftsThePath) {
  const Fly low = fly_over_terrain(48, 2, 120);
  const Fly high = fly_over_terrain(48, 2, 120, {"--clearance", "5"});
  ASSERT_EQ(high.cameras.size(), 120u);
  size_t worst = 0;
  EXPECT_LT(least_clearance(low, 4.99, worst), 5.0);
  EXPECT_GE(least_clearance(high, 4.99, worst), 5.0 - 2e-6) << "frame " << worst;
}

// The lift is smoothed: the eye's height changes from frame to frame by little more than the
// spline's own steps, without the jumps a per-frame lift would make over every ridge.
TEST(FlyPath, ClimbsWithoutJitter) {
  const Fly f = fly_over_terrain(48, 1, 600);
  ASSERT_EQ(f.cameras.size(), 600u);
  double mean_step = 0.0, bend = 0.0;
  const size_t n = f.cameras.size();
  for (size_t i = 0; i < n; ++i) {
    const Vec3 &a = f.cameras[(i + n - 1) % n].eye, &b = f.cameras[i].eye, &c = f.cameras[(i + 1) % n].eye;
    mean_step += glm::length(c - b) / double(n);
    bend = std::max(bend, std::abs(a.z - 2.0 * b.z + c.z));
  }
  EXPECT_LT(bend, 0.2 * mean_step) << "the eye's height jerks from frame to frame";
}

// A model cut short in its faces: the fly path's ground pass names the file and the byte offset and
// exits 1 (bad input), writing no path.
TEST(FlyPath, TruncatedModelIsAnErrorNamingIt) {
  const fs::path whole = scratch() / "whole.ply", cut = scratch() / "cut.ply", cam = scratch() / "cut.cam";
  ASSERT_EQ(run_gen({"terrain", "--grid", "16", "-q", "-o", whole.string()}).exit_code, 0);
  fs::copy_file(whole, cut, fs::copy_options::overwrite_existing);
  fs::resize_file(cut, fs::file_size(whole) - 100);
  const auto r = run_gen({"path", "--model", cut.string(), "--kind", "fly", "--frames", "10", "-o", cam.string()});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find(cut.string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("byte "), std::string::npos) << r.err;  // the offset
  EXPECT_FALSE(fs::exists(cam));
}

// --- the ground map ---------------------------------------------------------------------------

// z of the triangle's plane at (x, y) for a point inside its projection.
double plane_z(const Vec3& a, const Vec3& b, const Vec3& c, double x, double y) {
  const Vec3 n = glm::cross(b - a, c - a);
  return a.z - (n.x * (x - a.x) + n.y * (y - a.y)) / n.z;
}

// Random triangles (small and large, gentle and steep), far from the origin or not: the map is
// at least the triangle's height at random points of it, and at most its highest vertex.
TEST(GroundMap, BoundsEveryTriangleFromAbove) {
  for (double offset : {0.0, 1e6}) {
    SCOPED_TRACE(offset);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const Aabb bounds(Vec3(offset, offset, -50.0), Vec3(offset + 100.0, offset + 60.0, 50.0));
    gen::GroundMap map(bounds, 64);
    struct Tri {
      Vec3 v[3];
    };
    std::vector<Tri> tris;
    for (int i = 0; i < 300; ++i) {
      const double size = i % 3 == 0 ? 40.0 : 3.0, steep = i % 4 == 0 ? 200.0 : 10.0;
      const Vec3 base(offset + 10.0 + 80.0 * u(rng), offset + 10.0 + 40.0 * u(rng), 0.0);
      Tri t;
      for (Vec3& v : t.v) v = base + Vec3(size * (u(rng) - 0.5), size * (u(rng) - 0.5), steep * (u(rng) - 0.5));
      for (Vec3& v : t.v) v = glm::clamp(v, bounds.lo, bounds.hi);
      tris.push_back(t);
      map.add_triangle(t.v[0], t.v[1], t.v[2]);
    }
    for (const Tri& t : tris) {
      const Vec3 n = glm::cross(t.v[1] - t.v[0], t.v[2] - t.v[0]);
      if (std::abs(n.z) < 1e-3 * glm::length(n)) continue;
      for (int k = 0; k < 20; ++k) {
        double r1 = u(rng), r2 = u(rng);
        if (r1 + r2 > 1.0) r1 = 1.0 - r1, r2 = 1.0 - r2;
        const Vec3 p = t.v[0] + r1 * (t.v[1] - t.v[0]) + r2 * (t.v[2] - t.v[0]);
        const double z = plane_z(t.v[0], t.v[1], t.v[2], p.x, p.y);
        EXPECT_GE(map.highest_near(p.x, p.y, 0.0), z - 1e-9 * (1.0 + offset));
      }
    }
    // Tight where nothing slopes: one flat triangle over the whole map holds exactly its height.
    gen::GroundMap flat(bounds, 64);
    flat.add_triangle(Vec3(offset - 1.0, offset - 1.0, 3.5), Vec3(offset + 300.0, offset - 1.0, 3.5),
                      Vec3(offset - 1.0, offset + 300.0, 3.5));
    EXPECT_EQ(flat.highest_near(offset + 50.0, offset + 30.0, 0.0), 3.5);
    EXPECT_EQ(flat.highest_near(offset + 50.0, offset + 30.0, 7.0), 3.5);
  }
}

// A vertical wall (no plane over x, y) and an axis-parallel box raise the cells under them to
// their top; nothing else is raised.
TEST(GroundMap, VerticalAndBoxesRaiseTheirFootprint) {
  const Aabb bounds(Vec3(0.0), Vec3(10.0, 10.0, 10.0));
  gen::GroundMap map(bounds, 10);
  map.add_triangle(Vec3(2.5, 2.5, 0.0), Vec3(2.5, 7.5, 0.0), Vec3(2.5, 5.0, 9.0));
  map.add_box(Aabb(Vec3(6.2, 6.2, 1.0), Vec3(6.8, 6.8, 4.0)));
  EXPECT_EQ(map.highest_near(2.5, 5.0, 0.0), 9.0);
  EXPECT_EQ(map.highest_near(6.5, 6.5, 0.0), 4.0);
  EXPECT_EQ(map.highest_near(8.5, 1.5, 0.0), -kInfinity);
  EXPECT_EQ(map.highest_near(8.5, 2.5, 2.0), -kInfinity);
  EXPECT_EQ(map.highest_near(8.5, 5.0, 2.5), 4.0);
}

// widened(r) answers in one cell what highest_near(x, y, r) finds in many, from above, inside
// the grid and beyond its edge.
TEST(GroundMap, WidenedBoundsTheNeighbourhood) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Aabb bounds(Vec3(-5.0, -5.0, 0.0), Vec3(45.0, 25.0, 10.0));
  gen::GroundMap map(bounds, 50);
  for (int i = 0; i < 40; ++i) {
    const Vec3 c(-5.0 + 50.0 * u(rng), -5.0 + 30.0 * u(rng), 0.0);
    map.add_box(Aabb(c, c + Vec3(0.3, 0.3, 10.0 * u(rng))));
  }
  for (double r : {0.5, 2.0, 7.3}) {
    const gen::GroundMap wide = map.widened(r);
    for (int k = 0; k < 2000; ++k) {
      const double x = -15.0 + 70.0 * u(rng), y = -15.0 + 50.0 * u(rng);
      const double exact = map.highest_near(x, y, r);
      EXPECT_GE(wide.highest_near(x, y, 0.0), exact) << x << " " << y << " r " << r;
    }
  }
}

}  // namespace
}  // namespace frontier
