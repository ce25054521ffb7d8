// frontier-gen: deterministic huge models and walkthrough camera paths, streamed to disk.
// Commands and formats are documented in data_gen/README.md.
//
// Exit codes: 0 success; 2 bad or impossible parameters (the message names the option);
// 1 I/O or other runtime failure.
#include "data_gen/building.h"
#include "data_gen/model_bounds.h"
#include "data_gen/paths.h"
#include "data_gen/piece_stream.h"
#include "data_gen/spheres.h"
#include "data_gen/terrain.h"
#include "src/io/camera_path.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <tbb/global_control.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>

namespace {

using namespace frontier;
using namespace frontier::gen;

constexpr double kMaxPlyVertices = 4294967295.0;

int report(const Status& st) {
  std::fprintf(stderr, "frontier-gen: %s\n", st.to_string().c_str());
  return st.code() == Status::Code::InvalidArgument ? 2 : 1;
}

// Sidecar next to a model: NAME.ply -> NAME.json; none for stdout or devices.
std::string default_sidecar(const std::string& model) {
  if (model.empty() || model == "-" || model.rfind("/dev/", 0) == 0) return {};
  return std::filesystem::path(model).replace_extension(".json").string();
}

struct Common {
  std::string output;
  uint64_t seed = 1;
  bool quiet = false, normals = false, colors = false, count_only = false;
  int threads = 0;
};

void add_mesh_options(CLI::App* cmd, Common& c) {
  cmd->add_option("-o,--output", c.output, "output PLY file ('-' for stdout)");
  cmd->add_option("--seed", c.seed, "random seed (same arguments, same bytes)");
  cmd->add_flag("--normals", c.normals, "write per-vertex normals");
  cmd->add_flag("--colors", c.colors, "write per-vertex colours");
  cmd->add_flag("--count-only", c.count_only,
                "print the vertex and triangle counts (JSON on stdout) without writing");
  cmd->add_option("--threads", c.threads, "worker threads (0: all cores)")->check(CLI::Range(0, 1024));
  cmd->add_flag("-q,--quiet", c.quiet, "no progress on stderr");
}

std::string command_line(int argc, char** argv) {
  std::string s = "frontier-gen";
  for (int i = 1; i < argc; ++i) s += std::string(" ") + argv[i];
  return s;
}

void print_counts(const std::string& model, const MeshCounts& counts, nlohmann::ordered_json extra) {
  nlohmann::ordered_json j = {{"model", model}, {"triangles", counts.triangles}, {"vertices", counts.vertices}};
  for (auto& [k, v] : extra.items()) j[k] = v;
  std::printf("%s\n", j.dump().c_str());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"frontier-gen: deterministic huge models and walkthrough camera paths"};
  app.require_subcommand(1);
  std::string invocation = command_line(argc, argv);

  // building
  Common bc;
  BuildingParams bp;
  bp.shape.floors = 3;
  bp.shape.rooms = 12;
  std::optional<uint64_t> building_target;
  std::string sidecar;
  auto* building = app.add_subcommand("building", "architectural interior (PLY + JSON sidecar)");
  add_mesh_options(building, bc);
  auto* o_floors = building->add_option("--floors", bp.shape.floors, "floors (>= 1)")
                       ->check(CLI::Range(1, kMaxFloors));
  auto* o_rooms = building->add_option("--rooms", bp.shape.rooms, "rooms per floor (>= 1)")
                      ->check(CLI::Range(1, kMaxRoomsPerFloor));
  auto* o_furniture = building->add_option("--furniture", bp.detail.density, "furniture density (0 = bare rooms, 1 = furnished)")
                          ->check(CLI::Range(0.0, kMaxFurniture));
  auto* o_tess = building->add_option("--tessellation", bp.detail.segments,
                                      "segments around round things (3 to 128)")
                     ->check(CLI::Range(kMinSegments, kMaxSegments));
  building->add_option("--triangles", building_target,
                       "pick the free parameters to land within 5% of this many triangles")
      ->check(CLI::Range(uint64_t{1}, uint64_t{6000000000}));
  building->add_option("--sidecar", sidecar, "sidecar JSON (default: output with .json)");

  // terrain
  Common tc;
  TerrainParams tp;
  std::optional<uint64_t> terrain_target;
  uint64_t grid = 256;
  auto* terrain = app.add_subcommand("terrain", "fractal height field (PLY)");
  add_mesh_options(terrain, tc);
  auto* o_grid = terrain->add_option("--grid", grid, "quads per side (2 * grid^2 triangles)")
                     ->check(CLI::Range(uint64_t{1}, kMaxTerrainQuadsPerSide));
  terrain->add_option("--triangles", terrain_target, "square grid closest to this many triangles")
      ->check(CLI::Range(uint64_t{2}, uint64_t{8000000000}));
  terrain->add_option("--spacing", tp.spacing, "metres between grid points")->check(CLI::Range(1e-4, 1e4));
  terrain->add_option("--relief", tp.relief, "height amplitude / extent")->check(CLI::Range(0.0, 10.0));
  terrain->add_option("--octaves", tp.octaves, "noise octaves")->check(CLI::Range(1, 24));
  terrain->add_option("--tile", tp.tile, "quads per tile side (one piece)")->check(CLI::Range(1, 1024));
  o_grid->excludes(terrain->get_option("--triangles"));

  // spheres
  SpheresParams sp;
  std::string sphere_output;
  bool sphere_quiet = false;
  auto* spheres = app.add_subcommand("spheres", "SPD-like quadric scenes (NFF)");
  const std::map<std::string, SphereFamily> families = {{"rings", SphereFamily::Rings},
                                                        {"tree", SphereFamily::Tree},
                                                        {"flake", SphereFamily::Flake},
                                                        {"shells", SphereFamily::Shells}};
  spheres->add_option("--family", sp.family, "rings, tree, flake or shells")
      ->required()
      ->transform(CLI::CheckedTransformer(families, CLI::ignore_case));
  spheres->add_option("--size", sp.size, "size factor (>= 1)")->required()->check(CLI::Range(1, 100000));
  spheres->add_option("--seed", sp.seed, "random seed");
  spheres->add_option("-o,--output", sphere_output, "output NFF file ('-' for stdout)")->required();
  spheres->add_flag("-q,--quiet", sphere_quiet, "no progress on stderr");

  // path
  std::string model, path_sidecar, path_output, kind;
  PathOptions po;
  auto* path = app.add_subcommand("path", "camera path (.cam) through or around a model");
  path->add_option("--model", model, "model file (.ply, .nff, .obj)")->required();
  path->add_option("--sidecar", path_sidecar, "building sidecar (default: model with .json)");
  path->add_option("--kind", kind, "walk, orbit or fly")->required()->check(CLI::IsMember({"walk", "orbit", "fly"}));
  path->add_option("--frames", po.frames, "number of frames")->required()->check(CLI::Range(1, 100000000));
  path->add_option("--seed", po.seed, "random seed");
  path->add_option("--step", po.step, "walk: metres per frame")->check(CLI::Range(1e-4, 100.0));
  path->add_option("--vfov", po.vfov_deg, "vertical field of view, degrees")->check(CLI::Range(1.0, 170.0));
  path->add_option("-o,--output", path_output, "output .cam file ('-' for stdout)")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }

  auto need_output = [](const Common& c, const char* cmd) -> Status {
    if (c.output.empty() && !c.count_only)
      return Status::invalid_argument(fmt::format("{}: --output is required (or --count-only)", cmd));
    return Status::ok();
  };
  std::unique_ptr<tbb::global_control> threads;
  const int want_threads = building->parsed() ? bc.threads : terrain->parsed() ? tc.threads : 0;
  if (want_threads > 0)
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    static_cast<size_t>(want_threads));

  if (building->parsed()) {
    Status st = need_output(bc, "building");
    if (!st) return report(st);
    bp.shape.seed = bc.seed;
    bp.layout = {bc.normals, bc.colors};
    if (building_target) {
      FitOptions fo;
      fo.floors_fixed = o_floors->count() > 0;
      fo.rooms_fixed = o_rooms->count() > 0;
      fo.furniture_fixed = o_furniture->count() > 0;
      fo.tessellation_fixed = o_tess->count() > 0;
      auto fitted = fit_building(bp, *building_target, fo);
      if (!fitted) return report(fitted.status());
      bp = *fitted;
    }
    st = validate(bp);
    if (!st) return report(st);
    {
      // Refuse what 32-bit PLY indices cannot address before spending a counting pass on it.
      BuildingParams probe = bp;
      probe.shape.floors = 1;
      probe.shape.rooms = std::min(bp.shape.rooms, 32);
      const double per_room = static_cast<double>(count_building(probe).vertices) / probe.shape.rooms;
      const double estimate = per_room * bp.shape.floors * bp.shape.rooms;
      if (estimate > kMaxPlyVertices)
        return report(Status::invalid_argument(fmt::format(
            "--floors {} x --rooms {}: about {:.3g} vertices, more than the {:.3g} that 32-bit PLY "
            "indices address; use fewer floors or rooms",
            bp.shape.floors, bp.shape.rooms, estimate, kMaxPlyVertices)));
    }
    const BuildingLayout layout(bp.shape);
    const PieceFunction piece = [&](uint64_t i, MeshBuilder& mb) { building_piece(layout, bp.detail, i, mb); };
    const nlohmann::ordered_json params = {{"floors", bp.shape.floors},
                                           {"rooms", bp.shape.rooms},
                                           {"furniture", bp.detail.density},
                                           {"tessellation", bp.detail.segments},
                                           {"seed", bp.shape.seed}};
    if (!bc.quiet)
      std::fprintf(stderr, "building: %d floor(s) x %d room(s), furniture %g, tessellation %d, seed %llu\n",
                   bp.shape.floors, bp.shape.rooms, bp.detail.density, bp.detail.segments,
                   static_cast<unsigned long long>(bp.shape.seed));
    if (bc.count_only) {
      print_counts("building", count_pieces(building_piece_count(layout), piece, bp.layout), params);
      return 0;
    }
    StreamOptions so;
    so.path = bc.output;
    so.layout = bp.layout;
    so.quiet = bc.quiet;
    so.label = "building";
    so.comments = {"frontier-gen building: z up, metres",
                   fmt::format("floors {} rooms {} furniture {} tessellation {} seed {}", bp.shape.floors,
                               bp.shape.rooms, bp.detail.density, bp.detail.segments, bp.shape.seed)};
    auto counts = write_pieces(building_piece_count(layout), piece, so);
    if (!counts) return report(counts.status());
    const std::string side = sidecar.empty() ? default_sidecar(bc.output) : sidecar;
    if (!side.empty()) {
      st = write_building_sidecar(bp, *counts, std::filesystem::path(bc.output).filename().string(), side);
      if (!st) return report(st);
    }
    return 0;
  }

  if (terrain->parsed()) {
    Status st = need_output(tc, "terrain");
    if (!st) return report(st);
    tp.nx = tp.ny = grid;
    tp.seed = tc.seed;
    tp.layout = {tc.normals, tc.colors};
    if (terrain_target) fit_terrain(tp, *terrain_target);
    st = validate(tp);
    if (!st) return report(st);
    if (const double v = static_cast<double>(terrain_counts(tp).vertices); v > kMaxPlyVertices)
      return report(Status::invalid_argument(fmt::format(
          "--grid/--triangles: {:.3g} vertices, more than the {:.3g} that 32-bit PLY indices address",
          v, kMaxPlyVertices)));
    const nlohmann::ordered_json params = {{"grid", tp.nx}, {"spacing", tp.spacing}, {"seed", tp.seed}};
    if (tc.count_only) {
      print_counts("terrain", terrain_counts(tp), params);
      return 0;
    }
    StreamOptions so;
    so.path = tc.output;
    so.layout = tp.layout;
    so.quiet = tc.quiet;
    so.label = "terrain";
    so.comments = {"frontier-gen terrain: z up, metres",
                   fmt::format("grid {} x {} spacing {} relief {} octaves {} seed {}", tp.nx, tp.ny,
                               tp.spacing, tp.relief, tp.octaves, tp.seed)};
    auto counts = write_pieces(terrain_piece_count(tp),
                               [&](uint64_t i, MeshBuilder& mb) { terrain_piece(tp, i, mb); }, so);
    if (!counts) return report(counts.status());
    return 0;
  }

  if (spheres->parsed()) {
    const Status st = write_spheres(sp, sphere_output, sphere_quiet);
    return st ? 0 : report(st);
  }

  if (path->parsed()) {
    const std::string side = path_sidecar.empty() ? default_sidecar(model) : path_sidecar;
    Result<std::vector<Camera>> frames = Status::invalid_argument("--kind: unknown");
    if (kind == "walk") {
      if (side.empty() || !std::filesystem::exists(side))
        return report(Status::invalid_argument(fmt::format(
            "--kind walk needs a building sidecar: '{}' not found (give --sidecar)", side)));
      auto m = read_walk_sidecar(side);
      if (!m) return report(m.status());
      frames = walk_path(*m, po);
    } else {
      Result<Aabb> bounds = Status::not_found("");
      if (!path_sidecar.empty() || (!side.empty() && std::filesystem::exists(side)))
        bounds = read_sidecar_bounds(side);
      else
        bounds = scan_model_bounds(model);
      if (!bounds) return report(bounds.status());
      frames = kind == "orbit" ? orbit_path(*bounds, po) : fly_path(*bounds, po);
    }
    if (!frames) return report(frames.status());
    const Status st = write_camera_path(
        path_output, *frames,
        {invocation, "frontier camera path: eye(x y z)  look-at(x y z)  up(x y z)  vfov_deg; z up"});
    return st ? 0 : report(st);
  }
  return 0;
}
