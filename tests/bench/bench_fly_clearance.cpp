// How high a camera path flies over a model: for every camera, the highest surface straight
// below or above the eye (a vertical ray against every triangle of the model, exact, read in
// one streaming pass), and the eye's height over it. Measures frontier-gen's fly paths
// (issue 25: "the fly path stays above the terrain surface").
//
//   bench_fly_clearance --model terrain.ply --path fly.cam
//
// Prints one JSON line: cameras, cameras with ground under them, the minimum height over ground
// (negative: under the surface) with its frame and the ground there, the highest ground under
// any camera, primitives read and curved primitives skipped (only polygons are tested).
#include "src/core/primitives.h"
#include "src/io/camera_path.h"
#include "src/io/scene_reader.h"
#include "src/io/triangulate.h"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

using namespace frontier;

namespace {

// Cameras bucketed by their (x, y) on a grid, so a triangle tests only the cameras under its box.
class CameraGrid {
 public:
  static constexpr int kSide = 64;
  explicit CameraGrid(const std::vector<Camera>& cams) : cams_(cams) {
    for (const Camera& c : cams) box_.extend(c.eye);
    cell_ = std::max({box_.extent().x, box_.extent().y, 1e-9}) / kSide;
    buckets_.resize(kSide * kSide);
    for (size_t i = 0; i < cams.size(); ++i) buckets_[bucket(index(cams[i].eye.x, box_.lo.x), index(cams[i].eye.y, box_.lo.y))].push_back(i);
  }
  // Calls f(camera index) for every camera whose (x, y) may lie in `b`'s xy extent.
  template <class F>
  void near(const Aabb& b, F&& f) const {
    if (b.hi.x < box_.lo.x || b.lo.x > box_.hi.x || b.hi.y < box_.lo.y || b.lo.y > box_.hi.y) return;
    for (int j = index(b.lo.y, box_.lo.y); j <= index(b.hi.y, box_.lo.y); ++j)
      for (int i = index(b.lo.x, box_.lo.x); i <= index(b.hi.x, box_.lo.x); ++i)
        for (size_t c : buckets_[bucket(i, j)]) f(c);
  }

 private:
  int index(double v, double lo) const { return std::clamp(static_cast<int>(std::floor((v - lo) / cell_)), 0, kSide - 1); }
  static size_t bucket(int i, int j) { return static_cast<size_t>(j) * kSide + static_cast<size_t>(i); }
  const std::vector<Camera>& cams_;
  Aabb box_;
  double cell_ = 1.0;
  std::vector<std::vector<size_t>> buckets_;
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_fly_clearance: each camera's height over the model surface below it (exact, streamed)"};
  std::string model, path;
  app.add_option("--model", model, "model file (.ply, .nff, .obj, .off, .stl)")->required();
  app.add_option("--path", path, "camera path (.cam)")->required();
  CLI11_PARSE(app, argc, argv);

  auto cams = read_camera_path(path);
  if (!cams) {
    std::fprintf(stderr, "bench_fly_clearance: %s\n", cams.status().to_string().c_str());
    return 1;
  }
  auto reader = open_scene_reader(model);
  if (!reader) {
    std::fprintf(stderr, "bench_fly_clearance: %s\n", reader.status().to_string().c_str());
    return 1;
  }
  const auto start = std::chrono::steady_clock::now();
  const CameraGrid grid(*cams);
  std::vector<double> ground(cams->size(), -kInfinity);
  uint64_t primitives = 0, skipped = 0;
  InputPrimitive prim;
  std::vector<std::array<uint32_t, 3>> tris;
  auto test = [&](const Triangle& t) {
    const Aabb b = bounds_of(t);
    grid.near(b, [&](size_t c) {
      const Vec3& e = (*cams)[c].eye;
      if (e.x < b.lo.x || e.x > b.hi.x || e.y < b.lo.y || e.y > b.hi.y) return;
      // Down from above the triangle: the hit is the surface's height at the eye's (x, y).
      const Ray down{Vec3(e.x, e.y, b.hi.z + 1.0), Vec3(0.0, 0.0, -1.0)};
      double hit = 0.0;
      if (intersect_triangle(t, down, 0.0, kInfinity, hit)) ground[c] = std::max(ground[c], down.origin.z - hit);
    });
  };
  for (bool end = false;;) {
    if (Status s = (*reader)->next(prim, end); !s) {
      std::fprintf(stderr, "bench_fly_clearance: %s\n", s.to_string().c_str());
      return 1;
    }
    if (end) break;
    ++primitives;
    if (prim.kind != InputPrimitive::Kind::Polygon) {
      ++skipped;
      continue;
    }
    tris.clear();
    if (prim.vertices.size() == 3) tris.push_back({0, 1, 2});
    else triangulate_polygon(prim.vertices, tris);
    for (const auto& t : tris) test(Triangle{prim.vertices[t[0]], prim.vertices[t[1]], prim.vertices[t[2]]});
  }
  nlohmann::ordered_json out = {{"model", model}, {"path", path}, {"cameras", cams->size()}};
  size_t over = 0, lowest = 0;
  double min_height = kInfinity, max_ground = -kInfinity;
  for (size_t c = 0; c < cams->size(); ++c) {
    if (!std::isfinite(ground[c])) continue;
    ++over;
    max_ground = std::max(max_ground, ground[c]);
    const double h = (*cams)[c].eye.z - ground[c];
    if (h < min_height) min_height = h, lowest = c;
  }
  out["cameras_over_ground"] = over;
  if (over > 0) {
    out["min_height_over_ground"] = min_height;
    out["min_frame"] = lowest;
    out["ground_at_min"] = ground[lowest];
    out["eye_z_at_min"] = (*cams)[lowest].eye.z;
    out["max_ground_under_path"] = max_ground;
  }
  out["primitives"] = primitives;
  out["curved_skipped"] = skipped;
  out["seconds"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%s\n", out.dump().c_str());
  return 0;
}
