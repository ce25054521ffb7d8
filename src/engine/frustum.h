// Frustum casting (Teller & Alex 1998, §3–§5): frusta advance through the k-d tree from the
// eye outward, split where their corner rays disagree about the next cell or where elements
// impinge, and resolve single pixels by ray walking only at 2×2 resolution.
//
// What it keeps from the paper:
// - frustum descriptors whose planes are shared: every pixel column and row of the view is one
//   plane through the eye, computed once per frame, so children reuse the parent's planes and
//   corner rays for free (§3.1);
// - ternary classification of element bounds with straddle inheritance (§4): an element that
//   straddles both planes of an axis is never tested against that axis again in descendants;
// - four corner rays hitting the same nearest element fill the frustum (§4) — here checked per
//   pixel against that element and the few elements that could be nearer, so it stays exact;
//   for a triangle (a floor, a wall) whose interior holds all four corner hits inside the cell,
//   every pixel takes its distance from the plane without a ray of its own (fill_plane); when
//   the hits lie beyond the cell, the few elements ahead in front of the triangle's plane are
//   found in the tree and tested as occluders (fill_plane_ahead);
// - per frame, each cell's elements carry a screen rectangle (of the part beyond the near
//   plane, so a floor reaching behind the eye covers only where it is seen), a lower bound on
//   their distance and the cone of eye directions that can reach them (exact for spheres), so a pixel tests
//   only elements it can hit, nearest first, and stops at the first bound beyond its hit;
// - look-ahead (beyond the paper): a frustum one or two levels above the leaf that cannot
//   advance asks the whole tree which elements could lie in it beyond its cell (node bounds,
//   then each element's own shape against the frustum's planes); when at most four do, its
//   pixels test only those, listed like a cell's elements (or, when the corners all hit one of
//   them, a triangle, take their distance from its plane as fill_plane does), and when none
//   does, it is background. This replaces the strips of lone walks along the images of cell
//   boundaries over floors and open sky (gather_ahead). In a scene of (almost only) triangles,
//   only frusta above twice the leaf size look ahead: smaller ones split into packet leaves;
// - leaf frusta that cannot advance trace their open pixels as ray packets of 4x4 pixels
//   (src/engine/packet.h) from where the frustum is, not one walk per pixel (beyond the paper:
//   one descent, one read of each leaf and a filter over its triangles for 16 rays);
// - lone pixel walks (anchors, blocks packets refuse) reuse the arrival cell of the pixel
//   walked before them when a box test confirms it (NextCells), instead of descending from
//   the rope;
// - near plane; eye outside the root (§4 special case);
// - the job queue of §5.2: levels of a breadth-first subdivision, each level interleaved across
//   the screen, interruptible between jobs by a time or sample budget, resumable next frame
//   (in Z order, siblings in a row while their cells are in cache; a budgeted frame takes
//   the Z order in runs spread over the screen, see order_level).
//
// The implementation is split by topic behind src/engine/frustum_internal.h: frustum.cpp (the
// frame, the job queue and its order, anchors, parking), frustum_advance.cpp (a frustum's
// steps through the cells, splitting), frustum_walk.cpp (lone pixel walks), frustum_resolve.cpp
// (incidence lists, resolving pixels against them), frustum_fill.cpp (plane and §4 fills) and
// frustum_ahead.cpp (look-ahead).
//
// Exactness argument (why frusta may advance): a frustum moves from cell A to cell B only when
// all four corner rays leave A through the same face into B; the frustum's cross-section with
// that face is the convex hull of the corner points, so every interior ray makes the same move,
// and no element of A impinged on the frustum. Elements are tested with conservative bounds.
#pragma once

#include "src/core/counters.h"
#include "src/engine/cell_gate.h"
#include "src/engine/kdtree.h"
#include "src/engine/prim_accel.h"
#include "src/engine/ray_walk.h"
#include "src/core/sample_buffer.h"
#include "src/core/scene.h"
#include "src/engine/shading.h"
#include "src/core/view.h"

#include <array>
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <vector>

namespace frontier {

class PacketLayout;

// When to stop working on a frame (paper §5.5: peg either frame time or sample count).
struct FrameBudget {
  double ms = 0.0;       // 0: no time limit
  uint64_t samples = 0;  // 0: no sample limit
};

class FrustumCaster {
 public:
  // `threads` worker threads (0: all cores).
  FrustumCaster(const Scene& scene, const KdTree& tree, const Shader& shader, int threads);
  ~FrustumCaster();

  // Frusta of at most `pixels` × `pixels` that still need work resolve their pixels
  // individually: as 4×4 ray packets in a scene of (almost only) triangles (packets_apply()),
  // else by walking them one by one (the paper walks 2 × 2). Larger leaves trade frustum
  // bookkeeping for per-pixel work.
  // REQUIRES: pixels >= 2. Default kDefaultLeafPixels.
  static constexpr int kDefaultLeafPixels = 16;
  void set_leaf_pixels(int pixels) { leaf_ = pixels < 2 ? 2 : pixels; }
  // In-memory scenes (no gate): packets trace through Embree's BVH over the scene with the same
  // exact tests (prim_accel.h; built at the first begin()) or through the k-d tree, whichever
  // traces faster (KernelChoice, measured as they run); false: the k-d tree alone.
  void set_accel(bool on) { use_accel_ = on; }

  // Previews (in budgeted runs of a scene of triangles): each leaf
  // frustum first traces only points of its quadrant subdivision about 4 pixels apart (1/25 of
  // its pixels) and comes back for the rest after every leaf has had its preview, so a frame
  // whose budget ends among the leaves shows the unfinished ones at that resolution instead of
  // interpolated from anchors 32 pixels apart. It costs sampled pixels: the preview's rays are
  // far apart, so its packets share little. A 20 M terrain's pegged orbit at 1280x720 with
  // previews in every frame sampled 0.40-0.50 of its geometry pixels against 0.62-0.80 (same
  // PSNR); its fly-over, whose frames run to the sample floor anyway, 0.20-0.26 against
  // 0.29-0.32, at 23.6-24.2 dB against 23.5-23.8, and showed its horizon and ridges where it
  // showed blocks of blur. Off by default; Walkthrough turns it on after a frame that needed
  // its sample floor. A leaf already previewed finishes either way when it is changed mid-image.
  void set_preview(bool on) { preview_ = on; }
  bool preview() const { return preview_; }

  // Starts a new frame for `view`; the buffer's frame stamp advances (nothing is cleared).
  // `shade` false resolves visibility only (no lighting work); `shadows` enables the deferred
  // shadow effect when the scene declares lights.
  void begin(const View& view, SampleBuffer& buffer, CellMarks& marks, bool shade, bool shadows);
  // Runs queued jobs until the frame is complete or the budget (time or samples of this call)
  // is spent; counters accumulate.
  // Returns true when every pixel is resolved. May be called again to continue the frame.
  bool run(const FrameBudget& budget, Counters& counters);
  // Every pixel resolved: no queued and no parked work.
  bool complete() const;
  // Queued work that run() could do now (parked work excluded).
  bool runnable() const;
  // Jobs queued that run() could do now (work a frame left unfinished when its budget ended).
  size_t queued() const;

  // Paging. With a gate set, a frustum or pixel that reaches a missing cell is parked (see
  // CellGate); run() does everything else and returns. After cells arrived, the owner calls
  // tree_changed() (the tree grew or changed between slices: per-cell state is resized, this
  // frame's marks kept) and resume_parked(), which queues the parked work again from the eye.
  // REQUIRES for both: no run() in progress.
  void set_gate(CellGate* gate) {
    gate_ = gate;
    cone_terms_.clear();  // a paged scene changes under a frame
    sphere_terms_.clear();
  }
  void tree_changed();
  size_t parked() const;
  void resume_parked();

  // Frames whose cells do not all fit in memory at once are rendered in passes, each over a
  // part of the parked work (Walkthrough). Confirmed pixels stay confirmed across passes.
  // REQUIRES for both: no run() in progress and nothing runnable (only parked work left).
  // renumbered(): the tree's cells were renumbered (compacted) since the last slice: this
  // frame's per-cell state (marks, incidence lists) is dropped; parked work is kept.
  void renumbered();
  // Orders the parked and held work by screen position (Z order) and leaves parked only the
  // first jobs of at most `pixels` pixels in all (at least one job; a first job larger than
  // that is split in halves until it fits); the rest is held back from
  // resume_parked() until a later call. Returns the pixels of the jobs left parked.
  uint64_t hold_parked(uint64_t pixels);
  // Jobs held back by hold_parked(); complete() is false while there are any.
  size_t held() const;

 private:
  struct Job;
  struct Incidence;
  struct Worker;
  struct AheadPlanes;
  enum class Side : uint8_t { Inside, Straddle, Outside };
  enum class Step : uint8_t;

  void process(Job job, Worker& w);
  Step enter_root(Job& job, const std::array<Ray, 4>& rays, const std::array<double, 4>& tmins, Worker& w);
  Step resolve_cell_elements(const Job& job, const std::array<Ray, 4>& rays, const std::array<double, 4>& tmins,
                             Worker& w);
  Step advance(Job& job, const std::array<Ray, 4>& rays, Worker& w);
  bool look_ahead(const Job& job, const std::array<Ray, 4>& rays, const std::array<double, 4>& tmins, Worker& w);
  Side classify(const Vec3& normal, const Aabb& box) const;
  bool in_front(const Aabb& box) const;
  bool gather_ahead(const Job& job, const std::array<Ray, 4>& rays, const Triangle* before, size_t limit,
                    Worker& w) const;
  AheadPlanes ahead_planes(const Job& job, const std::array<Ray, 4>& rays, const Triangle* before) const;
  bool gather_cell(const Job& job, int32_t cell, uint16_t node_planes, const AheadPlanes& planes, size_t limit,
                   size_t& budget, Worker& w) const;
  void push_children(int32_t node, uint16_t node_planes, const Aabb& box, const AheadPlanes& planes,
                     Worker& w) const;
  bool fill_plane_ahead(const Job& job, const Incidence* list, uint32_t n, const std::array<Ray, 4>& rays,
                        const std::array<double, 4>& tmins, Worker& w);
  uint32_t plane_candidate(const Job& job, const Incidence* list, uint32_t n, const std::array<Ray, 4>& rays,
                           const std::array<double, 4>& tmins, const Aabb* cell, Vec3& normal, double& max_t,
                           Worker& w) const;
  bool add_list_occluders(const Job& job, const Incidence* list, uint32_t n, uint32_t element, const Vec3& normal,
                          double max_t, Worker& w) const;
  void resolve_against_ahead(const Job& job, const std::array<Ray, 4>& rays, const std::array<double, 4>& tmins,
                             Worker& w);
  bool classify_planes(int x0, int x1, int y0, int y1, const Aabb& box, uint8_t planes, uint8_t& straddle) const;
  bool collect(const Job& job, Worker& w);
  void resolve_by_walking(const Job& job, Worker& w, bool from_next_cell);
  void walk_open_pixel(const Job& job, int x, int y, const Ray& ray, double tmin, Worker& w, bool from_next_cell);
  void resolve_by_packets(const Job& job, Worker& w, bool from_next_cell);
  void trace_preview(const Job& job, Worker& w, bool from_next_cell);
  void trace_packet(const Job& job, const int* px, const int* py, int n, Worker& w, bool from_next_cell);
  // Leaf frusta go on as ray packets: the scene is (almost) all triangles. Packets filter only
  // triangles and test other primitives exactly per lane, where a walk's cell lists skip most
  // (rings.nff, all spheres and cones, ran at half speed with packets); a few curved primitives
  // among millions of triangles must not send every frustum walking (an 8 M-triangle mountain
  // under four spheres at 1280x720: a sample on 0.27 of the worst frame's geometry pixels once
  // a sphere's cell was paged in, against 0.6 while proxies stood in for them).
  bool packets_apply() const { return 64 * (scene_.size() - scene_.triangles.size()) <= scene_.size(); }
  template <typename Visit>
  void for_each_open_pixel(const Job& job, const Visit& visit) const;
  // Pixel rectangle covered by a reference's bounds. `bounded` is false when the bounds reach
  // behind the eye plane: then the rectangle is the whole view and plane tests decide.
  struct PixelRect {
    int x0, y0, x1, y1;
    bool bounded = true;
  };
  struct CellCache;
  const std::vector<Incidence>& cell_entries(int32_t cell) const;
  Incidence incidence(uint32_t r, const Aabb& box) const;
  // True for the first lone pixel walk into a cell not yet listed this frame (see walk_pixel).
  bool first_pixel_visit(int32_t cell) const;
  // Walks one pixel; parks it (and returns no hit with `parked` set) at a missing cell.
  RayHit walk_pixel(int x, int y, const Ray& ray, double tmin, int32_t cell, Worker& w, bool& parked) const;
  bool gate_missing(int32_t cell) const;
  void park(const Job& job, Worker& w) const;
  double footprint(const Job& job, const Incidence* list, uint32_t n, Worker& w) const;
  size_t resolve_pixel_major(const Job& job, const Incidence* list, uint32_t n, bool to_infinity, Worker& w);
  size_t resolve_in_cell(const Job& job, const Incidence* list, uint32_t n, bool have_rects, Worker& w);
  bool corners_and_fill(const Job& job, const Incidence* list, uint32_t n, const std::array<Ray, 4>& rays,
                        const std::array<double, 4>& tmins, Worker& w);
  void fill_background(const Job& job, Worker& w);
  bool try_fill(const Job& job, const Incidence* list, uint32_t n, uint32_t element, Worker& w);
  bool fill_plane(const Job& job, const Incidence* list, uint32_t n, const std::array<Ray, 4>& rays,
                  const std::array<double, 4>& tmins, const Aabb* cell, Worker& w);
  bool corners_on_triangle(const Triangle& tri, const std::array<Ray, 4>& rays, const std::array<double, 4>& tmins,
                           const Aabb* cell, Vec3& normal, double& max_t, Worker& w) const;
  void fill_from_plane(const Job& job, uint32_t element, const Vec3& normal, Worker& w);
  bool coplanar(uint32_t prim, uint32_t element, const Vec3& normal) const;
  void split(const Job& job, const Incidence* list, uint32_t n, Worker& w);
  void park_pixel(int x, int y, Worker& w) const;
  void reopen_unshaded();
  bool claim(const Job& job, int x, int y, size_t i) const;
  void confirm(const Job& job, int x, int y, uint32_t prim, double t, const Ray& ray, Worker& w);
  void flush_samples(Worker& w);
  void finish_level();
  static void order_level(std::vector<Job>& level, bool budgeted);
  Worker& current_worker();
  void compute_eye_terms(const View& view);
  void reset_workers(size_t pixels);
  void queue_root();
  void plan_anchors(int width, int height);
  template <typename OutOfBudget>
  void walk_anchors(const OutOfBudget& out_of_budget);

  const Scene& scene_;
  const KdTree& tree_;
  CellGate* gate_ = nullptr;
  const Shader& shader_;
  View view_;
  SampleBuffer* buffer_ = nullptr;
  CellMarks* marks_ = nullptr;
  int leaf_ = kDefaultLeafPixels;
  bool shade_ = true;
  bool budgeted_ = false;  // this run() has a time or sample budget (resolve_by_packets previews)
  bool preview_ = false;   // leaves trace their previews first (set_preview)
  bool shadows_ = true;
  double slack_scale_ = 1.0;

  // Every cone's and sphere's terms that depend only on the eye, for this frame (in-memory
  // scenes of at most kMaxEyeTerms of each; a paged scene changes under the frame). offer()
  // uses them.
  static constexpr size_t kMaxEyeTerms = size_t{1} << 16;
  std::vector<ConeFromOrigin> cone_terms_;
  std::vector<SphereFromOrigin> sphere_terms_;
  void offer(uint32_t prim, const Ray& ray, double tmin, double tmax, RayHit& best, Counters& counters) const;
  // Leaves laid out for ray packets (resolve_by_packets), made on the first frame of a tree
  // that does not change (no gate); a paged tree's packets read its cells directly.
  std::unique_ptr<PacketLayout> packet_layout_;
  bool use_accel_ = true;
  std::unique_ptr<PrimAccel> accel_;
  KernelChoice kernel_choice_;  // Embree's BVH or the k-d tree, whichever traces faster
  std::vector<Vec3> column_normal_;  // plane of pixel column x, oriented towards larger x
  std::vector<Vec3> row_normal_;     // plane of pixel row y, oriented towards larger y

  // Per-cell incidence prototypes of this frame (see cell_entries).
  uint32_t frame_ = 0;
  // Makes cell_cache_ hold at least `cells` entries, keeping those it has.
  void grow_cell_cache(size_t cells);
  size_t cell_cache_count_ = 0;
  std::unique_ptr<CellCache[]> cell_cache_;
  mutable std::array<std::mutex, 64> cell_locks_;

  // Reconstruction anchors (§5.2, §5.4): the pixels at the corners, edge midpoints and centres
  // of the quadrant subdivision (the one frusta and reconstruction use) down to rectangles of
  // kAnchorSpacing pixels, coarse to fine. A budgeted image walks them before its frusta, so an
  // image stopped early still has exact samples spread over the screen where reconstruction
  // interpolates from (frusta that finish whole blocks would leave it a few confirmed blocks).
  // Unbudgeted runs skip them: the frusta cover every pixel anyway. Anchors are walked one by
  // one from the eye, which costs more per sample than frusta, so the spacing trades samples
  // per budgeted frame against the quality of an image stopped early (bench_accuracy --knobs
  // samples measures both): finer spacing costs samples, coarser loses quality quickly.
  static constexpr int kAnchorSpacing = 32;
  std::vector<uint32_t> anchors_;  // pixel indices, for an image of anchor_width_ × anchor_height_
  int anchor_width_ = 0, anchor_height_ = 0;
  size_t anchors_next_ = 0;        // first anchor of this image not yet walked

  std::vector<Job> current_;                      // jobs of the current level not yet run
  std::vector<Job> held_;                         // parked work held back (hold_parked)
  bool level_ordered_ = false;                    // current_ is in order_level's order
  std::vector<std::vector<Incidence>> arenas_in_;  // incidence lists the current level reads
  std::vector<std::unique_ptr<Worker>> workers_;
  std::atomic<uint64_t> samples_done_{0};  // samples confirmed in this run() (sample budgets only)
  bool count_samples_ = false;
  int threads_ = 1;
  struct Arena;
  std::unique_ptr<Arena> arena_;
};

}  // namespace frontier
