// Walkthrough: the out-of-core frame loop (see walkthrough.h).
#include "src/walk/walkthrough.h"

#include "src/engine/render.h"
#include "src/walk/walker.h"

#include <nlohmann/json.hpp>

#include <malloc.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <chrono>
#include <functional>
#include <thread>

namespace frontier {

namespace {

using Clock = std::chrono::steady_clock;

// How many frames ahead the eye's path is prefetched.
constexpr int kPrefetchFrames = 4;
// The share of the decoded cells' room a pass of a thrashing image aims to fill (the rest
// absorbs the error of estimating a part's cells from the last part's).
constexpr double kPassFill = 0.75;
// What use_slack() leaves of a pegged frame for the frame's reports (at most a tenth of it).
constexpr double kSlackReserveMs = 0.5;

bool same_camera(const Camera& a, const Camera& b) {
  return a.eye == b.eye && a.look_at == b.look_at && a.up == b.up && a.vfov_deg == b.vfov_deg;
}

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }
// `ms` milliseconds as a clock duration (deadlines are time points plus these).
Clock::duration ms_duration(double ms) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::milli>(ms));
}

}  // namespace

nlohmann::json FrameReport::to_json() const {
  nlohmann::json j = {{"frame", frame},
                      {"eye", {eye.x, eye.y, eye.z}},
                      {"cells_touched", cells_touched},
                      {"cells_paged_in", cells_paged_in},
                      {"bytes_read", bytes_read},
                      {"resident_bytes", resident_bytes},
                      {"pinned_bytes", pinned_bytes},
                      {"cache_budget", cache_budget},
                      {"primitives_tested", primitives_tested},
                      {"ray_primitive_tests", ray_primitive_tests},
                      {"rays", rays},
                      {"samples", samples},
                      {"frame_ms", frame_ms},
                      {"stall_ms", stall_ms},
                      {"floor_ms", floor_ms},
                      {"preview", preview},
                      {"image_samples", image_samples},
                      {"pixels", pixels},
                      {"complete", complete},
                      {"continued", continued},
                      {"shadows", shadows},
                      {"parked", parked},
                      {"cells_evicted", cells_evicted},
                      {"cells_dropped", cells_dropped},
                      {"page_errors", page_errors},
                      {"resident_cells", resident_cells},
                      {"thrashing", thrashing},
                      {"unfit", unfit},
                      {"passes", passes},
                      {"cells_reread", cells_reread},
                      {"working_set_bytes", working_set_bytes},
                      {"cache_needed", cache_needed},
                      {"collision_queries", collision_queries},
                      {"collision_bricks", collision_bricks},
                      {"collision_bytes", collision_bytes},
                      {"collision_loads", collision_loads},
                      {"collision_errors", collision_errors},
                      {"decode_ms", decode_ms},
                      {"decode_ahead_ms", decode_ahead_ms},
                      {"reconstruct_ms", reconstruct_ms},
                      {"shading_ops", shading_ops},
                      {"shadow_rays", shadow_rays},
                      {"pixel_error", pixel_error},
                      {"unfinished", unfinished},
                      {"cut_nodes", cut_nodes},
                      {"proxy_nodes", proxy_nodes},
                      {"proxy_cells", proxy_cells},
                      {"requests", requests},
                      {"cut_error", cut_error},
                      {"proxy_pixels", proxy_pixels},
                      {"stand_ins", stand_ins},
                      {"proxies_loaded", proxies_loaded}};
  j["visibility"] = visibility_name(visibility);
  j["nodes_touched"] = nodes_touched;
  j["primitives_touched"] = primitives_touched;
  j["pixels_rasterized"] = pixels_rasterized;
  j["culling_rate"] = culling_rate;
  if (cull) j["cull"] = cull->to_json();
  if (oracle_cells) j["oracle_cells"] = *oracle_cells;
  if (oracle_ratio) j["touched_oracle_ratio"] = *oracle_ratio;
  return j;
}

void FrameReport::add_walk_counters(const Walker& walker) {
  collision_queries = walker.queries();
  const CollisionGrid::Counters c = walker.grid().counters();
  collision_bricks = c.resident;
  collision_bytes = c.resident_bytes;
  collision_loads = c.loads;
  collision_errors = c.errors;
}

void tune_allocator_for_walk() { mallopt(M_MMAP_THRESHOLD, 64 << 10); }

KdBuildOptions page_refine_options(const WalkOptions& options) {
  KdBuildOptions build;
  build.max_cell_prims = options.cell_prims;
  build.traversal_cost = options.cell_traversal_cost;
  build.forced_split_max_share = options.cell_split_share;
  return build;
}

Result<std::unique_ptr<Walkthrough>> Walkthrough::open(const std::string& store_path, const WalkOptions& options) {
  if (options.width < 1 || options.height < 1) return Status::invalid_argument("image size must be at least 1x1");
  if (!(options.paging_share > 0.0 && options.paging_share <= 1.0)) {
    return Status::invalid_argument("the paging share must be in (0, 1]");
  }
  auto model = StoreModel::open(store_path);
  if (!model) return model.status();
  std::unique_ptr<Walkthrough> w(new Walkthrough());
  w->options_ = options;
  w->model_ = std::move(*model);
  PagedWorldOptions po;
  po.budget_bytes = options.cache_bytes;
  po.cell_build = page_refine_options(options);
  if (options.cell_build_from_store && w->model_->info().cell_tree) {
    po.cell_build = *w->model_->info().cell_tree;
    po.cell_build.root.reset();
  }
  w->world_ = std::make_unique<PagedWorld>(*w->model_, po);
  w->shader_ = std::make_unique<Shader>(w->world_->scene(), w->world_->tree());
  w->caster_ = std::make_unique<FrustumCaster>(w->world_->scene(), w->world_->tree(), *w->shader_, options.threads);
  w->caster_->set_leaf_pixels(options.leaf_pixels > 0 ? options.leaf_pixels
                                                       : WalkOptions::auto_leaf_pixels(options.width));
  w->caster_->set_gate(w->world_.get());
  if (options.oracle) w->oracle_ = std::make_unique<StoreOracle>(*w->model_);
  if (options.visibility != Visibility::kFrustumAdvance) {
    if (options.visibility == Visibility::kPortals && w->model_->portals() == nullptr) {
      return Status::invalid_argument(store_path +
                                      ": --visibility portals needs a store with cells and portals (built from a "
                                      "model with a frontier-gen building sidecar)");
    }
    CullOptions co;
    co.visibility = options.visibility;
    co.cull_back_faces = options.cull_back_faces;
    co.threads = options.threads;
    w->culler_ = std::make_unique<CullingRenderer>(co, w->model_->portals());
  }
  return w;
}

Walkthrough::~Walkthrough() = default;

void Walkthrough::start_image(bool shadows, double pixel_error) {
  // Frames that may end before every page is in draw the cut of what is resident (no ray
  // parks); what arrived since the last image is placed first, within the paging share.
  const FrameBudget& budget = options_.budget;
  const bool pegged = !options_.sync_paging && (budget.ms > 0.0 || budget.samples > 0);
  world_->set_detail(view_, pixel_error, pegged);
  if (pegged && pixel_error > 0.0 && world_->has_proxies()) {
    const double share =
        budget.ms > 0.0 ? WalkOptions::paging_share_for(options_.paging_share, last_cut_error_, pixel_error) * budget.ms
                        : 8.0;
    world_->sync(Clock::now() + ms_duration(share));
  }
  world_->begin_frame(marks_);
  image_shadows_ = shadows;
  image_pixel_error_ = pixel_error;
  image_proxy_pixels_ = 0;
  // Kernel-bound frames (the last one needed the sample floor) preview their leaves first.
  caster_->set_preview(needed_floor_);
  caster_->begin(view_, buffer_, marks_, true, shadows);
  image_samples_ = 0;
  passes_ = Passes();
  earlier_ids_.clear();
  passes_.pixels = view_.pixels();
}

namespace {

// The paged world as the culling classes see it: missing cells are paged in on request, and
// cells a frame already drew may be evicted while it goes on.
class PagedCullSource final : public CullSource {
 public:
  explicit PagedCullSource(PagedWorld& world) : world_(world) {}
  const KdTree& tree() const override { return world_.tree(); }
  const Scene& scene() const override { return world_.scene(); }
  bool missing(int32_t cell) const override { return world_.missing(cell); }
  void want(int32_t cell) override { world_.want(cell); }
  bool fetch() override {
    if (world_.pending() == 0) return false;
    stall_ms += world_.wait_for_pages(Clock::time_point::max());
    world_.sync_evicting();
    return true;
  }
  uint64_t generation() const override { return world_.generation(); }
  void used(int32_t cell) override { world_.touch(world_.store_cell(cell)); }

  double stall_ms = 0.0;

 private:
  PagedWorld& world_;
};

}  // namespace

// One complete frame of a rasterizing visibility class.
FrameReport Walkthrough::culling_frame(const Camera& camera) {
  const auto start = Clock::now();
  FrameReport r;
  r.frame = frames_++;
  r.eye = camera.eye;
  r.visibility = options_.visibility;
  view_ = View(camera, options_.width, options_.height);
  last_camera_ = camera;
  world_->begin_frame(marks_);
  PagedCullSource source(*world_);
  const CullCounters cc = culler_->render(view_, source);
  cull_image_.clear();
  reconstruct_for_display(r);
  r.cells_touched = world_->end_frame(CellMarks());
  r.pinned_bytes = world_->pinned_bytes();
  r.primitives_tested = cc.primitives_touched;
  r.pixels = view_.pixels();
  r.samples = r.image_samples = r.pixels;
  r.complete = cc.cells_unavailable == 0;
  r.stall_ms = source.stall_ms;
  r.nodes_touched = cc.nodes_touched;
  r.primitives_touched = cc.primitives_touched;
  r.pixels_rasterized = cc.pixels_rasterized;
  r.cull = cc;
  report_paging(r);
  r.frame_ms = ms_since(start);
  report_oracle(r);
  return r;
}

// The fields every frame reports the same way, whatever rendered it: paging since the last
// frame, the cache, and the culling rate of r.primitives_touched.
void Walkthrough::report_paging(FrameReport& r) {
  const PagingCounters paging = world_->take_counters();
  const store::PageCacheStats cache = world_->cache_stats();
  r.cells_paged_in = paging.cells_paged_in;
  r.cells_evicted = paging.cells_evicted;
  r.cells_dropped = paging.cells_dropped;
  r.cells_reread = paging.cells_reread;
  r.stand_ins = paging.stand_ins;
  r.proxies_loaded = paging.proxies_loaded;
  r.decode_ms = paging.decode_ms;
  r.decode_ahead_ms = paging.decode_ahead_ms;
  r.bytes_read = cache.bytes_read - last_bytes_read_;
  last_bytes_read_ = cache.bytes_read;
  r.page_errors = cache.errors;
  r.resident_bytes = world_->resident_bytes();
  r.resident_cells = world_->resident_cells();
  r.cache_budget = world_->budget_bytes();
  const uint64_t refs = model_->info().references;
  r.culling_rate = refs > 0 ? 1.0 - std::min(1.0, double(r.primitives_touched) / double(refs)) : 0.0;
  r.working_set_bytes = world_->working_set_bytes();
  r.cache_needed = PagedWorld::budget_for(r.working_set_bytes);
  if (!culler_) {
    r.passes = passes_.count;
    r.unfit = passes_.unfit;
  }
  r.thrashing = r.passes > 1 || r.cells_reread > 0 || r.unfit ||
                r.bytes_read > r.cache_budget || (!culler_ && passes_.overflowed);
}

void Walkthrough::report_oracle(FrameReport& r) {
  if (!oracle_) return;
  oracle_frame_ = oracle_->frame(view_, options_.threads);
  r.oracle_cells = oracle_frame_->cells.size();
  if (!oracle_frame_->cells.empty()) r.oracle_ratio = double(r.cells_touched) / double(oracle_frame_->cells.size());
}

// One frame's clock: when the job queue and paging in must stop, and the quality floor.
struct Walkthrough::FramePlan {
  Clock::time_point start;
  // The job queue stops here; moved once, by kFloorMaxOvertime frame times, for the floor.
  Clock::time_point deadline = Clock::time_point::max();
  // Paging in stops here while other work is queued.
  Clock::time_point page_in_deadline = Clock::time_point::max();
  bool wait_for_all = false;   // wait for every page the image needs (sync paging, no budget)
  uint64_t floor_samples = 0;  // WalkOptions::min_sampled of the view (moving frames, time peg)
  bool overtime = false;       // past the pegged time to reach floor_samples
};

FrameReport Walkthrough::frame(const Camera& camera) { return render_frame(camera, false); }

FrameReport Walkthrough::still_frame(const Camera& camera) { return render_frame(camera, true); }

FrameReport Walkthrough::render_frame(const Camera& camera, bool deferred_now) {
  if (culler_) return culling_frame(camera);
  const auto start = Clock::now();
  FrameReport r;
  r.frame = frames_++;
  r.eye = camera.eye;
  const std::optional<Camera> previous = last_camera_;
  const bool still = previous && same_camera(*previous, camera);
  r.continued = !choose_image(camera, still, deferred_now);
  parked_at_start_ = r.continued ? caster_->parked() + caster_->held() : 0;
  passes_.reclaimed = false;
  last_camera_ = camera;
  FramePlan plan = plan_frame(start, still);
  Counters counters;
  r.stall_ms = render_image(plan, counters);
  // A pegged cut draws the eye's cell from what is resident like any other: no prefetch.
  if (previous && !world_->pegged_cut()) prefetch(camera, *previous);
  const auto finish_start = Clock::now();
  reconstruct_for_display(r);
  r.cells_touched = world_->end_frame(marks_);
  report_image(r, counters);
  image_proxy_pixels_ = r.proxy_pixels;
  last_cut_error_ = r.cut_error;
  const double slack = use_slack(plan);
  report_paging(r);
  r.frame_ms = ms_since(start);
  if (plan.overtime) r.floor_ms = std::max(0.0, r.frame_ms - options_.budget.ms);
  needed_floor_ = r.floor_ms > 0.0;
  r.preview = caster_->preview();
  // The estimate follows increases at once and decreases slowly (a late frame costs more
  // than a few samples).
  const double finish = ms_since(finish_start) - slack;  // the slack is not bookkeeping
  finish_ms_ = finish > finish_ms_ ? finish : 0.9 * finish_ms_ + 0.1 * finish;
  report_oracle(r);
  return r;
}

bool Walkthrough::choose_image(const Camera& camera, bool still, bool deferred_now) {
  const bool lights = shader_->effects().shadows && options_.shadows;
  if (!still) {
    view_ = View(camera, options_.width, options_.height);
    // A still frame is the exact image at once; a moving camera's frames use the pixel error.
    start_image(deferred_now && lights, deferred_now ? 0.0 : options_.pixel_error);
  } else if (caster_->complete() && image_proxy_pixels_ > 0 && image_pixel_error_ > 0.0) {
    // The camera stopped and its image is complete but shows proxies: a finer cut while what it
    // asked for comes in (as long as the cut still changes), then the exact image (pixel error 0).
    const bool changed = world_->cut_changes() != still_cut_changes_;
    still_cut_changes_ = world_->cut_changes();
    still_waits_ = changed ? 0 : still_waits_ + 1;
    const bool refine = world_->requests_outstanding() > 0 && still_waits_ < kStillWaits;
    start_image(image_shadows_, refine ? image_pixel_error_ : 0.0);
  } else if (caster_->complete() && lights && !image_shadows_) {
    // The camera stopped and the image is complete: now the deferred effects, exactly (shadow
    // rays go anywhere, also where no cut was chosen for the view).
    start_image(true, 0.0);
  } else if (world_->pegged_cut() && !caster_->runnable() && !caster_->complete()) {
    // A pegged cut's image cannot finish work that parked (never expected: `parked` says so):
    // the exact image instead.
    start_image(image_shadows_, 0.0);
  } else {
    return false;
  }
  return true;
}

Walkthrough::FramePlan Walkthrough::plan_frame(Clock::time_point start, bool still) const {
  const FrameBudget& budget = options_.budget;
  const auto after = [&](double ms) {
    return start + ms_duration(ms);
  };
  FramePlan plan;
  plan.start = start;
  plan.wait_for_all = options_.sync_paging || (budget.ms <= 0.0 && budget.samples == 0);
  if (budget.ms > 0.0) {
    // A pegged frame time covers everything: the job queue stops early by what reconstruction
    // and bookkeeping took lately (a running estimate), so the frame ends on time.
    plan.deadline = after(std::max(0.5 * budget.ms, budget.ms - finish_ms_));
    // Paging in (decode + subtree build) is frame time too: it gets at most its share
    // (WalkOptions::paging_share) of the frame while other work is queued; the rest waits for
    // the next frame (its work stays parked), so a burst of new cells costs samples over a few
    // frames instead of most of one.
    plan.page_in_deadline = std::min(plan.deadline, after(options_.paging_share * budget.ms));
    // The quality floor (WalkOptions::min_sampled) holds for moving frames under a time peg.
    if (!still) plan.floor_samples = static_cast<uint64_t>(options_.min_sampled * double(view_.pixels()));
  }
  return plan;
}

double Walkthrough::render_image(FramePlan& plan, Counters& counters) {
  const FrameBudget& budget = options_.budget;
  double stall_ms = 0.0;
  // A pegged cut's tree stays as it is until the next image: nothing parks, nothing is placed.
  const bool cut = world_->pegged_cut();
  while (true) {
    // With nothing else to do, paging in may go on, a paging share at a time in a frame that
    // may end early (what it grafts is drawn before the frame ends), to the end of a frame
    // that waits for every page.
    if (!cut && world_->sync(caster_->runnable() ? plan.page_in_deadline : page_in_slice(plan))) {
      caster_->tree_changed();
      caster_->resume_parked();
    }
    if (caster_->complete() || out_of_time(plan)) break;
    if (budget.samples > 0 && counters.samples >= budget.samples) break;
    if (caster_->runnable()) {
      run_slice(plan, counters);
      continue;
    }
    if (cut) break;  // parked work (a bug: the report's parked says so) waits for the next image
    // Only parked (or held) work is left. With no page on its way, the part a pass resumed is
    // done, or what it waits for was dropped for lack of room.
    if (world_->pending() == 0) {
      if (next_pass(plan.wait_for_all)) continue;
      break;
    }
    stall_ms += world_->wait_for_pages(plan.wait_for_all ? Clock::time_point::max() : plan.deadline);
  }
  return stall_ms;
}

double Walkthrough::use_slack(const FramePlan& plan) {
  if (!world_->pegged_cut() || image_pixel_error_ <= 0.0 || options_.budget.ms <= 0.0 || !caster_->complete()) {
    return 0.0;
  }
  // The frame's own end: what is left of its time after the bookkeeping still to come.
  const auto deadline = plan.start + ms_duration(options_.budget.ms - std::min(kSlackReserveMs, 0.1 * options_.budget.ms));
  const auto start = Clock::now();
  bool changed = false;
  // The image is done: what this does only appends to the world (no primitive is renumbered,
  // so the image's ids stay) and is drawn once the next image chooses its cut.
  while (Clock::now() < deadline && world_->requests_outstanding() > 0) {
    const uint64_t before = world_->installs();
    changed = world_->sync(deadline) || changed;
    if (world_->installs() != before) continue;
    // Pages in and nothing placed: what is left does not fit beside what the cut holds.
    if (world_->cells_ready()) break;
    // Nothing arrived to decode: wait a little for the reads asked for.
    std::this_thread::sleep_for(std::chrono::microseconds(300));
  }
  if (changed) caster_->tree_changed();
  return ms_since(start);
}

Clock::time_point Walkthrough::page_in_slice(const FramePlan& plan) const {
  if (plan.wait_for_all || options_.budget.ms <= 0.0) return plan.deadline;
  return std::min(plan.deadline, Clock::now() + ms_duration(options_.paging_share * options_.budget.ms));
}

bool Walkthrough::next_pass(bool finish) {
  const bool stuck = caster_->parked() > 0;
  // Cells of earlier images go first, once a frame: nothing this image holds is read again.
  if (stuck && !passes_.reclaimed) {
    passes_.reclaimed = true;
    keep_ids();
    if (world_->reclaim_untouched(marks_)) {
      resume_renumbered();
      return true;
    }
  }
  passes_.overflowed = passes_.overflowed || stuck;
  if (!finish) return false;  // a budgeted frame degrades: the missing cells' pixels stay reconstructed
  // A pass over one pixel that began with an empty cache and got nowhere: that pixel's cells
  // alone do not fit.
  if (stuck && passes_.count > 1 && passes_.pixels <= 1 && image_samples_ == passes_.samples_at_start) {
    passes_.unfit = true;
    return false;
  }
  // The next part's size from this pass's demand: three quarters of the room for its cells,
  // at most twice this part, and less than this part when this one did not fit.
  keep_ids();
  const uint64_t demand = world_->release_pass(marks_);
  double scale = demand > 0 ? kPassFill * double(world_->decoded_budget()) / double(demand) : 2.0;
  scale = std::min(scale, stuck ? kPassFill : 2.0);
  passes_.pixels = std::max<uint64_t>(1, static_cast<uint64_t>(double(passes_.pixels) * scale));
  ++passes_.count;
  passes_.pixels = caster_->hold_parked(passes_.pixels);
  passes_.samples_at_start = image_samples_;
  resume_renumbered();
  return true;
}

void Walkthrough::resume_renumbered() {
  caster_->renumbered();
  caster_->resume_parked();
}

bool Walkthrough::out_of_time(FramePlan& plan) const {
  if (plan.overtime && image_samples_ >= plan.floor_samples) return true;
  if (Clock::now() < plan.deadline) return false;
  if (plan.overtime || image_samples_ >= plan.floor_samples) return true;
  plan.overtime = true;
  // kFloorMaxOvertime frame times past the pegged end, and never less than that from now: a
  // frame whose start was held up (paging, a descheduled thread) still gets its floor's time
  // instead of ending with no sample (a black frame).
  plan.deadline = std::max(plan.start + ms_duration((1.0 + kFloorMaxOvertime) * options_.budget.ms),
                           Clock::now() + ms_duration(kFloorMaxOvertime * options_.budget.ms));
  return false;
}

void Walkthrough::run_slice(const FramePlan& plan, Counters& counters) {
  const FrameBudget& budget = options_.budget;
  FrameBudget slice;
  if (budget.ms > 0.0) {
    slice.ms = std::max(0.01, std::chrono::duration<double, std::milli>(plan.deadline - Clock::now()).count());
  }
  if (budget.samples > 0) slice.samples = budget.samples - counters.samples;
  if (plan.overtime) slice.samples = plan.floor_samples - image_samples_;
  const uint64_t before = counters.samples;
  caster_->run(slice, counters);
  image_samples_ += counters.samples - before;
}

// The cells the eye will be in over the next frames if it keeps moving as it did. A frame whose
// eye cell is missing can do nothing until that page is in; asking early keeps walks from
// stalling there. Prefetched cells are paged in, not touched.
void Walkthrough::prefetch(const Camera& camera, const Camera& previous) {
  const Vec3 step = camera.eye - previous.eye;
  for (int ahead = 1; ahead <= kPrefetchFrames && glm::length(step) > 0.0; ++ahead) {
    const int32_t c = world_->tree().locate(camera.eye + double(ahead) * step, step);
    if (c != KdTree::kNone && world_->missing(c)) world_->want(c);
  }
}

void Walkthrough::reconstruct_for_display(FrameReport& r) {
  reconstructed_ = false;
  if (options_.reconstruct_each_frame) {
    const auto t = Clock::now();
    image();
    r.reconstruct_ms = ms_since(t);
  }
}

void Walkthrough::report_image(FrameReport& r, const Counters& counters) const {
  r.pinned_bytes = world_->pinned_bytes() + world_->touched_bytes();
  r.primitives_tested = counters.primitives_tested;
  r.nodes_touched = counters.cell_visits;
  r.primitives_touched = counters.primitives_tested;
  r.ray_primitive_tests = counters.ray_primitive_tests;
  r.rays = counters.rays;
  r.samples = counters.samples;
  r.shading_ops = counters.shading_ops;
  r.shadow_rays = counters.shadow_rays;
  r.pixels = view_.pixels();
  r.image_samples = image_samples_;
  r.complete = caster_->complete();
  r.shadows = image_shadows_;
  // Every job that waited in this frame: parked during it, or still parked (or held) from an
  // earlier frame of the image when it began; and what the budget left queued.
  r.parked = counters.parks + parked_at_start_;
  r.unfinished = caster_->queued();
  r.pixel_error = image_pixel_error_;
  if (world_->has_proxies()) {
    const StandInReport s = world_->stand_in_report();
    r.cut_nodes = s.cut_nodes;
    r.proxy_nodes = s.proxy_nodes;
    r.proxy_cells = s.proxy_cells;
    r.requests = s.requests;
    r.cut_error = s.cut_error;
    // Over every pixel, so in parallel: at 1280x720 a frame's millisecond on one thread.
    r.proxy_pixels = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, buffer_.size(), size_t{1} << 14), uint64_t{0},
        [&](const tbb::blocked_range<size_t>& range, uint64_t n) {
          for (size_t i = range.begin(); i < range.end(); ++i) {
            if (!buffer_.sky(i) && buffer_.confirmed(i) && world_->stand_in_prim(buffer_.prim(i))) ++n;
          }
          return n;
        },
        std::plus<>());
  }
}

const std::vector<Rgb>& Walkthrough::image() {
  if (culler_) {
    if (cull_image_.empty()) {
      Counters counters;
      cull_image_ = culler_->shade(*shader_, counters);
    }
    return cull_image_;
  }
  if (!reconstructed_) {
    reconstruct(buffer_, shader_->background());
    reconstructed_ = true;
  }
  return buffer_.image();
}

std::vector<uint32_t> Walkthrough::ids() const {
  if (culler_) return culler_->ids();
  std::vector<uint32_t> out(buffer_.size(), kNoPrim);
  const Scene& scene = world_->scene();
  for (size_t i = 0; i < out.size(); ++i) {
    if (!buffer_.confirmed(i)) continue;
    if (!earlier_ids_.empty() && earlier_ids_[i] != kUnsetId) {
      out[i] = earlier_ids_[i];
      continue;
    }
    const uint32_t p = buffer_.prim(i);
    if (p != kNoPrim) out[i] = scene.prims[p].source;
  }
  return out;
}

// The buffer holds world primitives, which a release renumbers (or unlinks): the source ids of
// the pixels confirmed so far are kept before it.
void Walkthrough::keep_ids() {
  if (earlier_ids_.empty()) earlier_ids_.assign(buffer_.size(), kUnsetId);
  const Scene& scene = world_->scene();
  for (size_t i = 0; i < earlier_ids_.size(); ++i) {
    if (earlier_ids_[i] != kUnsetId || !buffer_.confirmed(i)) continue;
    const uint32_t p = buffer_.prim(i);
    earlier_ids_[i] = p == kNoPrim ? kNoPrim : scene.prims[p].source;
  }
}

}  // namespace frontier
