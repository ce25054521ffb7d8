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
#include "src/core/option_checks.h"
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
#include <string>
#include <utility>
#include <vector>

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

Status need_output(const Common& c, const char* cmd) {
  if (c.output.empty() && !c.count_only)
    return Status::invalid_argument(fmt::format("{}: --output is required (or --count-only)", cmd));
  return Status::ok();
}

// How a mesh command streams its PLY: to --output, labelled with the command's name, the
// comments saying what it is and then its parameters.
StreamOptions stream_options(const Common& c, const char* command, const PlyVertexLayout& layout,
                             std::string parameters) {
  StreamOptions so;
  so.path = c.output;
  so.layout = layout;
  so.quiet = c.quiet;
  so.label = command;
  so.comments = {fmt::format("frontier-gen {}: z up, metres", command), std::move(parameters)};
  return so;
}

// --- building ---------------------------------------------------------------------------------

struct BuildingCommand {
  CLI::App* cmd = nullptr;
  Common common;
  BuildingParams params;
  std::optional<uint64_t> target;
  std::string sidecar;
  // Options given on the command line stay fixed when --triangles fits the others.
  CLI::Option* floors = nullptr;
  CLI::Option* rooms = nullptr;
  CLI::Option* furniture = nullptr;
  CLI::Option* tessellation = nullptr;
};

// REQUIRES: `b` outlives parsing (the options write into it).
void add_building_command(CLI::App& app, BuildingCommand& b) {
  b.params.shape.floors = 3;
  b.params.shape.rooms = 12;
  b.cmd = app.add_subcommand("building", "architectural interior (PLY + JSON sidecar)");
  add_mesh_options(b.cmd, b.common);
  b.floors = b.cmd->add_option("--floors", b.params.shape.floors, "floors (>= 1)")->check(CLI::Range(1, kMaxFloors));
  b.rooms = b.cmd->add_option("--rooms", b.params.shape.rooms, "rooms per floor (>= 1)")
                ->check(CLI::Range(1, kMaxRoomsPerFloor));
  b.furniture = b.cmd->add_option("--furniture", b.params.detail.density, "furniture density (0 = bare rooms, 1 = furnished)")
                    ->check(frontier::option_checks::between(0.0, kMaxFurniture));
  b.tessellation = b.cmd->add_option("--tessellation", b.params.detail.segments, "segments around round things (3 to 128)")
                       ->check(CLI::Range(kMinSegments, kMaxSegments));
  b.cmd->add_option("--triangles", b.target, "pick the free parameters to land within 5% of this many triangles")
      ->check(CLI::Range(uint64_t{1}, uint64_t{6000000000}));
  b.cmd->add_option("--sidecar", b.sidecar, "sidecar JSON (default: output with .json)");
}

// Refuses what 32-bit PLY indices cannot address before a counting pass is spent on it: the
// vertices of up to 32 rooms of one floor, scaled to the whole building.
Status check_building_fits_ply(const BuildingParams& bp) {
  BuildingParams probe = bp;
  probe.shape.floors = 1;
  probe.shape.rooms = std::min(bp.shape.rooms, 32);
  const double per_room = static_cast<double>(count_building(probe).vertices) / probe.shape.rooms;
  const double estimate = per_room * bp.shape.floors * bp.shape.rooms;
  if (estimate > kMaxPlyVertices)
    return Status::invalid_argument(fmt::format(
        "--floors {} x --rooms {}: about {:.3g} vertices, more than the {:.3g} that 32-bit PLY "
        "indices address; use fewer floors or rooms",
        bp.shape.floors, bp.shape.rooms, estimate, kMaxPlyVertices));
  return Status::ok();
}

// The building's parameters from the command line: fitted to --triangles if given, validated.
Result<BuildingParams> building_params(const BuildingCommand& b) {
  BuildingParams bp = b.params;
  bp.shape.seed = b.common.seed;
  bp.layout = {b.common.normals, b.common.colors};
  if (b.target) {
    FitOptions fo;
    fo.floors_fixed = b.floors->count() > 0;
    fo.rooms_fixed = b.rooms->count() > 0;
    fo.furniture_fixed = b.furniture->count() > 0;
    fo.tessellation_fixed = b.tessellation->count() > 0;
    auto fitted = fit_building(bp, *b.target, fo);
    if (!fitted) return fitted.status();
    bp = *fitted;
  }
  if (Status st = validate(bp); !st) return st;
  if (Status st = check_building_fits_ply(bp); !st) return st;
  return bp;
}

int run_building(const BuildingCommand& b) {
  const Common& bc = b.common;
  if (Status st = need_output(bc, "building"); !st) return report(st);
  Result<BuildingParams> fitted = building_params(b);
  if (!fitted) return report(fitted.status());
  const BuildingParams& bp = *fitted;
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
  const StreamOptions so = stream_options(
      bc, "building", bp.layout,
      fmt::format("floors {} rooms {} furniture {} tessellation {} seed {}", bp.shape.floors, bp.shape.rooms,
                  bp.detail.density, bp.detail.segments, bp.shape.seed));
  auto counts = write_pieces(building_piece_count(layout), piece, so);
  if (!counts) return report(counts.status());
  const std::string side = b.sidecar.empty() ? default_sidecar(bc.output) : b.sidecar;
  if (!side.empty()) {
    const Status st = write_building_sidecar(bp, *counts, std::filesystem::path(bc.output).filename().string(), side);
    if (!st) return report(st);
  }
  return 0;
}

// --- terrain ----------------------------------------------------------------------------------

struct TerrainCommand {
  CLI::App* cmd = nullptr;
  Common common;
  TerrainParams params;
  std::optional<uint64_t> target;
  uint64_t grid = 256;
};

// REQUIRES: `t` outlives parsing.
void add_terrain_command(CLI::App& app, TerrainCommand& t) {
  t.cmd = app.add_subcommand("terrain", "fractal height field (PLY)");
  add_mesh_options(t.cmd, t.common);
  auto* o_grid = t.cmd->add_option("--grid", t.grid, "quads per side (2 * grid^2 triangles)")
                     ->check(CLI::Range(uint64_t{1}, kMaxTerrainQuadsPerSide));
  t.cmd->add_option("--triangles", t.target, "square grid closest to this many triangles")
      ->check(CLI::Range(uint64_t{2}, uint64_t{8000000000}));
  t.cmd->add_option("--spacing", t.params.spacing, "metres between grid points")->check(frontier::option_checks::between(1e-4, 1e4));
  t.cmd->add_option("--relief", t.params.relief, "height amplitude / extent")->check(frontier::option_checks::between(0.0, 10.0));
  t.cmd->add_option("--octaves", t.params.octaves, "noise octaves")->check(CLI::Range(1, 24));
  t.cmd->add_option("--tile", t.params.tile, "quads per tile side (one piece)")->check(CLI::Range(1, 1024));
  o_grid->excludes(t.cmd->get_option("--triangles"));
}

int run_terrain(const TerrainCommand& t) {
  const Common& tc = t.common;
  Status st = need_output(tc, "terrain");
  if (!st) return report(st);
  TerrainParams tp = t.params;
  tp.nx = tp.ny = t.grid;
  tp.seed = tc.seed;
  tp.layout = {tc.normals, tc.colors};
  if (t.target) fit_terrain(tp, *t.target);
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
  const StreamOptions so = stream_options(tc, "terrain", tp.layout,
                                          fmt::format("grid {} x {} spacing {} relief {} octaves {} seed {}", tp.nx,
                                                      tp.ny, tp.spacing, tp.relief, tp.octaves, tp.seed));
  auto counts = write_pieces(terrain_piece_count(tp),
                             [&](uint64_t i, MeshBuilder& mb) { terrain_piece(tp, i, mb); }, so);
  if (!counts) return report(counts.status());
  return 0;
}

// --- spheres ----------------------------------------------------------------------------------

struct SpheresCommand {
  CLI::App* cmd = nullptr;
  SpheresParams params;
  std::string output;
  bool quiet = false;
};

// REQUIRES: `s` outlives parsing.
void add_spheres_command(CLI::App& app, SpheresCommand& s) {
  static const std::map<std::string, SphereFamily> families = {{"rings", SphereFamily::Rings},
                                                               {"tree", SphereFamily::Tree},
                                                               {"flake", SphereFamily::Flake},
                                                               {"shells", SphereFamily::Shells}};
  s.cmd = app.add_subcommand("spheres", "SPD-like quadric scenes (NFF)");
  s.cmd->add_option("--family", s.params.family, "rings, tree, flake or shells")
      ->required()
      ->transform(CLI::CheckedTransformer(families, CLI::ignore_case));
  s.cmd->add_option("--size", s.params.size, "size factor (>= 1)")->required()->check(CLI::Range(1, 100000));
  s.cmd->add_option("--seed", s.params.seed, "random seed");
  s.cmd->add_option("-o,--output", s.output, "output NFF file ('-' for stdout)")->required();
  s.cmd->add_flag("-q,--quiet", s.quiet, "no progress on stderr");
}

int run_spheres(const SpheresCommand& s) {
  const Status st = write_spheres(s.params, s.output, s.quiet);
  return st ? 0 : report(st);
}

// --- path -------------------------------------------------------------------------------------

struct PathCommand {
  CLI::App* cmd = nullptr;
  std::string model, sidecar, output, kind;
  PathOptions options;
};

// REQUIRES: `p` outlives parsing.
void add_path_command(CLI::App& app, PathCommand& p) {
  p.cmd = app.add_subcommand("path", "camera path (.cam) through or around a model");
  p.cmd->add_option("--model", p.model, "model file (.ply, .nff, .obj)")->required();
  p.cmd->add_option("--sidecar", p.sidecar, "building sidecar (default: model with .json)");
  p.cmd->add_option("--kind", p.kind, "walk, orbit or fly")->required()->check(CLI::IsMember({"walk", "orbit", "fly"}));
  p.cmd->add_option("--frames", p.options.frames, "number of frames")->required()->check(CLI::Range(1, 100000000));
  p.cmd->add_option("--seed", p.options.seed, "random seed");
  p.cmd->add_option("--step", p.options.step, "walk: metres per frame")->check(frontier::option_checks::between(1e-4, 100.0));
  p.cmd->add_option("--speed", p.options.speed,
                    "orbit, fly: metres the eye moves per frame, going round again as often as --frames needs "
                    "(default: one loop spread over --frames, however many)")
      ->check(frontier::option_checks::between(1e-9, 1e12));
  p.cmd->add_option("--vfov", p.options.vfov_deg, "vertical field of view, degrees")->check(frontier::option_checks::between(1.0, 170.0));
  p.cmd->add_option("--clearance", p.options.clearance,
                    "fly: metres kept between the eye and the highest geometry within that distance of it "
                    "(default: 1% of the model's larger horizontal side)")
      ->check(frontier::option_checks::between(1e-6, 1e9));
  p.cmd->add_option("-o,--output", p.output, "output .cam file ('-' for stdout)")->required();
}

// The cameras of the path: a walk through the rooms of a building sidecar, or an orbit or fly
// around the bounds (from the sidecar when there is one, else scanned from the model); a fly
// reads the model once more for the ground it keeps clear of.
Result<std::vector<Camera>> path_cameras(const PathCommand& p) {
  const std::string side = p.sidecar.empty() ? default_sidecar(p.model) : p.sidecar;
  if (p.kind == "walk") {
    if (side.empty() || !std::filesystem::exists(side))
      return Status::invalid_argument(
          fmt::format("--kind walk needs a building sidecar: '{}' not found (give --sidecar)", side));
    auto m = read_walk_sidecar(side);
    if (!m) return m.status();
    return walk_path(*m, p.options);
  }
  Result<Aabb> bounds = Status::not_found("");
  if (!p.sidecar.empty() || (!side.empty() && std::filesystem::exists(side)))
    bounds = read_sidecar_bounds(side);
  else
    bounds = scan_model_bounds(p.model);
  if (!bounds) return bounds.status();
  if (p.kind == "orbit") return orbit_path(*bounds, p.options);
  auto ground = scan_ground(p.model, *bounds);
  if (!ground) return ground.status();
  return fly_path(*bounds, *ground, p.options);
}

int run_path(const PathCommand& p, const std::string& invocation) {
  Result<std::vector<Camera>> frames = path_cameras(p);
  if (!frames) return report(frames.status());
  const Status st = write_camera_path(
      p.output, *frames,
      {invocation, "frontier camera path: eye(x y z)  look-at(x y z)  up(x y z)  vfov_deg; z up"});
  return st ? 0 : report(st);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"frontier-gen: deterministic huge models and walkthrough camera paths"};
  app.require_subcommand(1);
  const std::string invocation = command_line(argc, argv);
  // Subcommands in the order the help lists them.
  BuildingCommand building;
  add_building_command(app, building);
  TerrainCommand terrain;
  add_terrain_command(app, terrain);
  SpheresCommand spheres;
  add_spheres_command(app, spheres);
  PathCommand path;
  add_path_command(app, path);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }

  std::unique_ptr<tbb::global_control> threads;
  const int want_threads = building.cmd->parsed() ? building.common.threads
                           : terrain.cmd->parsed() ? terrain.common.threads
                                                   : 0;
  if (want_threads > 0)
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    static_cast<size_t>(want_threads));

  if (building.cmd->parsed()) return run_building(building);
  if (terrain.cmd->parsed()) return run_terrain(terrain);
  if (spheres.cmd->parsed()) return run_spheres(spheres);
  if (path.cmd->parsed()) return run_path(path, invocation);
  return 0;
}
