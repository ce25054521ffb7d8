// The tables of Fuchs, Abram & Grant 1983 on models of today's sizes, against frontier's
// z-buffer rasterizer measured in the same run:
//  * Table 1: input polygons and tree size for k = 1, 3, 5, 15 and all root candidates (§3.1),
//    with splits, depth, build time and memory. 'all' is O(n^2) per node: it runs only on models
//    up to --all-max polygons, and every build stops at --budget-ms (shown as '>budget').
//  * Table 2: frames per second, small and large image, of back-to-front painter's (with and
//    without back-face removal) and front-to-back 4x4 coverage-mask anti-aliasing, as ratios
//    against the z-buffer rendering of the same (unsplit) triangles.
//  * Table 3: what accuracy costs: for N x N masks, time and the mean absolute colour error on
//    edge pixels against a 16 x 16 reference (edge pixel: the reference mixes colours there).
//
// Models (any NFF/PLY/OBJ/OFF; curved primitives are tessellated with --segments):
//   SPD scenes:    ../shared/data/spd/{rings,tree,shells}.nff
//   Debian meshes: apt-get install libcgal-demo; then /usr/share/doc/libcgal-demo/... *.off
//                  (find /usr/share -name '*.off' lists them)
//   data_gen:      frontier-gen building --triangles 1000000 -o building.ply
//                  frontier-gen terrain --triangles 1000000 -o terrain.ply
//   bench_bsp MODEL... [--threads 2] [--all-max 20000] [--budget-ms 120000]
#include "src/io/load_scene.h"
#include "src/raster/bsp.h"
#include "src/raster/bsp_render.h"
#include "src/raster/raster.h"
#include "src/core/scene.h"
#include "src/core/tessellate.h"
#include "src/core/view.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

using namespace frontier;

namespace {

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

struct Model {
  std::string name;
  Scene triangles;  // the z-buffer's input: the same triangles the tree was built from
  PolygonSoup soup;
  Camera camera;
};

// Best frame time of the z-buffer baseline: every triangle of the model through the rasterizer.
double zbuffer_ms(const Model& m, const View& view, int threads, int repeats) {
  double best = kInfinity;
  RasterOptions ro;
  ro.threads = threads;
  Rasterizer r(view, ro);
  for (int rep = 0; rep < repeats; ++rep) {
    r.clear();
    const auto start = std::chrono::steady_clock::now();
    rasterize_scene(m.triangles, r);
    best = std::min(best, ms_since(start));
  }
  return best;
}

bool parse_size(const std::string& s, int& w, int& h) { return std::sscanf(s.c_str(), "%dx%d", &w, &h) == 2 && w > 0 && h > 0; }

std::string candidates_name(int k) { return k == 0 ? "all" : std::to_string(k); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_bsp: BSP tree size, build time and frame rate (Fuchs, Abram & Grant 1983) against the z-buffer"};
  std::vector<std::string> paths;
  std::vector<int> candidates = {1, 3, 5, 15, 0};
  std::vector<std::string> sizes = {"320x240", "1280x960"};
  std::vector<int> masks = {1, 2, 4, 8};
  int threads = 2, repeats = 3, segments = 12, render_k = 5, reference_mask = 16;
  size_t all_max = 20000;
  double budget_ms = 120000.0;
  uint64_t seed = 1;
  app.add_option("models", paths, "model files")->required();
  app.add_option("--candidates", candidates, "root candidates per node (0: all)");
  app.add_option("--all-max", all_max, "largest input (polygons) built with all candidates");
  app.add_option("--budget-ms", budget_ms, "time budget per build");
  app.add_option("--render-candidates", render_k, "k of the tree rendered in tables 2 and 3");
  app.add_option("--sizes", sizes, "small and large image WxH");
  app.add_option("--masks", masks, "coverage mask sizes N (table 3)");
  app.add_option("--reference-mask", reference_mask, "reference mask size N for the edge error");
  app.add_option("--segments", segments, "tessellation segments for curved primitives");
  app.add_option("--threads", threads, "worker threads");
  app.add_option("--repeats", repeats, "runs per frame measurement (best is kept)");
  app.add_option("--seed", seed, "candidate choice seed");
  CLI11_PARSE(app, argc, argv);

  std::vector<Model> models;
  for (const std::string& path : paths) {
    Model m;
    m.name = std::filesystem::path(path).filename().string();
    Scene scene;
    if (Status s = load_scene(path, scene); !s) {
      fmt::print(stderr, "bench_bsp: {}\n", s.to_string());
      return 1;
    }
    TessellateOptions to;
    to.segments = segments;
    to.smooth_normals = false;
    m.triangles = tessellate(scene, to);
    m.soup = polygon_soup(m.triangles, segments);
    m.camera = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
    models.push_back(std::move(m));
  }
  fmt::print("bench_bsp: {} threads, seed {}, tessellation {} segments, 'all' up to {} polygons, build budget {:.0f} s\n\n",
             threads, seed, segments, all_max, budget_ms / 1000.0);

  // ---- Table 1 ----
  fmt::print("### Table 1: tree size (output polygons, and growth over the input) for k root candidates\n\n");
  fmt::print("| model | input polygons |");
  for (int k : candidates) fmt::print(" k={} |", candidates_name(k));
  fmt::print(" build ms (k=5) |\n|---|---|");
  for (size_t i = 0; i < candidates.size(); ++i) fmt::print("---|");
  fmt::print("---|\n");
  struct Detail {
    std::string model;
    int k;
    BspStats stats;
  };
  std::vector<Detail> details;
  std::vector<std::optional<BspTree>> render_trees(models.size());
  for (size_t mi = 0; mi < models.size(); ++mi) {
    const Model& m = models[mi];
    fmt::print("| {} | {} |", m.name, m.soup.size());
    std::fflush(stdout);
    double ms5 = -1.0;
    for (int k : candidates) {
      if (k == 0 && m.soup.size() > all_max) {
        fmt::print(" (not run) |");
        continue;
      }
      BspBuildOptions options;
      options.candidates = k;
      options.seed = seed;
      options.time_budget_ms = budget_ms;
      auto tree = BspTree::build(m.soup, options);
      if (!tree.is_ok()) {
        fmt::print(" >budget |");
        std::fflush(stdout);
        continue;
      }
      const BspStats& s = tree->stats();
      fmt::print(" {} ({:.2f}×) |", s.output_polygons, double(s.output_polygons) / double(std::max<uint64_t>(1, s.input_polygons)));
      std::fflush(stdout);
      if (k == 5) ms5 = s.build_ms;
      details.push_back({m.name, k, s});
      if (k == render_k) render_trees[mi] = std::move(tree.value());
    }
    if (ms5 >= 0.0) {
      fmt::print(" {:.0f} |\n", ms5);
    } else {
      fmt::print(" — |\n");
    }
  }
  fmt::print("\n| model | k | output | splits | coplanar | max depth | mean depth | build ms | classifications | memory MB | "
             "degenerate fragments |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Detail& d : details) {
    const BspStats& s = d.stats;
    fmt::print("| {} | {} | {} | {} | {} | {} | {:.1f} | {:.1f} | {} | {:.1f} | {} |\n", d.model, candidates_name(d.k),
               s.output_polygons, s.splits, s.coplanar, s.max_depth, s.mean_depth, s.build_ms, s.classifications,
               double(s.memory_bytes) / 1e6, s.degenerate_fragments);
  }

  // ---- Table 2 ----
  fmt::print("\n### Table 2: frames per second (k={} trees) against the z-buffer of the same triangles\n\n", render_k);
  fmt::print("| model | polygons in tree | image | z-buffer fps | painter's fps (×z) | painter's, back faces removed fps (×z) | "
             "4×4 front-to-back fps (×z) | traverse ms | pixels full 4×4 |\n|---|---|---|---|---|---|---|---|---|\n");
  for (size_t mi = 0; mi < models.size(); ++mi) {
    if (!render_trees[mi]) continue;
    const BspTree& tree = *render_trees[mi];
    const Model& m = models[mi];
    for (const std::string& size : sizes) {
      int w = 0, h = 0;
      if (!parse_size(size, w, h)) {
        fmt::print(stderr, "bench_bsp: bad size '{}'\n", size);
        return 1;
      }
      const View view(m.camera, w, h);
      const double z_ms = zbuffer_ms(m, view, threads, repeats);
      auto best = [&](const BspRenderOptions& options, BspFrameCounters* counters) {
        double ms = kInfinity;
        for (int rep = 0; rep < repeats; ++rep) {
          const BspFrame f = render_bsp(tree, view, options);
          if (f.counters.total_ms < ms) {
            ms = f.counters.total_ms;
            if (counters != nullptr) *counters = f.counters;
          }
        }
        return ms;
      };
      BspRenderOptions options;
      options.threads = threads;
      options.colors = false;  // the z-buffer baseline writes ids only too
      BspFrameCounters painter;
      const double painter_ms = best(options, &painter);
      options.cull_back_faces = true;
      const double culled_ms = best(options, nullptr);
      options.cull_back_faces = false;
      options.order = BspOrder::FrontToBack;
      options.aa = 4;
      options.colors = true;
      BspFrameCounters aa;
      const double aa_ms = best(options, &aa);
      fmt::print("| {} | {} | {}×{} | {:.2f} | {:.2f} ({:.2f}×) | {:.2f} ({:.2f}×) | {:.2f} ({:.2f}×) | {:.1f} | {:.1f}% |\n", m.name,
                 tree.faces().size(), w, h, 1000.0 / z_ms, 1000.0 / painter_ms, z_ms / painter_ms, 1000.0 / culled_ms,
                 z_ms / culled_ms, 1000.0 / aa_ms, z_ms / aa_ms, painter.traverse_ms,
                 100.0 * double(aa.pixels_full) / double(view.pixels()));
      std::fflush(stdout);
    }
  }

  // ---- Table 3 ----
  int w = 0, h = 0;
  if (!parse_size(sizes.front(), w, h)) return 1;
  fmt::print("\n### Table 3: what accuracy costs: N×N coverage mask, {}×{} image, error against {}×{} on edge pixels\n\n", w, h,
             reference_mask, reference_mask);
  fmt::print("| model | N | ms | ×z-buffer time | edge pixels | mean abs error (edge pixels) | sub-sample tests | "
             "pixel visits skipped (full) | faces drawn |\n|---|---|---|---|---|---|---|---|---|\n");
  for (size_t mi = 0; mi < models.size(); ++mi) {
    if (!render_trees[mi]) continue;
    const BspTree& tree = *render_trees[mi];
    const Model& m = models[mi];
    const View view(m.camera, w, h);
    const double z_ms = zbuffer_ms(m, view, threads, repeats);
    BspRenderOptions options;
    options.threads = threads;
    options.order = BspOrder::FrontToBack;
    options.aa = reference_mask;
    options.edge_flags = true;
    const BspFrame reference = render_bsp(tree, view, options);
    options.edge_flags = false;
    std::vector<int> all_masks = masks;
    all_masks.push_back(reference_mask);
    for (int n : all_masks) {
      options.aa = n;
      BspFrame frame;
      double ms = kInfinity;
      for (int rep = 0; rep < repeats; ++rep) {
        BspFrame f = render_bsp(tree, view, options);
        if (f.counters.total_ms < ms) {
          ms = f.counters.total_ms;
          frame = std::move(f);
        }
      }
      double error = 0.0;
      size_t edges = 0;
      for (size_t p = 0; p < view.pixels(); ++p) {
        if (!reference.mixed[p]) continue;
        ++edges;
        error += (std::abs(frame.colors[p].r - reference.colors[p].r) + std::abs(frame.colors[p].g - reference.colors[p].g) +
                  std::abs(frame.colors[p].b - reference.colors[p].b)) / 3.0;
      }
      const BspFrameCounters& c = frame.counters;
      fmt::print("| {} | {} | {:.1f} | {:.2f}× | {} | {:.4f} | {} | {:.1f}% | {} |\n", m.name, n, ms, ms / z_ms, edges,
                 edges ? error / double(edges) : 0.0, c.subsample_tests,
                 c.pixel_visits ? 100.0 * double(c.pixels_skipped_full) / double(c.pixel_visits) : 0.0, c.faces_drawn);
      std::fflush(stdout);
    }
  }
  return 0;
}
