// Page-in speed of an existing store, as frontier-view pays it on its frame's thread: every proxy
// page (or cell page) read into memory first, then decoded with its stored tree as the walk does
// (StoreModel::decode_proxy_page / decode_page with the walk's build options), the payload and
// the tree timed apart. Several rounds; the best round per figure (the machine is noisy).
// Prints Markdown: pages, triangles, microseconds per page and nanoseconds per triangle.
#include "src/codec/cell_tree.h"
#include "src/paging/store_model.h"
#include "src/walk/walkthrough.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>

#include <algorithm>
#include <chrono>
#include <optional>
#include <vector>

using namespace frontier;

namespace {

double since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

struct Page {
  uint32_t id = 0;  // node (proxies) or cell
  store::OwnedPage data;
};

struct Round {
  double payload_s = 0.0, tree_s = 0.0, total_s = 0.0;
  uint64_t pages = 0, triangles = 0, trees = 0, failed = 0, mismatches = 0;
};

}  // namespace

int main(int argc, char** argv) {
  tune_allocator_for_walk();  // as frontier-view does
  CLI::App app{"bench_pagein: decode speed of a store's proxy or cell pages with their stored trees"};
  std::string path;
  bool cells = false;
  int rounds = 3;
  size_t limit = 4000;
  bool check = false;
  app.add_option("store", path, "a .frontier store")->required();
  app.add_flag("--cells", cells, "cell pages instead of proxy pages");
  app.add_option("--rounds", rounds, "rounds over the pages (the best one is printed)")->check(CLI::Range(1, 100));
  app.add_option("--pages", limit, "at most this many pages, from the top of the tree (proxies) or the first cells");
  app.add_flag("--check", check, "also check every stored tree against the tree the builder makes (untimed)");
  CLI11_PARSE(app, argc, argv);

  auto model = StoreModel::open(path);
  if (!model) {
    fmt::print(stderr, "bench_pagein: {}\n", model.status().message());
    return 1;
  }
  const StoreModel& m = **model;
  const KdBuildOptions cell_options =
      m.info().cell_tree ? *m.info().cell_tree : page_refine_options(WalkOptions{});
  std::vector<Page> pages;
  if (cells) {
    for (uint32_t c = 0; c < m.cells().size() && pages.size() < limit; ++c) {
      if (m.cells()[c].page == StoreCell::kNoPage) continue;
      auto p = m.reader().read_page(m.cells()[c].page);
      if (p) pages.push_back({c, std::move(*p)});
    }
  } else {
    for (uint32_t n = 0; n < m.nodes().size() && pages.size() < limit; ++n) {
      if (m.proxy(n) == nullptr) continue;
      auto p = m.reader().read_page(m.proxy(n)->page);
      if (p) pages.push_back({n, std::move(*p)});
    }
  }
  std::optional<Round> best;
  for (int r = 0; r < rounds; ++r) {
    Round round;
    Scene scene;
    for (const Page& p : pages) {
      KdBuildOptions options = cells ? cell_options : proxy_tree_options(cell_options);
      options.root = cells ? m.cells()[p.id].bounds : m.node_region(p.id);
      std::optional<KdTree> tree, none;
      auto t = std::chrono::steady_clock::now();
      const Status payload = cells ? m.decode_page(p.id, p.data.codec, p.data.payload, scene)
                                   : m.decode_proxy_page(p.id, p.data.codec, p.data.payload, scene, nullptr, none);
      round.payload_s += since(t);
      t = std::chrono::steady_clock::now();
      const Status whole = cells ? m.decode_page(p.id, p.data.codec, p.data.payload, scene, options, tree)
                                 : m.decode_proxy_page(p.id, p.data.codec, p.data.payload, scene, &options, tree);
      round.total_s += since(t);
      if (!payload || !whole) {
        ++round.failed;
        continue;
      }
      ++round.pages;
      round.triangles += scene.size();
      round.trees += tree ? 1 : 0;
      if (check && tree && !same_tree(*tree, KdTree::build(scene, options))) ++round.mismatches;
    }
    round.tree_s = std::max(0.0, round.total_s - round.payload_s);
    if (!best || round.total_s < best->total_s) best = round;
  }
  const Round& b = *best;
  const double per_page = b.pages > 0 ? 1e6 / double(b.pages) : 0.0;
  const double per_tri = b.triangles > 0 ? 1e9 / double(b.triangles) : 0.0;
  fmt::print("| store | pages | triangles/page | trees | payload us/page | tree us/page | total us/page | total ns/triangle |\n");
  fmt::print("|---|---:|---:|---:|---:|---:|---:|---:|\n");
  fmt::print("| {} ({}) | {} | {:.0f} | {} | {:.1f} | {:.1f} | {:.1f} | {:.0f} |\n", path, cells ? "cells" : "proxies",
             b.pages, b.pages > 0 ? double(b.triangles) / double(b.pages) : 0.0, b.trees, b.payload_s * per_page,
             b.tree_s * per_page, b.total_s * per_page, b.total_s * per_tri);
  if (check) fmt::print("\nstored trees unlike the builder's: {}\n", b.mismatches);
  return b.failed == 0 && b.mismatches == 0 ? 0 : 1;
}
