// Headless store modes. A walk reads its path, opens its outputs, renders frame after frame
// (moving the eye with the walker in walk mode), adds each frame's report into the totals, and
// ends with the summary: in --report as its last line and on stderr.
#include "viewer/headless.h"

#include "src/io/camera_path.h"
#include "src/io/image.h"
#include "viewer/outputs.h"
#include "viewer/walk_mode.h"

#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <sys/resource.h>

#include <algorithm>
#include <fstream>

namespace frontier {
namespace {

double peak_rss_mib() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t i = std::min(v.size() - 1, static_cast<size_t>(p * double(v.size() - 1) + 0.5));
  return v[i];
}

// The cameras of the walk: --path's, or `start` alone without one.
Result<std::vector<Camera>> walk_path(const ViewerOptions& o, const Camera& start) {
  if (o.path_file.empty()) return std::vector<Camera>{start};
  auto cams = read_camera_path(o.path_file);
  if (!cams) return cams.status();
  if (cams->empty()) return Status::invalid_argument(o.path_file + ": the path has no frames");
  return cams;
}

// --report opened for writing and --png-dir and --ids-dir created, when asked for.
Status open_outputs(const ViewerOptions& o, std::ofstream& report) {
  if (!o.report_path.empty()) {
    report.open(o.report_path);
    if (!report) return Status::io_error(o.report_path + ": cannot write");
  }
  if (!o.png_dir.empty()) {
    if (Status s = make_output_dir("--png-dir", o.png_dir); !s) return s;
  }
  if (!o.ids_dir.empty()) {
    if (Status s = make_output_dir("--ids-dir", o.ids_dir); !s) return s;
  }
  return Status::ok();
}

// The path gives where the walker wants to go; collision and gravity decide where it is.
// `eye` carries the walker's position from frame to frame.
Camera walked(Walker& walker, Camera cam, size_t frame, Vec3& eye) {
  const Vec3 look = cam.look_at - cam.eye;
  eye = frame == 0 ? walker.step(cam.eye, cam.eye, 0.0) : walker.step(eye, cam.eye, 1.0 / 30.0);
  cam.eye = eye;
  cam.look_at = eye + look;
  return cam;
}

// What the summary adds up over a walk's frames.
struct WalkTotals {
  std::vector<double> frame_ms;
  double samples = 0.0, ratio_sum = 0.0, ratio_max = 0.0;
  uint64_t bytes_read = 0, ratio_frames = 0, errors = 0, resident_max = 0, collision_max = 0;
  uint64_t complete = 0, floor_frames = 0;
  // The first frame whose image was complete (every pixel sampled, from pages or proxies) and
  // the frame time spent up to its end (-1, 0: none was).
  int64_t first_complete = -1;
  double ms_to_first_complete = 0.0, ms_so_far = 0.0;
  // Thrashing (FrameReport::thrashing): frames, the largest working set and the cache it needs.
  uint64_t thrashing = 0, unfit = 0, cells_reread = 0, working_set_max = 0, frame_read_max = 0;
  // The cache that holds the largest working set (FrameReport::cache_needed of that frame).
  uint64_t cache_needed() const { return PagedWorld::budget_for(working_set_max); }

  void add(const FrameReport& r) {
    thrashing += r.thrashing ? 1 : 0;
    unfit += r.unfit ? 1 : 0;
    cells_reread += r.cells_reread;
    working_set_max = std::max(working_set_max, r.working_set_bytes);
    frame_read_max = std::max(frame_read_max, r.bytes_read);
    frame_ms.push_back(r.frame_ms);
    samples += double(r.samples);
    bytes_read += r.bytes_read;
    errors = r.page_errors;  // cumulative already
    resident_max = std::max(resident_max, r.resident_bytes);
    collision_max = std::max(collision_max, r.collision_bytes);
    complete += r.complete ? 1 : 0;
    ms_so_far += r.frame_ms;
    if (r.complete && first_complete < 0) {
      first_complete = int64_t(frame_ms.size()) - 1;
      ms_to_first_complete = ms_so_far;
    }
    floor_frames += r.floor_ms > 0.0 ? 1 : 0;
    if (r.oracle_ratio) {
      ratio_sum += *r.oracle_ratio;
      ratio_max = std::max(ratio_max, *r.oracle_ratio);
      ++ratio_frames;
    }
  }
  size_t frames() const { return frame_ms.size(); }
  double mean_samples() const { return frames() ? samples / double(frames()) : 0.0; }
};

nlohmann::json summary_json(const ViewerOptions& o, const WalkTotals& t, const Walkthrough& walk,
                            const Walker* walker) {
  const CollisionGrid::Counters grid = walker ? walker->grid().counters() : CollisionGrid::Counters{};
  nlohmann::json summary = {{"frames", t.frames()},
                            {"p50_frame_ms", percentile(t.frame_ms, 0.5)},
                            {"p95_frame_ms", percentile(t.frame_ms, 0.95)},
                            {"mean_samples", t.mean_samples()},
                            {"complete_frames", t.complete},
                            {"first_complete_frame", t.first_complete},
                            {"ms_to_first_complete", t.ms_to_first_complete},
                            {"floor_frames", t.floor_frames},
                            {"peak_rss_mib", peak_rss_mib()},
                            {"max_resident_bytes", t.resident_max},
                            {"cache_budget", walk.world().budget_bytes()},
                            {"total_bytes_read", t.bytes_read},
                            {"page_errors", t.errors},
                            {"collision_queries", walker ? walker->queries() : 0},
                            {"max_collision_bytes", t.collision_max},
                            {"collision_cache_budget", walker ? o.collision_cache : 0},
                            {"collision_loads", grid.loads},
                            {"collision_errors", grid.errors},
                            {"thrashing_frames", t.thrashing},
                            {"unfit_frames", t.unfit},
                            {"cells_reread", t.cells_reread},
                            {"max_working_set_bytes", t.working_set_max},
                            {"cache_needed", t.cache_needed()}};
  if (t.ratio_frames > 0) {
    summary["mean_touched_oracle_ratio"] = t.ratio_sum / double(t.ratio_frames);
    summary["max_touched_oracle_ratio"] = t.ratio_max;
  }
  return summary;
}

void print_summary(const ViewerOptions& o, const WalkTotals& t, const Walkthrough& walk, const Walker* walker) {
  fmt::print(stderr, "frontier-view: {} frames; frame ms p50 {:.1f} p95 {:.1f}; mean samples {:.0f} of {}; "
                     "{} complete{}; {} past the peg for the sample floor; peak RSS {:.0f} MiB "
                     "(resident at most {:.1f} of {:.1f} MiB); read {:.1f} MiB; "
                     "{} page errors{}\n",
             t.frames(), percentile(t.frame_ms, 0.5), percentile(t.frame_ms, 0.95), t.mean_samples(),
             walk.view().pixels(), t.complete,
             t.first_complete >= 0
                 ? fmt::format(" (the first: frame {}, {:.0f} ms into the walk)", t.first_complete, t.ms_to_first_complete)
                 : std::string(),
             t.floor_frames, peak_rss_mib(), double(t.resident_max) / 1048576.0,
             double(walk.world().budget_bytes()) / 1048576.0, double(t.bytes_read) / 1048576.0, t.errors,
             t.ratio_frames ? fmt::format("; touched/oracle mean {:.3f} max {:.3f}", t.ratio_sum / double(t.ratio_frames),
                                          t.ratio_max)
                            : std::string());
  if (!walker) return;
  const CollisionGrid::Counters grid = walker->grid().counters();
  fmt::print(stderr, "frontier-view: collision grid: {} of {} bricks read ({:.1f} ms), at most {:.1f} of {:.1f} MiB "
                     "resident, {} evicted, {} unreadable\n",
             grid.loads, grid.bricks, grid.load_ms, double(t.collision_max) / 1048576.0,
             double(o.collision_cache) / 1048576.0, grid.evictions, grid.errors);
  if (grid.errors > 0) fmt::print(stderr, "frontier-view: {}\n", walker->grid().error().to_string());
}

// --png, --ids and --stats of the frame `walk` rendered last (a still frame, or a path's last).
int write_last_frame(const ViewerOptions& o, Walkthrough& walk, const FrameReport& r) {
  Frame frame;  // only what is written: image() reconstructs, ids() maps every pixel
  if (!o.png_path.empty()) frame.colors = walk.image();
  if (!o.ids_path.empty()) frame.ids = walk.ids();
  frame.stats = r.to_json();
  return write_frame_files(o, walk.view().width, walk.view().height, frame);
}

// Once a run, when frames thrashed: by how much, and the --cache that holds the largest frame.
void print_thrashing(const ViewerOptions& o, const WalkTotals& t, const Walkthrough& walk) {
  if (t.thrashing == 0) return;
  const double mib = 1048576.0;
  fmt::print(stderr,
             "frontier-view: thrashing in {} of {} frames: a frame's cells take up to {:.1f} MiB decoded, more than "
             "the {:.1f} MiB that --cache {} holds for decoded cells, so frames page cells in again ({} cells re-read "
             "within a frame, up to {:.1f} MiB read from the store in one frame); use --cache {:.0f}M or more\n",
             t.thrashing, t.frames(), double(t.working_set_max) / mib, double(walk.world().decoded_budget()) / mib,
             o.cache_text, t.cells_reread, double(t.frame_read_max) / mib, double(t.cache_needed()) / mib);
  if (t.unfit > 0) {
    fmt::print(stderr,
               "frontier-view: {} frames could not complete: the cells one pixel's rays cross do not fit in --cache {}; "
               "use --cache {:.0f}M or more\n",
               t.unfit, o.cache_text, double(t.cache_needed()) / mib);
  }
}

}  // namespace

int store_frame(const ViewerOptions& o, Walkthrough& walk, const Camera& camera) {
  const FrameReport r = walk.still_frame(camera);
  fmt::print(stderr, "{}: {} cells touched, {} paged in ({:.1f} MiB read), {:.1f} ms, {} samples\n", o.scene_path,
             r.cells_touched, r.cells_paged_in, double(r.bytes_read) / 1048576.0, r.frame_ms, r.image_samples);
  WalkTotals totals;
  totals.add(r);
  print_thrashing(o, totals, walk);
  if (!o.ids_dir.empty()) {
    // The still frame is frame 0 of a walk of one camera.
    if (Status s = make_output_dir("--ids-dir", o.ids_dir); !s) return fail(s);
    if (Status s = write_ids(frame_file(o.ids_dir, 0, "ids"), walk.ids()); !s) return fail(s);
  }
  return write_last_frame(o, walk, r);
}

int walk_headless(const ViewerOptions& o, Walkthrough& walk, const Camera& start) {
  auto path = walk_path(o, start);
  if (!path) return fail(path.status());
  const size_t frames = o.frames > 0 ? static_cast<size_t>(o.frames) : path->size();
  WalkMode mode;
  if (o.walk) {
    if (const int code = open_walk_mode(o, walk.model(), mode); code != 0) return code;
  }
  Walker* const walker = mode.walker.get();
  std::ofstream report;
  if (Status s = open_outputs(o, report); !s) return fail(s);
  const size_t png_every = o.png_every > 0 ? size_t(o.png_every) : std::max<size_t>(1, frames / 4);
  WalkTotals totals;
  Vec3 eye = path->front().eye;
  FrameReport r;
  for (size_t f = 0; f < frames; ++f) {
    const Camera& planned = (*path)[std::min(f, path->size() - 1)];
    r = walk.frame(walker ? walked(*walker, planned, f, eye) : planned);
    if (walker) r.add_walk_counters(*walker);
    totals.add(r);
    if (report.is_open()) report << r.to_json().dump() << "\n";
    if (!o.png_dir.empty() && (f % png_every == 0 || f + 1 == frames)) {
      const std::string file = frame_file(o.png_dir, f, "png");
      if (Status s = write_png(file, walk.view().width, walk.view().height, walk.image()); !s) return fail(s);
    }
    if (!o.ids_dir.empty()) {
      if (Status s = write_ids(frame_file(o.ids_dir, f, "ids"), walk.ids()); !s) return fail(s);
    }
  }
  if (report.is_open()) {
    report << nlohmann::json{{"summary", summary_json(o, totals, walk, walker)}}.dump() << "\n";
    if (!report) return fail(Status::io_error(o.report_path + ": cannot write"));
  }
  print_summary(o, totals, walk, walker);
  print_thrashing(o, totals, walk);
  return write_last_frame(o, walk, r);
}

}  // namespace frontier
