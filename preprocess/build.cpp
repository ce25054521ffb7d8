// The out-of-core store build (stages in build.h).
#include "preprocess/build.h"

#include "preprocess/spill.h"
#include "preprocess/temp_dir.h"
#include "preprocess/walkable_grid.h"
#include "src/engine/kdtree.h"
#include "src/io/load_scene.h"
#include "src/raster/portals.h"
#include "src/core/progress.h"
#include "src/io/scene_reader.h"
#include "src/codec/cell_tree.h"
#include "src/lod/proxy.h"
#include "src/paging/store_model.h"
#include "src/walk/walkthrough.h"
#include "src/core/tessellate.h"
#include "store/page_file.h"
#include "store/store_file.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <climits>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <thread>

#include <malloc.h>
#include <stdlib.h>

namespace frontier {
namespace {

namespace fs = std::filesystem;

constexpr size_t kBatch = 4096;            // records per spill read
constexpr size_t kSampleSize = 1 << 15;    // reservoir of primitive centres per file
constexpr size_t kPartBuffer = 1 << 20;    // spill buffer of each part being written
constexpr size_t kMaxFanOut = 64;          // parts written in one pass
constexpr size_t kEncodeChunk = 256;       // cells encoded in parallel before they are written

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// A uniform sample of at most `capacity` primitive centres (Vitter's algorithm R), deterministic.
class Reservoir {
 public:
  explicit Reservoir(uint64_t seed, size_t capacity = kSampleSize) : rng_(seed), capacity_(capacity) {}
  void offer(const Vec3& p) {
    ++seen_;
    if (points_.size() < capacity_) {
      points_.push_back(p);
      return;
    }
    const uint64_t k = std::uniform_int_distribution<uint64_t>(0, seen_ - 1)(rng_);
    if (k < capacity_) points_[k] = p;
  }
  std::vector<Vec3>& points() { return points_; }

 private:
  std::mt19937_64 rng_;
  size_t capacity_;
  std::vector<Vec3> points_;
  uint64_t seen_ = 0;
};

// Batches handed from a producer thread to the thread that consumes them, at most `depth` in
// flight: reading and parsing overlap with what is done with the primitives (two cores do both
// halves of a serial stage at once).
template <typename T>
class Handoff {
 public:
  explicit Handoff(size_t depth) : depth_(depth) {}

  // Producer: false when the consumer gave up (stop producing).
  bool push(T item) {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return queue_.size() < depth_ || cancelled_; });
    if (cancelled_) return false;
    queue_.push_back(std::move(item));
    changed_.notify_all();
    return true;
  }
  // Producer: no more items; `status` is why (ok: the input ended).
  void close(Status status) {
    std::lock_guard<std::mutex> lock(mutex_);
    status_ = std::move(status);
    closed_ = true;
    changed_.notify_all();
  }
  // Consumer: the next item, or false once the producer closed and everything was taken.
  bool pop(T& item) {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return !queue_.empty() || closed_; });
    if (queue_.empty()) return false;
    item = std::move(queue_.front());
    queue_.pop_front();
    changed_.notify_all();
    return true;
  }
  // Consumer: stop the producer (its next push returns false).
  void cancel() {
    std::lock_guard<std::mutex> lock(mutex_);
    cancelled_ = true;
    changed_.notify_all();
  }
  // After pop() returned false: the producer's status.
  Status status() {
    std::lock_guard<std::mutex> lock(mutex_);
    return status_;
  }

 private:
  const size_t depth_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<T> queue_;
  bool closed_ = false, cancelled_ = false;
  Status status_;
};

// Runs `produce(handoff)` on its own thread for the lifetime of this object; the destructor
// cancels the handoff and joins (a consumer that returns early never leaves the thread behind).
template <typename T>
class Producer {
 public:
  template <typename F>
  Producer(Handoff<T>& handoff, F produce)
      : handoff_(handoff), thread_([&handoff, produce = std::move(produce)]() mutable {
          handoff.close(produce(handoff));
        }) {}
  ~Producer() {
    handoff_.cancel();
    thread_.join();
  }
  Producer(const Producer&) = delete;
  Producer& operator=(const Producer&) = delete;

 private:
  Handoff<T>& handoff_;
  std::thread thread_;
};

// Runs `produce(handoff)` on a reader thread and `consume(item)` here on each item it hands
// over, so the two halves of a serial stage overlap. Returns the first error of either.
template <typename T, typename Produce, typename Consume>
Status overlap(Produce produce, Consume consume) {
  Handoff<T> handoff(4);
  Producer<T> producer(handoff, std::move(produce));
  T item;
  while (handoff.pop(item)) {
    if (Status s = consume(item); !s) return s;
  }
  return handoff.status();
}

// Zero-area triangles (after snapping to the lattice) are dropped like the readers drop them.
bool zero_area(const Triangle& t) {
  const Vec3 n = glm::cross(t.v1 - t.v0, t.v2 - t.v0);
  return !(glm::dot(n, n) > 0.0);
}

// Encodes a cell's (or a proxy's) primitives. Draco refuses cells spanning 2^24 lattice steps or
// more (its entropy coder's tables grow with the span; see cell_codec.h): such a page is stored
// raw, still on the lattice.
Result<EncodedCell> encode_page(const Scene& local, const CellCodecOptions& codec) {
  Result<EncodedCell> e = encode_cell(local, codec);
  if (!e && codec.codec == CellCodec::Draco && e.status().code() == Status::Code::InvalidArgument) {
    CellCodecOptions raw = codec;
    raw.codec = CellCodec::Raw;
    e = encode_cell(local, raw);
  }
  return e;
}

// A cell page with its in-cell tree in front (cell_tree.h): the tree frontier-view builds with
// `options` when it pages the cell in, built here on the cell as a reader decodes it. A tree that
// does not assemble back bit for bit (never seen) leaves the page without one: the viewer
// builds that cell's tree itself.
struct TreePage {
  std::vector<uint8_t> payload;
  uint8_t codec = 0;
  uint64_t tree_bytes = 0;  // 0: no tree
};
TreePage with_cell_tree(const EncodedCell& e, const Aabb& region, KdBuildOptions options) {
  TreePage page{e.payload, static_cast<uint8_t>(e.codec), 0};
  options.root = region;
  auto tree = encode_cell_tree(e.decoded, KdTree::build(e.decoded, options), options);
  if (!tree) return page;
  page.payload = join_tree_page(*tree, e.payload);
  page.codec |= kCellTreeFlag;
  page.tree_bytes = tree->size();
  return page;
}

// A node's proxy is simplified from its descendants this many levels down (leaves above that
// stand for themselves), merged: simplifying the children's proxies instead compounds the error
// level by level (and widens the slits between them into holes), so that a 20 M terrain's root
// proxy lay 215 from the original on a height range of 82. The memory is a few proxies per node
// of the path being built.
constexpr size_t kProxyInputLevels = 3;
// A subtree's meshes by level below its root: [0] the root's (its proxy, or a leaf's input),
// [j] those j levels below (a leaf shallower than that standing for itself), shared, not copied.
using MeshLevels = std::array<std::vector<std::shared_ptr<const ProxyMesh>>, kProxyInputLevels>;

// A proxy page made on a worker thread, written by the builder's thread afterwards.
struct PendingProxyPage {
  std::optional<Result<EncodedCell>> page;  // none: a leaf, or a subtree without triangles
  StoreProxy record;
  bool shell = false;
  bool sloppy = false;
  std::vector<uint8_t> tree;  // the proxy's tree (cell_tree.h), empty: none
};

// A file of primitives that still has to be turned into cells.
struct Part {
  std::string path;      // its spill file; empty when the part is the inputs themselves
  uint64_t bytes = 0;    // the spill file's size
  Aabb region;
  uint64_t count = 0;
  std::vector<Vec3> sample;
  bool snapped = false;  // written by distribute(): triangles already on the lattice
};

// A batch of parsed input primitives and the input bytes it took.
struct IngestBatch {
  Scene scene;
  uint64_t bytes = 0;
};

// The upper levels of the tree planned from a sample: median splits on the longest axis.
struct PlanNode {
  int axis = -1;                // -1: leaf
  double split = 0.0;
  int lower = -1, upper = -1;   // plan node indices
  int part = -1;                // leaf: index into the parts being written
  Aabb region;
};

class StoreBuilder {
 public:
  explicit StoreBuilder(const BuildOptions& options) : options_(options) {}

  Result<BuildReport> run() {
    const auto start = std::chrono::steady_clock::now();
    if (Status s = check_options(); !s) return s;
    if (Status s = check_inputs(); !s) return s;
    if (Status s = read_portals(); !s) return s;
    if (Status s = open_temporaries(); !s) return s;
    if (Status s = check_disk_space(); !s) return s;
    const int threads = options_.threads > 0 ? options_.threads : static_cast<int>(tbb::task_arena::automatic);
    arena_.emplace(threads);

    auto t = std::chrono::steady_clock::now();
    Part root;
    if (Status s = ingest(root); !s) return s;
    report_.ingest_seconds = seconds_since(t);

    if (options_.walkable) {
      const double voxel = options_.sdf_voxel > 0.0 ? options_.sdf_voxel : WalkableGridBuilder::default_voxel_size(bounds_);
      const int band = WalkableGridBuilder::band_voxels_for_radius(options_.walk_radius, voxel);
      if (Status s = WalkableGridBuilder::check_options(voxel, band); !s) return s;
      grid_.emplace(voxel, band, temp_->path());
      info_.sdf_voxel = voxel;
      info_.walk_radius = options_.walk_radius;
    }
    root_count_ = root.count;
    build_progress_.emplace("build", "primitives", root.count, options_.quiet);
    if (Status s = process(std::move(root), 0); !s) return s;
    build_progress_->finish();

    if (Status s = finish(); !s) return s;
    report_.seconds = seconds_since(start);
    return report_;
  }

 private:
  Status check_options() const {
    if (options_.inputs.empty()) return Status::invalid_argument("no input files");
    if (options_.output.empty()) return Status::invalid_argument("no output file (-o)");
    if (options_.quant_bits < 8 || options_.quant_bits > 30) {
      return Status::invalid_argument(fmt::format("--quant-bits {}: must be 8..30", options_.quant_bits));
    }
    if (options_.cell_prims < 1) return Status::invalid_argument("--cell-prims must be at least 1");
    if (const CellCodec proxies = proxy_codec(options_);
        cell_codec_on_lattice(proxies) && !cell_codec_on_lattice(options_.codec)) {
      return Status::invalid_argument(fmt::format("--proxy-codec {} needs a lattice: not with --codec {}",
                                                  cell_codec_name(proxies), cell_codec_name(options_.codec)));
    }
    if (options_.memory < (uint64_t{16} << 20)) {
      return Status::invalid_argument(fmt::format("--memory {}: at least 16M is needed", options_.memory));
    }
    if (options_.threads < 0) return Status::invalid_argument("--threads must be >= 0");
    if (!options_.tmp_dir.empty()) {
      if (Status s = check_temp_dir(options_.tmp_dir, "--tmp-dir"); !s) return s;
    }
    if (options_.walkable && !(options_.walk_radius > 0.0 && std::isfinite(options_.walk_radius))) {
      return Status::invalid_argument("--walk-radius must be positive");
    }
    if (options_.walkable && options_.sdf_voxel != 0.0) {
      if (Status s = WalkableGridBuilder::check_options(options_.sdf_voxel, WalkableGridBuilder::kDefaultBandVoxels); !s) {
        return s;
      }
    }
    for (const std::string& in : options_.inputs) {
      if (fs::exists(in) && fs::exists(options_.output) && fs::equivalent(in, options_.output)) {
        return Status::invalid_argument(fmt::format("{}: the output would overwrite an input", in));
      }
    }
    return Status::ok();
  }

  // Every input opens as a model (a file, not a directory; a known extension; a sound header)
  // before anything is made on disk: NotFound or Corruption naming the file, exit 1.
  Status check_inputs() const {
    for (const std::string& in : options_.inputs) {
      if (auto reader = open_scene_reader(in); !reader) return reader.status();
    }
    return Status::ok();
  }

  // The first pass hands each input's new warnings (scene_reader.h) to stderr and the report,
  // so each is told once although binary inputs are parsed twice.
  void report_warnings(const SceneReader& reader, size_t& reported) {
    const std::vector<std::string>& w = reader.warnings();
    for (; reported < w.size(); ++reported) {
      std::fprintf(stderr, "warning: %s\n", w[reported].c_str());
      report_.warnings.push_back(w[reported]);
    }
  }

  std::string output_dir() const {
    const fs::path out(options_.output);
    return out.has_parent_path() ? out.parent_path().string() : std::string(".");
  }

  // The temporary directory (--tmp-dir, else beside the output) and OUT.tmp, both locked for the
  // build's life, after removing what dead builds left there (said on stderr, even when quiet).
  Status open_temporaries() {
    std::vector<Leftover> removed;
    const std::string out_dir = output_dir();
    if (!options_.tmp_dir.empty()) remove_dead_temp_dirs(out_dir, removed);  // from builds without it
    auto temp = BuildTempDir::create(options_.tmp_dir.empty() ? out_dir : options_.tmp_dir, options_.output, removed);
    if (!temp) return temp.status();
    temp_.emplace(std::move(*temp));
    auto staging = StagingLock::claim(options_.output, removed);
    for (const Leftover& l : removed) std::fprintf(stderr, "frontier-build: %s\n", describe(l).c_str());
    if (!staging) return staging.status();
    staging_.emplace(std::move(*staging));
    auto writer = store::StoreWriter::create(fsys_, options_.output);
    if (!writer) {
      ::unlink((options_.output + ".tmp").c_str());  // ours: claimed above
      return writer.status();
    }
    writer_ = std::move(*writer);
    return Status::ok();
  }

  // Decides whether the inputs are parsed again instead of spilled, and fails at once when the
  // temporary folder cannot hold what the build will write there: the spill files and, on the
  // same file system, the store; estimated from the primitives the inputs declare (or, for
  // formats that declare none, their sizes).
  Status check_disk_space() {
    constexpr uint64_t kTextBytesPerPrimitive = 24, kStoreBytesDraco = 4, kStoreBytesRaw = 80;
    uint64_t primitives = 0;
    bool binary = true;
    for (const std::string& in : options_.inputs) {
      auto reader = open_scene_reader(in);
      if (!reader) continue;  // reported by the ingest pass
      const int64_t declared = (*reader)->declared_primitives();
      primitives += declared >= 0 ? static_cast<uint64_t>(declared) : (*reader)->bytes_total() / kTextBytesPerPrimitive;
      binary = binary && (*reader)->binary();
    }
    reparse_ = options_.reparse_binary_ply && binary;
    const bool draco = cell_codec_on_lattice(options_.codec);  // Draco or meshopt
    uint64_t needed = reparse_ ? 0 : primitives * kSpillBytesPerExactPrimitive;
    if (primitives > capacity()) {  // parts, straddlers included
      needed += primitives * 6 / 5 * (draco ? kSpillBytesPerLatticeTriangle : kSpillBytesPerExactPrimitive);
    }
    const bool with_store = same_file_system(temp_->path(), output_dir());
    if (with_store) needed += primitives * (draco ? kStoreBytesDraco : kStoreBytesRaw);
    return check_free_space(fs::path(temp_->path()).parent_path().string(), needed,
                            with_store ? "the build's temporary files and the store" : "the build's temporary files");
  }

  // The cells and portals of the single input's sidecar, kept serialized until the end. Rooms
  // and portals describe one model: with several inputs the store is no longer that model.
  Status read_portals() {
    if (!options_.portals || options_.inputs.size() != 1) return Status::ok();
    const std::string sidecar = fs::path(options_.inputs[0]).replace_extension(".json").string();
    auto graph = PortalGraph::from_sidecar(sidecar);
    if (!graph) return graph.status().code() == Status::Code::NotFound ? Status::ok() : graph.status();
    portals_ = graph->serialize();
    report_.portals_sidecar = sidecar;
    report_.portal_rooms = graph->room_count();
    report_.portals = graph->portal_count();
    return Status::ok();
  }

  // Stage 1: bounds and a sample of every input, and, unless the inputs are cheap to read
  // again, one spill file of all primitives (the root part). Binary PLY is parsed again by the
  // first partition pass instead: at 20 M triangles that is 1.7 GB not written and not read
  // back, for a second parse of 0.4 GB.
  Status ingest(Part& root) {
    SpillWriter out;
    if (!reparse_) {
      root.path = temp_->file("ingest");
      if (Status s = out.open(root.path); !s) return s;
    }
    Reservoir sample(0x5eed);
    uint64_t total_bytes = 0;
    for (const std::string& in : options_.inputs) {
      std::error_code ec;
      total_bytes += fs::file_size(in, ec);
    }
    report_.input_bytes = total_bytes;
    Progress progress("read", "bytes", total_bytes, options_.quiet);
    // This thread keeps the bounds and the sample and writes the spill file while the producer
    // parses the next batch.
    const Status read = overlap<IngestBatch>(
        [this](Handoff<IngestBatch>& to) { return read_inputs(to); },
        [&](const IngestBatch& item) {
          const Scene& batch = item.scene;
          for (uint32_t i = 0; i < batch.size(); ++i) {
            const Aabb b = batch.prim_bounds(i);
            bounds_.extend(b);
            sample.offer(b.center());
            if (reparse_) continue;
            if (Status s = out.write(batch, i); !s) return s;
          }
          report_.degenerate_dropped += batch.degenerate_dropped;
          report_.primitives += batch.size();
          report_.triangles += batch.triangles.size();
          progress.advance(item.bytes);
          return Status::ok();
        });
    if (!read) return read;
    progress.finish();
    if (report_.primitives == 0) {
      std::string inputs;
      for (const std::string& in : options_.inputs) inputs += (inputs.empty() ? "" : ", ") + in;
      return no_primitives_error(inputs, report_.input_primitives);
    }
    if (!reparse_) {
      if (Status s = out.close(); !s) return s;
      root.bytes = out.bytes();
      spilled(root.bytes);
    }
    if (bounds_.empty()) bounds_ = Aabb(Vec3(-1.0), Vec3(1.0));  // an empty model still makes a store
    if (cell_codec_on_lattice(options_.codec)) lattice_ = Lattice::covering(bounds_, options_.quant_bits);
    proxy_options_.target_triangles = options_.proxy_triangles;
    if (cell_codec_on_lattice(options_.codec)) proxy_options_.lattice = lattice_;
    const double slack = cell_codec_on_lattice(options_.codec) ? lattice_.step : 0.0;
    root.region = KdTree::root_bounds(bounds_, slack);
    root_region_ = root.region;
    root.count = reparse_ ? report_.primitives : out.records();
    root.sample = std::move(sample.points());
    return Status::ok();
  }

  // Ingest's producer (its own thread): parses every input into batches of kBatch primitives
  // (tessellated when asked) and records what the inputs declare (materials, lights, camera).
  Status read_inputs(Handoff<IngestBatch>& to) {
    return parse_inputs(true, [&to](Scene&& batch, uint64_t bytes) { return to.push({std::move(batch), bytes}); });
  }

  // Parses every input into batches handed to `push` (false: stop, cancelled). The first pass
  // records what the inputs declare; a later pass (the root part read again) must yield the
  // same primitives, or the inputs changed under the build.
  template <typename Push>
  Status parse_inputs(bool first, const Push& push) {
    uint64_t source_base = 0;
    Scene batch;
    InputPrimitive prim;
    for (size_t k = 0; k < options_.inputs.size(); ++k) {
      const std::string& in = options_.inputs[k];
      auto opened = open_scene_reader(in);
      if (!opened) return opened.status();
      SceneReader& reader = **opened;
      size_t warned = 0;
      if (first) report_warnings(reader, warned);
      // Each input's materials follow the previous inputs' (the first pass appends them).
      if (first) material_bases_.push_back(static_cast<uint32_t>(info_.materials.size()));
      const uint32_t material_base = material_bases_[k];
      SceneBuilder builder(batch);
      uint64_t local = 0, last_bytes = 0;
      for (;;) {
        bool end = false;
        if (Status s = reader.next(prim, end); !s) {
          if (first) report_warnings(reader, warned);
          return s;
        }
        if (!end) {
          if (source_base + local >= UINT32_MAX) {
            return Status::unsupported(fmt::format("{}: more than {} primitives in all inputs", in, UINT32_MAX - 1));
          }
          prim.material += material_base;
          builder.add(prim, static_cast<uint32_t>(source_base + local));
          ++local;
        }
        if (batch.size() >= kBatch || (end && batch.size() > 0)) {
          if (options_.tessellate > 0 && batch.triangles.size() < batch.size()) {
            TessellateOptions t;
            t.segments = options_.tessellate;
            batch = tessellate(batch, t);  // keeps the batch's degenerate count, adds its own
          }
          const uint64_t now = reader.bytes_read();
          if (!push(std::move(batch), now - std::min(now, last_bytes))) return Status::ok();  // cancelled
          batch = Scene{};
          last_bytes = now;
        }
        if (end) break;
      }
      source_base += local;
      if (!first) continue;
      report_warnings(reader, warned);
      // One rule for every format: a file with nothing in it is bad input, not an empty store.
      if (local == 0) return no_primitives_error(in, 0);
      const SceneHeader& h = reader.header();
      info_.materials.insert(info_.materials.end(), h.materials.begin(), h.materials.end());
      if (info_.materials.size() == material_base) info_.materials.emplace_back();  // meshes: one default
      info_.lights.insert(info_.lights.end(), h.lights.begin(), h.lights.end());
      if (!info_.camera && h.camera) {
        info_.camera = h.camera;
        info_.background = h.background;
      }
      info_.inputs.push_back(fs::path(in).filename().string());
    }
    if (first) {
      report_.input_primitives = source_base;
    } else if (source_base != report_.input_primitives) {
      return Status::io_error(fmt::format("{}: the inputs changed during the build ({} primitives read first, {} now)",
                                          options_.inputs.front(), report_.input_primitives, source_base));
    }
    return Status::ok();
  }

  // Most primitives of one part in core: the budget less the store's tree, cell table and page
  // handles, held until the end (where no part is in core and their sections take as much
  // again); at least four cells' worth.
  uint64_t capacity() const {
    if (options_.part_primitives > 0) return options_.part_primitives;
    const uint64_t tables = cells_.capacity() * sizeof(StoreCell) + nodes_.capacity() * sizeof(KdTree::Node) +
                            proxies_.capacity() * sizeof(StoreProxy) +
                            2 * (report_.pages + report_.proxy_pages) * sizeof(store::Handle);
    const uint64_t free = options_.memory - std::min(options_.memory, tables);
    return std::max<uint64_t>(free / kBytesPerPrimitive, 4ull * options_.cell_prims);
  }

  // Plans median splits of `part` from its sample until every leaf's estimate fits.
  std::vector<PlanNode> plan(const Part& part) const {
    std::vector<PlanNode> nodes;
    const double per_sample = static_cast<double>(part.count) / std::max<double>(1.0, part.sample.size());
    std::vector<Vec3> sample = part.sample;
    struct Todo {
      int node;
      size_t begin, end;
    };
    nodes.push_back({-1, 0.0, -1, -1, -1, part.region});
    std::vector<Todo> todo{{0, 0, sample.size()}};
    size_t leaves = 1;
    while (!todo.empty()) {
      const Todo t = todo.back();
      todo.pop_back();
      const Aabb region = nodes[t.node].region;
      // Straddling primitives are written to both sides: estimate 15 % on top.
      const double estimate = 1.15 * per_sample * static_cast<double>(t.end - t.begin);
      if (estimate <= 0.7 * static_cast<double>(capacity()) || t.end - t.begin < 64 || leaves >= kMaxFanOut) continue;
      const Vec3 e = region.extent();
      const int axis = e.x >= e.y && e.x >= e.z ? 0 : (e.y >= e.z ? 1 : 2);
      const size_t mid = t.begin + (t.end - t.begin) / 2;
      std::nth_element(sample.begin() + static_cast<ptrdiff_t>(t.begin), sample.begin() + static_cast<ptrdiff_t>(mid),
                       sample.begin() + static_cast<ptrdiff_t>(t.end),
                       [axis](const Vec3& a, const Vec3& b) { return a[axis] < b[axis]; });
      double split = sample[mid][axis];
      if (!(split > region.lo[axis] && split < region.hi[axis])) split = region.center()[axis];
      Aabb lo = region, hi = region;
      lo.hi[axis] = split;
      hi.lo[axis] = split;
      const int l = static_cast<int>(nodes.size());
      nodes.push_back({-1, 0.0, -1, -1, -1, lo});
      nodes.push_back({-1, 0.0, -1, -1, -1, hi});
      nodes[t.node].axis = axis;
      nodes[t.node].split = split;
      nodes[t.node].lower = l;
      nodes[t.node].upper = l + 1;
      ++leaves;
      size_t cut = t.begin;  // points on the lower side first
      for (size_t i = t.begin; i < t.end; ++i) {
        if (sample[i][axis] < split) std::swap(sample[i], sample[cut++]);
      }
      todo.push_back({l, t.begin, cut});
      todo.push_back({l + 1, cut, t.end});
    }
    return nodes;
  }

  // Turns a part into cells: in core when it fits, else split on disk first.
  Status process(Part part, uint32_t depth) {
    if (part.count <= capacity() || depth >= 16) return build_in_core(part, depth);
    std::vector<PlanNode> nodes = plan(part);
    std::vector<Vec3>().swap(part.sample);  // planned: not needed while the parts are built
    if (nodes.size() == 1) return build_in_core(part, depth);
    std::vector<Part> parts;
    if (Status s = distribute(part, nodes, parts); !s) return s;
    // A split that separated nothing (everything straddles) would recurse forever.
    bool progress = false;
    for (const Part& p : parts) progress |= p.count < part.count;
    remove_spill(part);
    return emit(nodes, 0, parts, depth, progress);
  }

  // Appends the plan's node `n` (preorder) and builds its leaves.
  Status emit(const std::vector<PlanNode>& nodes, int n, std::vector<Part>& parts, uint32_t depth, bool progress) {
    const PlanNode& p = nodes[static_cast<size_t>(n)];
    if (p.axis < 0) {
      Part& part = parts[static_cast<size_t>(p.part)];
      return progress ? process(std::move(part), depth) : build_in_core(part, depth);
    }
    const size_t index = nodes_.size();
    nodes_.push_back({});
    if (Status s = emit(nodes, p.lower, parts, depth + 1, progress); !s) return s;
    const auto upper = static_cast<uint32_t>(nodes_.size());
    if (Status s = emit(nodes, p.upper, parts, depth + 1, progress); !s) return s;
    nodes_[index] = {p.split, static_cast<uint32_t>(p.axis), upper};
    if (options_.proxy_triangles > 0) return merge_pending(static_cast<uint32_t>(index), p.region);
    return Status::ok();
  }

  // Stage 3: one pass writes every primitive of `part` to each planned leaf it overlaps.
  Status distribute(const Part& part, std::vector<PlanNode>& nodes, std::vector<Part>& parts) {
    std::vector<std::unique_ptr<SpillWriter>> writers;
    std::vector<Reservoir> samples;
    // The part buffers together take at most a quarter of the budget, their samples an eighth
    // (a 1G budget keeps full samples).
    size_t leaves = 0;
    for (const PlanNode& n : nodes) leaves += n.axis < 0 ? 1 : 0;
    leaves = std::max<size_t>(leaves, 1);
    const size_t buffer = std::clamp<size_t>(options_.memory / 4 / leaves, 64 << 10, kPartBuffer);
    const size_t sample_size = std::clamp<size_t>(options_.memory / 8 / sizeof(Vec3) / leaves, 1024, kSampleSize);
    for (PlanNode& n : nodes) {
      if (n.axis >= 0) continue;
      n.part = static_cast<int>(parts.size());
      Part p;
      p.path = temp_->file(fmt::format("part-{}", next_file_++));
      p.region = n.region;
      p.snapped = true;
      parts.push_back(std::move(p));
      writers.push_back(std::make_unique<SpillWriter>(buffer));
      if (Status s = writers.back()->open(parts.back().path, spill_lattice(parts.back())); !s) return s;
      samples.emplace_back(0x5eed + parts.size(), sample_size);
    }
    const auto t = std::chrono::steady_clock::now();
    const double scale = glm::length(part.region.extent());
    const double eps = 2e-9 * scale + 1e-12 * std::max(1.0, part.region.magnitude());
    std::vector<int> stack;
    Progress progress("partition", "primitives", part.count, options_.quiet);
    // The producer reads (and snaps) the next batch while this thread sorts one into the parts.
    const Status sorted = overlap<Scene>(
        [this, &part](Handoff<Scene>& to) { return read_part(part, to); },
        [&](const Scene& batch) {
          for (uint32_t i = 0; i < batch.size(); ++i) {
            Aabb b = batch.prim_bounds(i);
            if (b.empty()) continue;  // dropped by snapping
            b.lo -= Vec3(eps);
            b.hi += Vec3(eps);
            stack.assign(1, 0);
            while (!stack.empty()) {
              const PlanNode& n = nodes[static_cast<size_t>(stack.back())];
              stack.pop_back();
              if (n.axis < 0) {
                const auto k = static_cast<size_t>(n.part);
                if (Status s = writers[k]->write(batch, i); !s) return s;
                samples[k].offer(b.center());
                continue;
              }
              if (b.lo[n.axis] <= n.split) stack.push_back(n.lower);
              if (b.hi[n.axis] >= n.split) stack.push_back(n.upper);
            }
          }
          progress.advance(batch.size());
          return Status::ok();
        });
    if (!sorted) return sorted;
    progress.finish();
    for (size_t k = 0; k < parts.size(); ++k) {
      if (Status s = writers[k]->close(); !s) return s;
      parts[k].count = writers[k]->records();
      // Only a part that is split again is planned from its sample.
      if (parts[k].count > capacity()) parts[k].sample = std::move(samples[k].points());
      samples[k] = Reservoir(0);
      parts[k].bytes = writers[k]->bytes();
      spilled(parts[k].bytes);
    }
    report_.spill_seconds += seconds_since(t);
    return Status::ok();
  }

  // Reads a part's spill file in batches into `to` (a producer), snapped to the lattice unless
  // it already is.
  Status read_part(const Part& part, Handoff<Scene>& to) {
    if (part.path.empty()) {  // the root part: the inputs, parsed again
      return parse_inputs(false, [&](Scene&& batch, uint64_t) {
        snap(batch);
        return to.push(std::move(batch));
      });
    }
    SpillReader in;
    if (Status s = in.open(part.path, spill_lattice(part)); !s) return s;
    for (bool end = false; !end;) {
      Scene batch;
      if (Status s = in.read(batch, kBatch, end); !s) return s;
      if (!part.snapped) snap(batch);  // snapping is idempotent: parts are snapped once
      if (!to.push(std::move(batch))) return Status::ok();  // cancelled
    }
    return Status::ok();
  }

  // Spill files on disk: the report's total and peak.
  void spilled(uint64_t bytes) {
    report_.spill_bytes += bytes;
    spill_on_disk_ += bytes;
    report_.spill_peak_bytes = std::max(report_.spill_peak_bytes, spill_on_disk_);
  }
  void remove_spill(const Part& part) {
    if (part.path.empty()) return;
    std::error_code ec;
    fs::remove(part.path, ec);
    spill_on_disk_ -= std::min(spill_on_disk_, part.bytes);
  }

  // The lattice a part's spill file stores positions on: the store's, once snapped to it.
  std::optional<Lattice> spill_lattice(const Part& part) const {
    return part.snapped && cell_codec_on_lattice(options_.codec) ? std::optional<Lattice>(lattice_) : std::nullopt;
  }

  // Snaps triangles to the lattice (Draco, meshopt) and drops those that lose their area; spheres and
  // other shapes are stored exactly.
  void snap(Scene& batch) {
    if (!cell_codec_on_lattice(options_.codec) || batch.triangles.empty()) return;
    Scene kept;
    kept.triangle_normals.reserve(batch.triangle_normals.size());
    for (uint32_t i = 0; i < batch.size(); ++i) {
      const PrimRef& p = batch.prims[i];
      if (p.kind != PrimKind::Triangle) {
        kept.add_from(batch, i);
        continue;
      }
      const Triangle& t = batch.triangles[p.index];
      const Triangle s{lattice_.snap(t.v0), lattice_.snap(t.v1), lattice_.snap(t.v2)};
      if (zero_area(s)) {
        ++snapped_away_;
        continue;
      }
      kept.add_triangle(s, p.source, p.material,
                        batch.triangle_normals.empty() ? nullptr : &batch.triangle_normals[p.index]);
    }
    batch = std::move(kept);
  }

  // Stage 4: one part in core -> cells -> pages.
  Status build_in_core(const Part& part, uint32_t depth) {
    auto t = std::chrono::steady_clock::now();
    Scene scene;
    // Sized once (most parts are triangles; untouched capacity costs address space only).
    scene.prims.reserve(part.count);
    scene.triangles.reserve(part.count);
    const Status loaded = overlap<Scene>([this, &part](Handoff<Scene>& to) { return read_part(part, to); },
                                         [&](const Scene& batch) {
                                           for (uint32_t i = 0; i < batch.size(); ++i) scene.add_from(batch, i);
                                           return Status::ok();
                                         });
    if (!loaded) return loaded;
    remove_spill(part);
    ++report_.parts;

    KdBuildOptions kd;
    kd.max_cell_prims = options_.cell_prims;
    kd.min_cell_prims = options_.cell_prims;
    kd.forced_split_max_share = 1.0;  // pages hold at most --cell-prims wherever a plane separates
    kd.root = part.region;
    const KdTree tree = KdTree::build(scene, kd);
    report_.build_seconds += seconds_since(t);
    report_.depth = std::max(report_.depth, depth + tree.depth());

    if (grid_) {
      if (Status s = grid_->add_partition(scene, part.region); !s) return s;
    }

    // Graft the part's tree: its node and cell indices move by what precedes them.
    const auto node_base = static_cast<uint32_t>(nodes_.size());
    const auto cell_base = static_cast<uint32_t>(cells_.size());
    for (KdTree::Node n : tree.nodes()) {
      n.child += n.is_leaf() ? cell_base : node_base;
      nodes_.push_back(n);
    }

    t = std::chrono::steady_clock::now();
    const auto& cells = tree.cells();
    const CellCodecOptions codec = codec_options();
    std::vector<Result<EncodedCell>> encoded;
    std::vector<uint32_t> references;
    std::vector<TreePage> tree_pages;
    for (size_t first = 0; first < cells.size(); first += kEncodeChunk) {
      const size_t last = std::min(cells.size(), first + kEncodeChunk);
      encoded.assign(last - first, Result<EncodedCell>(Status::ok()));
      references.assign(last - first, 0);
      tree_pages.assign(options_.cell_trees ? last - first : 0, TreePage{});
      arena_->execute([&] {
        tbb::parallel_for(first, last, [&](size_t c) {
          const KdTree::Cell& cell = cells[c];
          if (cell.count == 0) return;
          Scene local;
          for (uint32_t r = cell.first; r < cell.first + cell.count; ++r) local.add_from(scene, tree.ref(r));
          Result<EncodedCell> e = encode_page(local, codec);
          if (e) {  // only the count of the decoded cell is needed: 256 of them would be megabytes
            references[c - first] = static_cast<uint32_t>(e->decoded.size());
            if (options_.cell_trees && e->decoded.size() > 0) {
              tree_pages[c - first] = with_cell_tree(*e, cell.bounds, cell_tree_options_);
              e->payload.clear();
            }
            e->decoded = Scene{};
          }
          encoded[c - first] = std::move(e);
        });
      });
      for (size_t c = first; c < last; ++c) {
        StoreCell record;
        record.bounds = cells[c].bounds;
        record.content = cells[c].content;
        if (cells[c].count > 0) {
          Result<EncodedCell>& e = encoded[c - first];
          if (!e) return e.status();
          const TreePage* with_tree = options_.cell_trees && !tree_pages[c - first].payload.empty()
                                          ? &tree_pages[c - first] : nullptr;
          const std::vector<uint8_t>& payload = with_tree ? with_tree->payload : e->payload;
          auto page = writer_->add_page(with_tree ? with_tree->codec : static_cast<uint8_t>(e->codec), payload);
          if (!page) return page.status();
          record.page = *page;
          record.references = references[c - first];
          report_.page_bytes += payload.size();
          if (with_tree && with_tree->tree_bytes > 0) {
            ++report_.cell_tree_pages;
            report_.cell_tree_bytes += with_tree->tree_bytes;
          }
          ++report_.pages;
          if (record.references == 0) record.page = StoreCell::kNoPage;  // everything dropped
        }
        report_.references += record.references;
        cells_.push_back(record);
      }
    }
    report_.encode_seconds += seconds_since(t);
    if (options_.proxy_triangles > 0) {
      if (Status s = build_part_proxies(scene, tree, node_base); !s) return s;
    }
    // Straddling primitives are counted in every part: never report more than the total.
    build_progress_->advance(std::min(part.count, root_count_ - std::min(root_count_, build_progress_->done())));
    return Status::ok();
  }

  CellCodecOptions codec_options() const {
    CellCodecOptions codec;
    codec.codec = options_.codec;
    codec.lattice = lattice_;
    if (const char* s = std::getenv("FRONTIER_DRACO_SPEED")) codec.draco_speed = std::atoi(s);
    return codec;
  }

  // Proxy pages' codec options (BuildOptions::proxy_codec).
  CellCodecOptions proxy_codec_options() const {
    CellCodecOptions codec = codec_options();
    codec.codec = proxy_codec(options_);
    return codec;
  }

  // Proxies of a part's tree (grafted at node_base), bottom-up on the worker threads; their pages
  // are written here in node order. Each proxy's bound is measured against the part's original
  // triangles through the part's hierarchy (proxy_bound.h), which is held until the part is done;
  // the part root's mesh goes on the pending stack with the hierarchy's top kBoundLevels levels.
  Status build_part_proxies(const Scene& scene, const KdTree& tree, uint32_t node_base) {
    const auto t = std::chrono::steady_clock::now();
    std::vector<PendingProxyPage> pages(tree.nodes().size());
    std::vector<BoundNode> bounds(tree.nodes().size());
    const CellCodecOptions codec = proxy_codec_options();
    MeshLevels root;
    arena_->execute([&] { root = part_proxy(scene, tree, 0, tree.bounds(), pages, bounds, codec); });
    for (size_t i = 0; i < pages.size(); ++i) {
      if (Status s = write_proxy(node_base + static_cast<uint32_t>(i), pages[i]); !s) return s;
    }
    pending_.push_back({std::move(root), bound_summary(bounds, 0, kBoundLevels)});
    report_.proxy_seconds += seconds_since(t);
    return Status::ok();
  }

  // The meshes of local node `node` of a part's tree by level (MeshLevels): a leaf's input, or
  // an interior node's proxy (whose page goes to pages[node]) and its descendants'; bounds[node]
  // is its place in the hierarchy.
  MeshLevels part_proxy(const Scene& scene, const KdTree& tree, uint32_t node, const Aabb& region,
                       std::vector<PendingProxyPage>& pages, std::vector<BoundNode>& bounds,
                       const CellCodecOptions& codec) const {
    const KdTree::Node& n = tree.nodes()[node];
    if (n.is_leaf()) {
      const KdTree::Cell& cell = tree.cells()[n.child];
      Scene local;
      for (uint32_t r = cell.first; r < cell.first + cell.count; ++r) local.add_from(scene, tree.ref(r));
      ProxyMesh mesh = proxy_input(local, proxy_options_);
      pages[node].record.subtree_triangles = mesh.subtree_triangles;
      BoundNode& b = bounds[node];
      b.positions = mesh.positions;
      b.indices = mesh.indices;
      for (const Vec3& p : b.positions) b.box.extend(p);
      b.original = true;
      return leaf_levels(std::move(mesh));
    }
    Aabb lower_region = region, upper_region = region;
    lower_region.hi[n.axis_or_leaf] = n.split;
    upper_region.lo[n.axis_or_leaf] = n.split;
    MeshLevels lower, upper;
    tbb::parallel_invoke([&] { lower = part_proxy(scene, tree, node + 1, lower_region, pages, bounds, codec); },
                         [&] { upper = part_proxy(scene, tree, n.child, upper_region, pages, bounds, codec); });
    return make_proxy(std::move(lower), std::move(upper), region, pages[node], codec, bounds, node, node + 1, n.child);
  }

  // A leaf's mesh at every level (it stands for itself however deep its siblings go).
  static MeshLevels leaf_levels(ProxyMesh mesh) {
    const auto shared = std::make_shared<const ProxyMesh>(std::move(mesh));
    MeshLevels levels;
    for (auto& l : levels) l = {shared};
    return levels;
  }

  // The parent's proxy, encoded into `out`, from its children's MeshLevels: simplified from the
  // descendants kProxyInputLevels levels down (merged), not from the children's proxies, so that
  // simplification error does not compound level by level; its bound is measured through `bounds`
  // (the children at lower_index and upper_index, complete) and the proxy takes its place there
  // at `index`. Returns the parent's MeshLevels.
  MeshLevels make_proxy(MeshLevels lower, MeshLevels upper, const Aabb& region, PendingProxyPage& out,
                        const CellCodecOptions& codec, std::vector<BoundNode>& bounds, uint32_t index,
                        uint32_t lower_index, uint32_t upper_index) const {
    std::vector<const ProxyMesh*> input;
    for (const MeshLevels* side : {&lower, &upper}) {
      for (const auto& m : (*side)[kProxyInputLevels - 1]) input.push_back(m.get());
    }
    ProxyMesh merged = merge_proxies(input);
    // Monotone: a parent's bound is at least its children's (the descendants' may be smaller).
    const double children_error = std::max(lower[0].front()->error, upper[0].front()->error);
    merged.error = std::max(merged.error, children_error);
    const uint32_t children[2] = {lower_index, upper_index};
    const ProxyMeasure measure = [&](const ProxyMesh& candidate) {
      return measure_against_original(candidate.positions, candidate.indices, bounds, children);
    };
    ProxySimplifyStats stats;
    ProxyMesh proxy = simplify_proxy(merged, proxy_options_, &stats, &region, &measure);
    if (!stats.kept_input) shade_proxy(merged, proxy);  // a kept input keeps its own normals
    merged = ProxyMesh{};
    proxy.error = std::max(proxy.error, children_error);
    out.shell = stats.shell;
    out.sloppy = stats.sloppy;
    out.record.error = proxy.error;
    out.record.subtree_triangles = proxy.subtree_triangles;
    if (!proxy.empty()) {
      out.page = encode_page(proxy_scene(proxy), codec);
      if (options_.cell_trees && *out.page && (*out.page)->decoded.size() > 0) out.tree = proxy_tree(**out.page, region);
    }
    const BoundNode& l = bounds[lower_index];
    const BoundNode& u = bounds[upper_index];
    BoundNode b;
    b.lower = lower_index;
    b.upper = upper_index;
    b.box = l.box;
    b.box.extend(u.box);
    if (stats.kept_input) {  // the descendants' meshes: measured as they are
      MeasuredBound m = measure(proxy);
      b.to_original = m.to_original;
      b.from_proxy = m.from_proxy;
      b.triangle_error = std::move(m.triangle_error);
    } else {
      b.to_original = stats.bound.to_original;
      b.from_proxy = stats.bound.from_proxy;
      b.triangle_error = std::move(stats.bound.triangle_error);
    }
    b.positions = proxy.positions;
    b.indices = proxy.indices;
    bounds[index] = std::move(b);
    MeshLevels levels;
    levels[0] = {std::make_shared<const ProxyMesh>(std::move(proxy))};
    for (size_t j = 1; j < levels.size(); ++j) {
      levels[j] = std::move(lower[j - 1]);
      levels[j].insert(levels[j].end(), upper[j - 1].begin(), upper[j - 1].end());
    }
    return levels;
  }

  // A proxy page's tree, as with_cell_tree makes a cell's: built with the viewer's proxy
  // options over the node's region on the proxy as a reader decodes it; empty when it would not
  // assemble back bit for bit (never seen: the viewer then builds it).
  std::vector<uint8_t> proxy_tree(const EncodedCell& e, const Aabb& region) const {
    KdBuildOptions options = proxy_tree_options(cell_tree_options_);
    options.root = region;
    auto tree = encode_cell_tree(e.decoded, KdTree::build(e.decoded, options), options);
    return tree ? std::move(*tree) : std::vector<uint8_t>{};
  }

  // Writes a node's proxy page (if it has one) and keeps its record.
  Status write_proxy(uint32_t node, PendingProxyPage& pending) {
    if (proxies_.size() <= node) proxies_.resize(nodes_.size());
    StoreProxy& record = proxies_[node];
    record = pending.record;
    if (!pending.page) return Status::ok();
    Result<EncodedCell>& e = *pending.page;
    if (!e) return e.status();
    const bool with_tree = !pending.tree.empty();
    std::vector<uint8_t> joined;
    if (with_tree) joined = join_tree_page(pending.tree, e->payload);
    const std::span<const uint8_t> payload = with_tree ? std::span<const uint8_t>(joined) : e->payload;
    auto page = writer_->add_page(static_cast<uint8_t>(uint8_t(e->codec) | (with_tree ? kCellTreeFlag : 0)), payload);
    if (!page) return page.status();
    record.page = *page;
    record.triangles = e->decoded.size();
    if (record.triangles == 0) record.page = StoreProxy::kNoPage;  // everything dropped
    report_.proxy_bytes += payload.size() + store::kBlockTrailerSize;
    if (with_tree) {
      ++report_.proxy_tree_pages;
      report_.proxy_tree_bytes += pending.tree.size();
    }
    report_.proxy_triangles += record.triangles;
    report_.proxy_shells += pending.shell ? 1 : 0;
    report_.proxy_sloppy += pending.sloppy ? 1 : 0;
    ++report_.proxy_pages;
    pending.page.reset();
    return Status::ok();
  }

  // `more` after the nodes of `to`, its child links moved along.
  static void append_bounds(std::vector<BoundNode>& to, std::vector<BoundNode>&& more) {
    const auto offset = static_cast<uint32_t>(to.size());
    for (BoundNode& b : more) {
      if (b.lower != BoundNode::kNone) b.lower += offset;
      if (b.upper != BoundNode::kNone) b.upper += offset;
      to.push_back(std::move(b));
    }
  }

  // A plan node above the parts whose children are done: its proxy from the two pending meshes.
  Status merge_pending(uint32_t node, const Aabb& region) {
    const auto t = std::chrono::steady_clock::now();
    if (pending_.size() < 2) return Status::invalid_argument("build: proxy stack underflow (a bug)");
    PendingSubtree upper = std::move(pending_.back());
    pending_.pop_back();
    PendingSubtree lower = std::move(pending_.back());
    pending_.pop_back();
    // The parts' original triangles are gone: the hierarchy is what the pending subtrees kept
    // (their top levels, the deepest cut off), below a new node 0 for this one.
    std::vector<BoundNode> bounds(1);
    const auto lower_index = static_cast<uint32_t>(bounds.size());
    append_bounds(bounds, std::move(lower.bounds));
    const auto upper_index = static_cast<uint32_t>(bounds.size());
    append_bounds(bounds, std::move(upper.bounds));
    PendingProxyPage page;
    MeshLevels levels;
    arena_->execute([&] {
      levels = make_proxy(std::move(lower.levels), std::move(upper.levels), region, page, proxy_codec_options(), bounds, 0,
                          lower_index, upper_index);
    });
    if (Status s = write_proxy(node, page); !s) return s;
    pending_.push_back({std::move(levels), bound_summary(bounds, 0, kBoundLevels)});
    report_.proxy_seconds += seconds_since(t);
    return Status::ok();
  }

  // Stage 5: sections and footer.
  Status finish() {
    report_.degenerate_dropped += snapped_away_;
    report_.cells = cells_.size();
    info_.codec = options_.codec;
    info_.lattice = lattice_;
    info_.bounds = root_region_;
    info_.input_primitives = report_.input_primitives;
    info_.primitives = report_.primitives - snapped_away_;
    info_.references = report_.references;
    info_.triangles = report_.triangles - snapped_away_;
    info_.degenerate_dropped = report_.degenerate_dropped;
    info_.cell_prims = options_.cell_prims;
    if (report_.cell_tree_pages > 0 || report_.proxy_tree_pages > 0) {
      info_.cell_tree = cell_tree_options_;
      info_.cell_tree_pages = report_.cell_tree_pages;
      info_.cell_tree_bytes = report_.cell_tree_bytes;
    }
    if (report_.proxy_tree_pages > 0) {
      info_.proxy_tree_cell_prims = proxy_tree_options(cell_tree_options_).max_cell_prims;
      info_.proxy_tree_pages = report_.proxy_tree_pages;
      info_.proxy_tree_bytes = report_.proxy_tree_bytes;
    }
    if (grid_) {
      // Every brick becomes a page as soon as it is assembled; the section is their table.
      auto bytes = grid_->finish([&](std::vector<uint8_t> brick) -> Result<uint64_t> {
        auto id = writer_->add_page(sdf_format::kBrickCodec, brick);
        if (!id) return id.status();
        report_.sdf_bytes += brick.size() + store::kBlockTrailerSize;
        ++report_.sdf_bricks;
        return uint64_t(*id);
      });
      if (!bytes) return bytes.status();
      if (Status s = writer_->add_section(kSdfSection, *bytes); !s) return s;
      report_.sdf_bytes += bytes->size();
      report_.sdf_memory = grid_->memory_bytes();
      report_.sdf_spill_bytes = grid_->spill_bytes();
      info_.walkable = true;
    }
    if (Status s = writer_->add_section(kModelSection, info_.to_bytes()); !s) return s;
    if (Status s = writer_->add_section(kTreeSection, encode_tree(nodes_)); !s) return s;
    if (Status s = writer_->add_section(kCellsSection, encode_cells(cells_)); !s) return s;
    if (!portals_.empty()) {
      if (Status s = writer_->add_section(kPortalsSection, portals_); !s) return s;
    }
    if (options_.proxy_triangles > 0) {
      proxies_.resize(nodes_.size());
      report_.proxy_root_error = proxies_[0].error;
      if (Status s = writer_->add_section(kProxiesSection, encode_proxies(proxies_)); !s) return s;
    }
    if (Status s = writer_->finish(); !s) return s;
    std::error_code ec;
    report_.store_bytes = fs::file_size(options_.output, ec);
    return Status::ok();
  }

  const BuildOptions& options_;
  std::optional<BuildTempDir> temp_;  // declared first: removed last, after the writer
  std::optional<StagingLock> staging_;  // released after the writer removed or renamed OUT.tmp
  // The writer's file system outlives the writer: a failed build's writer removes NAME.tmp
  // through it when the builder is destroyed.
  store::PosixFileSystem fsys_;
  std::unique_ptr<store::StoreWriter> writer_;
  std::optional<tbb::task_arena> arena_;
  std::optional<Progress> build_progress_;
  std::optional<WalkableGridBuilder> grid_;
  Aabb bounds_;
  Aabb root_region_;  // bounds_ padded: the top tree's root
  Lattice lattice_;
  // How frontier-view refines a paged-in cell by default: the in-cell trees stored in pages.
  const KdBuildOptions cell_tree_options_ = page_refine_options(WalkOptions{});
  uint64_t root_count_ = 0;
  bool reparse_ = false;  // the root part is the inputs, parsed again (no ingest spill)
  std::vector<uint32_t> material_bases_;  // per input: its first material in info_.materials
  uint64_t snapped_away_ = 0;
  uint64_t spill_on_disk_ = 0;  // bytes of the spill files that exist now
  int next_file_ = 0;
  StoreModelInfo info_;
  std::vector<KdTree::Node> nodes_;
  std::vector<StoreCell> cells_;
  std::vector<uint8_t> portals_;  // the serialized PortalGraph; empty: no portals section
  ProxyOptions proxy_options_;
  std::vector<StoreProxy> proxies_;  // per node of nodes_ (grown as proxies are written)
  // A finished subtree whose parent is not done yet: its mesh and the top of its hierarchy.
  struct PendingSubtree {
    MeshLevels levels;  // the subtree root's proxy and its descendants' (make_proxy)
    std::vector<BoundNode> bounds;
  };
  std::vector<PendingSubtree> pending_;
  BuildReport report_;
};

}  // namespace

void tune_allocator_for_build() {
  mallopt(M_TRIM_THRESHOLD, INT_MAX);
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TOP_PAD, 256 << 20);
}

CellCodec proxy_codec(const BuildOptions& options) {
  if (options.proxy_codec) return *options.proxy_codec;
  return options.codec == CellCodec::Draco ? CellCodec::Meshopt : options.codec;
}

Result<BuildReport> build_store(const BuildOptions& options) {
  StoreBuilder builder(options);
  return builder.run();
}

}  // namespace frontier
