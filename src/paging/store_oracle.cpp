// StoreOracle: exact two-level ray walking over a store (see store_oracle.h).
#include "src/paging/store_oracle.h"

#include "src/engine/ray_walk.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>

namespace frontier {

struct StoreOracle::CellGeometry {
  Scene scene;
  KdTree tree;
};

StoreOracle::StoreOracle(const StoreModel& model, size_t max_cells)
    : model_(model), top_(KdTree::top_only(model.nodes(), model.info().bounds)), max_cells_(std::max<size_t>(1, max_cells)) {}

StoreOracle::~StoreOracle() = default;

std::shared_ptr<const StoreOracle::CellGeometry> StoreOracle::cell(uint32_t c, uint64_t& errors) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = cells_.find(c);
    if (it != cells_.end()) {
      lru_.splice(lru_.begin(), lru_, it->second.second);
      return it->second.first;
    }
  }
  auto g = std::make_shared<CellGeometry>();
  if (Status s = model_.read_cell(c, g->scene); !s) {
    ++errors;
    g->scene = Scene{};
  }
  KdBuildOptions options;
  options.root = model_.cells()[c].bounds;
  g->tree = KdTree::build(g->scene, options);
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = cells_.find(c);
  if (it != cells_.end()) return it->second.first;
  lru_.push_front(c);
  cells_.emplace(c, std::make_pair(g, lru_.begin()));
  while (cells_.size() > max_cells_) {
    cells_.erase(lru_.back());
    lru_.pop_back();
  }
  return g;
}

OracleFrame StoreOracle::frame(const View& view, int threads) {
  OracleFrame out;
  out.ids.assign(view.pixels(), kNoPrim);
  const size_t ncells = model_.cells().size();
  std::vector<std::atomic<uint8_t>> seen(ncells);
  std::atomic<uint64_t> errors{0};
  tbb::task_arena arena(threads > 0 ? threads : tbb::info::default_concurrency());
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, view.height), [&](const tbb::blocked_range<int>& rows) {
      Counters counters;
      uint64_t local_errors = 0;
      for (int y = rows.begin(); y != rows.end(); ++y) {
        for (int x = 0; x < view.width; ++x) {
          const Ray ray = view.ray(x, y);
          const double tmin = view.tmin(ray);
          double t_in = tmin;
          int32_t c = top_.locate(ray.at(tmin), ray.dir);
          if (c == KdTree::kNone) {
            int face;
            c = top_.enter_root(ray, tmin, t_in, face);
            t_in = std::max(t_in, tmin);
          }
          size_t steps = ncells + 16;
          while (c != KdTree::kNone && steps-- > 0) {
            seen[size_t(c)].store(1, std::memory_order_relaxed);
            const KdTree::Exit e = top_.exit(c, ray);
            const StoreCell& sc = model_.cells()[size_t(c)];
            if (sc.page != StoreCell::kNoPage) {
              auto g = cell(static_cast<uint32_t>(c), local_errors);
              if (g->scene.size() > 0) {
                // Enter the cell's subtree where the ray enters the cell (clamped into it).
                Vec3 p = ray.at(t_in);
                p = glm::clamp(p, sc.bounds.lo, sc.bounds.hi);
                const int32_t start = g->tree.descend(0, p, ray.dir);
                const RayHit hit = walk_ray(g->scene, g->tree, ray, tmin, start, counters, nullptr);
                if (hit.hit()) {
                  out.ids[size_t(y) * size_t(view.width) + size_t(x)] = g->scene.prims[hit.prim].source;
                  break;
                }
              }
            }
            t_in = std::max(t_in, e.t);
            c = top_.arrival(c, ray, e);
          }
        }
      }
      errors += local_errors;
    });
  });
  for (size_t c = 0; c < ncells; ++c) {
    if (seen[c].load(std::memory_order_relaxed)) out.cells.push_back(static_cast<uint32_t>(c));
  }
  out.page_errors = errors.load();
  return out;
}

}  // namespace frontier
