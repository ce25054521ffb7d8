// frontier-view: the command-line front end.
//
//   frontier-view STORE [--cache 512M] [--size WxH] [--threads N] [--frame-ms MS | --samples N]
//       a window (GLFW) walking through a store, paging cells in as the view reaches them;
//   frontier-view STORE --headless --path PATH.cam --report frames.jsonl [--frames N]
//       [--png-dir DIR] [--oracle] [--sync-paging] [--walk]
//       the same walk along a camera path without a window, one JSON line per frame and a summary;
//   frontier-view STORE --headless [--png F] [--ids F] [--stats F]
//       one complete frame of a store from its camera (paged, waiting for pages);
//   frontier-view MODEL --headless [--method brute|raywalk|frustum] [--png F] [--ids F] [--stats F]
//       a model file (NFF, PLY, OBJ, OFF) rendered in memory (or a store with --in-memory);
//   frontier-view MODEL --headless --method imr|tessellated|mesa [--order O] [--bound-slices N]
//       [--tessellation N] [--back-sample-culling]
//       immediate-mode ray casting of its curved primitives (src/raster/imr.h), or the paper's
//       baselines: the objects tessellated and lit per vertex on frontier's rasterizer, or
//       through real OpenGL (Mesa llvmpipe, offscreen EGL);
//   frontier-view MODEL --headless --method bsp [--bsp-candidates K] [--aa NxN] [--bsp-stats F]
//       a BSP tree (src/raster/bsp.h) built with K root candidates per node, rendered back to front
//       (painter's, no depth buffer) or, with --aa, front to back with an NxN coverage mask.
//   Any of these with --visibility exhaustive|frustum-cull|occlusion-cull|portals renders with
//   that visibility class (src/raster/visibility.h) and the z-buffer rasterizer instead of frustum
//   casting (frustum-advance, the default).
//
// Exit codes: 0 success, 1 bad input (the message names the file and line or page), 2 bad options.
#include "src/io/camera_path.h"
#include "src/paging/collision_grid.h"
#include "src/raster/bsp.h"
#include "src/raster/bsp_render.h"
#include "src/raster/gouraud.h"
#include "src/io/image.h"
#include "src/raster/imr.h"
#include "src/engine/kdtree.h"
#include "src/core/progress.h"
#include "src/engine/render.h"
#include "src/core/scene.h"
#include "src/paging/store_model.h"
#include "src/core/view.h"
#include "src/paging/walker.h"
#include "src/paging/walkthrough.h"
#include "store/page_format.h"
#include "viewer/mesa_renderer.h"
#include "viewer/window.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
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

// Writes `j` (indented) to `path`: the --stats and --bsp-stats files.
Status write_json(const std::string& path, const nlohmann::json& j) {
  std::ofstream out(path);
  out << j.dump(2) << "\n";
  return out ? Status::ok() : Status::io_error(path + ": cannot write");
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

int fail(const Status& s) {
  std::fprintf(stderr, "frontier-view: %s\n", s.to_string().c_str());
  return 1;
}

int bad_option(const std::string& message) {
  std::fprintf(stderr, "frontier-view: %s\n", message.c_str());
  return 2;
}

double peak_rss_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t i = std::min(v.size() - 1, static_cast<size_t>(p * double(v.size() - 1) + 0.5));
  return v[i];
}

struct Options {
  std::string scene_path, size_text, method_text = "frustum", png_path, ids_path, stats_path;
  std::string cache_text = "512M", collision_cache_text = "64M", path_file, report_path, png_dir, visibility_text = "frustum-advance";
  bool cull_back_faces = false, back_sample_culling = false;
  std::string order_text = "input", aa_text, bsp_stats_path;
  int bsp_candidates = BspBuildOptions{}.candidates;
  int bound_slices = ImrOptions{}.slices, tessellation = TessellatedOptions{}.segments;
  bool headless = false, no_shadows = false, in_memory = false, oracle = false, sync_paging = false, walk = false;
  int threads = 0, frames = 0, png_every = 0;
  uint32_t cell_prims = 8, min_cell_prims = 0;
  int leaf_pixels = FrustumCaster::kDefaultLeafPixels;
  double frame_ms = 0.0, eye_height = 0.0, radius = 0.0;
  double min_sampled = WalkOptions{}.min_sampled;
  uint64_t samples = 0;
  uint64_t collision_cache = CollisionGrid::kDefaultBudget;
  int width = 0, height = 0;
};

// One frame of a model in memory with a rasterizing visibility class.
int render_culling_in_memory(const Options& o, const Scene& scene, const KdTree& tree, const View& view,
                             Visibility visibility) {
  if (visibility == Visibility::kPortals) {
    return bad_option("--visibility portals needs a store built from a model with cells and portals");
  }
  CullOptions co;
  co.visibility = visibility;
  co.cull_back_faces = o.cull_back_faces;
  co.threads = o.threads;
  CullingRenderer renderer(co);
  MemoryCullSource source(scene, tree);
  const CullCounters counters = renderer.render(view, source);
  fmt::print(stderr, "{}: {} primitives, {} cells; {} {}x{}: {:.1f} ms, {} nodes, {} cells, {} primitives touched, "
                     "{} rasterized, {} fragments\n",
             o.scene_path, scene.size(), tree.cells().size(), visibility_name(visibility), view.width, view.height,
             counters.ms, counters.nodes_touched, counters.cells_touched, counters.primitives_touched,
             counters.primitives_rasterized, counters.pixels_rasterized);
  if (!o.png_path.empty()) {
    const Shader shader(scene, tree);
    Counters shading;
    if (Status s = write_png(o.png_path, view.width, view.height, renderer.shade(shader, shading)); !s) return fail(s);
  }
  if (!o.ids_path.empty()) {
    if (Status s = write_ids(o.ids_path, renderer.ids()); !s) return fail(s);
  }
  if (!o.stats_path.empty()) {
    nlohmann::json j = counters.to_json();
    j["visibility"] = visibility_name(visibility);
    j["width"] = view.width;
    j["height"] = view.height;
    j["primitives"] = scene.size();
    j["cells"] = tree.cells().size();
    if (Status st = write_json(o.stats_path, j); !st) return fail(st);
  }
  return 0;
}

// One frame of a model by immediate-mode ray casting or one of the paper's two baselines.
int render_immediate(const Options& o, const Scene& scene, const View& view) {
  bool ok = false;
  const IssueOrder order = parse_issue_order(o.order_text, ok);
  std::vector<Rgb> colors;
  std::vector<uint32_t> ids;  // scene primitive indices
  nlohmann::json stats;
  double ms = 0.0;
  if (o.method_text == "imr") {
    ImrOptions io;
    io.slices = o.bound_slices;
    io.order = order;
    io.back_sample_culling = o.back_sample_culling;
    io.cull_back_faces = o.cull_back_faces;
    io.shadows = !o.no_shadows;
    io.threads = o.threads;
    ImrRenderer imr(scene, io);
    const ImrCounters c = imr.render(view);
    stats = c.to_json();
    stats["bound_triangles"] = imr.bound_triangles();
    ms = c.ms;
    colors = imr.rasterizer().colors();
    ids = imr.rasterizer().ids();
  } else {
    TessellatedOptions to;
    to.segments = o.tessellation;
    to.order = order;
    to.cull_back_faces = o.cull_back_faces;
    to.threads = o.threads;
    TessellatedRenderer tess(scene, to);
    if (o.method_text == "tessellated") {
      const TessellatedCounters c = tess.render(view);
      stats = c.to_json();
      ms = c.ms;
      colors = tess.rasterizer().colors();
      ids = tess.prim_ids();
    } else {
      std::string error;
      auto mesa = MesaRenderer::create(view.width, view.height, error);
      if (!mesa) return fail(Status::io_error("--method mesa: " + error));
      const Scene triangles = tess.tessellated_scene();
      if (Status s = mesa->set_scene(triangles); !s) return fail(s);
      const std::vector<uint32_t> triangle_order = tess.triangle_order(view);
      MesaOptions mo;
      mo.cull_back_faces = o.cull_back_faces;
      mo.id_kind = MesaIdKind::Primitive;
      auto frame = mesa->render(view, &triangle_order, mo);
      if (!frame) return fail(frame.status());
      std::vector<uint32_t> triangle_ids;
      if (Status s = mesa->ids(view, triangle_ids, &triangle_order, mo); !s) return fail(s);
      ids.resize(triangle_ids.size());
      for (size_t i = 0; i < ids.size(); ++i) {
        // Triangle k of the tessellation belongs to the scene primitive whose range holds it.
        ids[i] = kNoPrim;
        if (triangle_ids[i] == kNoPrim) continue;
        uint32_t lo = 0, hi = static_cast<uint32_t>(scene.size());
        while (hi - lo > 1) {
          const uint32_t mid = (lo + hi) / 2;
          (tess.triangle_range(mid).first <= triangle_ids[i] ? lo : hi) = mid;
        }
        ids[i] = lo;
      }
      stats = {{"renderer", mesa->renderer()},         {"triangles_issued", frame->triangles_issued},
               {"vertices_lit", frame->vertices_lit},   {"pixels_covered", frame->pixels_covered},
               {"samples_passed", frame->samples_passed}, {"lights_used", frame->lights_used},
               {"lights_dropped", frame->lights_dropped}, {"ms", frame->frame_ms}};
      ms = frame->frame_ms;
      colors = frame->colors;
    }
    stats["tessellation"] = o.tessellation;
    stats["triangles"] = tess.triangles();
  }
  fmt::print(stderr, "{}: {} primitives; {} ({}) {}x{}: {:.1f} ms\n", o.scene_path, scene.size(), o.method_text,
             issue_order_name(order), view.width, view.height, ms);
  if (!o.png_path.empty()) {
    if (Status s = write_png(o.png_path, view.width, view.height, colors); !s) return fail(s);
  }
  if (!o.ids_path.empty()) {
    for (uint32_t& id : ids) {
      if (id != kNoPrim) id = scene.prims[id].source;
    }
    if (Status s = write_ids(o.ids_path, ids); !s) return fail(s);
  }
  if (!o.stats_path.empty()) {
    stats["method"] = o.method_text;
    stats["order"] = issue_order_name(order);
    stats["width"] = view.width;
    stats["height"] = view.height;
    stats["primitives"] = scene.size();
    if (Status st = write_json(o.stats_path, stats); !st) return fail(st);
  }
  return 0;
}

// One frame of a model through a BSP tree: painter's, or front to back with a coverage mask.
int render_bsp_frame(const Options& o, const Scene& scene, const View& view) {
  int aa = 0;
  if (!o.aa_text.empty()) {
    int n = 0, m = 0;
    if (!parse_size(o.aa_text, n, m) || n != m || (n != 1 && n != 2 && n != 4 && n != 8 && n != 16)) {
      return bad_option("--aa " + o.aa_text + ": expected NxN with N in 1, 2, 4, 8, 16 (the paper's: 4x4)");
    }
    aa = n;
  }
  const PolygonSoup soup = polygon_soup(scene, o.tessellation);
  BspBuildOptions bo;
  bo.candidates = o.bsp_candidates;
  auto tree = BspTree::build(soup, bo);
  if (!tree) return fail(Status::invalid_argument(o.scene_path + ": " + tree.status().message()));
  const BspStats stats = tree->stats();
  fmt::print(stderr, "{}", stats.to_text());
  BspRenderOptions ro;
  ro.order = aa > 0 ? BspOrder::FrontToBack : BspOrder::BackToFront;
  ro.aa = aa > 0 ? aa : 1;
  ro.cull_back_faces = o.cull_back_faces;
  ro.threads = o.threads;
  ro.background = scene.background;
  const BspFrame frame = render_bsp(*tree, view, ro);
  fmt::print(stderr, "{}: {} polygons -> {} faces; bsp {} {}x{}: {:.1f} ms\n", o.scene_path, stats.input_polygons,
             stats.output_polygons, aa > 0 ? fmt::format("front-to-back {}x{}", aa, aa) : std::string("painter's"),
             view.width, view.height, frame.counters.total_ms);
  if (!o.png_path.empty()) {
    if (Status s = write_png(o.png_path, view.width, view.height, frame.colors); !s) return fail(s);
  }
  if (!o.ids_path.empty()) {
    std::vector<uint32_t> ids = frame.ids;
    for (uint32_t& id : ids) {
      if (id != kNoPrim) id = tree->faces()[id].source;
    }
    if (Status s = write_ids(o.ids_path, ids); !s) return fail(s);
  }
  for (const std::string& path : {o.stats_path, o.bsp_stats_path}) {
    if (path.empty()) continue;
    nlohmann::json j = nlohmann::json::parse(stats.to_json());
    if (path == o.stats_path) {
      const BspFrameCounters& c = frame.counters;
      j["method"] = "bsp";
      j["order"] = aa > 0 ? "front-to-back" : "back-to-front";
      j["aa"] = aa;
      j["width"] = view.width;
      j["height"] = view.height;
      j["frame"] = {{"nodes_visited", c.nodes_visited},   {"faces_drawn", c.faces_drawn},
                    {"faces_culled_back", c.faces_culled_back}, {"pixel_visits", c.pixel_visits},
                    {"pixels_skipped_full", c.pixels_skipped_full}, {"pixels_full", c.pixels_full},
                    {"traverse_ms", c.traverse_ms},        {"raster_ms", c.raster_ms},
                    {"ms", c.total_ms}};
    }
    if (Status st = write_json(path, j); !st) return fail(st);
  }
  return 0;
}

// A model file, or a store decoded whole, rendered in memory: one frame.
int render_in_memory(const Options& o, bool store) {
  const bool immediate = o.method_text == "imr" || o.method_text == "tessellated" || o.method_text == "mesa";
  Method method = Method::Frustum;
  if (!immediate && o.method_text != "bsp") parse_method(o.method_text, method);
  Scene scene;
  KdTree tree;
  KdBuildOptions build;
  build.max_cell_prims = o.cell_prims;
  build.min_cell_prims = o.min_cell_prims;
  const auto t0 = std::chrono::steady_clock::now();
  if (store) {
    auto model = StoreModel::open(o.scene_path);
    Status s = model ? (*model)->load_all(scene, tree, build) : model.status();
    if (!s) return fail(s);
  } else {
    if (Status s = load_scene(o.scene_path, scene); !s) return fail(s);
  }
  const auto t1 = std::chrono::steady_clock::now();
  if (!store) tree = KdTree::build(scene, build);
  const auto t2 = std::chrono::steady_clock::now();
  Camera camera = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
  int width = camera.width > 0 ? camera.width : 512, height = camera.height > 0 ? camera.height : 512;
  if (o.width > 0) {
    width = o.width;
    height = o.height;
  }
  const View view(camera, width, height);
  if (immediate) return render_immediate(o, scene, view);
  if (o.method_text == "bsp") return render_bsp_frame(o, scene, view);
  RenderOptions options;
  options.method = method;
  options.threads = o.threads;
  options.shadows = !o.no_shadows;
  options.budget.ms = o.frame_ms;
  options.budget.samples = o.samples;
  options.leaf_pixels = o.leaf_pixels;
  const Visibility visibility = *parse_visibility(o.visibility_text);
  if (visibility != Visibility::kFrustumAdvance) return render_culling_in_memory(o, scene, tree, view, visibility);
  SampleBuffer buffer;
  const Counters counters = render_frame(scene, tree, view, options, buffer);
  fmt::print(stderr, "{}: {} primitives ({} input, {} degenerate dropped), {} cells, depth {}; "
                     "load {:.0f} ms, build {:.0f} ms; {} {}x{}: {:.1f} ms, {} samples\n",
             o.scene_path, scene.size(), scene.input_primitives, scene.degenerate_dropped, tree.cells().size(),
             tree.depth(), std::chrono::duration<double, std::milli>(t1 - t0).count(),
             std::chrono::duration<double, std::milli>(t2 - t1).count(), method_name(method), width, height,
             counters.ms, counters.samples);
  if (!o.png_path.empty()) {
    if (Status s = write_png(o.png_path, width, height, buffer.image()); !s) return fail(s);
  }
  if (!o.ids_path.empty()) {
    if (Status s = write_ids(o.ids_path, id_image(scene, buffer)); !s) return fail(s);
  }
  if (!o.stats_path.empty()) {
    nlohmann::json j = counters.to_json();
    j["method"] = method_name(method);
    j["width"] = width;
    j["height"] = height;
    j["primitives"] = scene.size();
    j["cells"] = tree.cells().size();
    j["shadows_declared"] = !scene.lights.empty();
    if (Status st = write_json(o.stats_path, j); !st) return fail(st);
  }
  return 0;
}

// Walk mode: the store must carry a distance grid (frontier-build --walkable).
Result<std::unique_ptr<CollisionGrid>> load_grid(const StoreModel& model, uint64_t budget) {
  if (!model.info().walkable) {
    return Status::invalid_argument(model.reader().name() +
                                    ": the store declares no walk mode (build it with --walkable)");
  }
  return open_collision_grid(model.reader(), budget);
}

WalkParams walk_params(const Options& o, const StoreModel& model) {
  WalkParams p;
  if (o.eye_height > 0.0) p.eye_height = o.eye_height;
  if (o.radius > 0.0) {
    p.radius = o.radius;
  } else if (model.info().walk_radius > 0.0) {
    p.radius = model.info().walk_radius;
  }
  return p;
}

// Walk mode's grid and walker. Returns 0 when ready; else prints why and returns 1 (the store
// has no usable grid) or 2 (the walk options do not fit the grid).
struct WalkMode {
  std::unique_ptr<CollisionGrid> grid;
  std::unique_ptr<Walker> walker;
};
int open_walk_mode(const Options& o, const StoreModel& model, WalkMode& mode) {
  auto grid = load_grid(model, o.collision_cache);
  if (!grid) return fail(grid.status());
  mode.grid = std::move(*grid);
  const WalkParams params = walk_params(o, model);
  if (Status s = Walker::check(*mode.grid, params); !s) return bad_option("walk mode: " + s.message());
  mode.walker = std::make_unique<Walker>(*mode.grid, params);
  return 0;
}

// The walk along a camera path without a window: frames.jsonl, PNGs, summary.
int walk_headless(const Options& o, Walkthrough& walk, const Camera& start) {
  std::vector<Camera> path;
  if (!o.path_file.empty()) {
    auto cams = read_camera_path(o.path_file);
    if (!cams) return fail(cams.status());
    path = std::move(*cams);
    if (path.empty()) return fail(Status::invalid_argument(o.path_file + ": the path has no frames"));
  } else {
    path.push_back(start);
  }
  const size_t frames = o.frames > 0 ? static_cast<size_t>(o.frames) : path.size();
  WalkMode mode;
  if (o.walk) {
    if (const int code = open_walk_mode(o, walk.model(), mode); code != 0) return code;
  }
  Walker* const walker = mode.walker.get();
  std::ofstream report;
  if (!o.report_path.empty()) {
    report.open(o.report_path);
    if (!report) return fail(Status::io_error(o.report_path + ": cannot write"));
  }
  if (!o.png_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.png_dir, ec);
    if (ec) return fail(Status::io_error(o.png_dir + ": " + ec.message()));
  }
  const size_t png_every = o.png_every > 0 ? size_t(o.png_every) : std::max<size_t>(1, frames / 4);
  std::vector<double> frame_ms;
  double samples = 0.0, ratio_sum = 0.0, ratio_max = 0.0;
  uint64_t collision_max = 0;
  uint64_t bytes_read = 0, ratio_frames = 0, errors = 0, resident_max = 0, complete = 0, floor_frames = 0;
  Vec3 eye = path.front().eye;
  for (size_t f = 0; f < frames; ++f) {
    Camera cam = path[std::min(f, path.size() - 1)];
    if (walker) {
      // The path gives where the walker wants to go; collision and gravity decide where it is.
      const Vec3 look = cam.look_at - cam.eye;
      eye = f == 0 ? walker->step(cam.eye, cam.eye, 0.0) : walker->step(eye, cam.eye, 1.0 / 30.0);
      cam.eye = eye;
      cam.look_at = eye + look;
    }
    FrameReport r = walk.frame(cam);
    if (walker) r.add_walk_counters(*walker);
    frame_ms.push_back(r.frame_ms);
    samples += double(r.samples);
    bytes_read += r.bytes_read;
    errors = r.page_errors;
    resident_max = std::max(resident_max, r.resident_bytes);
    collision_max = std::max(collision_max, r.collision_bytes);
    complete += r.complete ? 1 : 0;
    floor_frames += r.floor_ms > 0.0 ? 1 : 0;
    if (r.oracle_ratio) {
      ratio_sum += *r.oracle_ratio;
      ratio_max = std::max(ratio_max, *r.oracle_ratio);
      ++ratio_frames;
    }
    if (report.is_open()) report << r.to_json().dump() << "\n";
    if (!o.png_dir.empty() && (f % png_every == 0 || f + 1 == frames)) {
      const std::string file = fmt::format("{}/frame_{:05d}.png", o.png_dir, f);
      if (Status s = write_png(file, walk.view().width, walk.view().height, walk.image()); !s) return fail(s);
    }
  }
  const CollisionGrid::Counters grid = walker ? walker->grid().counters() : CollisionGrid::Counters{};
  nlohmann::json summary = {{"frames", frames},
                            {"p50_frame_ms", percentile(frame_ms, 0.5)},
                            {"p95_frame_ms", percentile(frame_ms, 0.95)},
                            {"mean_samples", frames ? samples / double(frames) : 0.0},
                            {"complete_frames", complete},
                            {"floor_frames", floor_frames},
                            {"peak_rss_mib", peak_rss_mib()},
                            {"max_resident_bytes", resident_max},
                            {"cache_budget", walk.world().budget_bytes()},
                            {"total_bytes_read", bytes_read},
                            {"page_errors", errors},
                            {"collision_queries", walker ? walker->queries() : 0},
                            {"max_collision_bytes", collision_max},
                            {"collision_cache_budget", walker ? o.collision_cache : 0},
                            {"collision_loads", grid.loads},
                            {"collision_errors", grid.errors}};
  if (ratio_frames > 0) {
    summary["mean_touched_oracle_ratio"] = ratio_sum / double(ratio_frames);
    summary["max_touched_oracle_ratio"] = ratio_max;
  }
  if (report.is_open()) {
    report << nlohmann::json{{"summary", summary}}.dump() << "\n";
    if (!report) return fail(Status::io_error(o.report_path + ": cannot write"));
  }
  fmt::print(stderr, "frontier-view: {} frames; frame ms p50 {:.1f} p95 {:.1f}; mean samples {:.0f} of {}; "
                     "{} complete; {} past the peg for the sample floor; peak RSS {:.0f} MiB "
                     "(resident at most {:.1f} of {:.1f} MiB); read {:.1f} MiB; "
                     "{} page errors{}\n",
             frames, percentile(frame_ms, 0.5), percentile(frame_ms, 0.95), frames ? samples / double(frames) : 0.0,
             walk.view().pixels(), complete, floor_frames, peak_rss_mib(), double(resident_max) / 1048576.0,
             double(walk.world().budget_bytes()) / 1048576.0, double(bytes_read) / 1048576.0, errors,
             ratio_frames ? fmt::format("; touched/oracle mean {:.3f} max {:.3f}", ratio_sum / double(ratio_frames),
                                        ratio_max)
                          : std::string());
  if (walker) {
    fmt::print(stderr, "frontier-view: collision grid: {} of {} bricks read ({:.1f} ms), at most {:.1f} of {:.1f} MiB "
                       "resident, {} evicted, {} unreadable\n",
               grid.loads, grid.bricks, grid.load_ms, double(collision_max) / 1048576.0,
               double(o.collision_cache) / 1048576.0, grid.evictions, grid.errors);
    if (grid.errors > 0) fmt::print(stderr, "frontier-view: {}\n", walker->grid().error().to_string());
  }
  return 0;
}

// One complete frame of a store from its camera (--png/--ids/--stats).
int store_frame(const Options& o, Walkthrough& walk, const Camera& camera) {
  const FrameReport r = walk.frame(camera);
  fmt::print(stderr, "{}: {} cells touched, {} paged in ({:.1f} MiB read), {:.1f} ms, {} samples\n", o.scene_path,
             r.cells_touched, r.cells_paged_in, double(r.bytes_read) / 1048576.0, r.frame_ms, r.image_samples);
  if (!o.png_path.empty()) {
    if (Status s = write_png(o.png_path, walk.view().width, walk.view().height, walk.image()); !s) {
      return fail(s);
    }
  }
  if (!o.ids_path.empty()) {
    if (Status s = write_ids(o.ids_path, walk.ids()); !s) return fail(s);
  }
  if (!o.stats_path.empty()) {
    if (Status st = write_json(o.stats_path, r.to_json()); !st) return fail(st);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"frontier-view: walk through a store far larger than memory with exact per-pixel visibility\n"
               "(frustum casting on the CPU), paging in only the cells the view reaches, and report the\n"
               "working set every frame. Also renders a model file (NFF, PLY, OBJ, OFF) in memory."};
  Options o;
  app.add_option("SCENE", o.scene_path, "store file (frontier-build) or model file (.nff, .ply, .obj, .off)")
      ->required();
  app.add_flag("--headless", o.headless, "no window: walk --path, or render one frame");
  app.add_option("--size", o.size_text, "image size WxH (default 640x480 for stores; a model's own resolution or 512x512)");
  app.add_option("--threads", o.threads, "render threads (0 = all cores)")->check(CLI::NonNegativeNumber);
  auto* peg_time = app.add_option("--frame-ms", o.frame_ms, "peg frame time: stop each frame after MS milliseconds (window default: 50)")
                       ->check(CLI::PositiveNumber);
  auto* peg_samples = app.add_option("--samples", o.samples, "peg sample count: stop each frame after N samples")
                          ->check(CLI::PositiveNumber);
  peg_time->excludes(peg_samples);
  app.add_option("--min-sampled", o.min_sampled,
                 "store, with a pegged frame time: a moving frame goes on past its time (at most one more frame "
                 "time) until this share of its pixels is sampled; 0 = pure frame-time pegging (default 0.5)")
      ->check(CLI::Range(0.0, 1.0));
  // Stores.
  app.add_option("--cache", o.cache_text, "store: memory budget for paged cells, compressed and decoded (e.g. 512M, 2G)");
  app.add_option("--collision-cache", o.collision_cache_text,
                 "walk mode: memory budget for the collision grid's bricks, paged in as the walker reaches them "
                 "(default 64M)");
  app.add_option("--path", o.path_file, "store, headless: camera path (.cam, from frontier-gen path)");
  app.add_option("--frames", o.frames, "frames to render (default: the path's length; window: until closed)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--report", o.report_path, "store: write one JSON object per frame, then a summary line");
  app.add_option("--png-dir", o.png_dir, "store, headless: write some frames as PNG into DIR");
  app.add_option("--png-every", o.png_every, "with --png-dir: every Nth frame (default: frames/4) and the last")
      ->check(CLI::PositiveNumber);
  app.add_flag("--oracle", o.oracle, "store: count oracle_cells, the cells exact per-pixel rays pass before their first hit");
  app.add_flag("--sync-paging", o.sync_paging, "store: wait for every page a frame needs (exact, complete frames)");
  app.add_flag("--walk", o.walk, "store: walk mode along the path (gravity, collision); the store must be --walkable");
  app.add_option("--eye-height", o.eye_height, "walk mode: eye height above the floor")->check(CLI::PositiveNumber);
  app.add_option("--radius", o.radius, "walk mode: clearance kept from geometry (default: the store's)")
      ->check(CLI::PositiveNumber);
  app.add_flag("--in-memory", o.in_memory, "store: decode every page into memory and render like a model file");
  // One frame.
  app.add_option("--png", o.png_path, "one frame: write the image as PNG");
  app.add_option("--ids", o.ids_path,
                 "one frame: write the first-hit input primitive per pixel (uint32 little-endian, row-major, "
                 "0xFFFFFFFF = background)");
  app.add_option("--stats", o.stats_path, "one frame: write counters as JSON");
  app.add_option("--method", o.method_text,
                 "model file: brute | raywalk | frustum (ray casting), imr (immediate-mode ray casting of curved "
                 "primitives), tessellated (objects tessellated, lit per vertex, frontier's rasterizer), mesa (the "
                 "same through OpenGL: Mesa llvmpipe, offscreen), bsp (a BSP tree: painter's, or front to back "
                 "with --aa)")
      ->check(CLI::IsMember({"brute", "raywalk", "frustum", "imr", "tessellated", "mesa", "bsp"}));
  app.add_option("--bsp-candidates", o.bsp_candidates,
                 "bsp: root candidates tried per node, the one cutting fewest others wins (0: all; paper: 5)")
      ->check(CLI::Range(0, 1 << 30));
  app.add_option("--aa", o.aa_text, "bsp: front-to-back rendering with an NxN sub-pixel coverage mask (1x1 .. 16x16; paper: 4x4)");
  app.add_option("--bsp-stats", o.bsp_stats_path, "bsp: write the tree statistics (sizes, splits, depth, build ms) as JSON");
  app.add_option("--order", o.order_text,
                 "imr, tessellated, mesa: object order: input | random | front-to-back (k-d tree) | nearest-first "
                 "(sorted by distance)")
      ->check(CLI::IsMember({"input", "random", "front-to-back", "nearest-first"}));
  app.add_option("--bound-slices", o.bound_slices, "imr: bounding polyhedron slices (spheres: slices/2 stacks)")
      ->check(CLI::Range(3, 256));
  app.add_option("--tessellation", o.tessellation, "tessellated, mesa, bsp: segments around a full circle")
      ->check(CLI::Range(3, 1024));
  app.add_flag("--back-sample-culling", o.back_sample_culling,
               "imr: discard ray samples facing away from the eye (the inside of open or clipped surfaces)");
  app.add_option("--cell-prims", o.cell_prims, "largest k-d cell kept when it could split (default 8; stores, inside a page: 16)")
      ->check(CLI::Range(1u, 1000000u));
  app.add_option("--min-cell-prims", o.min_cell_prims, "model file: cells at or below this size never split")
      ->check(CLI::Range(0u, 1000000u));
  app.add_option("--leaf-pixels", o.leaf_pixels, "frusta up to N×N pixels walk their pixels individually (paper: 2)")
      ->check(CLI::Range(2, 4096));
  app.add_flag("--no-shadows", o.no_shadows, "skip the deferred shadow effect");
  app.add_option("--visibility", o.visibility_text,
                 "visibility class: frustum-advance (frustum casting, default) | exhaustive | frustum-cull | "
                 "occlusion-cull | portals (the last four rasterize complete frames; portals needs a store with "
                 "cells and portals)")
      ->check(CLI::IsMember({"frustum-advance", "exhaustive", "frustum-cull", "occlusion-cull", "portals"}));
  app.add_flag("--cull-back-faces", o.cull_back_faces,
               "rasterizing classes: drop triangles facing away from the eye (exact for closed solids seen from outside)");
  CLI11_PARSE(app, argc, argv);

  if (!o.size_text.empty() && !parse_size(o.size_text, o.width, o.height)) {
    return bad_option("--size " + o.size_text + ": expected WxH with 1 <= W, H <= 16384");
  }
  const bool store = is_store(o.scene_path);
  if (!store || o.in_memory) {
    if (!o.path_file.empty() || !o.report_path.empty() || o.walk || o.oracle) {
      return bad_option("--path, --report, --walk and --oracle need a store (frontier-build) and no --in-memory");
    }
    if (!o.headless) return bad_option("a model file is rendered headless: add --headless (or build a store)");
    return render_in_memory(o, store);
  }
  const auto cache = parse_byte_size(o.cache_text);
  if (!cache || *cache < (1u << 20)) return bad_option("--cache " + o.cache_text + ": expected a size of at least 1M, e.g. 512M");
  const auto collision_cache = parse_byte_size(o.collision_cache_text);
  if (!collision_cache || *collision_cache < (1u << 20)) {
    return bad_option("--collision-cache " + o.collision_cache_text + ": expected a size of at least 1M, e.g. 64M");
  }
  o.collision_cache = *collision_cache;

  WalkOptions wo;
  wo.cache_bytes = *cache;
  wo.width = o.width > 0 ? o.width : 640;
  wo.height = o.height > 0 ? o.height : 480;
  wo.threads = o.threads;
  wo.budget.ms = o.frame_ms;
  wo.budget.samples = o.samples;
  wo.min_sampled = o.min_sampled;
  wo.sync_paging = o.sync_paging;
  wo.oracle = o.oracle;
  wo.shadows = !o.no_shadows;
  if (app.count("--cell-prims") > 0) wo.cell_prims = o.cell_prims;
  wo.leaf_pixels = o.leaf_pixels;
  wo.reconstruct_each_frame = !o.headless;  // headless: only for the frames written as PNG
  wo.visibility = *parse_visibility(o.visibility_text);
  wo.cull_back_faces = o.cull_back_faces;
  auto walk = Walkthrough::open(o.scene_path, wo);
  if (!walk) return fail(walk.status());
  const StoreModelInfo& info = (*walk)->model().info();
  const Camera start = info.camera ? *info.camera : automatic_camera(info.bounds);

  if (o.headless) {
    if (o.path_file.empty() && o.report_path.empty()) return store_frame(o, **walk, start);
    return walk_headless(o, **walk, start);
  }
  // An interactive window pegs frame time (50 ms unless told otherwise): frames keep coming
  // while pages arrive and the image refines.
  if (wo.budget.ms <= 0.0 && wo.budget.samples == 0) {
    wo.budget.ms = 50.0;
    (*walk)->set_budget(wo.budget);
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
  win.budget = wo.budget;
  win.start_walking = o.walk;
  WalkMode mode;
  if (info.walkable) {
    // Options that do not fit the grid only matter when walking was asked for.
    const int code = open_walk_mode(o, (*walk)->model(), mode);
    if (code == 1 || (code == 2 && o.walk)) return code;
    win.walk_available = mode.walker != nullptr;
  }
  return run_window(**walk, win, mode.walker.get());
}
