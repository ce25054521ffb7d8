// frontier-view: the command-line front end. This version renders a model file or a store loaded
// in memory, headless, with a choice of visibility method; exit code 0 on success, 1 on bad input
// (the message names the file and line), 2 on bad options.
#include "src/image.h"
#include "src/kdtree.h"
#include "src/render.h"
#include "src/scene.h"
#include "src/store_model.h"
#include "src/view.h"
#include "store/page_format.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>

using namespace frontier;

namespace {

bool parse_size(const std::string& text, int& w, int& h) {
  int a = 0, b = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &a, &x, &b, &extra) != 3 || (x != 'x' && x != 'X')) return false;
  if (a < 1 || b < 1 || a > 16384 || b > 16384) return false;
  w = a;
  h = b;
  return true;
}

// A store file starts with the store magic (store/FORMAT.md); anything else is a model file.
bool is_store(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return false;
  char magic[8] = {};
  const size_t got = std::fread(magic, 1, sizeof magic, f);
  std::fclose(f);
  return got == sizeof magic && std::memcmp(magic, store::kMagic.data(), sizeof magic) == 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"frontier-view: render a model with exact per-pixel visibility (ray casting on the CPU).\n"
               "Reads NFF, PLY, OBJ or OFF (or a store from frontier-build, decoded whole) into memory,\n"
               "builds a k-d tree and renders one frame headless."};
  std::string scene_path, size_text, method_text = "frustum", png_path, ids_path, stats_path;
  bool headless = false, no_shadows = false;
  int threads = 0;
  uint32_t cell_prims = 8, min_cell_prims = 0;
  int leaf_pixels = FrustumCaster::kDefaultLeafPixels;
  double frame_ms = 0.0;
  uint64_t samples = 0;
  app.add_option("SCENE", scene_path, "model file (.nff, .ply, .obj, .off) or store file (frontier-build)")->required();
  app.add_flag("--headless", headless, "render without a window (required in this version)");
  app.add_option("--size", size_text, "image size WxH (default: the scene's resolution, else 512x512)");
  app.add_option("--method", method_text, "visibility method: brute | raywalk | frustum")
      ->check(CLI::IsMember({"brute", "raywalk", "frustum"}));
  app.add_option("--png", png_path, "write the shaded image as PNG");
  app.add_option("--ids", ids_path,
                 "write the first-hit input primitive per pixel (uint32 little-endian, row-major, "
                 "0xFFFFFFFF = background)");
  app.add_option("--stats", stats_path, "write counters as JSON");
  app.add_option("--threads", threads, "worker threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  app.add_option("--cell-prims", cell_prims, "largest cell the k-d tree keeps when it could split")
      ->check(CLI::Range(1u, 1000000u));
  app.add_option("--min-cell-prims", min_cell_prims, "cells at or below this size never split (coarser cells)")
      ->check(CLI::Range(0u, 1000000u));
  app.add_option("--leaf-pixels", leaf_pixels,
                 "frustum: frusta up to N×N pixels walk their pixels individually (paper: 2)")
      ->check(CLI::Range(2, 4096));
  app.add_flag("--no-shadows", no_shadows, "skip the deferred shadow effect");
  auto* peg_time = app.add_option("--frame-ms", frame_ms, "frustum: peg frame time (stop after MS milliseconds)")
                       ->check(CLI::PositiveNumber);
  auto* peg_samples = app.add_option("--samples", samples, "frustum: peg sample count (stop after N samples)")
                          ->check(CLI::PositiveNumber);
  peg_time->excludes(peg_samples);
  CLI11_PARSE(app, argc, argv);

  if (!headless) {
    std::fprintf(stderr, "frontier-view: only --headless rendering exists in this version\n");
    return 2;
  }
  Method method;
  parse_method(method_text, method);

  Scene scene;
  KdTree tree;
  KdBuildOptions build;
  build.max_cell_prims = cell_prims;
  build.min_cell_prims = min_cell_prims;
  const auto t0 = std::chrono::steady_clock::now();
  auto t1 = t0;
  if (is_store(scene_path)) {
    // A store rendered in memory: every page decoded, each store cell refined by the SAH builder.
    auto model = StoreModel::open(scene_path);
    Status s = model ? (*model)->load_all(scene, tree, build) : model.status();
    if (!s) {
      std::fprintf(stderr, "frontier-view: %s\n", s.to_string().c_str());
      return 1;
    }
    t1 = std::chrono::steady_clock::now();
  } else {
    if (Status s = load_scene(scene_path, scene); !s) {
      std::fprintf(stderr, "frontier-view: %s\n", s.to_string().c_str());
      return 1;
    }
    t1 = std::chrono::steady_clock::now();
    tree = KdTree::build(scene, build);
  }
  const auto t2 = std::chrono::steady_clock::now();

  Camera camera = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
  int width = camera.width > 0 ? camera.width : 512, height = camera.height > 0 ? camera.height : 512;
  if (!size_text.empty() && !parse_size(size_text, width, height)) {
    std::fprintf(stderr, "frontier-view: --size %s: expected WxH with 1 <= W, H <= 16384\n", size_text.c_str());
    return 2;
  }
  const View view(camera, width, height);
  RenderOptions options;
  options.method = method;
  options.threads = threads;
  options.shadows = !no_shadows;
  options.budget.ms = frame_ms;
  options.leaf_pixels = leaf_pixels;
  options.budget.samples = samples;
  SampleBuffer buffer;
  const Counters counters = render_frame(scene, tree, view, options, buffer);

  fmt::print(stderr, "{}: {} primitives ({} input, {} degenerate dropped), {} cells, depth {}; "
                     "load {:.0f} ms, build {:.0f} ms; {} {}x{}: {:.1f} ms, {} samples\n",
             scene_path, scene.size(), scene.input_primitives, scene.degenerate_dropped, tree.cells().size(),
             tree.depth(), std::chrono::duration<double, std::milli>(t1 - t0).count(),
             std::chrono::duration<double, std::milli>(t2 - t1).count(), method_name(method), width, height,
             counters.ms, counters.samples);
  if (!png_path.empty()) {
    if (Status s = write_png(png_path, width, height, buffer.image()); !s) {
      std::fprintf(stderr, "frontier-view: %s\n", s.to_string().c_str());
      return 1;
    }
  }
  if (!ids_path.empty()) {
    if (Status s = write_ids(ids_path, id_image(scene, buffer)); !s) {
      std::fprintf(stderr, "frontier-view: %s\n", s.to_string().c_str());
      return 1;
    }
  }
  if (!stats_path.empty()) {
    nlohmann::json j = counters.to_json();
    j["method"] = method_name(method);
    j["width"] = width;
    j["height"] = height;
    j["primitives"] = scene.size();
    j["cells"] = tree.cells().size();
    j["shadows_declared"] = !scene.lights.empty();
    std::ofstream out(stats_path);
    out << j.dump(2) << "\n";
    if (!out) {
      std::fprintf(stderr, "frontier-view: %s: cannot write\n", stats_path.c_str());
      return 1;
    }
  }
  return 0;
}
