// frontier-view's command line: the value of every option (ViewerOptions) and their
// registration with CLI11, grouped by what they apply to (any scene, stores, one frame, the
// methods for model files). --method's choices and help come from the method table
// (viewer/methods.h), so a method is added in one place.
#pragma once

#include "src/engine/frustum.h"
#include "src/raster/bsp.h"
#include "src/raster/gouraud.h"
#include "src/raster/imr.h"
#include "src/walk/collision_grid.h"
#include "src/walk/walkthrough.h"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <string>

namespace frontier {

struct ViewerOptions {
  std::string scene_path;
  bool headless = false;
  std::string size_text;
  int width = 0, height = 0;  // from --size (0: not given)
  int threads = 0;
  double frame_ms = 0.0;
  uint64_t samples = 0;
  double min_sampled = WalkOptions{}.min_sampled;
  double paging_share = WalkOptions{}.paging_share;
  bool no_shadows = false;
  // Stores.
  std::string cache_text = "512M", collision_cache_text = "64M";
  uint64_t collision_cache = CollisionGrid::kDefaultBudget;  // --collision-cache parsed (stores only)
  std::string path_file, report_path, png_dir, ids_dir;
  int frames = 0, png_every = 0;
  bool oracle = false, sync_paging = false, walk = false, in_memory = false;
  double pixel_error = -1.0;  // --pixel-error; negative: not given (1, or 0 with --sync-paging)
  double eye_height = 0.0, radius = 0.0;
  // One frame.
  std::string png_path, ids_path, stats_path;
  // Methods and visibility classes.
  std::string method_text = "frustum", visibility_text = "frustum-advance";
  int bsp_candidates = BspBuildOptions{}.candidates;
  std::string aa_text, bsp_stats_path;
  std::string order_text = "input";
  int bound_slices = ImrOptions{}.slices, tessellation = TessellatedOptions{}.segments;
  bool back_sample_culling = false, cull_back_faces = false;
  uint32_t cell_prims = 8, min_cell_prims = 0;
  bool cell_prims_given = false;  // --cell-prims on the command line (stores keep their own default)
  int leaf_pixels = 0;  // --leaf-pixels; 0: the method's own (frustum casting 16, a store's walk by its width)
  bool kd_kernel = false;  // --kd-kernel: packets through the k-d tree, not Embree's BVH
};

// Registers every option of frontier-view with `app`, writing into `o`.
void register_options(CLI::App& app, ViewerOptions& o);

// After app's parse: fills in what CLI11 does not (the size from --size, whether --cell-prims
// was given). Returns the message for exit code 2 when --size is malformed, else empty.
std::string finish_options(const CLI::App& app, ViewerOptions& o);

// "WxH" with 1 <= W, H <= 16384.
bool parse_size(const std::string& text, int& w, int& h);

}  // namespace frontier
