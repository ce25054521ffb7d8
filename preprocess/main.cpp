// frontier-build: streams model files into one store file in bounded memory (preprocess/build.h).
#include "preprocess/build.h"
#include "preprocess/temp_dir.h"
#include "src/core/option_checks.h"
#include "src/core/progress.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <new>
#include <optional>
#include <regex>
#include <system_error>
#include <thread>

#include <pthread.h>
#include <unistd.h>

namespace {

// A data_gen sidecar (MODEL.json beside MODEL) saying "walkable": true asks for the collision
// grid. Only its head is read: the flag comes first, and sidecars of huge buildings are large.
bool sidecar_says_walkable(const std::string& input) {
  std::filesystem::path side(input);
  side.replace_extension(".json");
  std::ifstream in(side);
  if (!in) return false;
  std::string head(8192, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(in.gcount()));
  return std::regex_search(head, std::regex(R"("walkable"\s*:\s*true)"));
}

const char* signal_name(int sig) {
  switch (sig) {
    case SIGINT: return "SIGINT";
    case SIGTERM: return "SIGTERM";
    case SIGHUP: return "SIGHUP";
    default: return "a signal";
  }
}

// SIGINT, SIGTERM and SIGHUP stop the build on a thread of their own, which removes what the
// build wrote (its temporary directory and OUT.tmp: temp_dir.h), says so and exits with 128 + the
// signal. Blocked in every other thread (threads made later inherit the mask), so none is stopped
// half way; called before any thread starts.
void stop_cleanly_on_signals() {
  sigset_t stopping;
  sigemptyset(&stopping);
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&stopping, sig);
  pthread_sigmask(SIG_BLOCK, &stopping, nullptr);
  std::thread([stopping] {
    int sig = 0;
    if (sigwait(&stopping, &sig) != 0) return;
    std::vector<frontier::Leftover> removed;
    frontier::remove_own_temporaries(removed);
    std::string what;
    for (const frontier::Leftover& l : removed) {
      what += fmt::format("{}{} ({:.1f} MB)", what.empty() ? "" : ", ", l.path, static_cast<double>(l.bytes) / 1e6);
    }
    std::fprintf(stderr, "\nfrontier-build: stopped by %s; %s\n", signal_name(sig),
                 what.empty() ? "nothing written yet" : ("removed " + what).c_str());
    std::fflush(stderr);
    ::_exit(128 + sig);
  }).detach();
}

}  // namespace

int main(int argc, char** argv) {
  frontier::tune_allocator_for_build();
  stop_cleanly_on_signals();
  CLI::App app{
      "frontier-build: stream PLY/OBJ/OFF/NFF/STL models into one paged, compressed, checksummed k-d tree store.\n"
      "Memory stays within --memory (plus buffers): parts of the model that do not fit are split on disk\n"
      "first. The store appears atomically (OUT.tmp, fsync, rename); a failed build leaves no OUT.\n"
      "A single input with a frontier-gen sidecar (MODEL.json beside MODEL) that lists rooms and portals\n"
      "also stores that cells-and-portals graph (section \"portals\", for frontier-view --visibility portals).\n"
      "Exit status: 0 ok; 1 bad input (a missing or unreadable file, a malformed model or one with no\n"
      "primitives: the message names the file and line or byte offset) or a failed write; 2 bad options;\n"
      "128 + N when stopped by signal N (SIGINT, SIGTERM, SIGHUP), after removing what it wrote.",
      "frontier-build"};
  frontier::BuildOptions options;
  std::string memory = "1G", codec = "draco", proxy_codec;
  // Inputs are checked by build_store (exit 1 naming the file), not by CLI11 (whose exit codes
  // are its own).
  app.add_option("inputs", options.inputs, "model files (.ply .obj .off .nff .stl); several go into one store")
      ->required();
  app.add_option("-o,--output", options.output, "the store file to write")->required();
  app.add_option("--tmp-dir", options.tmp_dir,
                 "directory for the build's temporary files (default: beside the output); leftovers of "
                 "killed builds there are removed");
  app.add_option("--memory", memory, "memory budget for the build, e.g. 512M, 1G (default 1G); peak RSS stays within it + 64 MiB");
  app.add_option("--codec", codec, "cell page codec: draco (default; smallest), meshopt (meshoptimizer's vertex and "
                 "index codecs: larger pages, several times faster decoding) or raw (exact doubles)")
      ->check(CLI::IsMember({"draco", "meshopt", "raw"}));
  app.add_option("--proxy-codec", proxy_codec,
                 "proxy page codec: meshopt (the default with --codec draco: a proxy of ~130 triangles decodes "
                 "about 4x faster than with Draco, whose per-mesh setup dominates so small a mesh, for 9-13 % "
                 "more proxy bytes on terrains; the same lattice points), draco or raw; default: --codec's own otherwise")
      ->check(CLI::IsMember({"draco", "meshopt", "raw"}));
  app.add_option("--quant-bits", options.quant_bits, "bits per axis of the global position lattice (draco, meshopt), 8..30")
      ->default_val(16);
  app.add_option("--cell-prims", options.cell_prims, "at most this many primitives per cell page")->default_val(1024);
  app.add_option("--proxy-triangles", options.proxy_triangles,
                 "triangles of the proxy page every interior node of the store's top tree gets: a coarse "
                 "stand-in for its whole subtree (meshoptimizer, borders locked; at most twice this where "
                 "borders stop it) with a measured object-space error bound, for frontier-view to draw far and missing "
                 "subtrees; 0: no proxies (a faster build, but a walk shows nothing where cells are not yet in)")
      ->default_val(frontier::kDefaultProxyTriangles);
  app.add_option("--threads", options.threads, "threads that build and encode parts (0: all cores; at most 4 per "
                 "hardware thread); reading and partitioning use a reader thread besides")
      ->default_val(0)
      ->check(frontier::option_checks::thread_count());
  app.add_flag("--walkable", options.walkable,
               "add a sparse OpenVDB distance grid for walk-mode collision, built out of core (spilled beside "
               "the output) and stored as 64^3-voxel brick pages (also when a MODEL.json sidecar says "
               "\"walkable\": true)");
  bool no_cell_trees = false;
  app.add_flag("--no-cell-trees", no_cell_trees,
               "store cell and proxy pages without their k-d trees (smaller pages; frontier-view then builds "
               "each cell's or proxy's tree when it pages it in, as stores before in-cell trees)");
  bool no_walkable = false;
  auto* no_walk = app.add_flag("--no-walkable", no_walkable, "no collision grid, whatever a sidecar says");
  no_walk->excludes(app.get_option("--walkable"));
  bool no_portals = false;
  app.add_option("--tessellate", options.tessellate,
                 "turn spheres, cones and boxes into triangle meshes with N segments around a circle "
                 "(for the rasterizing visibility classes, which draw triangles only)")
      ->check(CLI::Range(3, 1024));
  app.add_flag("--no-portals", no_portals, "do not store the cells and portals of a MODEL.json sidecar");
  app.add_option("--sdf-voxel", options.sdf_voxel, "voxel size of the collision grid (default: from the model size)")
      ->check(frontier::option_checks::non_negative());
  app.add_option("--walk-radius", options.walk_radius,
                 "walker clearance the collision grid must resolve (default 0.25, model units)")
      ->check(frontier::option_checks::positive());
  app.add_flag("-q,--quiet", options.quiet, "no progress output");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints the help, or the error and a hint
    return code == 0 ? 0 : 2;
  }

  const auto bytes = frontier::parse_byte_size(memory);
  if (!bytes) {
    std::fprintf(stderr, "frontier-build: --memory %s: not a size (try 512M or 2G)\n", memory.c_str());
    return 2;
  }
  options.memory = *bytes;
  options.codec = *frontier::cell_codec_named(codec);
  if (!proxy_codec.empty()) options.proxy_codec = *frontier::cell_codec_named(proxy_codec);
  if (!no_walkable) {
    for (const std::string& in : options.inputs) options.walkable = options.walkable || sidecar_says_walkable(in);
  }
  options.portals = !no_portals;
  options.cell_trees = !no_cell_trees;

  // Running out of memory or threads is a failed build (exit 1, its temporaries removed on the
  // way out), not an abort.
  std::optional<frontier::Result<frontier::BuildReport>> report;
  try {
    report.emplace(frontier::build_store(options));
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "frontier-build: out of memory (a smaller --memory or fewer --threads may fit)\n");
    return 1;
  } catch (const std::system_error& e) {
    std::fprintf(stderr, "frontier-build: %s\n", e.what());
    return 1;
  }
  if (!*report) {
    std::fprintf(stderr, "frontier-build: %s\n", report->status().to_string().c_str());
    return report->status().code() == frontier::Status::Code::InvalidArgument ? 2 : 1;
  }
  const frontier::BuildReport& r = **report;
  if (!options.quiet) {
    const double per_tri = r.triangles > 0 ? static_cast<double>(r.store_bytes) / static_cast<double>(r.triangles) : 0.0;
    std::fprintf(stderr, "%s",
                 fmt::format("{}: {} primitives ({} triangles, {} dropped) in {} cells, {} pages, depth {}\n"
                             "  {:.1f} MB, {:.2f} bytes/triangle; {} parts built in core; {:.1f} s "
                             "({} primitives/s): read {:.1f} s, partition {:.1f} s, build {:.1f} s, encode {:.1f} s\n",
                             options.output, r.primitives, r.triangles, r.degenerate_dropped, r.cells, r.pages,
                             r.depth, static_cast<double>(r.store_bytes) / 1e6, per_tri, r.parts, r.seconds,
                             frontier::human_count(static_cast<double>(r.primitives) / std::max(r.seconds, 1e-9)),
                             r.ingest_seconds, r.spill_seconds, r.build_seconds, r.encode_seconds)
                     .c_str());
    if (r.cell_tree_pages > 0) {
      std::fprintf(stderr, "  in-cell trees: %llu pages, %.1f MB (%.2f bytes/triangle)\n",
                   static_cast<unsigned long long>(r.cell_tree_pages), static_cast<double>(r.cell_tree_bytes) / 1e6,
                   static_cast<double>(r.cell_tree_bytes) / static_cast<double>(std::max<uint64_t>(r.triangles, 1)));
    }
    if (r.spill_bytes > 0) {
      std::fprintf(stderr, "  temporary spill: %.1f MB written, at most %.1f MB on disk at once (%.1f bytes/primitive)\n",
                   static_cast<double>(r.spill_bytes) / 1e6, static_cast<double>(r.spill_peak_bytes) / 1e6,
                   static_cast<double>(r.spill_peak_bytes) / static_cast<double>(std::max<uint64_t>(r.primitives, 1)));
    }
    if (options.walkable) {
      std::fprintf(stderr, "  collision grid: %.1f MB in the store (%llu bricks), %.1f MB in memory, %.1f MB spilled\n",
                   static_cast<double>(r.sdf_bytes) / 1e6, static_cast<unsigned long long>(r.sdf_bricks),
                   static_cast<double>(r.sdf_memory) / 1e6, static_cast<double>(r.sdf_spill_bytes) / 1e6);
    }
    if (r.proxy_pages > 0) {
      std::fprintf(stderr, "%s",
                   fmt::format("  proxies: {} pages, {} triangles, {:.1f} MB ({:.2f} bytes/triangle of the model), "
                               "{} voxel shells, {} sloppy, root error {:.4g}; {:.1f} s; trees in {} pages, {:.1f} MB\n",
                               r.proxy_pages, r.proxy_triangles, static_cast<double>(r.proxy_bytes) / 1e6,
                               static_cast<double>(r.proxy_bytes) / static_cast<double>(std::max<uint64_t>(r.triangles, 1)),
                               r.proxy_shells, r.proxy_sloppy, r.proxy_root_error, r.proxy_seconds, r.proxy_tree_pages,
                               static_cast<double>(r.proxy_tree_bytes) / 1e6)
                       .c_str());
    }
    if (!r.portals_sidecar.empty()) {
      std::fprintf(stderr, "  cells and portals: %llu rooms, %llu portals from %s\n",
                   static_cast<unsigned long long>(r.portal_rooms), static_cast<unsigned long long>(r.portals),
                   r.portals_sidecar.c_str());
    }
  }
  return 0;
}
