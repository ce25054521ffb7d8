// Throughput of the z-buffer rasterizer (every triangle of the scene submitted, no culling:
// the exhaustive class) against frontier's frustum casting of the same view, measured in the
// same run: triangles/s, fragments/s, and the frame-time ratio. Also reports how many pixels
// the two agree on (ids), as a sanity check of what is being compared.
//
//   frontier-gen building --triangles 1000000 -o building.ply
//   bench_raster building.ply --threads 2
#include "src/engine/kdtree.h"
#include "src/io/load_scene.h"
#include "src/raster/raster.h"
#include "src/engine/render.h"
#include "src/core/scene.h"
#include "src/core/view.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <chrono>
#include <string>
#include <vector>

using namespace frontier;

namespace {

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

struct RasterRun {
  double ms = kInfinity;
  RasterCounters counters;
  std::vector<uint32_t> ids;
};

RasterRun measure_raster(const Scene& scene, const View& view, int threads, int repeats) {
  RasterRun best;
  RasterOptions options;
  options.threads = threads;
  Rasterizer rasterizer(view, options);
  for (int r = 0; r < repeats; ++r) {
    rasterizer.clear();
    rasterizer.reset_counters();
    const auto start = std::chrono::steady_clock::now();
    const RasterCounters c = rasterize_scene(scene, rasterizer);
    const double ms = ms_since(start);
    if (ms < best.ms) best = {ms, c, rasterizer.ids()};
  }
  return best;
}

struct CastRun {
  double ms = kInfinity;
  std::vector<uint32_t> prims;
};

CastRun measure_frustum(const Scene& scene, const KdTree& tree, const View& view, int threads, int repeats) {
  CastRun best;
  for (int r = 0; r < repeats; ++r) {
    RenderOptions options;
    options.method = Method::Frustum;
    options.threads = threads;
    options.shade = false;
    SampleBuffer buffer;
    const auto start = std::chrono::steady_clock::now();
    render_frame(scene, tree, view, options, buffer);
    const double ms = ms_since(start);
    if (ms < best.ms) {
      best.ms = ms;
      best.prims.assign(view.pixels(), kNoPrim);
      for (size_t i = 0; i < view.pixels(); ++i) best.prims[i] = buffer.confirmed(i) ? buffer.prim(i) : kNoPrim;
    }
  }
  return best;
}

Camera look(const Vec3& eye, const Vec3& at, const Vec3& up, double fov) {
  Camera c;
  c.eye = eye;
  c.look_at = at;
  c.up = up;
  c.vfov_deg = fov;
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_raster: z-buffer rasterization against frustum casting of the same view"};
  std::string path;
  int threads = 2, repeats = 3;
  std::vector<std::string> sizes = {"640x480", "1024x1024"};
  app.add_option("scene", path, "model file (e.g. a frontier-gen building)")->required();
  app.add_option("--threads", threads, "worker threads");
  app.add_option("--repeats", repeats, "runs per measurement (best is kept)");
  app.add_option("--sizes", sizes, "image sizes WxH");
  CLI11_PARSE(app, argc, argv);

  Scene scene;
  auto start = std::chrono::steady_clock::now();
  if (Status s = load_scene(path, scene); !s) {
    fmt::print(stderr, "bench_raster: {}\n", s.to_string());
    return 1;
  }
  const double load_ms = ms_since(start);
  start = std::chrono::steady_clock::now();
  const KdTree tree = KdTree::build(scene);
  fmt::print("{}: {} triangles, loaded in {:.0f} ms, k-d tree in {:.0f} ms, {} threads\n\n", path,
             scene.triangles.size(), load_ms, ms_since(start), threads);

  // An outside view of the whole model, and one inside at eye height looking down its length
  // (a building's z is up; for other models the second view is just another diagonal).
  const Aabb b = scene.bounds();
  const Vec3 e = b.extent();
  const Vec3 inside = b.lo + Vec3(0.12 * e.x, 0.17 * e.y, 0.17 * e.z);
  const std::pair<std::string, Camera> cameras[] = {
      {"outside", scene.camera ? *scene.camera : automatic_camera(b)},
      {"inside", look(inside, inside + Vec3(0.6 * e.x, 0.5 * e.y, 0.0), Vec3(0, 0, 1), 70.0)}};

  fmt::print("| view | size | raster ms (setup / tiles) | Mtriangles/s | Mfragments/s | fragments/pixel | "
             "frustum ms | raster/frustum time | same id |\n");
  fmt::print("|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& [name, camera] : cameras) {
    for (const std::string& size : sizes) {
      int w = 0, h = 0;
      if (std::sscanf(size.c_str(), "%dx%d", &w, &h) != 2 || w <= 0 || h <= 0) {
        fmt::print(stderr, "bench_raster: bad size '{}'\n", size);
        return 1;
      }
      const View view(camera, w, h);
      const RasterRun raster = measure_raster(scene, view, threads, repeats);
      const CastRun cast = measure_frustum(scene, tree, view, threads, repeats);
      size_t same = 0;
      for (size_t i = 0; i < view.pixels(); ++i) same += raster.ids[i] == cast.prims[i];
      const RasterCounters& c = raster.counters;
      fmt::print("| {} | {}×{} | {:.1f} ({:.1f} / {:.1f}) | {:.2f} | {:.1f} | {:.2f} | {:.1f} | {:.2f}× | {:.3f}% |\n",
                 name, w, h, raster.ms, c.setup_ms, c.raster_ms, double(c.submitted) / raster.ms / 1e3,
                 double(c.fragments) / raster.ms / 1e3, double(c.fragments) / double(view.pixels()), cast.ms,
                 raster.ms / cast.ms, 100.0 * double(same) / double(view.pixels()));
      std::fflush(stdout);
    }
  }
  return 0;
}
