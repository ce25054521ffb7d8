// The method table of frontier-view: each method's options, factory and stderr line. The
// factories translate ViewerOptions into the renderer's own option struct and nothing more;
// what a method does lives in its library (src/engine, src/raster, viewer/mesa_frame_renderer).
#include "viewer/methods.h"

#include "src/engine/render.h"
#include "src/raster/bsp.h"
#include "src/raster/bsp_render.h"
#include "src/raster/gouraud.h"
#include "src/raster/imr.h"
#include "src/raster/visibility.h"
#include "viewer/mesa_frame_renderer.h"
#include "viewer/outputs.h"

#include <fmt/core.h>

#include <algorithm>

namespace frontier {
namespace {

using MakeResult = Result<std::unique_ptr<FrameRenderer>>;

template <class R>
MakeResult owned(std::unique_ptr<R> renderer) {
  return std::unique_ptr<FrameRenderer>(std::move(renderer));
}

// Ray casting: brute force, ray walking, frustum casting (the frustum-advance class).

template <Method kMethod>
MakeResult make_ray_cast(const MethodInput& in) {
  const ViewerOptions& o = in.options;
  RenderOptions options;
  options.method = kMethod;
  options.threads = o.threads;
  options.shadows = !o.no_shadows;
  options.budget.ms = o.frame_ms;
  options.budget.samples = o.samples;
  options.leaf_pixels = o.leaf_pixels > 0 ? o.leaf_pixels : FrustumCaster::kDefaultLeafPixels;
  options.accel = !o.kd_kernel;
  return owned(std::make_unique<RayCastFrameRenderer>(in.scene, in.tree, options));
}

std::string ray_cast_summary(const MethodInput& in, const Frame& frame) {
  const Scene& scene = in.scene;
  return fmt::format("{}: {} primitives ({} input, {} degenerate dropped), {} cells, depth {}; "
                     "load {:.0f} ms, build {:.0f} ms; {} {}x{}: {:.1f} ms, {} samples\n",
                     in.options.scene_path, scene.size(), scene.input_primitives, scene.degenerate_dropped,
                     in.tree.cells().size(), in.tree.depth(), in.load_ms, in.build_ms,
                     frame.stats.at("method").get<std::string>(), in.view.width, in.view.height, frame.ms,
                     frame.stats.at("samples").get<uint64_t>());
}

// The rasterizing visibility classes.

constexpr const char* kPortalsNeedAStore =
    "--visibility portals needs a store built from a model with cells and portals";

std::string refuse_portals(const ViewerOptions&) { return kPortalsNeedAStore; }

template <Visibility kVisibility>
MakeResult make_culling(const MethodInput& in) {
  if (kVisibility == Visibility::kPortals) return Status::invalid_argument(kPortalsNeedAStore);
  CullOptions options;
  options.visibility = kVisibility;
  options.cull_back_faces = in.options.cull_back_faces;
  options.threads = in.options.threads;
  return owned(std::make_unique<CullingFrameRenderer>(in.scene, in.tree, options));
}

std::string culling_summary(const MethodInput& in, const Frame& frame) {
  const nlohmann::json& s = frame.stats;
  return fmt::format("{}: {} primitives, {} cells; {} {}x{}: {:.1f} ms, {} nodes, {} cells, {} primitives touched, "
                     "{} rasterized, {} fragments\n",
                     in.options.scene_path, in.scene.size(), in.tree.cells().size(),
                     s.at("visibility").get<std::string>(), in.view.width, in.view.height, frame.ms,
                     s.at("nodes_touched").get<uint64_t>(), s.at("cells_touched").get<uint64_t>(),
                     s.at("primitives_touched").get<uint64_t>(), s.at("primitives_rasterized").get<uint64_t>(),
                     s.at("pixels_rasterized").get<uint64_t>());
}

// Immediate-mode ray casting and its two scan-conversion baselines.

IssueOrder issue_order_of(const ViewerOptions& o) {
  bool ok = false;
  return parse_issue_order(o.order_text, ok);  // CLI11 checked the name
}

TessellatedOptions tessellated_options(const ViewerOptions& o) {
  TessellatedOptions options;
  options.segments = o.tessellation;
  options.order = issue_order_of(o);
  options.cull_back_faces = o.cull_back_faces;
  options.threads = o.threads;
  return options;
}

MakeResult make_imr(const MethodInput& in) {
  const ViewerOptions& o = in.options;
  ImrOptions options;
  options.slices = o.bound_slices;
  options.order = issue_order_of(o);
  options.back_sample_culling = o.back_sample_culling;
  options.cull_back_faces = o.cull_back_faces;
  options.shadows = !o.no_shadows;
  options.threads = o.threads;
  return owned(std::make_unique<ImrFrameRenderer>(in.scene, options));
}

MakeResult make_tessellated(const MethodInput& in) {
  return owned(std::make_unique<TessellatedFrameRenderer>(in.scene, tessellated_options(in.options)));
}

MakeResult make_mesa(const MethodInput& in) {
  std::string error;
  auto mesa = MesaRenderer::create(in.view.width, in.view.height, error);
  if (!mesa) return Status::io_error("--method mesa: " + error);
  auto renderer = MesaFrameRenderer::create(in.scene, tessellated_options(in.options), std::move(mesa));
  if (!renderer) return renderer.status();
  return owned(std::move(*renderer));
}

std::string immediate_summary(const MethodInput& in, const Frame& frame) {
  return fmt::format("{}: {} primitives; {} ({}) {}x{}: {:.1f} ms\n", in.options.scene_path, in.scene.size(),
                     frame.stats.at("method").get<std::string>(), frame.stats.at("order").get<std::string>(),
                     in.view.width, in.view.height, frame.ms);
}

// BSP trees.

// --aa: N of the NxN coverage mask, 0 when not given (painter's). False when malformed.
bool parse_aa(const std::string& text, int& aa) {
  aa = 0;
  if (text.empty()) return true;
  int n = 0, m = 0;
  if (!parse_size(text, n, m) || n != m || (n != 1 && n != 2 && n != 4 && n != 8 && n != 16)) return false;
  aa = n;
  return true;
}

std::string check_bsp(const ViewerOptions& o) {
  int aa = 0;
  if (parse_aa(o.aa_text, aa)) return {};
  return "--aa " + o.aa_text + ": expected NxN with N in 1, 2, 4, 8, 16 (the paper's: 4x4)";
}

// Builds the tree, prints its statistics and writes them to --bsp-stats: they are complete
// before any frame.
MakeResult make_bsp(const MethodInput& in) {
  const ViewerOptions& o = in.options;
  int aa = 0;
  parse_aa(o.aa_text, aa);  // check_bsp accepted it
  BspBuildOptions build;
  build.candidates = o.bsp_candidates;
  auto tree = BspTree::build(polygon_soup(in.scene, o.tessellation), build);
  if (!tree) return Status::invalid_argument(o.scene_path + ": " + tree.status().message());
  fmt::print(stderr, "{}", tree->stats().to_text());
  if (!o.bsp_stats_path.empty()) {
    if (Status s = write_json(o.bsp_stats_path, nlohmann::json::parse(tree->stats().to_json())); !s) return s;
  }
  BspRenderOptions options;
  options.order = aa > 0 ? BspOrder::FrontToBack : BspOrder::BackToFront;
  options.aa = aa > 0 ? aa : 1;
  options.cull_back_faces = o.cull_back_faces;
  options.threads = o.threads;
  options.background = in.scene.background;
  return owned(std::make_unique<BspFrameRenderer>(std::move(*tree), options));
}

std::string bsp_summary(const MethodInput& in, const Frame& frame) {
  const nlohmann::json& s = frame.stats;
  const int aa = s.at("aa").get<int>();
  return fmt::format("{}: {} polygons -> {} faces; bsp {} {}x{}: {:.1f} ms\n", in.options.scene_path,
                     s.at("input_polygons").get<uint64_t>(), s.at("output_polygons").get<uint64_t>(),
                     aa > 0 ? fmt::format("front-to-back {}x{}", aa, aa) : std::string("painter's"), in.view.width,
                     in.view.height, frame.ms);
}

// The table's rows by family: what a family's methods share is said once.
using Make = MakeResult (*)(const MethodInput&);

// Ray casting: the frustum-advance visibility class.
ViewMethod ray_casting(std::string_view name, std::string_view help, std::string_view reads, Make make) {
  return {.name = name, .help = help, .reads = reads, .frustum_advance = true, .make = make, .summary = ray_cast_summary};
}

// Immediate-mode ray casting and the baselines: objects issued in --order.
ViewMethod immediate(std::string_view name, std::string_view help, std::string_view reads, Make make) {
  return {.name = name, .help = help, .reads = reads, .make = make, .summary = immediate_summary};
}

// A rasterizing visibility class, named by --visibility.
ViewMethod rasterizing_class(std::string_view name, std::string_view help, Make make,
                             std::string (*check)(const ViewerOptions&) = nullptr) {
  return {.name = name,
          .help = help,
          .reads = "--cull-back-faces, --cell-prims, --min-cell-prims",
          .option = "--visibility",
          .check = check,
          .make = make,
          .summary = culling_summary};
}

}  // namespace

const std::vector<ViewMethod>& view_methods() {
  static const std::vector<ViewMethod> methods = {
      ray_casting("brute", "ray casting, every ray against every primitive: the reference",
                  "--no-shadows, --cell-prims, --min-cell-prims", make_ray_cast<Method::Brute>),
      ray_casting("raywalk", "ray casting, each ray walked through the k-d tree",
                  "--no-shadows, --cell-prims, --min-cell-prims", make_ray_cast<Method::RayWalk>),
      ray_casting("packet", "ray casting in packets of 4x4 pixels through Embree's BVH with frontier's exact tests",
                  "--kd-kernel, --no-shadows, --cell-prims, --min-cell-prims", make_ray_cast<Method::Packet>),
      ray_casting("frustum",
                  "frustum casting through the k-d tree, the leaf frusta's packets through Embree's BVH with "
                  "frontier's exact tests (the default)",
                  "--frame-ms, --samples, --leaf-pixels, --kd-kernel, --no-shadows, --cell-prims, --min-cell-prims",
                  make_ray_cast<Method::Frustum>),
      immediate("imr", "immediate-mode ray casting of curved primitives",
                "--order, --bound-slices, --back-sample-culling, --cull-back-faces, --no-shadows", make_imr),
      immediate("tessellated", "objects tessellated, lit per vertex, frontier's rasterizer",
                "--order, --tessellation, --cull-back-faces", make_tessellated),
      immediate("mesa", "the same through OpenGL: Mesa llvmpipe, offscreen", "--order, --tessellation, --cull-back-faces",
                make_mesa),
      {.name = "bsp",
       .help = "a BSP tree: painter's, or front to back with --aa",
       .reads = "--tessellation, --bsp-candidates, --aa, --bsp-stats, --cull-back-faces",
       .check = check_bsp,
       .make = make_bsp,
       .summary = bsp_summary},
      rasterizing_class("exhaustive", "every primitive into the z-buffer", make_culling<Visibility::kExhaustive>),
      rasterizing_class("frustum-cull", "hierarchical view-frustum culling of the k-d tree, then the z-buffer",
                        make_culling<Visibility::kFrustumCull>),
      rasterizing_class("occlusion-cull", "frustum culling front to back, skipping what a z-pyramid hides",
                        make_culling<Visibility::kOcclusionCull>),
      rasterizing_class("portals", "cells and portals: stores only", make_culling<Visibility::kPortals>,
                        refuse_portals),
  };
  return methods;
}

const ViewMethod& pick_method(const ViewerOptions& options) {
  const std::vector<ViewMethod>& methods = view_methods();
  auto named = [&](std::string_view option, const std::string& name) {
    return std::find_if(methods.begin(), methods.end(),
                        [&](const ViewMethod& m) { return m.option == option && m.name == name; });
  };
  const auto method = named("--method", options.method_text);
  if (method->frustum_advance) {
    if (const auto visibility = named("--visibility", options.visibility_text); visibility != methods.end()) {
      return *visibility;
    }
  }
  return *method;
}

std::vector<std::string> method_names() {
  std::vector<std::string> names;
  for (const ViewMethod& m : view_methods()) {
    if (m.option == "--method") names.emplace_back(m.name);
  }
  return names;
}

std::string method_help() {
  std::string help = "model file:";
  for (const ViewMethod& m : view_methods()) {
    if (m.option != "--method") continue;
    help += fmt::format("{} {} ({}; reads {})", help.back() == ':' ? "" : " |", m.name, m.help, m.reads);
  }
  return help;
}

}  // namespace frontier
