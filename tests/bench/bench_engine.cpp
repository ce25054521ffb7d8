// Primary-ray throughput of ray walking and frustum casting (and brute force where it
// finishes) on the SPD scenes: rays/s, cells touched, ray-primitive tests, hit ratio (the
// immediate-mode paper's Table 4 measure: hits / ray-primitive tests). Visibility only, no
// shading. Prints a Markdown table; the ratio column is frustum rays/s over ray walking rays/s
// measured in the same run, same scene, same rays.
#include "src/engine/kdtree.h"
#include "src/engine/render.h"
#include "src/core/scene.h"
#include "src/core/view.h"
#include "src/io/load_scene.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <vector>

using namespace frontier;

namespace {

struct Run {
  double ms = 0.0;
  Counters counters;
};

// Best of `repeats` frames (the least disturbed), visibility only, with one Renderer as a viewer
// keeps it: the first frame's allocation of per-cell state is not what a frame costs.
Run measure(const Scene& scene, const KdTree& tree, const View& view, Method method, int threads, int repeats,
            int leaf) {
  Run best;
  best.ms = kInfinity;
  Renderer renderer(scene, tree, threads);
  SampleBuffer buffer;
  for (int r = 0; r < repeats; ++r) {
    RenderOptions options;
    options.method = method;
    options.threads = threads;
    options.shade = false;
    options.leaf_pixels = leaf;
    const auto t0 = std::chrono::steady_clock::now();
    const Counters c = renderer.render(view, options, buffer);
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    if (ms < best.ms) best = {ms, c};
  }
  return best;
}

// Each method on the k-d tree that suits it best: the SAH traversal costs `costs` are tried
// for both, and the best time of each is compared (the main table shares one tree, which may
// favour one method: ray walking prefers finer cells than frustum casting).
std::vector<std::string> own_trees(const std::string& name, const Scene& scene, KdBuildOptions build, const std::vector<double>& costs,
               const std::vector<int>& sizes, int threads, int repeats, int leaf) {
  std::vector<std::string> rows;
  for (int size : sizes) {
    double best[2] = {kInfinity, kInfinity};
    double best_cost[2] = {0.0, 0.0};
    for (double cost : costs) {
      build.traversal_cost = cost;
      const KdTree tree = KdTree::build(scene, build);
      const View view(scene.camera ? *scene.camera : automatic_camera(scene.bounds()), size, size);
      const Method methods[2] = {Method::RayWalk, Method::Frustum};
      for (int m = 0; m < 2; ++m) {
        const double ms = measure(scene, tree, view, methods[m], threads, repeats, leaf).ms;
        if (ms < best[m]) {
          best[m] = ms;
          best_cost[m] = cost;
        }
      }
    }
    rows.push_back(fmt::format("| {} | {}² | {:.1f} (cost {}) | {:.1f} (cost {}) | {:.2f}× |", name, size, best[0],
                               best_cost[0], best[1], best_cost[1], best[0] / best[1]));
  }
  return rows;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_engine: rays/s of frustum casting against ray walking on the SPD scenes"};
  std::vector<std::string> scenes;
  std::vector<int> sizes = {129, 513, 1025};
  int threads = 2, repeats = 3;
  bool brute = false, frustum_only = false;
  uint32_t min_cell = 0;
  KdBuildOptions build;
  std::vector<int> leaves = {FrustumCaster::kDefaultLeafPixels};
  app.add_option("scenes", scenes, "NFF/PLY/OBJ/OFF files")->required();
  app.add_option("--sizes", sizes, "square image sizes");
  app.add_option("--threads", threads, "worker threads");
  app.add_option("--repeats", repeats, "runs per measurement (best is kept)");
  app.add_flag("--brute", brute, "also run brute force at the smallest size");
  app.add_option("--leaf-pixels", leaves, "frustum leaf sizes to measure (one row each)");
  app.add_option("--min-cell-prims", min_cell, "k-d tree: cells at or below this size never split");
  app.add_option("--max-cell-prims", build.max_cell_prims, "k-d tree: cells above this size split even if SAH prefers a leaf");
  app.add_option("--traversal-cost", build.traversal_cost, "k-d tree: SAH cost of a cell step against one ray-primitive test");
  app.add_option("--empty-bonus", build.empty_bonus, "k-d tree: SAH discount for cutting off empty space");
  app.add_flag("--frustum-only", frustum_only, "only frustum casting (for profiling)");
  std::vector<double> own_costs;
  app.add_option("--own-trees", own_costs,
                 "also compare each method on its best tree among these SAH traversal costs (e.g. 0.5 1 2 4)");
  CLI11_PARSE(app, argc, argv);
  std::vector<std::string> own_rows;  // --own-trees, printed after the main table

  fmt::print("| scene | size | method | ms | Mrays/s | cells touched | cell visits/ray | ray-prim tests/ray | hit ratio | frustum/raywalk |\n");
  fmt::print("|---|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& path : scenes) {
    Scene scene;
    if (Status s = load_scene(path, scene); !s) {
      fmt::print(stderr, "bench_engine: {}\n", s.to_string());
      return 1;
    }
    build.min_cell_prims = min_cell;
    const KdTree tree = KdTree::build(scene, build);
    const Camera camera = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
    std::string name = path.substr(path.find_last_of('/') + 1);
    if (!own_costs.empty()) {
      for (std::string& row : own_trees(name, scene, build, own_costs, sizes, threads, repeats, leaves.front())) {
        own_rows.push_back(std::move(row));
      }
    }
    for (int size : sizes) {
      const View view(camera, size, size);
      std::vector<Method> methods = {Method::RayWalk, Method::Frustum};
      if (frustum_only) methods = {Method::Frustum};
      if (brute && size == sizes.front()) methods.insert(methods.begin(), Method::Brute);
      double walk_rate = 0.0;
      for (Method m : methods) {
        for (int leaf : (m == Method::Frustum ? leaves : std::vector<int>{0})) {
        const Run run = measure(scene, tree, view, m, threads, m == Method::Brute ? 1 : repeats, leaf);
        const double rays = double(view.pixels());
        const double rate = rays / (run.ms / 1000.0);
        if (m == Method::RayWalk) walk_rate = rate;
        const Counters& c = run.counters;
        const std::string label = m == Method::Frustum ? fmt::format("frustum (leaf {})", leaf) : method_name(m);
        fmt::print("| {} | {}² | {} | {:.1f} | {:.2f} | {} | {:.2f} | {:.2f} | {:.3f} | {} |\n", name, size,
                   label, run.ms, rate / 1e6, c.cells_touched, double(c.cell_visits) / rays,
                   double(c.ray_primitive_tests) / rays,
                   c.ray_primitive_tests ? double(c.hits) / double(c.ray_primitive_tests) : 0.0,
                   m == Method::Frustum && walk_rate > 0 ? fmt::format("{:.2f}×", rate / walk_rate) : "");
        std::fflush(stdout);
        }
      }
    }
  }
  if (!own_costs.empty()) {
    fmt::print("\nEach method on its own best tree (SAH traversal costs {}):\n\n", fmt::join(own_costs, ", "));
    fmt::print("| scene | size | ray walking ms | frustum ms (leaf {}) | ratio of bests |\n|---|---|---|---|---|\n",
               leaves.front());
    for (const std::string& row : own_rows) fmt::print("{}\n", row);
  }
  return 0;
}
