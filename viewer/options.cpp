// frontier-view's options, registered in the order --help lists them: any scene, stores, one
// frame, then the methods and visibility classes.
#include "viewer/options.h"

#include "src/core/option_checks.h"
#include "viewer/methods.h"

#include <cstdio>

namespace frontier {
namespace {

namespace checks = option_checks;

void add_scene_options(CLI::App& app, ViewerOptions& o) {
  app.add_option("SCENE", o.scene_path, "store file (frontier-build) or model file (.nff, .ply, .obj, .off)")
      ->required();
  app.add_flag("--headless", o.headless, "no window: walk --path, or render one frame");
  app.add_option("--size", o.size_text, "image size WxH (default 640x480 for stores; a model's own resolution or 512x512)");
  app.add_option("--threads", o.threads, "render threads (0 = all cores; at most 4 per hardware thread)")
      ->check(checks::thread_count());
  auto* peg_time = app.add_option("--frame-ms", o.frame_ms, "peg frame time: stop each frame after MS milliseconds (window default: 50); a store's image with proxies that is done sooner spends the rest on the pages its cut asked for")
                       ->check(checks::positive());
  auto* peg_samples = app.add_option("--samples", o.samples, "peg sample count: stop each frame after N samples")
                          ->check(checks::positive());
  peg_time->excludes(peg_samples);
  app.add_option("--min-sampled", o.min_sampled,
                 "store, with a pegged frame time: a moving frame goes on past its time (at most one more frame "
                 "time, from the peg or from when it was reached if later) until this share of its pixels is "
                 "sampled; 0 = pure frame-time pegging (default 0.5)")
      ->check(checks::between(0.0, 1.0));
  app.add_option("--paging-share", o.paging_share,
                 "store with proxies, with a pegged frame time: the most of each frame that paging in (the proxies "
                 "and pages the cut asked for) may take before its rays; more refines sooner, less samples more. A "
                 "frame takes all of it while the last frame's rays met proxies ten times the pixel error off or "
                 "more (the report's cut_error), a fifth at the pixel error (default 0.25)")
      ->check(checks::between(0.01, 1.0));
}

void add_store_options(CLI::App& app, ViewerOptions& o) {
  app.add_option("--cache", o.cache_text,
                 "store: memory budget for paged cells, compressed (an eighth) and decoded (e.g. 512M, 2G); frames "
                 "whose cells exceed it thrash (the report's thrashing and cache_needed)");
  app.add_option("--collision-cache", o.collision_cache_text,
                 "walk mode: memory budget for the collision grid's bricks, paged in as the walker reaches them "
                 "(default 64M)");
  app.add_option("--pixel-error", o.pixel_error,
                 "store with proxies: each image draws one cut of the tree, chosen before its first ray: a node "
                 "whose proxy's error bound projects below T pixels (at the node's point nearest the eye), or whose "
                 "children are not all resident, is drawn by its proxy, else by its children; what the rays reached "
                 "above T is asked for, for later images. 0 = exact (every cell from its page). A still camera "
                 "refines to 0. Default 1, and 0 with --sync-paging")
      ->check(checks::non_negative());
  app.add_option("--path", o.path_file, "store, headless: camera path (.cam, from frontier-gen path)");
  app.add_option("--frames", o.frames, "frames to render (default: the path's length; window: until closed)")
      ->check(checks::non_negative());
  app.add_option("--report", o.report_path, "store: write one JSON object per frame, then a summary line");
  app.add_option("--png-dir", o.png_dir, "store, headless: write some frames as PNG into DIR");
  app.add_option("--ids-dir", o.ids_dir,
                 "store, along --path (headless, or the window replaying it): write every frame's ids as "
                 "DIR/frame_NNNNN.ids (the --ids layout, numbered like --png-dir from 00000); DIR is created, and "
                 "one that cannot be created or written is an error (exit 1)");
  app.add_option("--png-every", o.png_every, "with --png-dir: every Nth frame (default: frames/4) and the last")
      ->check(checks::positive());
  app.add_flag("--oracle", o.oracle, "store: count oracle_cells, the cells exact per-pixel rays pass before their first hit");
  app.add_flag("--sync-paging", o.sync_paging,
               "store: wait for every page a frame needs (exact, complete frames; a frame whose cells exceed "
               "--cache is rendered in passes and reported as thrashing, with the --cache it needs)");
  app.add_flag("--walk", o.walk, "store: walk mode along the path (gravity, collision); the store must be --walkable");
  app.add_option("--eye-height", o.eye_height, "walk mode: eye height above the floor")->check(checks::positive());
  app.add_option("--radius", o.radius, "walk mode: clearance kept from geometry (default: the store's)")
      ->check(checks::positive());
  app.add_flag("--in-memory", o.in_memory, "store: decode every page into memory and render like a model file");
}

constexpr const char* kIdsHelp =
    "the frame (with --path: the last frame): write the first-hit input primitive per pixel (uint32 little-endian, row-major, "
    "0xFFFFFFFF = background)";

void add_frame_options(CLI::App& app, ViewerOptions& o) {
  app.add_option("--png", o.png_path, "the frame (with --path: the last frame): write the image as PNG");
  app.add_option("--ids", o.ids_path, kIdsHelp);
  app.add_option("--stats", o.stats_path, "the frame (with --path: the last frame): write counters as JSON");
}

void add_method_options(CLI::App& app, ViewerOptions& o) {
  app.add_option("--method", o.method_text, method_help())->check(CLI::IsMember(method_names()));
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
  app.add_option("--cell-prims", o.cell_prims, "largest k-d cell kept when it could split (default 8; stores, inside a page: as the store's in-cell trees were built, else 16; given for a store, its pages' trees are rebuilt with it at page-in)")
      ->check(CLI::Range(1u, 1000000u));
  app.add_option("--min-cell-prims", o.min_cell_prims, "model file: cells at or below this size never split")
      ->check(CLI::Range(0u, 1000000u));
  app.add_option("--leaf-pixels", o.leaf_pixels, "frusta up to N×N pixels resolve their pixels individually: as 4×4 ray packets in scenes of triangles, else walked one by one (paper: 2; default 16 for a model file, a twentieth of the width and at least 16 for a store's walk: 32 at 640, 64 at 1280)")
      ->check(CLI::Range(2, 4096));
  app.add_flag("--kd-kernel", o.kd_kernel,
               "model file, frustum and packet: trace the packets' rays through the k-d tree instead of Embree's BVH "
               "(the same image, exactly; slower: for comparison)");
  app.add_flag("--no-shadows", o.no_shadows, "skip the deferred shadow effect");
  app.add_option("--visibility", o.visibility_text,
                 "visibility class: frustum-advance (frustum casting, default) | exhaustive | frustum-cull | "
                 "occlusion-cull | portals (the last four rasterize complete frames; portals needs a store with "
                 "cells and portals)")
      ->check(CLI::IsMember({"frustum-advance", "exhaustive", "frustum-cull", "occlusion-cull", "portals"}));
  app.add_flag("--cull-back-faces", o.cull_back_faces,
               "rasterizing classes: drop triangles facing away from the eye (exact for closed solids seen from outside)");
}

}  // namespace

bool parse_size(const std::string& text, int& w, int& h) {
  int a = 0, b = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &a, &x, &b, &extra) != 3 || (x != 'x' && x != 'X')) return false;
  if (a < 1 || b < 1 || a > 16384 || b > 16384) return false;
  w = a;
  h = b;
  return true;
}

void register_options(CLI::App& app, ViewerOptions& o) {
  add_scene_options(app, o);
  add_store_options(app, o);
  add_frame_options(app, o);
  add_method_options(app, o);
}

std::string finish_options(const CLI::App& app, ViewerOptions& o) {
  o.cell_prims_given = app.count("--cell-prims") > 0;
  if (!o.size_text.empty() && !parse_size(o.size_text, o.width, o.height)) {
    return "--size " + o.size_text + ": expected WxH with 1 <= W, H <= 16384";
  }
  return {};
}

}  // namespace frontier
