// Preprocessing throughput against the I/O floor, bytes per triangle and page decode speed.
//
// For each model: the I/O floor measured in the same run (read the input once from a cold page
// cache + write and fsync a file of the store's size), then frontier-build's end-to-end time
// (triangles/s and the ratio to the floor), store bytes per triangle, and the decode speed of
// every page (pages read into memory first, so only decoding is timed), of refining every
// decoded page into the subtree frontier-view builds when it pages the cell in, and of loading
// that subtree from the page's in-cell tree instead (checked equal to the refine). With
// --proxy-triangles N the stores get proxies, and a second table gives, per proxy page, decode,
// building its tree as frontier-view did before proxy pages carried trees, and loading the
// stored tree (checked equal). Prints Markdown.
#include "preprocess/build.h"
#include "src/codec/cell_tree.h"
#include "src/core/progress.h"
#include "src/paging/store_model.h"
#include "src/walk/walkthrough.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

using namespace frontier;

namespace {

double since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// Drops a file from the OS page cache so that the next read goes to the disk.
void drop_cache(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return;
  ::fdatasync(fd);
  ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
  ::close(fd);
}

// Seconds to read `input` once (cold) and to write + fsync `bytes` bytes beside `output`.
double io_floor(const std::vector<std::string>& inputs, const std::string& output, uint64_t bytes) {
  std::vector<char> buffer(8 << 20);
  const auto t = std::chrono::steady_clock::now();
  for (const std::string& input : inputs) {
    drop_cache(input);
    const int fd = ::open(input.c_str(), O_RDONLY);
    while (fd >= 0 && ::read(fd, buffer.data(), buffer.size()) > 0) {
    }
    if (fd >= 0) ::close(fd);
  }
  const std::string scratch = output + ".floor";
  const int out = ::open(scratch.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  for (uint64_t left = bytes; out >= 0 && left > 0;) {
    const auto n = static_cast<size_t>(std::min<uint64_t>(left, buffer.size()));
    if (::write(out, buffer.data(), n) != static_cast<ssize_t>(n)) break;
    left -= n;
  }
  if (out >= 0) {
    ::fsync(out);
    ::close(out);
  }
  const double s = since(t);
  std::filesystem::remove(scratch);
  return s;
}

struct Decode {
  double seconds = 0.0;
  uint64_t payload_bytes = 0, primitives = 0;
  double refine_seconds = 0.0;  // building every decoded page's subtree as the viewer does on page-in
  // Loading the subtree stored in the page instead (pages with an in-cell tree only) and what
  // refining those same pages costs, so the two per-primitive figures compare like for like.
  double load_seconds = 0.0, refine_tree_pages_seconds = 0.0;
  uint64_t tree_bytes = 0, tree_primitives = 0, tree_mismatches = 0;
  // Proxy pages: decode, build of the proxy's tree (proxy_tree_options), load of the stored one.
  uint64_t proxies = 0, proxy_triangles = 0, proxy_trees = 0;
  double proxy_decode_seconds = 0.0, proxy_build_seconds = 0.0, proxy_load_seconds = 0.0;
};

Decode decode_all(const std::string& store) {
  Decode d;
  auto model = StoreModel::open(store);
  if (!model) {
    std::fprintf(stderr, "%s\n", model.status().to_string().c_str());
    return d;
  }
  std::vector<std::pair<const StoreCell*, store::OwnedPage>> pages;  // read first: decoding alone is timed
  for (const StoreCell& c : (*model)->cells()) {
    if (c.page == StoreCell::kNoPage) continue;
    auto p = (*model)->reader().read_page(c.page);
    if (p) pages.emplace_back(&c, std::move(*p));
  }
  // Each page decoded, then refined into its subtree with the walkthrough's options (a
  // page-in's two halves), timed apart.
  KdBuildOptions refine = page_refine_options(WalkOptions{});
  Scene cell;
  for (const auto& [c, p] : pages) {
    d.payload_bytes += p.payload.size();
    std::span<const uint8_t> tree_bytes, payload = p.payload;
    const bool has_tree = (p.codec & kCellTreeFlag) != 0 && split_tree_page(p.payload, tree_bytes, payload);
    const auto codec = static_cast<CellCodec>(p.codec & ~kCellTreeFlag);
    const auto t = std::chrono::steady_clock::now();
    const bool decoded = static_cast<bool>(decode_cell(payload, codec, (*model)->info().lattice, cell));
    d.seconds += since(t);
    if (!decoded) continue;
    d.primitives += cell.size();
    refine.root = c->bounds;
    const auto r = std::chrono::steady_clock::now();
    const KdTree subtree = KdTree::build(cell, refine);
    const double refine_s = since(r);
    d.refine_seconds += refine_s;
    if (!has_tree) continue;
    const auto l = std::chrono::steady_clock::now();
    Result<KdTree> stored = decode_cell_tree(tree_bytes, cell, c->bounds, refine);
    d.load_seconds += since(l);
    d.refine_tree_pages_seconds += refine_s;
    d.tree_bytes += tree_bytes.size();
    d.tree_primitives += cell.size();
    if (!stored || !same_tree(*stored, subtree)) ++d.tree_mismatches;
  }
  const StoreModel& m = **model;
  KdBuildOptions proxy_options = proxy_tree_options(page_refine_options(WalkOptions{}));
  for (uint32_t n = 0; n < m.nodes().size(); ++n) {
    if (m.proxy(n) == nullptr) continue;
    auto p = m.reader().read_page(m.proxy(n)->page);
    if (!p) continue;
    proxy_options.root = m.node_region(n);
    std::optional<KdTree> none;
    auto t = std::chrono::steady_clock::now();
    if (!m.decode_proxy_page(n, p->codec, p->payload, cell, nullptr, none)) continue;
    d.proxy_decode_seconds += since(t);
    ++d.proxies;
    d.proxy_triangles += cell.size();
    t = std::chrono::steady_clock::now();
    const KdTree built = KdTree::build(cell, proxy_options);
    d.proxy_build_seconds += since(t);
    if ((p->codec & kCellTreeFlag) == 0) continue;
    std::span<const uint8_t> tree_bytes, payload;
    if (!split_tree_page(p->payload, tree_bytes, payload)) continue;
    t = std::chrono::steady_clock::now();
    Result<KdTree> stored = decode_cell_tree(tree_bytes, cell, m.node_region(n), proxy_options);
    d.proxy_load_seconds += since(t);
    ++d.proxy_trees;
    if (!stored || !same_tree(*stored, built)) ++d.tree_mismatches;
  }
  return d;
}

}  // namespace

int main(int argc, char** argv) {
  frontier::tune_allocator_for_build();  // as frontier-build does
  CLI::App app{"bench_build: frontier-build throughput against the I/O floor, bytes/triangle, page decode speed"};
  std::vector<std::string> models;
  std::vector<int> bits = {16};
  std::vector<std::string> codecs = {"draco"};
  std::string memory = "1G", output = "bench_build.frontier";
  int threads = 2;
  uint32_t proxy_triangles = 0;
  bool spill_inputs = false;
  app.add_option("models", models, "model files (binary PLY from frontier-gen, ...)")->required();
  app.add_option("--bits", bits, "lattice bits to measure (Draco)");
  app.add_option("--codecs", codecs, "codecs to measure: draco, meshopt, raw");
  app.add_option("--memory", memory, "build memory budget");
  app.add_option("--threads", threads, "build threads");
  app.add_option("--proxy-triangles", proxy_triangles,
                 "give the stores proxies of this many triangles (frontier-build's option; 0: none, as before) and "
                 "print a second table: per proxy page, decode, tree build and stored-tree load");
  app.add_option("-o,--output", output, "scratch store path (removed at the end)");
  app.add_flag("--spill-inputs", spill_inputs,
               "spill binary PLY inputs to a temporary file first instead of parsing them again (the old path)");
  CLI11_PARSE(app, argc, argv);
  std::string proxy_rows;

  std::printf("| model | codec | bits | triangles | build s | Mtri/s | I/O floor s | build/floor | MB | bytes/tri | "
              "decode MB/s | decode Mtri/s | refine us/prim | tree load us/prim | refine/load | tree bytes/tri |\n"
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const std::string& model : models) {
    for (const std::string& codec : codecs) {
      for (const int b : bits) {
        if (codec == "raw" && b != bits.front()) continue;
        BuildOptions o;
        o.inputs = {model};
        o.output = output;
        const std::optional<CellCodec> tag = cell_codec_named(codec);
        if (!tag) {
          std::fprintf(stderr, "bench_build: unknown codec %s\n", codec.c_str());
          return 2;
        }
        o.codec = *tag;
        o.quant_bits = b;
        o.threads = threads;
        o.quiet = true;
        o.proxy_triangles = proxy_triangles;
        o.reparse_binary_ply = !spill_inputs;
        o.memory = parse_byte_size(memory).value_or(uint64_t{1} << 30);
        drop_cache(model);
        const auto t = std::chrono::steady_clock::now();
        auto report = build_store(o);
        const double build_s = since(t);
        if (!report) {
          std::fprintf(stderr, "%s\n", report.status().to_string().c_str());
          return 1;
        }
        const double floor_s = io_floor({model}, output, report->store_bytes);
        const Decode d = decode_all(output);
        const double tris = static_cast<double>(report->triangles);
        const double tree_prims = std::max(static_cast<double>(d.tree_primitives), 1.0);
        std::printf("| %s | %s | %d | %.0f | %.2f | %.2f | %.2f | %.1f | %.1f | %.2f | %.0f | %.1f | %.2f | %.3f | %.1f | %.2f |\n",
                    std::filesystem::path(model).filename().c_str(), codec.c_str(), codec == "raw" ? 0 : b, tris,
                    build_s, tris / build_s / 1e6, floor_s, build_s / floor_s,
                    static_cast<double>(report->store_bytes) / 1e6,
                    static_cast<double>(report->store_bytes) / std::max(tris, 1.0),
                    static_cast<double>(d.payload_bytes) / 1e6 / std::max(d.seconds, 1e-9),
                    static_cast<double>(d.primitives) / 1e6 / std::max(d.seconds, 1e-9),
                    d.refine_seconds * 1e6 / std::max(static_cast<double>(d.primitives), 1.0),
                    d.load_seconds * 1e6 / tree_prims, d.refine_tree_pages_seconds / std::max(d.load_seconds, 1e-12),
                    static_cast<double>(d.tree_bytes) / std::max(tris, 1.0));
        if (d.tree_mismatches > 0) {
          std::fprintf(stderr, "bench_build: %llu stored in-cell trees differ from the refine\n",
                       static_cast<unsigned long long>(d.tree_mismatches));
          return 1;
        }
        if (d.proxies > 0) {
          const double n = static_cast<double>(d.proxies);
          proxy_rows += fmt::format("| {} | {} | {} | {:.0f} | {:.1f} | {:.1f} | {:.1f} | {:.1f} | {:.2f} |\n",
                                    std::filesystem::path(model).filename().string(), codec, d.proxies,
                                    static_cast<double>(d.proxy_triangles) / n, d.proxy_decode_seconds * 1e6 / n,
                                    d.proxy_build_seconds * 1e6 / n,
                                    d.proxy_trees > 0 ? d.proxy_load_seconds * 1e6 / double(d.proxy_trees) : 0.0,
                                    (d.proxy_decode_seconds + d.proxy_build_seconds) * 1e6 / n,
                                    d.proxy_trees > 0 ? (d.proxy_decode_seconds + d.proxy_build_seconds) /
                                                            std::max(d.proxy_decode_seconds + d.proxy_load_seconds, 1e-12)
                                                      : 0.0);
        }
        std::fprintf(stderr, "  %s: read %.1f s, partition %.1f s, build %.1f s, encode %.1f s; %llu parts, %.2f GB spilled\n",
                     model.c_str(), report->ingest_seconds, report->spill_seconds, report->build_seconds,
                     report->encode_seconds, static_cast<unsigned long long>(report->parts),
                     static_cast<double>(report->spill_bytes) / 1e9);
        std::fflush(stdout);
        std::filesystem::remove(output);
      }
    }
  }
  if (!proxy_rows.empty()) {
    std::printf("\n| model | codec | proxies | triangles/proxy | decode us | tree build us | tree load us | decode+build us | "
                "(decode+build)/(decode+load) |\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n%s",
                proxy_rows.c_str());
  }
  return 0;
}
