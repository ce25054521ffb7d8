// frontier-view: the command-line front end.
//
//   frontier-view STORE [--cache 512M] [--size WxH] [--threads N] [--frame-ms MS | --samples N]
//       a window (GLFW) walking through a store, paging cells in as the view reaches them;
//   frontier-view STORE --headless --path PATH.cam --report frames.jsonl [--frames N]
//       [--png-dir DIR] [--ids-dir DIR] [--oracle] [--sync-paging] [--walk]
//       the same walk along a camera path without a window, one JSON line per frame and a summary;
//   frontier-view STORE --headless [--png F] [--ids F] [--stats F]
//       one complete frame of a store from its camera (paged, waiting for pages);
//   frontier-view MODEL --headless [--method brute|raywalk|frustum] [--png F] [--ids F] [--stats F]
//       a model file (NFF, PLY, OBJ, OFF, STL) rendered in memory (or a store with --in-memory);
//   frontier-view MODEL --headless --method imr|tessellated|mesa [--order O] [--bound-slices N]
//       [--tessellation N] [--back-sample-culling]
//       immediate-mode ray casting of its curved primitives (src/raster/imr.h), or the paper's
//       baselines: the objects tessellated and lit per vertex on frontier's rasterizer, or
//       through real OpenGL (Mesa llvmpipe, offscreen EGL);
//   frontier-view MODEL --headless --method bsp [--bsp-candidates K] [--aa NxN] [--bsp-stats F]
//       a BSP tree (src/raster/bsp.h) built with K root candidates per node, rendered back to front
//       (painter's, no depth buffer) or, with --aa, front to back with an NxN coverage mask.
//   A store, or a model with a ray-casting method, with --visibility
//   exhaustive|frustum-cull|occlusion-cull|portals renders with that visibility class
//   (src/raster/visibility.h) and the z-buffer rasterizer instead of frustum casting
//   (frustum-advance, the default); portals needs a store.
//
// Exit codes: 0 success, 1 bad input (the message names the file and line or page), 2 bad options.
//
// This file tells stores from model files and runs the mode asked for. The options are in
// viewer/options.cpp, a model's frame and its method table in viewer/model_frame.cpp and
// viewer/methods.cpp, the headless store modes in viewer/headless.cpp, walk mode in
// viewer/walk_mode.cpp, the window in viewer/window.cpp.
#include "src/core/progress.h"
#include "src/io/camera_path.h"
#include "src/paging/store_model.h"
#include "src/walk/walkthrough.h"
#include "store/page_format.h"
#include "viewer/headless.h"
#include "viewer/model_frame.h"
#include "viewer/options.h"
#include "viewer/outputs.h"
#include "viewer/walk_mode.h"
#include "viewer/window.h"

#include <CLI/CLI.hpp>

#include <cctype>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <new>
#include <system_error>

using namespace frontier;

namespace {

// A store is a file that starts with the store magic (store/FORMAT.md) or is named *.frontier
// (any case): a store whose header is damaged is still opened as one, so that the store reader
// says what is wrong with it instead of "unknown model format". Anything else is a model file.
bool is_store(const std::string& path) {
  std::string extension = std::filesystem::path(path).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (extension == ".frontier") return true;
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return false;
  char magic[8] = {};
  const size_t got = std::fread(magic, 1, sizeof magic, f);
  std::fclose(f);
  return got == sizeof magic && std::memcmp(magic, store::kMagic.data(), sizeof magic) == 0;
}

// Options that only the in-memory methods read, given for a paged store (which is walked by
// frustum casting or a --visibility class whatever they say). Returns the message for exit code
// 2, else empty.
std::string options_a_store_ignores(const CLI::App& app, const ViewerOptions& o) {
  if (app.count("--method") > 0 && o.method_text != "frustum") {
    return "--method " + o.method_text + " renders a model file, or a store with --in-memory; a store is walked by "
           "frustum casting (--visibility picks a rasterizing class instead)";
  }
  for (const char* option : {"--order", "--bound-slices", "--back-sample-culling", "--tessellation",
                             "--bsp-candidates", "--aa", "--bsp-stats"}) {
    if (app.count(option) > 0) {
      return std::string(option) + " is read by --method imr, tessellated, mesa or bsp, which render a model file "
             "or a store with --in-memory";
    }
  }
  return {};
}

// A model file (or a store with --in-memory): one headless frame; the walk options need a store.
int run_model(const ViewerOptions& o, bool store) {
  if (!o.path_file.empty() || !o.report_path.empty() || !o.ids_dir.empty() || o.walk || o.oracle) {
    return bad_option("--path, --report, --ids-dir, --walk and --oracle need a store (frontier-build) and no --in-memory");
  }
  if (!o.headless) return bad_option("a model file is rendered headless: add --headless (or build a store)");
  return render_model(o, store);
}

// The store's walkthrough options from the command line. Returns the message for exit code 2
// when a memory budget is malformed or below 1M, else empty (and sets o.collision_cache).
std::string walk_options(ViewerOptions& o, WalkOptions& wo) {
  const auto cache = parse_byte_size(o.cache_text);
  if (!cache || *cache < (1u << 20)) return "--cache " + o.cache_text + ": expected a size of at least 1M, e.g. 512M";
  const auto collision_cache = parse_byte_size(o.collision_cache_text);
  if (!collision_cache || *collision_cache < (1u << 20)) {
    return "--collision-cache " + o.collision_cache_text + ": expected a size of at least 1M, e.g. 64M";
  }
  o.collision_cache = *collision_cache;
  wo.cache_bytes = *cache;
  wo.width = o.width > 0 ? o.width : 640;
  wo.height = o.height > 0 ? o.height : 480;
  wo.threads = o.threads;
  wo.budget.ms = o.frame_ms;
  wo.budget.samples = o.samples;
  wo.min_sampled = o.min_sampled;
  wo.paging_share = o.paging_share;
  wo.sync_paging = o.sync_paging;
  wo.pixel_error = o.pixel_error >= 0.0 ? o.pixel_error : (o.sync_paging ? 0.0 : 1.0);
  wo.oracle = o.oracle;
  wo.shadows = !o.no_shadows;
  if (o.cell_prims_given) {
    wo.cell_prims = o.cell_prims;
    wo.cell_build_from_store = false;
  }
  wo.leaf_pixels = o.leaf_pixels;  // 0: the walk sizes its leaves by the image width
  wo.reconstruct_each_frame = !o.headless;  // headless: only for the frames written as PNG
  wo.visibility = *parse_visibility(o.visibility_text);
  wo.cull_back_faces = o.cull_back_faces;
  return {};
}

// The interactive window over an open walkthrough.
int run_interactive(const ViewerOptions& o, Walkthrough& walk, FrameBudget budget, const Camera& start) {
  // A window pegs frame time (50 ms unless told otherwise): frames keep coming while pages
  // arrive and the image refines.
  if (budget.ms <= 0.0 && budget.samples == 0) {
    budget.ms = 50.0;
    walk.set_budget(budget);
  }
  WindowOptions win;
  win.start = start;
  win.frames = o.frames;
  win.report = o.report_path;
  if (!o.path_file.empty()) {
    auto cams = read_camera_path(o.path_file);
    if (!cams) return fail(cams.status());
    win.path = std::move(*cams);
  }
  win.screenshot = o.png_path;
  if (!o.ids_dir.empty()) {
    if (win.path.empty()) return bad_option("--ids-dir in the window needs --path (the frames it replays)");
    if (Status s = make_output_dir("--ids-dir", o.ids_dir); !s) return fail(s);
    win.ids_dir = o.ids_dir;
  }
  win.budget = budget;
  win.start_walking = o.walk;
  WalkMode mode;
  if (walk.model().info().walkable) {
    // Options that do not fit the grid only matter when walking was asked for.
    const int code = open_walk_mode(o, walk.model(), mode);
    if (code == 1 || (code == 2 && o.walk)) return code;
    win.walk_available = mode.walker != nullptr;
  }
  return run_window(walk, win, mode.walker.get());
}

// A store, paged: one frame or a walk headless, else the window.
int run_store(ViewerOptions& o) {
  WalkOptions wo;
  if (const std::string why = walk_options(o, wo); !why.empty()) return bad_option(why);
  auto walk = Walkthrough::open(o.scene_path, wo);
  if (!walk) return fail(walk.status());
  const StoreModelInfo& info = (*walk)->model().info();
  const Camera start = info.camera ? *info.camera : automatic_camera(info.bounds);
  if (!o.headless) return run_interactive(o, **walk, wo.budget, start);
  if (o.path_file.empty() && o.report_path.empty()) return store_frame(o, **walk, start);
  return walk_headless(o, **walk, start);
}

int run_viewer(int argc, char** argv) {
  CLI::App app{"frontier-view: walk through a store far larger than memory with exact per-pixel visibility\n"
               "(frustum casting on the CPU), paging in only the cells the view reaches, and report the\n"
               "working set every frame. Also renders a model file (NFF, PLY, OBJ, OFF, STL) in memory.\n"
               "Exit status: 0 done, 1 bad input (a missing, malformed or empty model or store), 2 bad options."};
  ViewerOptions o;
  register_options(app, o);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints the help, or the error and a hint
    return code == 0 ? 0 : 2;
  }
  if (const std::string why = finish_options(app, o); !why.empty()) return bad_option(why);
  // A missing scene is bad input (exit 1) before any option that only fits a store or a model.
  if (std::error_code ec; !std::filesystem::exists(o.scene_path, ec) && !ec) {
    return fail(Status::not_found(o.scene_path + ": no such file"));
  }
  const bool store = is_store(o.scene_path);
  if (!store || o.in_memory) return run_model(o, store);
  if (const std::string why = options_a_store_ignores(app, o); !why.empty()) return bad_option(why);
  return run_store(o);
}

}  // namespace

int main(int argc, char** argv) {
  frontier::tune_allocator_for_walk();
  // Running out of memory or threads ends the run with a message (exit 1), not an abort.
  try {
    return run_viewer(argc, argv);
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "frontier-view: out of memory (a smaller --cache, --size or --threads may fit)\n");
  } catch (const std::system_error& e) {
    std::fprintf(stderr, "frontier-view: %s\n", e.what());
  }
  return 1;
}
