// Renderer: the ray-casting strategies' dispatch; RayCastFrameRenderer: the same behind the
// FrameRenderer interface.
#include "src/engine/render.h"

#include "src/engine/packet.h"
#include "src/engine/ray_walk.h"

#include <nlohmann/json.hpp>

#include <tbb/blocked_range2d.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>

namespace frontier {

const char* method_name(Method method) {
  switch (method) {
    case Method::Brute: return "brute";
    case Method::RayWalk: return "raywalk";
    case Method::Frustum: return "frustum";
    case Method::Packet: return "packet";
  }
  return "?";
}

struct Renderer::Arena {
  explicit Arena(int threads) : arena(threads) {}
  tbb::task_arena arena;
};

Renderer::Renderer(const Scene& scene, const KdTree& tree, int threads)
    : scene_(scene),
      tree_(tree),
      threads_(threads > 0 ? threads : tbb::info::default_concurrency()),
      shader_(scene, tree),
      arena_(std::make_unique<Arena>(threads_)) {}

Renderer::~Renderer() = default;

Counters Renderer::render(const View& view, const RenderOptions& options, SampleBuffer& buffer) {
  Counters total;
  const auto start = std::chrono::steady_clock::now();
  if (options.method == Method::Frustum) {
    if (!caster_) caster_ = std::make_unique<FrustumCaster>(scene_, tree_, shader_, threads_);
    caster_->set_leaf_pixels(options.leaf_pixels);
    caster_->set_accel(options.accel);
    caster_->begin(view, buffer, marks_, options.shade, options.shadows);
    caster_->run(options.budget, total);
  } else {
    buffer.resize(view.width, view.height);
    buffer.begin_frame();
    marks_.resize(tree_.cells().size());
    marks_.begin_frame();
    tbb::enumerable_thread_specific<Counters> local;
    if (options.method == Method::Packet && !layout_) layout_ = std::make_unique<PacketLayout>(scene_, tree_);
    if (options.method == Method::Packet && options.accel && !accel_) {
      accel_ = std::make_unique<PrimAccel>(PrimAccel::build(scene_));
    }
    const PrimAccel* accel = options.accel ? accel_.get() : nullptr;
    // A factory, not constructor arguments: those the container would keep copies of (the scene).
    tbb::enumerable_thread_specific<PacketTracer> tracers(
        [&] {
          return PacketTracer(scene_, tree_, &marks_, nullptr, layout_.get(), accel, &kernel_choice_);
        });
    const auto finish = [&](int x, int y, const Ray& ray, const RayHit& hit, Counters& c) {
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(view.width) + static_cast<size_t>(x);
      buffer.claim_exclusive(i);  // the blocks partition the image
      const Rgb color = options.shade ? shader_.shade(hit.prim, ray, hit.t, options.shadows, c) : Rgb{};
      buffer.set(i, hit.prim, hit.t, color);
      ++c.rays;
      ++c.samples;
    };
    arena_->arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range2d<int>(0, view.height, 8, 0, view.width, 8),
                        [&](const tbb::blocked_range2d<int>& r) {
        Counters& c = local.local();
        if (options.method == Method::Packet) {
          // 4x4 blocks of the range, each a packet; a packet the tracer refuses is walked.
          PacketTracer& tracer = tracers.local();
          for (int y0 = r.rows().begin(); y0 < r.rows().end(); y0 += 4) {
            for (int x0 = r.cols().begin(); x0 < r.cols().end(); x0 += 4) {
              RayPacket packet;
              int px[kPacketRays], py[kPacketRays];
              for (int y = y0; y < std::min(y0 + 4, r.rows().end()); ++y) {
                for (int x = x0; x < std::min(x0 + 4, r.cols().end()); ++x) {
                  const Ray ray = view.ray(x, y);
                  px[packet.count] = x;
                  py[packet.count] = y;
                  packet.add(ray, view.tmin(ray));
                }
              }
              PacketResult result;
              if (tracer.trace(packet, result, c)) {
                for (int l = 0; l < packet.count; ++l) finish(px[l], py[l], packet.rays[l], result.hit[l], c);
                continue;
              }
              for (int l = 0; l < packet.count; ++l) {
                const RayHit hit = cast_ray(scene_, tree_, packet.rays[l], packet.tmin[l], c, &marks_);
                ++c.rays_walked;
                finish(px[l], py[l], packet.rays[l], hit, c);
              }
            }
          }
          return;
        }
        for (int y = r.rows().begin(); y != r.rows().end(); ++y) {
          for (int x = r.cols().begin(); x != r.cols().end(); ++x) {
            const Ray ray = view.ray(x, y);
            const double tmin = view.tmin(ray);
            const RayHit hit = options.method == Method::Brute
                                   ? brute_force_hit(scene_, ray, tmin, c)
                                   : cast_ray(scene_, tree_, ray, tmin, c, &marks_);
            finish(x, y, ray, hit, c);
            if (options.method == Method::RayWalk) ++c.rays_walked;
          }
        }
      });
    });
    for (const Counters& c : local) total += c;
    total.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  }
  reconstruct(buffer, shader_.background());
  return total;
}

Counters render_frame(const Scene& scene, const KdTree& tree, const View& view,
                      const RenderOptions& options, SampleBuffer& buffer) {
  Renderer renderer(scene, tree, options.threads);
  return renderer.render(view, options, buffer);
}

RayCastFrameRenderer::RayCastFrameRenderer(const Scene& scene, const KdTree& tree, const RenderOptions& options)
    : scene_(scene), tree_(tree), options_(options), renderer_(scene, tree, options.threads) {}

Result<Frame> RayCastFrameRenderer::render(const View& view) {
  const Counters counters = renderer_.render(view, options_, buffer_);
  Frame frame;
  frame.colors = buffer_.image();
  frame.ids = id_image(scene_, buffer_);
  frame.ms = counters.ms;
  frame.stats = counters.to_json();
  frame.stats["method"] = method_name(options_.method);
  frame.stats["width"] = view.width;
  frame.stats["height"] = view.height;
  frame.stats["primitives"] = scene_.size();
  frame.stats["cells"] = tree_.cells().size();
  frame.stats["shadows_declared"] = !scene_.lights.empty();
  return frame;
}

std::vector<uint32_t> id_image(const Scene& scene, const SampleBuffer& buffer) {
  std::vector<uint32_t> ids(buffer.size(), kNoPrim);
  for (size_t i = 0; i < ids.size(); ++i) {
    if (buffer.confirmed(i) && buffer.prim(i) != kNoPrim) ids[i] = scene.prims[buffer.prim(i)].source;
  }
  return ids;
}

}  // namespace frontier
