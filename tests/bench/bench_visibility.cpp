// Fig. 1 of the frustum-casting paper (§1.5) as a measured figure: the working set of each
// visibility class — exhaustive, frustum culling, occlusion culling, cells and portals, frustum
// advance — along the same camera path through the same store with the same cache, against the
// oracle (the cells exact per-pixel rays pass before their first hit).
//
//   bench_visibility --store B.frontier --path walk.cam --label building [--frames N]
//       [--size 320x240] [--cache 64M] [--threads 2] [--classes frustum-advance,portals,...]
//       [--cull-back-faces] [--csv frames.csv] [--markdown table.md]
//
// Per frame and class: store cells touched, k-d nodes touched, primitive references touched,
// fragments rasterized, the working set in bytes — the compressed pages of the cells touched and
// the same cells decoded and refined (what the frame needed in memory at once, independent of
// what the cache kept) — the resident bytes after the frame, bytes read and frame time. Frustum advance renders complete frames (sync paging, no
// budget), like the rasterizing classes, so every class produces the same image.
//
// The table gives mean and max per class, the ratio to the oracle and to frustum advance, all
// from the same run.
#include "src/io/camera_path.h"
#include "src/core/progress.h"
#include "src/paging/store_model.h"
#include "src/raster/visibility.h"
#include "src/walk/walkthrough.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>
#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

using namespace frontier;

namespace {

struct Row {
  uint64_t cells = 0, nodes = 0, prims = 0, fragments = 0, working_bytes = 0, decoded_bytes = 0, resident = 0, read = 0,
           oracle = 0;
  double ms = 0.0;
};

struct Summary {
  double mean_cells = 0, max_cells = 0, mean_ratio = 0, max_ratio = 0, mean_prims = 0, mean_nodes = 0,
         mean_fragments = 0, mean_working_mib = 0, max_working_mib = 0, mean_decoded_mib = 0, max_decoded_mib = 0,
         max_resident_mib = 0, read_mib = 0,
         mean_ms = 0, p95_ms = 0;
};

Summary summarize(const std::vector<Row>& rows) {
  Summary s;
  if (rows.empty()) return s;
  std::vector<double> ms;
  size_t ratio_frames = 0;
  for (const Row& r : rows) {
    s.mean_cells += double(r.cells);
    s.max_cells = std::max(s.max_cells, double(r.cells));
    if (r.oracle > 0) {
      const double q = double(r.cells) / double(r.oracle);
      s.mean_ratio += q;
      s.max_ratio = std::max(s.max_ratio, q);
      ++ratio_frames;
    }
    s.mean_prims += double(r.prims);
    s.mean_nodes += double(r.nodes);
    s.mean_fragments += double(r.fragments);
    s.mean_working_mib += double(r.working_bytes) / 1048576.0;
    s.max_working_mib = std::max(s.max_working_mib, double(r.working_bytes) / 1048576.0);
    s.mean_decoded_mib += double(r.decoded_bytes) / 1048576.0;
    s.max_decoded_mib = std::max(s.max_decoded_mib, double(r.decoded_bytes) / 1048576.0);
    s.max_resident_mib = std::max(s.max_resident_mib, double(r.resident) / 1048576.0);
    s.read_mib += double(r.read) / 1048576.0;
    s.mean_ms += r.ms;
    ms.push_back(r.ms);
  }
  const double n = double(rows.size());
  s.mean_cells /= n;
  s.mean_prims /= n;
  s.mean_nodes /= n;
  s.mean_fragments /= n;
  s.mean_working_mib /= n;
  s.mean_decoded_mib /= n;
  s.read_mib /= n;
  s.mean_ms /= n;
  if (ratio_frames > 0) s.mean_ratio /= double(ratio_frames);
  std::sort(ms.begin(), ms.end());
  s.p95_ms = ms[std::min(ms.size() - 1, size_t(0.95 * double(ms.size() - 1) + 0.5))];
  return s;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_visibility: the working set of each visibility class along a camera path (Fig. 1)"};
  std::string store, path_file, label = "model", size_text = "320x240", cache_text = "64M", csv_path, md_path;
  std::string classes_text = "frustum-advance,portals,occlusion-cull,frustum-cull,exhaustive";
  int frames = 0, threads = 2;
  bool back_faces = false;
  app.add_option("--store", store, "store file (frontier-build)")->required();
  app.add_option("--path", path_file, "camera path (.cam)")->required();
  app.add_option("--label", label, "name of the model in the output");
  app.add_option("--frames", frames, "frames (default: the path's length)");
  app.add_option("--size", size_text, "image size WxH");
  app.add_option("--cache", cache_text, "cache budget, the same for every class");
  app.add_option("--threads", threads, "render threads");
  app.add_option("--classes", classes_text, "comma-separated visibility classes; the first must be frustum-advance "
                                            "(it also computes the oracle)");
  app.add_flag("--cull-back-faces", back_faces, "rasterizing classes drop back faces (closed solids)");
  app.add_option("--csv", csv_path, "per-frame rows: label,class,frame,...");
  app.add_option("--markdown", md_path, "append the summary table here");
  CLI11_PARSE(app, argc, argv);

  int width = 0, height = 0;
  if (std::sscanf(size_text.c_str(), "%dx%d", &width, &height) != 2 || width < 1 || height < 1) {
    fmt::print(stderr, "bench_visibility: --size {}: expected WxH\n", size_text);
    return 2;
  }
  const auto cache = parse_byte_size(cache_text);
  if (!cache) {
    fmt::print(stderr, "bench_visibility: --cache {}: expected a size like 64M\n", cache_text);
    return 2;
  }
  std::vector<Visibility> classes;
  std::stringstream list(classes_text);
  for (std::string item; std::getline(list, item, ',');) {
    const auto v = parse_visibility(item);
    if (!v) {
      fmt::print(stderr, "bench_visibility: --classes: unknown class {}\n", item);
      return 2;
    }
    classes.push_back(*v);
  }
  if (classes.empty() || classes.front() != Visibility::kFrustumAdvance) {
    fmt::print(stderr, "bench_visibility: --classes must start with frustum-advance (it computes the oracle)\n");
    return 2;
  }
  auto cams = read_camera_path(path_file);
  if (!cams) {
    fmt::print(stderr, "bench_visibility: {}\n", cams.status().to_string());
    return 1;
  }
  const size_t n = frames > 0 ? std::min(size_t(frames), cams->size()) : cams->size();
  auto model = StoreModel::open(store);
  if (!model) {
    fmt::print(stderr, "bench_visibility: {}\n", model.status().to_string());
    return 1;
  }
  std::vector<uint64_t> page_bytes((*model)->cells().size(), 0);
  for (size_t c = 0; c < page_bytes.size(); ++c) {
    const StoreCell& cell = (*model)->cells()[c];
    if (cell.page != StoreCell::kNoPage) page_bytes[c] = (*model)->reader().page_handle(cell.page).size;
  }
  const bool has_portals = (*model)->portals() != nullptr;

  std::ofstream csv;
  if (!csv_path.empty()) {
    const bool fresh = !std::ifstream(csv_path).good();
    csv.open(csv_path, std::ios::app);
    if (fresh) {
      csv << "label,class,frame,cells_touched,oracle_cells,nodes_touched,primitives_touched,pixels_rasterized,"
             "working_set_bytes,decoded_set_bytes,resident_bytes,bytes_read,frame_ms\n";
    }
  }
  std::vector<uint64_t> oracle(n, 0);
  std::map<Visibility, Summary> summaries;
  std::vector<Visibility> ran;
  for (const Visibility v : classes) {
    if (v == Visibility::kPortals && !has_portals) {
      fmt::print(stderr, "bench_visibility: {}: no cells and portals in the store, portals skipped\n", label);
      continue;
    }
    WalkOptions o;
    o.width = width;
    o.height = height;
    o.threads = threads;
    o.cache_bytes = *cache;
    o.sync_paging = true;
    o.shadows = false;
    o.reconstruct_each_frame = false;
    o.oracle = v == Visibility::kFrustumAdvance;
    o.visibility = v;
    o.cull_back_faces = back_faces;
    auto walk = Walkthrough::open(store, o);
    if (!walk) {
      fmt::print(stderr, "bench_visibility: {}\n", walk.status().to_string());
      return 1;
    }
    std::vector<Row> rows;
    for (size_t f = 0; f < n; ++f) {
      const FrameReport r = (*walk)->frame((*cams)[f]);
      if (r.oracle_cells) oracle[f] = *r.oracle_cells;
      Row row;
      row.cells = r.cells_touched;
      row.nodes = r.nodes_touched;
      row.prims = r.primitives_touched;
      row.fragments = r.pixels_rasterized;
      for (const uint32_t c : (*walk)->touched_cells()) {
        row.working_bytes += page_bytes[c];
        row.decoded_bytes += (*walk)->world().decoded_size(c);
      }
      row.resident = r.resident_bytes;
      row.read = r.bytes_read;
      row.oracle = oracle[f];
      row.ms = r.frame_ms;
      rows.push_back(row);
      if (csv.is_open()) {
        csv << fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{:.3f}\n", label, visibility_name(v), f, row.cells,
                           row.oracle, row.nodes, row.prims, row.fragments, row.working_bytes, row.decoded_bytes,
                           row.resident, row.read, row.ms);
      }
    }
    summaries[v] = summarize(rows);
    ran.push_back(v);
    fmt::print(stderr, "bench_visibility: {} {}: {} frames, mean {:.1f} ms\n", label, visibility_name(v), n,
               summaries[v].mean_ms);
  }

  const Summary& fa = summaries[Visibility::kFrustumAdvance];
  std::string table = fmt::format(
      "\n### {} ({} frames, {}x{}, cache {})\n\n"
      "| class | cells touched mean | max | / oracle mean | / oracle max | / frustum advance | primitives touched "
      "mean | nodes touched mean | fragments mean | pages MiB mean | max | decoded MiB mean | max | resident MiB max | "
      "read MiB/frame | frame ms mean | p95 |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
      label, n, width, height, cache_text);
  double oracle_mean = 0.0, oracle_max = 0.0;
  for (const uint64_t o : oracle) {
    oracle_mean += double(o);
    oracle_max = std::max(oracle_max, double(o));
  }
  oracle_mean /= double(std::max<size_t>(1, n));
  table += fmt::format("| oracle | {:.1f} | {:.0f} | 1.000 | 1.000 | {:.3f} | | | | | | | | | | | |\n", oracle_mean,
                       oracle_max, fa.mean_cells > 0 ? oracle_mean / fa.mean_cells : 0.0);
  for (const Visibility v : ran) {
    const Summary& s = summaries[v];
    table += fmt::format(
        "| {} | {:.1f} | {:.0f} | {:.3f} | {:.3f} | {:.3f} | {:.0f} | {:.0f} | {:.0f} | {:.2f} | {:.2f} | {:.1f} | "
        "{:.1f} | {:.1f} | {:.2f} | {:.1f} | {:.1f} |\n",
        visibility_name(v), s.mean_cells, s.max_cells, s.mean_ratio, s.max_ratio,
        fa.mean_cells > 0 ? s.mean_cells / fa.mean_cells : 0.0, s.mean_prims, s.mean_nodes, s.mean_fragments,
        s.mean_working_mib, s.max_working_mib, s.mean_decoded_mib, s.max_decoded_mib, s.max_resident_mib, s.read_mib,
        s.mean_ms, s.p95_ms);
  }
  fmt::print("{}", table);
  if (!md_path.empty()) {
    std::ofstream md(md_path, std::ios::app);
    md << table;
    if (!md) {
      fmt::print(stderr, "bench_visibility: {}: cannot write\n", md_path);
      return 1;
    }
  }
  return 0;
}
