// Walkthrough: the out-of-core frame loop of frontier-view — a store, a PagedWorld over it, a
// FrustumCaster over the world, and one FrameReport per displayed frame.
//
// A displayed frame renders the camera within its budget (time or samples; without either it
// runs until the image is complete). Frustum work that reaches a cell whose page is not in
// memory is parked while the cache's loader reads it; between job slices the arrived cells are
// decoded, refined and grafted, and the parked work resumes (paper §5.2's queue with paging).
// Without --sync-paging a frame never waits for the disk while other work is left; when only
// parked work is left and time remains it waits (that time is stall_ms). With sync paging it
// waits until the image is complete, so its ids equal an in-memory render of the same store.
//
// The cells the eye will enter if it keeps moving as it did are requested ahead (prefetch: a
// frame whose own eye cell is missing can do nothing until it arrives).
//
// Progressive (§5.3): a frame whose camera equals the previous one continues the same image
// (more samples) instead of starting a new one; the first complete image of a still camera
// is followed by one with the deferred effects (shadows) if the scene declares lights. While
// the camera moves, images have immediate effects only. still_frame() renders a camera that
// will not move with its deferred effects at once (a headless single frame). Shadow rays page
// in the cells they cross like primary rays do (a pixel whose shadow rays cross a missing
// cell waits for it), so a complete image with shadows equals the in-memory render.
//
// Frames that run to completion (sync paging, or no budget) always complete, also when their
// cells do not fit in the cache at once (thrashing): when what the frame waits for was
// dropped for lack of room, the cells of earlier images go first; when the frame's own cells
// fill the cache, the rest of the image is rendered in passes over parts of the screen (Z
// order), the cache emptied between them, each part half as large as the last one that did
// not fit (twice as large after one that did). Confirmed pixels stay, so samples never exceed
// pixels. Only when a single pixel's cells (its primary and shadow rays') do not fit does the
// frame end incomplete (FrameReport::unfit). Budgeted frames degrade instead (fewer samples).
//
// The report's fields are DESIGN.md's "Working set, defined once", counted in store cells (a
// store cell refined into a subtree counts once): see FrameReport.
#pragma once

#include "src/core/counters.h"
#include "src/engine/frustum.h"
#include "src/paging/paged_world.h"
#include "src/core/sample_buffer.h"
#include "src/engine/shading.h"
#include "src/paging/store_model.h"
#include "src/paging/store_oracle.h"
#include "src/core/view.h"
#include "src/raster/visibility.h"

#include <nlohmann/json_fwd.hpp>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace frontier {

struct WalkOptions {
  uint64_t cache_bytes = 512ull << 20;
  int width = 640, height = 480;
  int threads = 0;             // render threads (0: all cores)
  FrameBudget budget;          // per displayed frame; neither set: run each image to completion
  bool sync_paging = false;
  bool oracle = false;         // compute oracle_cells (exact per-pixel rays) every frame
  bool shadows = true;         // deferred shadows when the camera stops (scene must declare lights)
  // A quality floor under the frame-time peg: a moving frame that reaches its time with fewer
  // than this share of its pixels sampled goes on until it has them, for at most
  // kFloorMaxOvertime more frame times, counted from the peg or from the moment it was reached,
  // whichever is later (paging, a burst of new cells or a descheduled worker would otherwise
  // show a frame that is mostly reconstruction, or none). 0: pure frame-time pegging
  // (paper §5.5). The report's floor_ms says how long a frame ran past its peg for it.
  double min_sampled = 0.5;
  // The most of a pegged frame time that paging in may take on the frame's threads before its
  // rays (decoding the proxies and pages the cut asked for, and placing them): more refines the
  // cut sooner, less leaves more of the frame to rays. A frame takes all of it while the rays
  // of the last one met proxies kFullShareError times the pixel error off or more
  // (FrameReport::cut_error), less as they come closer, a fifth at the pixel error: a far
  // terrain's cut 2-6 pixels off gains more from samples than from refining, a fly-over's or a
  // building's 8-300 pixels off from refining (tests/bench/REPORT.md section 9, "The paging
  // share"). A frame whose image completes early gives the rest of its time to paging as well
  // (Walkthrough::use_slack).
  double paging_share = 0.25;
  static constexpr double kFullShareError = 10.0;
  // The share of the frame that paging in takes before the rays of a frame whose last frame's
  // cut was `cut_error` pixels off at pixel error `pixel_error` (none yet: the whole share).
  static double paging_share_for(double paging_share, std::optional<double> cut_error, double pixel_error) {
    if (!cut_error || !(pixel_error > 0.0)) return paging_share;
    return paging_share * std::clamp(*cut_error / (kFullShareError * pixel_error), 0.2, 1.0);
  }
  // How a paged-in store cell is refined (page-in time is frame time), and how frontier-build
  // builds the in-cell trees its pages carry. Measured on the 100 M triangle building walk
  // (tests/bench/bench_walk.sh): 16 / 4.0 / 0.75 build a cell in 1.3 ms instead of 2.9 ms
  // (8 / 2.0 / 1.0, the in-memory engine's), with 4.6 instead of 8.1 references per primitive
  // (half the memory) and more samples per 33 ms frame. A traversal cost of 8 instead of 4
  // (REPORT.md section 9, "In-cell trees of traversal cost 8"): 2.7x fewer nodes and 1.7x fewer
  // references on a 2 M building, a third less resident memory, pegged 1280x720 walks sampling
  // as much or more; complete exact-cell frames of the building 1.12x slower.
  uint32_t cell_prims = 16;
  double cell_traversal_cost = 8.0;
  double cell_split_share = 0.75;
  // A store whose pages carry in-cell trees is refined with the options it records (its trees
  // are used as stored, whatever the defaults above were when it was built); false: with the
  // options above (a tree built otherwise is then rebuilt at page-in).
  bool cell_build_from_store = true;
  // Frusta of at most this many pixels across resolve their pixels as ray packets
  // (FrustumCaster::set_leaf_pixels); 0: a twentieth of the image's width, at least the
  // in-memory caster's 16 (32 at 640 pixels, 64 at 1280). A walk's tree is the top tree with
  // every page's in-cell tree below it, so frusta of 16 split through many cells before they
  // are that small: pegged 1280x720 walks at 64 sample more of the geometry in their 33 ms, of
  // terrain, a building's exterior and its interior alike, while a 640x480 interior walk
  // samples less at 64 than at 16 or 32 (tests/bench/REPORT.md section 9, "Leaf frusta").
  int leaf_pixels = 0;
  // The leaf size a walk of `width` pixels uses when leaf_pixels is 0.
  static int auto_leaf_pixels(int width) { return std::max(FrustumCaster::kDefaultLeafPixels, width / 20); }
  // Reconstruct the displayed image at the end of every frame (inside the frame's time; a
  // window needs it). Off, image() reconstructs on demand: headless walks pay for it only for
  // the frames they write.
  bool reconstruct_each_frame = true;
  // Which visibility class renders the frames (src/raster/visibility.h). The rasterizing classes
  // render every frame complete (paging synchronously) and ignore the budget.
  Visibility visibility = Visibility::kFrustumAdvance;
  bool cull_back_faces = false;  // rasterizing classes: drop back faces (closed solids only)
  // Stores with proxies (PagedWorld "Level of detail"): the cut draws a node by its proxy when
  // the proxy's error bound projects below this many pixels (0: never; the exact renderer).
  // Budgeted frames (no sync paging) draw one cut of what is resident, chosen before the first
  // ray: no ray parks. A still camera refines: once its image is complete and nothing it asked
  // for is outstanding, the next is rendered with 0.
  double pixel_error = 0.0;
};

// Sets the process's allocator for a walk (call once, before opening one): blocks of 64 KiB or
// more — decoded cells and their trees, made on the decoder thread and freed on the frame's —
// are mapped and unmapped, not kept in the heap's free lists, so the resident set follows what
// the walk holds (fragmentation kept it at twice the --cache budget on a 100 M-triangle walk).
void tune_allocator_for_walk();

// How a paged-in store cell is refined into its own subtree under `options` (PagedWorld's
// cell_build; bench_build times the same).
KdBuildOptions page_refine_options(const WalkOptions& options);

class Walker;

struct FrameReport {
  uint64_t frame = 0;
  Vec3 eye{0.0};                    // the camera's eye (walk mode: after collision)
  // DESIGN.md "Working set, defined once".
  uint64_t cells_touched = 0;       // store cells a frustum or ray entered (in this image so far)
  uint64_t cells_paged_in = 0;      // store cells decoded and grafted during this frame
  uint64_t bytes_read = 0;          // page bytes read from the store file during this frame
  uint64_t resident_bytes = 0;      // compressed pages in the cache + decoded cells
  uint64_t pinned_bytes = 0;        // of those, what this image touched (not evictable now)
  uint64_t cache_budget = 0;
  uint64_t primitives_tested = 0;
  uint64_t ray_primitive_tests = 0;
  uint64_t rays = 0;
  uint64_t samples = 0;             // pixels confirmed during this frame (each at most once)
  double frame_ms = 0.0;
  double stall_ms = 0.0;            // waiting for pages with nothing else to do
  double floor_ms = 0.0;            // time past the pegged frame time spent reaching min_sampled
  bool preview = false;             // leaves traced a preview first (after a frame that needed the floor)
  // More.
  std::optional<uint64_t> oracle_cells;
  std::optional<double> oracle_ratio;  // cells_touched / oracle_cells
  uint64_t image_samples = 0;       // pixels confirmed in the image so far
  uint64_t pixels = 0;
  bool complete = false;            // every pixel of the image confirmed
  bool continued = false;           // same camera as the previous frame: the image went on
  bool shadows = false;             // the image has the deferred shadow effect
  // Frusta and pixels that waited for a missing cell in this frame: parked during it, or still
  // parked from an earlier frame of the same image (0 in every frame of a pegged cut).
  uint64_t parked = 0;
  uint64_t unfinished = 0;          // jobs still queued when the frame's budget ended
  uint64_t cells_evicted = 0;
  uint64_t cells_dropped = 0;
  uint64_t page_errors = 0;         // cumulative: pages that failed to read or decode
  uint64_t resident_cells = 0;
  // Thrashing: the image's own cells did not all fit in the cache at once (they filled it while
  // it waited for more, passes > 1, cells re-read, more bytes read than the cache holds, or
  // unfit). Cells dropped while earlier images' cells held the room are not thrashing.
  bool thrashing = false;
  bool unfit = false;               // one pixel's cells do not fit in the cache: cannot complete
  uint64_t passes = 1;              // parts the image was rendered in, the cache emptied between
  uint64_t cells_reread = 0;        // store cells paged in again within this image
  uint64_t working_set_bytes = 0;   // decoded bytes of the store cells the image touched
  uint64_t cache_needed = 0;        // the smallest cache_budget whose decoded share holds them
  uint64_t collision_queries = 0;   // filled in by the viewer's walk mode (0 without it)
  // Walk mode's collision grid (0 without it): bricks resident now and their memory, bricks
  // read since the start (cumulative), bricks that failed to read (cumulative; they read solid).
  uint64_t collision_bricks = 0;
  uint64_t collision_bytes = 0;
  uint64_t collision_loads = 0;
  uint64_t collision_errors = 0;
  // Fills the collision fields from a walker (queries) and its grid (brick cache).
  void add_walk_counters(const Walker& walker);
  double decode_ms = 0.0;        // paging in on the frame's thread (sync)
  double decode_ahead_ms = 0.0;  // decoding on the decoder thread, of the cells grafted in this frame
  double reconstruct_ms = 0.0;      // 0 when the frame did not reconstruct its image
  uint64_t shading_ops = 0;
  uint64_t shadow_rays = 0;
  // Level of detail (stores with proxies, PagedWorld "Level of detail"): the pixel error this
  // image was rendered with; the cut's nodes drawn by their proxies, and of those the nodes the
  // image's rays entered; the store cells below the nodes those rays entered; proxies
  // and pages asked for and not in yet; pixels confirmed on a proxy; nodes linked to their
  // proxies and proxies installed in this frame.
  double pixel_error = 0.0;
  uint64_t cut_nodes = 0;
  uint64_t proxy_nodes = 0;
  uint64_t proxy_cells = 0;
  uint64_t requests = 0;
  double cut_error = 0.0;  // StandInReport::cut_error
  uint64_t proxy_pixels = 0;
  uint64_t stand_ins = 0;
  uint64_t proxies_loaded = 0;
  // Issue 7's comparison of visibility classes. Frustum advance: nodes_touched counts cell
  // entries (with repetition: its navigation goes through ropes, not down from the root),
  // primitives_touched its primitive incidences, nothing is rasterized.
  Visibility visibility = Visibility::kFrustumAdvance;
  uint64_t nodes_touched = 0;
  uint64_t primitives_touched = 0;   // primitive references examined
  uint64_t pixels_rasterized = 0;    // fragments depth-tested (rasterizing classes)
  double culling_rate = 0.0;         // 1 - primitives_touched / the store's references
  std::optional<CullCounters> cull;  // the rasterizing classes' own counters
  nlohmann::json to_json() const;
};

class Walkthrough {
 public:
  // The longest a frame goes on past its pegged time for WalkOptions::min_sampled, in frame times.
  static constexpr double kFloorMaxOvertime = 1.0;
  static Result<std::unique_ptr<Walkthrough>> open(const std::string& store_path, const WalkOptions& options);
  ~Walkthrough();

  FrameReport frame(const Camera& camera);
  // One image of a camera that stays where it is: run to completion with the deferred effects
  // the scene declares (shadows) from the start, as an in-memory render shows it.
  FrameReport still_frame(const Camera& camera);
  // Changes the per-frame budget (pegging time or samples, paper §5.5) for the next frames.
  void set_budget(const FrameBudget& budget) { options_.budget = budget; }
  const FrameBudget& budget() const { return options_.budget; }
  // Changes the pixel error (WalkOptions::pixel_error) from the next moving frame on.
  void set_pixel_error(double pixel_error) { options_.pixel_error = std::max(0.0, pixel_error); }
  double pixel_error() const { return options_.pixel_error; }

  const StoreModel& model() const { return *model_; }
  const PagedWorld& world() const { return *world_; }
  const SampleBuffer& buffer() const { return buffer_; }
  // The displayed image (§5.4 reconstruction of the current samples), row-major, top row first.
  const std::vector<Rgb>& image();
  const View& view() const { return view_; }
  // Per pixel: the source id of the first hit (kNoPrim: background or not sampled yet).
  std::vector<uint32_t> ids() const;
  // Rasterizing classes: the ray parameter t per pixel (kInfinity: background); empty otherwise.
  std::vector<double> depths() const { return culler_ ? culler_->depths() : std::vector<double>{}; }
  // Store cells touched by the current image.
  std::vector<uint32_t> touched_cells() const {
    return culler_ ? world_->touched_this_frame() : world_->image_cells(marks_);
  }
  // The oracle's last frame (only with options.oracle).
  const OracleFrame* last_oracle() const { return oracle_frame_ ? &*oracle_frame_ : nullptr; }

 private:
  struct FramePlan;
  // How the current image's passes go (see the top of this file).
  struct Passes {
    uint64_t count = 1;             // passes so far
    uint64_t pixels = 0;            // pixels of the parked work the current pass resumed
    uint64_t samples_at_start = 0;  // image_samples_ when the current pass began
    bool reclaimed = false;         // this frame freed the cells of earlier images once
    bool overflowed = false;        // the image's own cells filled the cache
    bool unfit = false;
  };
  Walkthrough() = default;
  void start_image(bool shadows, double pixel_error);
  FrameReport culling_frame(const Camera& camera);
  FrameReport render_frame(const Camera& camera, bool deferred_now);
  // The steps of frame(), in order.
  // Starts a new image for a moved camera (with the deferred effects when `deferred_now`), or
  // the deferred effects for a stopped one whose image is complete; returns false when the
  // frame continues the current image.
  bool choose_image(const Camera& camera, bool still, bool deferred_now);
  // The frame's deadlines and quality floor, from its start and the budget.
  FramePlan plan_frame(std::chrono::steady_clock::time_point start, bool still) const;
  // Runs job slices, pages in and waits for pages until the image is complete or the frame's
  // budget is spent; returns the time spent waiting for pages (stall_ms).
  double render_image(FramePlan& plan, Counters& counters);
  // A pegged cut's image that finished before its frame time: the rest of the frame decodes
  // and installs what the cut asked for (used from the next image on). Returns the ms spent.
  double use_slack(const FramePlan& plan);
  // True when the frame must end now; moves the deadline once for the quality floor.
  bool out_of_time(FramePlan& plan) const;
  // When only parked work is left and no page is on its way: frees room and starts the next
  // pass (see the top of this file). False when the frame ends here.
  bool next_pass(bool finish);
  // When a sync() with nothing to render meanwhile stops paging in.
  std::chrono::steady_clock::time_point page_in_slice(const FramePlan& plan) const;
  // The caster goes on after the world's cells were renumbered.
  void resume_renumbered();
  void keep_ids();
  void run_slice(const FramePlan& plan, Counters& counters);
  // Wants the cells the eye reaches in the next frames if it keeps its last step.
  void prefetch(const Camera& camera, const Camera& previous);
  // Marks the displayed image stale, and rebuilds it now if every frame displays one.
  void reconstruct_for_display(FrameReport& r);
  void report_image(FrameReport& r, const Counters& counters) const;
  void report_paging(FrameReport& r);
  void report_oracle(FrameReport& r);

  WalkOptions options_;
  std::unique_ptr<StoreModel> model_;
  std::unique_ptr<PagedWorld> world_;
  std::unique_ptr<Shader> shader_;
  std::unique_ptr<FrustumCaster> caster_;
  std::unique_ptr<CullingRenderer> culler_;  // rasterizing visibility classes
  std::vector<Rgb> cull_image_;
  std::unique_ptr<StoreOracle> oracle_;
  std::optional<OracleFrame> oracle_frame_;
  SampleBuffer buffer_;
  CellMarks marks_;
  View view_;
  std::optional<Camera> last_camera_;
  bool image_shadows_ = false;
  double image_pixel_error_ = 0.0;   // the pixel error of the current image
  uint64_t parked_at_start_ = 0;     // jobs parked or held when the frame began (continued image)
  bool needed_floor_ = false;        // the last frame ran past its peg for min_sampled (previews next)
  // A still camera's images refine the cut while what it asked for comes in; after this many in
  // a row without a change of the cut, the exact image follows anyway.
  static constexpr int kStillWaits = 8;
  uint64_t still_cut_changes_ = 0;   // world's cut_changes() at the last still refinement
  int still_waits_ = 0;
  uint64_t image_proxy_pixels_ = 0;  // proxy pixels of the current image, as last reported
  std::optional<double> last_cut_error_;  // FrameReport::cut_error of the last frame
  uint64_t frames_ = 0;
  uint64_t last_bytes_read_ = 0;
  double finish_ms_ = 0.0;        // recent time from the end of the job queue to the end of a frame
  bool reconstructed_ = false;    // image() is up to date with the samples
  uint64_t image_samples_ = 0;    // pixels confirmed in the current image (each confirm counts one)
  Passes passes_;
  // Source ids of the pixels confirmed before the world was last renumbered in this image
  // (kUnsetId: not confirmed then); empty while it never was.
  static constexpr uint32_t kUnsetId = kNoPrim - 1;
  std::vector<uint32_t> earlier_ids_;
};

}  // namespace frontier
