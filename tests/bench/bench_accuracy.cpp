// What accuracy costs in time: one curve per knob, error (or memory) against time, measured on
// one model and one camera path in the same run (issue 6, item 3).
//
//   quant    the Draco lattice's bits per axis (10..20) against a raw store of the same model:
//            store bytes per triangle, page decode ms and MB/s (every page read into memory
//            first, only decoding timed), max and RMS distance of decoded vertices from the raw
//            store's (each decoded triangle matched to the raw triangle with the same input id
//            and the corner rotation that fits best, since Draco may rotate corners), in model
//            units, relative to the model diagonal and to the lattice step the store declares
//            (per axis the error is at most step/2), and the % of pixels whose first-hit id
//            differs from the raw store's render of the same cameras (complete frames, sync
//            paging), in all and not counting ids whose faces lie in one plane (coincident
//            faces: the tie may fall either way). Two controls: raw rendered again, and a raw
//            store with other cells.
//   samples  pegging by sample count (paper §5.5), then by frame time: frame ms, PSNR (8-bit
//            RGB) and % of pixels exactly equal against the complete image of the same camera
//            (sync paging and a warm cache, so only sampling differs).
//   cells    the builder's cell size (--cell-prims): a walk along the path, complete frames,
//            sync paging, cold cache of a fixed budget: bytes read, cells touched and paged in
//            per frame against frame and traversal ms (paging granularity vs traversal cost).
//   refine   WalkOptions.cell_prims (how a paged-in cell is refined): page-in ms against
//            traversal ms, resident bytes; same walk, default store.
//   cache    WalkOptions.cache_bytes: bytes read and cells paged in per frame, frames that stayed
//            complete, frame ms; same walk, default store.
//   sdf      the collision grid's voxel size (frontier-build --sdf-voxel, walk radius 0.25): the
//            grid's build seconds (a --walkable build minus the same build without), brick page
//            MB, active voxels, µs per distance() query (warm cache), against the error of
//            distance() from the exact distance to the model's triangles (min with the band width
//            W, which is what the grid can tell apart) at points near the surfaces: max, mean and
//            99th percentile, in model units and in voxels. The header's bound is 0.94 voxel.
//
// Stores are built with the builder API into --dir, named by their options (--reuse keeps ones
// already there). Prints a Markdown table per knob; --json FILE gets one JSON object per line
// per measured point ({"knob", "value", measures...}) for a plotting script. Traversal ms is
// frame ms minus page-in (decode + refine + graft), waiting for pages and reconstruction.
#include "preprocess/build.h"
#include "preprocess/walkable_grid.h"
#include "src/io/load_scene.h"
#include "src/walk/collision_grid.h"
#include "src/io/camera_path.h"
#include "src/io/image.h"
#include "src/core/progress.h"
#include "src/paging/store_model.h"
#include "src/walk/walkthrough.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <unordered_map>
#include <string>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

using namespace frontier;
using Clock = std::chrono::steady_clock;

namespace {

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

// Drops a file from the OS page cache so that the next read goes to the disk.
void drop_cache(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  if (fd < 0) return;
  ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
  ::close(fd);
}

int fail(const Status& s) {
  fmt::print(stderr, "bench_accuracy: {}\n", s.to_string());
  return 1;
}

std::string mib(uint64_t bytes) { return fmt::format("{:.1f}", double(bytes) / double(1 << 20)); }

struct Options {
  std::string model, path, dir, json_path, png_dir, memory = "1G";
  std::vector<std::string> knobs = {"quant", "samples", "cells", "refine", "cache"};
  std::vector<int> bits = {10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20};
  std::vector<uint32_t> cell_sizes = {256, 512, 1024, 2048, 4096, 8192};
  std::vector<uint32_t> refine_prims = {4, 8, 16, 32, 64};
  std::vector<std::string> caches = {"2M", "4M", "8M", "16M", "64M", "256M"};
  std::vector<double> sample_fractions = {0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0};
  std::vector<double> frame_ms = {5, 10, 20, 40, 60};
  std::vector<double> sdf_voxels = {0.4, 0.2, 0.1, 0.05};
  int sdf_points = 20000;
  int quant_cameras = 4, sample_cameras = 8, walk_frames = 60, walk_repeats = 2, threads = 2, width = 640, height = 480;
  int default_bits = 16;
  uint32_t default_cell_prims = 1024;
  std::string walk_cache = "128M", render_cache = "1G";
  bool reuse = false;
};

// One JSON object per measured point, one per line, written as soon as it is measured.
class JsonLines {
 public:
  bool open(const std::string& path) {
    if (path.empty()) return true;
    out_.open(path);
    return bool(out_);
  }
  void write(const nlohmann::json& point) {
    if (!out_.is_open()) return;
    out_ << point.dump() << '\n';
    out_.flush();
  }

 private:
  std::ofstream out_;
};

// ---- stores ------------------------------------------------------------------------------

struct StoreSpec {
  CellCodec codec = CellCodec::Draco;
  int bits = 16;
  uint32_t cell_prims = 1024;
};

std::string store_path(const Options& o, const StoreSpec& s) {
  const std::string codec = s.codec == CellCodec::Raw ? "raw" : fmt::format("draco{}", s.bits);
  return fmt::format("{}/{}-c{}.frontier", o.dir, codec, s.cell_prims);
}

// Builds the store unless this run built it already or --reuse finds it. Returns its path;
// `build_s` gets the build's seconds (0 for a store reused from an earlier run).
Result<std::string> ensure_store(const Options& o, const StoreSpec& s, double* build_s = nullptr) {
  // Stores this run built already, with their build seconds: knobs share the default store.
  static std::map<std::string, double> built;
  const std::string path = store_path(o, s);
  if (build_s) *build_s = 0.0;
  if (const auto it = built.find(path); it != built.end()) {
    if (build_s) *build_s = it->second;
    return path;
  }
  if (o.reuse && std::filesystem::exists(path)) return path;
  BuildOptions b;
  b.inputs = {o.model};
  b.output = path;
  b.codec = s.codec;
  b.quant_bits = s.bits;
  b.cell_prims = s.cell_prims;
  b.threads = o.threads;
  b.quiet = true;
  b.memory = parse_byte_size(o.memory).value_or(uint64_t{1} << 30);
  fmt::print(stderr, "bench_accuracy: building {}\n", path);
  const auto t = Clock::now();
  auto report = build_store(b);
  if (!report) return report.status();
  built[path] = ms_since(t) / 1000.0;
  if (build_s) *build_s = built[path];
  return path;
}

uint64_t file_bytes(const std::string& path) {
  std::error_code ec;
  const auto n = std::filesystem::file_size(path, ec);
  return ec ? 0 : uint64_t(n);
}

Result<std::vector<store::OwnedPage>> read_pages(const StoreModel& model) {
  std::vector<store::OwnedPage> pages;
  for (const StoreCell& c : model.cells()) {
    if (c.page == StoreCell::kNoPage) continue;
    auto p = model.reader().read_page(c.page);
    if (!p) return p.status();
    pages.push_back(std::move(*p));
  }
  return pages;
}

// ---- rendering ---------------------------------------------------------------------------

// `count` cameras spread evenly over the path (all of it when it is shorter).
std::vector<Camera> spread(const std::vector<Camera>& path, int count) {
  std::vector<Camera> out;
  const size_t n = std::min(path.size(), size_t(std::max(count, 1)));
  for (size_t i = 0; i < n; ++i) out.push_back(path[i * path.size() / n]);
  return out;
}

WalkOptions walk_options(const Options& o, const std::string& cache) {
  WalkOptions w;
  w.width = o.width;
  w.height = o.height;
  w.threads = o.threads;
  w.sync_paging = true;
  w.shadows = false;  // every image has the immediate effects only, pegged or complete
  w.min_sampled = 0.0;  // the frame-time curve is of pure pegging
  w.cache_bytes = parse_byte_size(cache).value_or(512ull << 20);
  return w;
}

// The displayed image as the PNG writer would store it (8 bits per channel).
std::vector<uint8_t> rgb8(const std::vector<Rgb>& image) {
  std::vector<uint8_t> out(image.size() * 3);
  const auto q = [](float c) { return static_cast<uint8_t>(std::clamp(c, 0.0f, 1.0f) * 255.0f + 0.5f); };
  for (size_t i = 0; i < image.size(); ++i) {
    out[3 * i] = q(image[i].r);
    out[3 * i + 1] = q(image[i].g);
    out[3 * i + 2] = q(image[i].b);
  }
  return out;
}

// Squared error summed over channels, and pixels whose three channels are all equal.
struct ImageDiff {
  double squared_error = 0.0;
  uint64_t channels = 0, pixels = 0, equal_pixels = 0;
  void add(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
    const size_t n = std::min(a.size(), b.size()) / 3;
    for (size_t i = 0; i < n; ++i) {
      bool equal = true;
      for (size_t k = 3 * i; k < 3 * i + 3; ++k) {
        const double d = double(a[k]) - double(b[k]);
        squared_error += d * d;
        equal = equal && a[k] == b[k];
      }
      equal_pixels += equal;
    }
    channels += 3 * n;
    pixels += n;
  }
  // PSNR of the pooled mean squared error; infinity for identical images.
  double psnr() const {
    const double mse = squared_error / double(std::max<uint64_t>(channels, 1));
    return mse == 0.0 ? std::numeric_limits<double>::infinity() : 10.0 * std::log10(255.0 * 255.0 / mse);
  }
  double equal_percent() const { return 100.0 * double(equal_pixels) / double(std::max<uint64_t>(pixels, 1)); }
};

nlohmann::json json_number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
std::string text_number(double v, int digits = 2) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, digits) : std::string("∞");
}

// Per-frame means of a walk.
struct WalkSummary {
  int frames = 0, complete = 0;
  double frame_ms = 0, page_in_ms = 0, stall_ms = 0, reconstruct_ms = 0, traversal_ms = 0;
  double bytes_read = 0, cells_touched = 0, cells_paged_in = 0, cells_evicted = 0, resident_bytes = 0;
  uint64_t total_bytes_read = 0, page_errors = 0;

  void add(const FrameReport& r) {
    ++frames;
    complete += r.complete;
    frame_ms += r.frame_ms;
    page_in_ms += r.decode_ms;
    stall_ms += r.stall_ms;
    reconstruct_ms += r.reconstruct_ms;
    traversal_ms += std::max(0.0, r.frame_ms - r.decode_ms - r.stall_ms - r.reconstruct_ms);
    bytes_read += double(r.bytes_read);
    total_bytes_read += r.bytes_read;
    cells_touched += double(r.cells_touched);
    cells_paged_in += double(r.cells_paged_in);
    cells_evicted += double(r.cells_evicted);
    resident_bytes += double(r.resident_bytes);
    page_errors = r.page_errors;
  }
  WalkSummary mean() const {
    WalkSummary m = *this;
    const double n = std::max(frames, 1);
    for (double* v : {&m.frame_ms, &m.page_in_ms, &m.stall_ms, &m.reconstruct_ms, &m.traversal_ms, &m.bytes_read,
                      &m.cells_touched, &m.cells_paged_in, &m.cells_evicted, &m.resident_bytes}) {
      *v /= n;
    }
    return m;
  }
  nlohmann::json to_json() const {
    return {{"frames", frames},
            {"complete_frames", complete},
            {"frame_ms", frame_ms},
            {"page_in_ms", page_in_ms},
            {"stall_ms", stall_ms},
            {"reconstruct_ms", reconstruct_ms},
            {"traversal_ms", traversal_ms},
            {"bytes_read_per_frame", bytes_read},
            {"cells_touched_per_frame", cells_touched},
            {"cells_paged_in_per_frame", cells_paged_in},
            {"cells_evicted_per_frame", cells_evicted},
            {"resident_bytes", resident_bytes},
            {"total_bytes_read", total_bytes_read},
            {"page_errors", page_errors}};
  }
};

// Walks the first `frames` cameras of the path from a cold cache (the OS page cache of the
// store dropped too): complete frames, sync paging. Per-frame means of the least disturbed of
// `repeats` walks (least total frame time; the machine is shared).
Result<WalkSummary> walk(const std::string& store, const std::vector<Camera>& path, int frames, int repeats,
                         const WalkOptions& options) {
  WalkSummary best;
  for (int r = 0; r < std::max(repeats, 1); ++r) {
    drop_cache(store);
    auto w = Walkthrough::open(store, options);
    if (!w) return w.status();
    WalkSummary sum;
    for (int f = 0; f < frames && f < int(path.size()); ++f) sum.add((*w)->frame(path[size_t(f)]));
    if (r == 0 || sum.frame_ms < best.frame_ms) best = sum;
  }
  return best.mean();
}

// ---- quant -------------------------------------------------------------------------------

// The raw store's triangles grouped by input id (source). A triangle straddling cells is stored
// in each; only the first cell holding a source contributes its triangles.
struct SourceTriangles {
  std::vector<uint32_t> begin;  // per source: triangles [begin[s], begin[s + 1])
  std::vector<Triangle> triangles;
  std::span<const Triangle> of(uint32_t s) const {
    if (size_t(s) + 1 >= begin.size()) return {};
    return {triangles.data() + begin[s], triangles.data() + begin[s + 1]};
  }
};

Status raw_triangles(const StoreModel& raw, const std::vector<store::OwnedPage>& pages, SourceTriangles& out) {
  const size_t sources = raw.info().input_primitives;
  std::vector<uint32_t> owner(sources, UINT32_MAX), count(sources, 0);
  Scene cell;
  // Pass 0 counts, pass 1 fills: the same owner rule both times.
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<uint32_t> fill;
    if (pass == 1) {
      out.begin.assign(sources + 1, 0);
      for (size_t s = 0; s < sources; ++s) out.begin[s + 1] = out.begin[s] + count[s];
      out.triangles.resize(out.begin[sources]);
      fill.assign(out.begin.begin(), out.begin.end() - 1);
    }
    for (size_t i = 0; i < pages.size(); ++i) {
      if (Status s = decode_cell(pages[i].payload, CellCodec::Raw, raw.info().lattice, cell); !s) return s;
      for (const PrimRef& p : cell.prims) {
        if (p.kind != PrimKind::Triangle || p.source >= sources) continue;
        uint32_t& o = owner[p.source];
        if (o == UINT32_MAX) o = uint32_t(i);
        if (o != uint32_t(i)) continue;
        if (pass == 0) {
          ++count[p.source];
        } else {
          out.triangles[fill[p.source]++] = cell.triangles[p.index];
        }
      }
    }
  }
  return Status::ok();
}

// A decoded triangle's corners matched to the raw triangle of the same source and the corner
// rotation (Draco may rotate a face's corners, never flip it) with the least squared distance.
// Returns the corners' distances and per-axis differences; false when the source has no raw
// triangle.
bool match_corners(const Triangle& decoded, std::span<const Triangle> candidates, std::array<Vec3, 3>& difference) {
  double best = kInfinity;
  for (const Triangle& c : candidates) {
    const std::array<Vec3, 3> raw = {c.v0, c.v1, c.v2};
    const std::array<Vec3, 3> dec = {decoded.v0, decoded.v1, decoded.v2};
    for (int rotation = 0; rotation < 3; ++rotation) {
      std::array<Vec3, 3> d;
      double cost = 0.0;
      for (int k = 0; k < 3; ++k) {
        d[size_t(k)] = dec[size_t(k)] - raw[size_t((k + rotation) % 3)];
        cost += glm::dot(d[size_t(k)], d[size_t(k)]);
      }
      if (cost < best) best = cost, difference = d;
    }
  }
  return best < kInfinity;
}

struct QuantPoint {
  int bits = 0;
  double step = 0, build_s = 0, bytes_per_triangle = 0, decode_ms = 0, decode_mb_s = 0, decode_mtri_s = 0;
  double max_error = 0, rms_error = 0, max_axis_error = 0;
  uint64_t triangles = 0, store_bytes = 0, payload_bytes = 0, vertices = 0, unmatched = 0;
  double id_differ_percent = 0, id_differ_geometric_percent = 0, render_ms = 0;
};

struct IdRender {
  std::vector<uint32_t> ids;
  double ms = 0;
};

// Complete frames of `cameras` from a cold cache, with sync paging: their ids and total ms.
Result<std::vector<IdRender>> render_ids(const std::string& store, const std::vector<Camera>& cameras,
                                         const WalkOptions& options) {
  drop_cache(store);
  auto w = Walkthrough::open(store, options);
  if (!w) return w.status();
  std::vector<IdRender> out;
  for (const Camera& c : cameras) {
    const FrameReport r = (*w)->frame(c);
    out.push_back({(*w)->ids(), r.frame_ms});
  }
  return out;
}

// True when the raw triangles of ids a and b lie in one plane (within `tolerance`): a pixel
// that names one where another render names the other shows the same surface point, the tie
// between coincident faces falling another way (or the edge between two halves of a face).
bool same_plane(const SourceTriangles& reference, uint32_t a, uint32_t b, double tolerance) {
  const std::span<const Triangle> ta = reference.of(a), tb = reference.of(b);
  if (ta.empty() || tb.empty()) return false;
  const Vec3 normal = glm::cross(ta[0].v1 - ta[0].v0, ta[0].v2 - ta[0].v0);
  const double length = glm::length(normal);
  if (length == 0.0) return false;
  const Vec3 n = normal / length;
  for (const Vec3& v : {tb[0].v0, tb[0].v1, tb[0].v2}) {
    if (std::abs(glm::dot(n, v - ta[0].v0)) > tolerance) return false;
  }
  return true;
}

// % of pixels whose id differs between two renders of the same cameras; with `reference`,
// pixels whose two ids lie in one plane (same_plane) do not count.
double ids_differ_percent(const std::vector<IdRender>& a, const std::vector<IdRender>& b,
                          const SourceTriangles* reference = nullptr, double tolerance = 0.0) {
  uint64_t differ = 0, pixels = 0;
  for (size_t c = 0; c < std::min(a.size(), b.size()); ++c) {
    for (size_t i = 0; i < std::min(a[c].ids.size(), b[c].ids.size()); ++i) {
      const uint32_t x = a[c].ids[i], y = b[c].ids[i];
      if (x == y) continue;
      const bool tie = reference && x != kNoPrim && y != kNoPrim && same_plane(*reference, x, y, tolerance);
      differ += !tie;
    }
    pixels += a[c].ids.size();
  }
  return 100.0 * double(differ) / double(std::max<uint64_t>(pixels, 1));
}

// Renders the quant table.
int run_quant(const Options& o, const std::vector<Camera>& path, JsonLines& json) {
  double raw_build_s = 0;
  auto raw_path = ensure_store(o, {CellCodec::Raw, o.default_bits, o.default_cell_prims}, &raw_build_s);
  if (!raw_path) return fail(raw_path.status());
  auto raw = StoreModel::open(*raw_path);
  if (!raw) return fail(raw.status());
  const Aabb bounds = (*raw)->info().bounds;
  const double diagonal = glm::length(bounds.hi - bounds.lo);
  // Coincident faces of the model: float32 inputs put them within an ulp or so of each other.
  const double plane_tolerance = 1e-7 * diagonal;
  SourceTriangles reference;
  {
    auto pages = read_pages(**raw);
    if (!pages) return fail(pages.status());
    if (Status s = raw_triangles(**raw, *pages, reference); !s) return fail(s);
  }
  const std::vector<Camera> cameras = spread(path, o.quant_cameras);
  const WalkOptions render = walk_options(o, o.render_cache);
  auto raw_ids = render_ids(*raw_path, cameras, render);
  if (!raw_ids) return fail(raw_ids.status());
  double raw_render_ms = 0;
  for (const IdRender& r : *raw_ids) raw_render_ms += r.ms;
  // The control: the raw store rendered again must give the same ids.
  auto raw_again = render_ids(*raw_path, cameras, render);
  if (!raw_again) return fail(raw_again.status());
  const double raw_control = ids_differ_percent(*raw_ids, *raw_again);
  // The second control: a raw store with other cells. Exact geometry, another tree: what differs
  // is how ties (coplanar, coincident surfaces) fall, the floor under the quantized stores.
  auto raw_other = ensure_store(o, {CellCodec::Raw, o.default_bits, std::max<uint32_t>(1, o.default_cell_prims / 2)});
  if (!raw_other) return fail(raw_other.status());
  auto raw_other_ids = render_ids(*raw_other, cameras, render);
  if (!raw_other_ids) return fail(raw_other_ids.status());
  const double raw_tree_control = ids_differ_percent(*raw_ids, *raw_other_ids);
  const uint64_t raw_triangles = (*raw)->info().triangles;
  const uint64_t raw_bytes = file_bytes(*raw_path);

  fmt::print("\n## quant: lattice bits (Draco) against the raw store\n\n");
  fmt::print("model diagonal {:.3f}; raw store {:.1f} MB, {:.2f} bytes/triangle, {} triangles; {} cameras of {}×{}, "
             "complete frames with sync paging, cold cache; raw render {:.0f} ms; raw rendered again: {:.3f}% ids differ; raw store "
             "with cells of {} prims: {:.3f}% ids differ (controls).\n"
             "Error: per decoded vertex, the distance to its corner of the raw triangle with the same input id "
             "(best match over the id's triangles and corner rotations), over every stored triangle reference. "
             "Triangles dropped: fewer distinct triangles than raw (collapsed on the lattice). "
             "Ids differ, off-plane: not counting pixels whose two ids' raw triangles lie in one plane "
             "(within {:.2g}: coincident faces whose tie falls another way, or the halves of one face).\n\n",
             diagonal, double(raw_bytes) / 1e6, double(raw_bytes) / double(std::max<uint64_t>(raw_triangles, 1)),
             raw_triangles, cameras.size(), o.width, o.height, raw_render_ms, raw_control,
             std::max<uint32_t>(1, o.default_cell_prims / 2), raw_tree_control, plane_tolerance);
  fmt::print("| bits | step | build s | bytes/tri | triangles dropped | decode ms | decode MB/s | decode Mtri/s | "
             "max err | RMS err | max err/diag | max err/step | max axis err/step | ids differ % | off-plane % | render ms |\n");
  fmt::print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (const int bits : o.bits) {
    QuantPoint q;
    q.bits = bits;
    auto store = ensure_store(o, {CellCodec::Draco, bits, o.default_cell_prims}, &q.build_s);
    if (!store) return fail(store.status());
    auto model = StoreModel::open(*store);
    if (!model) return fail(model.status());
    const Lattice& lattice = (*model)->info().lattice;
    q.step = lattice.step;
    q.triangles = (*model)->info().triangles;
    q.store_bytes = file_bytes(*store);
    q.bytes_per_triangle = double(q.store_bytes) / double(std::max<uint64_t>(q.triangles, 1));
    auto pages = read_pages(**model);
    if (!pages) return fail(pages.status());
    Scene cell;
    double decode_s = 0, squared = 0;
    uint64_t decoded_triangles = 0;
    for (const store::OwnedPage& p : *pages) {
      const auto start = Clock::now();
      const Status s = decode_cell(p.payload, static_cast<CellCodec>(p.codec), lattice, cell);
      decode_s += ms_since(start) / 1000.0;
      if (!s) return fail(s);
      q.payload_bytes += p.payload.size();
      decoded_triangles += cell.triangles.size();
      for (const PrimRef& ref : cell.prims) {
        if (ref.kind != PrimKind::Triangle) continue;
        std::array<Vec3, 3> difference;
        q.vertices += 3;
        if (!match_corners(cell.triangles[ref.index], reference.of(ref.source), difference)) {
          q.unmatched += 3;
          continue;
        }
        for (const Vec3& d : difference) {
          const double d2 = glm::dot(d, d);
          squared += d2;
          q.max_error = std::max(q.max_error, std::sqrt(d2));
          const Vec3 a = glm::abs(d);
          q.max_axis_error = std::max({q.max_axis_error, a.x, a.y, a.z});
        }
      }
    }
    const uint64_t matched = q.vertices - q.unmatched;
    q.rms_error = matched ? std::sqrt(squared / double(matched)) : 0.0;
    q.decode_ms = decode_s * 1000.0;
    q.decode_mb_s = double(q.payload_bytes) / 1e6 / std::max(decode_s, 1e-9);
    q.decode_mtri_s = double(decoded_triangles) / 1e6 / std::max(decode_s, 1e-9);
    pages->clear();

    auto ids = render_ids(*store, cameras, render);
    if (!ids) return fail(ids.status());
    for (const IdRender& r : *ids) q.render_ms += r.ms;
    q.id_differ_percent = ids_differ_percent(*ids, *raw_ids);
    q.id_differ_geometric_percent = ids_differ_percent(*ids, *raw_ids, &reference, plane_tolerance);
    const uint64_t dropped = raw_triangles > q.triangles ? raw_triangles - q.triangles : 0;
    fmt::print("| {} | {:.3g} | {:.1f} | {:.2f} | {} | {:.0f} | {:.0f} | {:.2f} | {:.3g} | {:.3g} | {:.2g} | {:.3f} | "
               "{:.3f} | {:.3f} | {:.3f} | {:.0f} |\n",
               bits, q.step, q.build_s, q.bytes_per_triangle, dropped, q.decode_ms, q.decode_mb_s, q.decode_mtri_s,
               q.max_error, q.rms_error, q.max_error / diagonal, q.max_error / q.step, q.max_axis_error / q.step,
               q.id_differ_percent, q.id_differ_geometric_percent, q.render_ms);
    std::fflush(stdout);
    if (q.unmatched) fmt::print(stderr, "  bits {}: {} decoded vertices had no raw triangle of their id\n", bits, q.unmatched);
    json.write({{"knob", "quant_bits"},
                {"value", bits},
                {"lattice_step", q.step},
                {"build_s", q.build_s},
                {"store_bytes", q.store_bytes},
                {"triangles", q.triangles},
                {"triangles_dropped", dropped},
                {"bytes_per_triangle", q.bytes_per_triangle},
                {"payload_bytes", q.payload_bytes},
                {"decode_ms", q.decode_ms},
                {"decode_mb_s", q.decode_mb_s},
                {"decode_mtri_s", q.decode_mtri_s},
                {"max_error", q.max_error},
                {"rms_error", q.rms_error},
                {"max_axis_error", q.max_axis_error},
                {"model_diagonal", diagonal},
                {"max_error_rel_diagonal", q.max_error / diagonal},
                {"rms_error_rel_diagonal", q.rms_error / diagonal},
                {"vertices", q.vertices},
                {"unmatched_vertices", q.unmatched},
                {"cameras", cameras.size()},
                {"ids_differ_percent", q.id_differ_percent},
                {"ids_differ_off_plane_percent", q.id_differ_geometric_percent},
                {"render_ms", q.render_ms},
                {"raw_render_ms", raw_render_ms},
                {"raw_control_ids_differ_percent", raw_control},
                {"raw_other_cells_ids_differ_percent", raw_tree_control},
                {"raw_bytes_per_triangle", double(raw_bytes) / double(std::max<uint64_t>(raw_triangles, 1))}});
  }
  return 0;
}

// ---- samples -----------------------------------------------------------------------------

// --png-dir: the first camera's image and its confirmed pixels (white) for one budget.
void write_peg_pngs(const Options& o, Walkthrough& w, const std::string& name) {
  std::vector<Rgb> mask(w.buffer().size());
  for (size_t i = 0; i < mask.size(); ++i) {
    if (w.buffer().confirmed(i)) mask[i] = {1.0f, 1.0f, 1.0f};
  }
  for (const Status& s : {write_png(fmt::format("{}/peg-{}.png", o.png_dir, name), o.width, o.height, w.image()),
                          write_png(fmt::format("{}/confirmed-{}.png", o.png_dir, name), o.width, o.height, mask)}) {
    if (!s) fmt::print(stderr, "bench_accuracy: {}\n", s.to_string());
  }
}

struct PegPoint {
  ImageDiff diff;
  double frame_ms = 0, samples = 0, reconstruct_ms = 0;
  int complete = 0;
};

int run_samples(const Options& o, const std::vector<Camera>& path, JsonLines& json) {
  auto store = ensure_store(o, {CellCodec::Draco, o.default_bits, o.default_cell_prims});
  if (!store) return fail(store.status());
  const std::vector<Camera> cameras = spread(path, o.sample_cameras);
  auto opened = Walkthrough::open(*store, walk_options(o, o.render_cache));
  if (!opened) return fail(opened.status());
  Walkthrough& w = **opened;
  // Complete images three times: the first pass pages everything in (cold); the faster of the
  // two warm passes, per camera, is the complete frame time pegged frames are compared with.
  // Consecutive cameras differ, so every frame starts a new image.
  std::vector<std::vector<uint8_t>> reference;
  std::vector<double> warm(cameras.size(), kInfinity);
  double cold_ms = 0;
  for (int pass = 0; pass < 3; ++pass) {
    for (size_t c = 0; c < cameras.size(); ++c) {
      const FrameReport r = w.frame(cameras[c]);
      if (!r.complete) fmt::print(stderr, "  samples: reference frame {} not complete\n", c);
      if (pass == 0) {
        cold_ms += r.frame_ms;
        reference.push_back(rgb8(w.image()));
        if (c == 0 && !o.png_dir.empty()) write_peg_pngs(o, w, "complete");
      } else {
        warm[c] = std::min(warm[c], r.frame_ms);
      }
    }
  }
  double warm_ms = 0;
  for (const double ms : warm) warm_ms += ms;
  const double n = double(cameras.size());
  const uint64_t pixels = uint64_t(o.width) * uint64_t(o.height);
  const auto measure = [&](const FrameBudget& budget) {
    w.set_budget(budget);
    PegPoint p;
    for (size_t c = 0; c < cameras.size(); ++c) {
      const FrameReport r = w.frame(cameras[c]);
      p.diff.add(rgb8(w.image()), reference[c]);
      if (!o.png_dir.empty() && c == 0) write_peg_pngs(o, w, fmt::format("{}-{}", budget.samples ? "samples" : "ms",
                                                                           budget.samples ? double(budget.samples) : budget.ms));
      p.frame_ms += r.frame_ms / n;
      p.reconstruct_ms += r.reconstruct_ms / n;
      p.samples += double(r.samples) / n;
      p.complete += r.complete;
    }
    return p;
  };

  fmt::print("\n## samples: pegging against the complete image (warm cache, sync paging)\n\n");
  fmt::print("{} cameras of {}×{} ({} pixels); complete frame {:.1f} ms warm (faster of two), {:.1f} ms cold (paging in). "
             "PSNR of 8-bit RGB pooled over the cameras; equal = all three channels equal.\n\n",
             cameras.size(), o.width, o.height, pixels, warm_ms / n, cold_ms / n);
  fmt::print("| peg | value | samples | samples % | frame ms | of complete | reconstruct ms | PSNR dB | equal pixels % | complete |\n");
  fmt::print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  const auto row = [&](const std::string& knob, double value, const PegPoint& p) {
    fmt::print("| {} | {} | {:.0f} | {:.1f} | {:.1f} | {:.2f} | {:.2f} | {} | {:.2f} | {}/{} |\n", knob,
               knob == "samples" ? fmt::format("{:.0f}", value) : fmt::format("{:.0f} ms", value), p.samples,
               100.0 * p.samples / double(pixels), p.frame_ms, p.frame_ms / (warm_ms / n), p.reconstruct_ms,
               text_number(p.diff.psnr()), p.diff.equal_percent(), p.complete, cameras.size());
    std::fflush(stdout);
    json.write({{"knob", knob == "samples" ? "peg_samples" : "peg_ms"},
                {"value", value},
                {"samples", p.samples},
                {"samples_fraction", p.samples / double(pixels)},
                {"frame_ms", p.frame_ms},
                {"complete_frame_ms", warm_ms / n},
                {"reconstruct_ms", p.reconstruct_ms},
                {"psnr_db", json_number(p.diff.psnr())},
                {"equal_pixels_percent", p.diff.equal_percent()},
                {"complete_frames", p.complete},
                {"cameras", cameras.size()},
                {"pixels", pixels}});
  };
  for (const double f : o.sample_fractions) {
    const uint64_t samples = std::max<uint64_t>(1, uint64_t(std::llround(f * double(pixels))));
    row("samples", double(samples), measure({0.0, samples}));
  }
  for (const double ms : o.frame_ms) row("ms", ms, measure({ms, 0}));
  return 0;
}

// ---- walks: cells, refine, cache ---------------------------------------------------------

void print_walk_header(const std::string& knob) {
  fmt::print("| {} | frame ms | traversal ms | page-in ms | stall ms | KiB read/frame | cells touched | "
             "paged in/frame | evicted/frame | resident MiB | complete |\n",
             knob);
  fmt::print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
}

void print_walk_row(const std::string& value, const WalkSummary& s) {
  fmt::print("| {} | {:.1f} | {:.1f} | {:.2f} | {:.2f} | {:.2f} | {:.0f} | {:.1f} | {:.1f} | {} | {}/{} |\n", value,
             s.frame_ms, s.traversal_ms, s.page_in_ms, s.stall_ms, s.bytes_read / 1024.0, s.cells_touched,
             s.cells_paged_in, s.cells_evicted, mib(uint64_t(s.resident_bytes)), s.complete, s.frames);
  std::fflush(stdout);
}

int run_cells(const Options& o, const std::vector<Camera>& path, JsonLines& json) {
  const WalkOptions options = walk_options(o, o.walk_cache);
  std::vector<std::pair<uint32_t, WalkSummary>> rows;
  std::vector<nlohmann::json> stores;
  for (const uint32_t cells : o.cell_sizes) {
    double build_s = 0;
    auto store = ensure_store(o, {CellCodec::Draco, o.default_bits, cells}, &build_s);
    if (!store) return fail(store.status());
    auto model = StoreModel::open(*store);
    if (!model) return fail(model.status());
    uint64_t pages = 0;
    for (const StoreCell& c : (*model)->cells()) pages += c.page != StoreCell::kNoPage;
    auto s = walk(*store, path, o.walk_frames, o.walk_repeats, options);
    if (!s) return fail(s.status());
    rows.emplace_back(cells, *s);
    nlohmann::json j = s->to_json();
    j["knob"] = "store_cell_prims";
    j["value"] = cells;
    j["store_cells"] = (*model)->cells().size();
    j["pages"] = pages;
    j["mean_page_bytes"] = double(file_bytes(*store)) / double(std::max<uint64_t>(pages, 1));
    j["store_bytes"] = file_bytes(*store);
    j["build_s"] = build_s;
    j["cache_budget"] = options.cache_bytes;
    json.write(j);
    stores.push_back(j);
  }
  fmt::print("\n## cells: the store's cell size (builder --cell-prims)\n\n");
  fmt::print("{} frames of the path (best of {} walks), complete, sync paging, cold cache of {} MiB, {}×{}, Draco {} bits. Page-in = "
             "decode + refine + graft.\n\n",
             o.walk_frames, o.walk_repeats, mib(options.cache_bytes), o.width, o.height, o.default_bits);
  fmt::print("| cell prims | store cells | KiB/page | frame ms | traversal ms | page-in ms | stall ms | KiB read/frame | "
             "cells touched | paged in/frame | evicted/frame | resident MiB | complete |\n");
  fmt::print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (size_t i = 0; i < rows.size(); ++i) {
    const WalkSummary& s = rows[i].second;
    fmt::print("| {} | {} | {:.1f} | {:.1f} | {:.1f} | {:.2f} | {:.2f} | {:.2f} | {:.0f} | {:.1f} | {:.1f} | {} | {}/{} |\n",
               rows[i].first, stores[i]["store_cells"].get<uint64_t>(),
               stores[i]["mean_page_bytes"].get<double>() / 1024.0, s.frame_ms, s.traversal_ms, s.page_in_ms,
               s.stall_ms, s.bytes_read / 1024.0, s.cells_touched, s.cells_paged_in, s.cells_evicted,
               mib(uint64_t(s.resident_bytes)), s.complete, s.frames);
  }
  std::fflush(stdout);
  return 0;
}

int run_refine(const Options& o, const std::vector<Camera>& path, JsonLines& json) {
  auto store = ensure_store(o, {CellCodec::Draco, o.default_bits, o.default_cell_prims});
  if (!store) return fail(store.status());
  fmt::print("\n## refine: WalkOptions.cell_prims (refinement of a paged-in cell)\n\n");
  fmt::print("{} frames of the path (best of {} walks), complete, sync paging, cold cache of {} MiB, {}×{}, store cells of {} prims.\n\n",
             o.walk_frames, o.walk_repeats, mib(walk_options(o, o.walk_cache).cache_bytes), o.width, o.height, o.default_cell_prims);
  print_walk_header("cell prims");
  for (const uint32_t prims : o.refine_prims) {
    WalkOptions options = walk_options(o, o.walk_cache);
    options.cell_prims = prims;
    options.cell_build_from_store = false;
    auto s = walk(*store, path, o.walk_frames, o.walk_repeats, options);
    if (!s) return fail(s.status());
    print_walk_row(std::to_string(prims), *s);
    nlohmann::json j = s->to_json();
    j["knob"] = "refine_cell_prims";
    j["value"] = prims;
    j["cache_budget"] = options.cache_bytes;
    json.write(j);
  }
  return 0;
}

int run_cache(const Options& o, const std::vector<Camera>& path, JsonLines& json) {
  auto store = ensure_store(o, {CellCodec::Draco, o.default_bits, o.default_cell_prims});
  if (!store) return fail(store.status());
  fmt::print("\n## cache: WalkOptions.cache_bytes (one budget for pages and decoded cells)\n\n");
  fmt::print("{} frames of the path (best of {} walks), complete unless the budget is too small, sync paging, cold start, {}×{}, "
             "store {:.1f} MB.\n\n",
             o.walk_frames, o.walk_repeats, o.width, o.height, double(file_bytes(*store)) / 1e6);
  print_walk_header("budget");
  for (const std::string& cache : o.caches) {
    const WalkOptions options = walk_options(o, cache);
    auto s = walk(*store, path, o.walk_frames, o.walk_repeats, options);
    if (!s) return fail(s.status());
    print_walk_row(cache, *s);
    nlohmann::json j = s->to_json();
    j["knob"] = "cache_bytes";
    j["value"] = options.cache_bytes;
    json.write(j);
  }
  return 0;
}

// ---- sdf: the collision grid's voxel size -----------------------------------------------------

// The model's triangles bucketed in cubes of `cell`, for exact nearest-distance queries up to
// `cell` away (each triangle in every cube its bounds touch).
class TriangleBuckets {
 public:
  TriangleBuckets(const Scene& scene, double cell) : scene_(scene), cell_(cell) {
    for (uint32_t i = 0; i < scene.size(); ++i) {
      if (scene.prims[i].kind != PrimKind::Triangle) continue;
      const Aabb b = scene.prim_bounds(i);
      const auto lo = key_of(b.lo), hi = key_of(b.hi);
      for (int64_t x = lo[0]; x <= hi[0]; ++x) {
        for (int64_t y = lo[1]; y <= hi[1]; ++y) {
          for (int64_t z = lo[2]; z <= hi[2]; ++z) buckets_[pack({x, y, z})].push_back(scene.prims[i].index);
        }
      }
    }
  }
  // min(exact distance to the nearest triangle, limit); REQUIRES limit <= cell.
  double distance(const Vec3& p, double limit) const {
    double best = limit;
    const auto k = key_of(p);
    for (int64_t x = k[0] - 1; x <= k[0] + 1; ++x) {
      for (int64_t y = k[1] - 1; y <= k[1] + 1; ++y) {
        for (int64_t z = k[2] - 1; z <= k[2] + 1; ++z) {
          const auto it = buckets_.find(pack({x, y, z}));
          if (it == buckets_.end()) continue;
          for (uint32_t t : it->second) {
            const Triangle& tri = scene_.triangles[t];
            best = std::min(best, point_triangle_distance(p, tri.v0, tri.v1, tri.v2));
          }
        }
      }
    }
    return best;
  }

 private:
  std::array<int64_t, 3> key_of(const Vec3& p) const {
    return {int64_t(std::floor(p.x / cell_)), int64_t(std::floor(p.y / cell_)), int64_t(std::floor(p.z / cell_))};
  }
  static uint64_t pack(const std::array<int64_t, 3>& k) {
    return (uint64_t(k[0] & 0x1fffff) << 42) | (uint64_t(k[1] & 0x1fffff) << 21) | uint64_t(k[2] & 0x1fffff);
  }
  const Scene& scene_;
  double cell_;
  std::unordered_map<uint64_t, std::vector<uint32_t>> buckets_;
};

int run_sdf(const Options& o, const std::vector<Camera>&, JsonLines& json) {
  constexpr double kRadius = 0.25;  // frontier-build's default --walk-radius
  Scene scene;
  if (Status s = load_scene(o.model, scene); !s) return fail(s);
  double widest = 0.0;  // the widest band of the voxel sizes measured
  for (double h : o.sdf_voxels) widest = std::max(widest, h * WalkableGridBuilder::band_voxels_for_radius(kRadius, h));
  const TriangleBuckets buckets(scene, widest);
  // Points near the surfaces: a random point of a random triangle moved up to the widest band
  // in a random direction, and their exact distances (clamped per voxel size below).
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<Vec3> points;
  std::vector<double> exact;
  for (int i = 0; i < o.sdf_points; ++i) {
    const Triangle& t = scene.triangles[scene.prims[size_t(u(rng) * scene.size()) % scene.size()].index];
    double a = u(rng), b = u(rng);
    if (a + b > 1.0) a = 1.0 - a, b = 1.0 - b;
    const Vec3 dir = glm::normalize(Vec3(n(rng), n(rng), n(rng)));
    const Vec3 p = t.v0 + a * (t.v1 - t.v0) + b * (t.v2 - t.v0) + u(rng) * widest * dir;
    points.push_back(p);
    exact.push_back(buckets.distance(p, widest));
  }

  fmt::print("\n## sdf: the collision grid's voxel size (frontier-build --sdf-voxel)\n\n");
  fmt::print("{} points within {:.2f} of the surfaces; error = |distance() - min(exact, W)|; walk radius {}; "
             "grid build s = a --walkable build minus the same build without.\n\n",
             points.size(), widest, kRadius);
  fmt::print("| voxel | band (voxels) | grid build s | brick MB | active voxels | µs/query | max error | mean error | "
             "p99 error | max / voxel |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  const auto build = [&](double h, bool walkable, const std::string& out) -> Result<double> {
    BuildOptions b;
    b.inputs = {o.model};
    b.output = out;
    b.threads = o.threads;
    b.quiet = true;
    b.memory = parse_byte_size(o.memory).value_or(uint64_t{1} << 30);
    b.walkable = walkable;
    b.sdf_voxel = h;
    b.walk_radius = kRadius;
    const auto t = Clock::now();
    auto report = build_store(b);
    if (!report) return report.status();
    return ms_since(t) / 1000.0;
  };
  const std::string plain = o.dir + "/sdf-none.frontier";
  auto plain_s = build(0.0, false, plain);
  if (!plain_s) return fail(plain_s.status());
  for (double h : o.sdf_voxels) {
    const std::string out = fmt::format("{}/sdf-{}.frontier", o.dir, h);
    auto build_s = build(h, true, out);
    if (!build_s) return fail(build_s.status());
    auto model = StoreModel::open(out);
    if (!model) return fail(model.status());
    auto grid = open_collision_grid((*model)->reader(), uint64_t{1} << 40);
    if (!grid) return fail(grid.status());
    uint64_t brick_bytes = 0;
    for (uint64_t p : (*grid)->brick_pages()) brick_bytes += (*model)->reader().page_handle(p).size;
    const double w = (*grid)->band_width();
    for (const Vec3& p : points) (void)(*grid)->distance(p);  // every brick in memory first
    std::vector<double> errors;
    const auto t = Clock::now();
    for (size_t i = 0; i < points.size(); ++i) errors.push_back(std::abs((*grid)->distance(points[i]) - std::min(exact[i], w)));
    const double us = ms_since(t) * 1000.0 / double(points.size());
    std::sort(errors.begin(), errors.end());
    double mean = 0.0;
    for (double e : errors) mean += e;
    mean /= double(errors.size());
    const double max = errors.back(), p99 = errors[size_t(0.99 * double(errors.size() - 1))];
    const double grid_s = *build_s - *plain_s;
    fmt::print("| {} | {} | {:.1f} | {:.1f} | {} | {:.2f} | {:.4f} | {:.4f} | {:.4f} | {:.2f} |\n", h,
               (*grid)->band_voxels(), grid_s, double(brick_bytes) / 1e6, (*grid)->active_voxels(), us, max, mean, p99,
               max / h);
    json.write({{"knob", "sdf_voxel"},
                {"value", h},
                {"band_voxels", (*grid)->band_voxels()},
                {"grid_build_s", grid_s},
                {"brick_bytes", brick_bytes},
                {"active_voxels", (*grid)->active_voxels()},
                {"query_us", us},
                {"max_error", max},
                {"mean_error", mean},
                {"p99_error", p99}});
    std::error_code ec;
    std::filesystem::remove(out, ec);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_accuracy: what accuracy costs in time, one table per knob"};
  Options o;
  app.add_option("--model", o.model, "model file (a building PLY from frontier-gen)")->required();
  app.add_option("--path", o.path, "camera path (.cam)")->required();
  app.add_option("--dir", o.dir, "scratch directory for the stores")->required();
  app.add_option("--json", o.json_path, "one JSON object per measured point, one per line");
  app.add_option("--knobs", o.knobs, "quant, samples, cells, refine, cache, sdf (default: all but sdf)")->delimiter(',');
  app.add_option("--sdf-voxels", o.sdf_voxels, "sdf: collision grid voxel sizes")->delimiter(',');
  app.add_option("--sdf-points", o.sdf_points, "sdf: points where distance() is checked");
  app.add_option("--bits", o.bits, "quant: lattice bits")->delimiter(',');
  app.add_option("--cell-sizes", o.cell_sizes, "cells: builder cell prims")->delimiter(',');
  app.add_option("--refine-prims", o.refine_prims, "refine: WalkOptions.cell_prims")->delimiter(',');
  app.add_option("--caches", o.caches, "cache: budgets")->delimiter(',');
  app.add_option("--sample-fractions", o.sample_fractions, "samples: budgets as fractions of the pixels")->delimiter(',');
  app.add_option("--frame-ms", o.frame_ms, "samples: frame time budgets")->delimiter(',');
  app.add_option("--quant-cameras", o.quant_cameras, "quant: cameras rendered for the id comparison");
  app.add_option("--sample-cameras", o.sample_cameras, "samples: cameras per budget");
  app.add_option("--walk-frames", o.walk_frames, "cells, refine, cache: frames walked");
  app.add_option("--walk-repeats", o.walk_repeats, "cells, refine, cache: walks per point (the fastest is kept)");
  app.add_option("--walk-cache", o.walk_cache, "cells, refine: cache budget of the walks");
  app.add_option("--render-cache", o.render_cache, "quant, samples: cache budget of the renders");
  app.add_option("--bits-default", o.default_bits, "lattice bits of the stores other knobs use");
  app.add_option("--cell-prims-default", o.default_cell_prims, "cell prims of the stores other knobs use");
  app.add_option("--memory", o.memory, "build memory budget");
  app.add_option("--threads", o.threads, "build and render threads");
  app.add_option("--width", o.width, "image width");
  app.add_option("--height", o.height, "image height");
  app.add_option("--png-dir", o.png_dir, "samples: write the first camera's pegged images and confirmed pixels");
  app.add_flag("--reuse", o.reuse, "keep stores already in --dir (named by their options)");
  CLI11_PARSE(app, argc, argv);

  const auto bad_option = [](const std::string& what) {
    fmt::print(stderr, "bench_accuracy: {}\n", what);
    return 2;
  };
  const std::set<std::string> known = {"quant", "samples", "cells", "refine", "cache", "sdf"};
  for (const std::string& k : o.knobs) {
    if (!known.contains(k)) return bad_option(fmt::format("unknown knob '{}'", k));
  }
  for (const std::string& c : o.caches) {
    if (!parse_byte_size(c)) return bad_option(fmt::format("bad cache size '{}'", c));
  }
  for (const std::string& dir : {o.dir, o.png_dir}) {
    std::error_code ec;
    if (!dir.empty()) std::filesystem::create_directories(dir, ec);
    if (ec) return fail(Status::io_error(dir + ": " + ec.message()));
  }
  auto path = read_camera_path(o.path);
  if (!path) return fail(path.status());
  if (path->empty()) return fail(Status::invalid_argument(o.path + ": the path has no frames"));
  JsonLines json;
  if (!json.open(o.json_path)) return fail(Status::io_error(o.json_path + ": cannot write"));

  fmt::print("# bench_accuracy: {} ({} frames of {}), {} threads\n", o.model, path->size(), o.path, o.threads);
  const std::map<std::string, int (*)(const Options&, const std::vector<Camera>&, JsonLines&)> runs = {
      {"quant", run_quant}, {"samples", run_samples}, {"cells", run_cells},
      {"refine", run_refine}, {"cache", run_cache},     {"sdf", run_sdf}};
  for (const std::string& k : o.knobs) {
    const auto t = Clock::now();
    if (const int code = runs.at(k)(o, *path, json); code != 0) return code;
    fmt::print(stderr, "bench_accuracy: {} took {:.0f} s\n", k, ms_since(t) / 1000.0);
  }
  return 0;
}
