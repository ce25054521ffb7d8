// Primary-ray throughput of frontier (frustum casting, ray walking) against Embree 3 on triangle
// scenes, visibility only: every method casts the same rays (View::ray per pixel centre, tnear =
// View::tmin) into the same triangles (curved NFF primitives tessellated first, src/core/tessellate.h),
// on the same number of threads, in the same process. Frontier's frustum casting and packets are
// measured as they run (their rays through Embree's BVH with frontier's exact tests,
// src/engine/prim_accel.h) and through the k-d tree alone ("k-d kernel"). Embree is measured with rtcIntersect1 per
// ray, 8- and 16-wide packets (4x2 and 4x4 pixels of a tile) and rtcIntersect1M streams of a
// whole tile. Each figure is the best of --repeats frames.
//
// Correctness check: per method, the share of pixels whose first-hit input primitive (source id)
// equals frustum casting's; Embree works in float, frontier in double, so only ties and
// float-rounding near-ties may differ. A low figure means the rays differ: do not trust the row.
//
// Prints a Markdown table (ratios against frustum casting and ray walking of the same run) and,
// with --json FILE, one JSON object per row and line.
#include "src/engine/kdtree.h"
#include "src/engine/prim_accel.h"
#include "src/engine/render.h"
#include "src/core/scene.h"
#include "src/core/tessellate.h"
#include "src/core/view.h"
#include "src/io/load_scene.h"

#include <CLI/CLI.hpp>
#include <embree3/rtcore.h>
#include <fmt/core.h>
#include <nlohmann/json.hpp>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

using namespace frontier;

namespace {

constexpr int kTile = 16;  // pixels per tile side: a parallel task, a stream, 8 packets of 4x4

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// The Embree ray of pixel (x, y): frontier's ray in float.
struct FloatRay {
  float org[3], dir[3], tnear;
};
FloatRay float_ray(const View& view, int x, int y) {
  const Ray r = view.ray(x, y);
  const double tnear = view.tmin(r);
  return {{float(r.origin.x), float(r.origin.y), float(r.origin.z)},
          {float(r.dir.x), float(r.dir.y), float(r.dir.z)},
          float(tnear)};
}

enum class EmbreeMethod { Single, Packet8, Packet16, Stream };

const char* embree_name(EmbreeMethod m) {
  switch (m) {
    case EmbreeMethod::Single: return "embree rtcIntersect1";
    case EmbreeMethod::Packet8: return "embree rtcIntersect8 (4x2)";
    case EmbreeMethod::Packet16: return "embree rtcIntersect16 (4x4)";
    case EmbreeMethod::Stream: return "embree rtcIntersect1M (tile)";
  }
  return "?";
}

// A packet of W rays over a 4 x (W / 4) block of pixels at (x0, y0); pixels outside the image are
// masked off. RayHitW is RTCRayHit8 or RTCRayHit16 (structure of arrays).
template <int W, typename RayHitW>
void setup_packet(const View& view, int x0, int y0, RayHitW& rh, int* valid) {
  for (int k = 0; k < W; ++k) {
    const int x = x0 + k % 4, y = y0 + k / 4;
    valid[k] = x < view.width && y < view.height ? -1 : 0;
    const FloatRay r = float_ray(view, std::min(x, view.width - 1), std::min(y, view.height - 1));
    rh.ray.org_x[k] = r.org[0];
    rh.ray.org_y[k] = r.org[1];
    rh.ray.org_z[k] = r.org[2];
    rh.ray.dir_x[k] = r.dir[0];
    rh.ray.dir_y[k] = r.dir[1];
    rh.ray.dir_z[k] = r.dir[2];
    rh.ray.tnear[k] = r.tnear;
    rh.ray.tfar[k] = std::numeric_limits<float>::infinity();
    rh.ray.time[k] = 0.0f;
    rh.ray.mask[k] = 0xFFFFFFFFu;
    rh.ray.id[k] = unsigned(k);
    rh.ray.flags[k] = 0;
    rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID[k] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
  }
}

template <int W, typename RayHitW>
void store_packet(const View& view, int x0, int y0, const RayHitW& rh, std::vector<uint32_t>& prim) {
  for (int k = 0; k < W; ++k) {
    const int x = x0 + k % 4, y = y0 + k / 4;
    if (x >= view.width || y >= view.height) continue;
    prim[size_t(y) * size_t(view.width) + size_t(x)] =
        rh.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID ? kNoPrim : rh.hit.primID[k];
  }
}

void set_ray(RTCRayHit& rh, const FloatRay& r) {
  rh.ray.org_x = r.org[0];
  rh.ray.org_y = r.org[1];
  rh.ray.org_z = r.org[2];
  rh.ray.dir_x = r.dir[0];
  rh.ray.dir_y = r.dir[1];
  rh.ray.dir_z = r.dir[2];
  rh.ray.tnear = r.tnear;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.time = 0.0f;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
}

// Casts every pixel's ray with `method`; prim[pixel] = Embree primID (index into the scene's
// primitives) or kNoPrim. Tiles of kTile x kTile pixels are the parallel tasks.
void embree_frame(RTCScene rtc, const View& view, EmbreeMethod method, std::vector<uint32_t>& prim) {
  const int tiles_x = (view.width + kTile - 1) / kTile, tiles_y = (view.height + kTile - 1) / kTile;
  tbb::parallel_for(tbb::blocked_range<int>(0, tiles_x * tiles_y), [&](const tbb::blocked_range<int>& range) {
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    // Primary rays of a tile are coherent; the flag matters to streams (and is a hint elsewhere).
    if (method != EmbreeMethod::Single) context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    for (int tile = range.begin(); tile != range.end(); ++tile) {
      const int x0 = (tile % tiles_x) * kTile, y0 = (tile / tiles_x) * kTile;
      const int x1 = std::min(view.width, x0 + kTile), y1 = std::min(view.height, y0 + kTile);
      switch (method) {
        case EmbreeMethod::Single:
          for (int y = y0; y < y1; ++y) {
            for (int x = x0; x < x1; ++x) {
              RTCRayHit rh;
              set_ray(rh, float_ray(view, x, y));
              rtcIntersect1(rtc, &context, &rh);
              prim[size_t(y) * size_t(view.width) + size_t(x)] =
                  rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? kNoPrim : rh.hit.primID;
            }
          }
          break;
        case EmbreeMethod::Packet8:
          for (int y = y0; y < y1; y += 2) {
            for (int x = x0; x < x1; x += 4) {
              RTCRayHit8 rh;
              alignas(32) int valid[8];
              setup_packet<8>(view, x, y, rh, valid);
              rtcIntersect8(valid, rtc, &context, &rh);
              store_packet<8>(view, x, y, rh, prim);
            }
          }
          break;
        case EmbreeMethod::Packet16:
          for (int y = y0; y < y1; y += 4) {
            for (int x = x0; x < x1; x += 4) {
              RTCRayHit16 rh;
              alignas(64) int valid[16];
              setup_packet<16>(view, x, y, rh, valid);
              rtcIntersect16(valid, rtc, &context, &rh);
              store_packet<16>(view, x, y, rh, prim);
            }
          }
          break;
        case EmbreeMethod::Stream: {
          RTCRayHit rays[kTile * kTile];
          unsigned n = 0;
          for (int y = y0; y < y1; ++y) {
            for (int x = x0; x < x1; ++x) set_ray(rays[n++], float_ray(view, x, y));
          }
          rtcIntersect1M(rtc, &context, rays, n, sizeof(RTCRayHit));
          n = 0;
          for (int y = y0; y < y1; ++y) {
            for (int x = x0; x < x1; ++x, ++n) {
              prim[size_t(y) * size_t(view.width) + size_t(x)] =
                  rays[n].hit.geomID == RTC_INVALID_GEOMETRY_ID ? kNoPrim : rays[n].hit.primID;
            }
          }
          break;
        }
      }
    }
  });
}

struct EmbreeScene {
  RTCScene scene = nullptr;
  double build_ms = 0.0;
};

// One triangle geometry, primID = index into scene.prims (all triangles).
EmbreeScene build_embree(RTCDevice device, const Scene& scene, RTCBuildQuality quality) {
  const auto t0 = std::chrono::steady_clock::now();
  RTCScene rtc = rtcNewScene(device);
  rtcSetSceneBuildQuality(rtc, quality);
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetGeometryBuildQuality(geom, quality);
  const size_t n = scene.size();
  // rtcSetNewGeometryBuffer pads and aligns the buffers as Embree's SIMD loads need.
  auto* vertices = static_cast<float*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n));
  auto* indices = static_cast<unsigned*>(
      rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), n));
  for (size_t i = 0; i < n; ++i) {
    const Triangle& t = scene.triangles[scene.prims[i].index];
    const Vec3 v[3] = {t.v0, t.v1, t.v2};
    for (size_t k = 0; k < 3; ++k) {
      for (int a = 0; a < 3; ++a) vertices[9 * i + 3 * k + size_t(a)] = float(v[k][a]);
      indices[3 * i + k] = unsigned(3 * i + k);
    }
  }
  rtcCommitGeometry(geom);
  rtcAttachGeometry(rtc, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(rtc);
  return {rtc, ms_since(t0)};
}

struct Build {
  std::string scene;
  size_t triangles = 0;
  double kd_ms = 0.0, embree_ms = 0.0, accel_ms = 0.0;
};

struct Row {
  std::string method;
  double ms = 0.0;
  double build_ms = 0.0;
  std::vector<uint32_t> ids;  // source id per pixel, kNoPrim for background
};

void embree_error(void*, RTCError code, const char* message) {
  fmt::print(stderr, "bench_embree: Embree error {}: {}\n", int(code), message ? message : "");
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_embree: primary rays/s of frustum casting and ray walking against Embree 3"};
  std::vector<std::string> scenes;
  std::vector<int> sizes = {513, 1025};
  int threads = 2, repeats = 3, segments = TessellateOptions::kDefaultSegments;
  std::string json_path, quality_name = "medium";
  KdBuildOptions kd_options;
  app.add_option("scenes", scenes, "NFF/PLY/OBJ/OFF files (curved NFF primitives are tessellated)")->required();
  app.add_option("--sizes", sizes, "square image sizes");
  app.add_option("--threads", threads, "worker threads for every method and both builds")->check(CLI::PositiveNumber);
  app.add_option("--repeats", repeats, "frames per measurement (the best is kept)")->check(CLI::PositiveNumber);
  app.add_option("--segments", segments, "tessellation: segments around a circle")->check(CLI::Range(3, 4096));
  app.add_option("--embree-quality", quality_name, "Embree BVH build quality")
      ->check(CLI::IsMember({"low", "medium", "high"}));
  app.add_option("--kd-max-share", kd_options.forced_split_max_share,
                 "k-d tree: forced splits only if the larger side keeps at most this share (1: hard cap)")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--json", json_path, "also write one JSON object per row to this file");
  std::string profile;
  app.add_option("--profile", profile,
                 "only render frontier's METHOD (frustum, raywalk, packet) --repeats times, no table (for perf)")
      ->check(CLI::IsMember({"frustum", "raywalk", "packet"}));
  CLI11_PARSE(app, argc, argv);

  const RTCBuildQuality quality = quality_name == "low"    ? RTC_BUILD_QUALITY_LOW
                                  : quality_name == "high" ? RTC_BUILD_QUALITY_HIGH
                                                           : RTC_BUILD_QUALITY_MEDIUM;
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
  const std::string config = fmt::format("threads={}", threads);
  RTCDevice device = rtcNewDevice(config.c_str());
  if (device == nullptr) {
    fmt::print(stderr, "bench_embree: rtcNewDevice failed ({})\n", int(rtcGetDeviceError(nullptr)));
    return 1;
  }
  rtcSetDeviceErrorFunction(device, embree_error, nullptr);
  const bool native8 = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) != 0;
  const bool native16 = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) != 0;
  const bool streams = rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_RAY_STREAM_SUPPORTED) != 0;
  fmt::print("Embree {}.{}.{}, {} threads, BVH quality {}; native ray8 {}, native ray16 {}{}, streams {}\n\n",
             rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION_MAJOR),
             rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION_MINOR),
             rtcGetDeviceProperty(device, RTC_DEVICE_PROPERTY_VERSION_PATCH), threads, quality_name,
             native8 ? "yes" : "no", native16 ? "yes" : "no",
             native16 ? "" : " (rtcIntersect16 is emulated on this CPU)", streams ? "yes" : "no");

  std::ofstream json;
  if (!json_path.empty()) {
    json.open(json_path);
    if (!json) {
      fmt::print(stderr, "bench_embree: cannot write {}\n", json_path);
      return 1;
    }
  }
  fmt::print("| scene | triangles | size | method | ms | Mrays/s | vs frustum | vs ray walk | same id as frustum |\n");
  fmt::print("|---|---|---|---|---|---|---|---|---|\n");
  std::fflush(stdout);

  std::vector<Build> builds;
  for (const std::string& path : scenes) {
    const std::string name = path.substr(path.find_last_of('/') + 1);
    Scene scene;
    {
      Scene loaded;
      if (Status s = load_scene(path, loaded); !s) {
        fmt::print(stderr, "bench_embree: {}\n", s.to_string());
        return 1;
      }
      TessellateOptions options;
      options.segments = segments;
      options.smooth_normals = false;  // visibility only
      TessellateStats stats;
      scene = tessellate(loaded, options, &stats);
      if (stats.quadrics_as_boxes > 0) {
        fmt::print(stderr, "bench_embree: {}: {} quadrics replaced by their bounding boxes\n", name,
                   stats.quadrics_as_boxes);
      }
    }
    const auto kd0 = std::chrono::steady_clock::now();
    const KdTree tree = KdTree::build(scene, kd_options);
    const double kd_ms = ms_since(kd0);
    const EmbreeScene rtc = build_embree(device, scene, quality);
    double accel_ms = 0.0;
    {
      tbb::task_arena arena(threads);
      const auto a0 = std::chrono::steady_clock::now();
      arena.execute([&] { const PrimAccel accel = PrimAccel::build(scene); });
      accel_ms = ms_since(a0);
    }
    fmt::print(stderr, "{}: {} triangles; builds on {} threads: k-d tree {:.0f} ms, Embree BVH {:.0f} ms\n", name,
               scene.triangles.size(), threads, kd_ms, rtc.build_ms);
    builds.push_back({name, scene.triangles.size(), kd_ms, rtc.build_ms, accel_ms});
    const Camera camera = scene.camera ? *scene.camera : automatic_camera(scene.bounds());

    for (int size : sizes) {
      const View view(camera, size, size);
      if (!profile.empty()) {
        RenderOptions options;
        options.method = profile == "frustum" ? Method::Frustum : profile == "raywalk" ? Method::RayWalk : Method::Packet;
        options.threads = threads;
        options.shade = false;
        SampleBuffer buffer;
        Renderer renderer(scene, tree, threads);
        double best = kInfinity;
        for (int r = 0; r < repeats; ++r) {
          const auto t0 = std::chrono::steady_clock::now();
          renderer.render(view, options, buffer);
          best = std::min(best, ms_since(t0));
        }
        fmt::print("{} {}² {}: best {:.1f} ms\n", name, size, profile, best);
        continue;
      }
      std::vector<Row> rows;
      // Frustum casting and packets with their rays through Embree's BVH and frontier's exact
      // tests (the default, src/engine/prim_accel.h), then the same through the k-d tree alone.
      const std::pair<Method, bool> methods[] = {{Method::Frustum, true},  {Method::RayWalk, false},
                                                 {Method::Packet, true},   {Method::Frustum, false},
                                                 {Method::Packet, false}};
      for (const auto& [m, accel] : methods) {
        const std::string label = std::string(m == Method::Frustum   ? "frontier frustum casting"
                                              : m == Method::RayWalk ? "frontier ray walking"
                                                                     : "frontier ray packets (4x4)") +
                                  (m != Method::RayWalk && !accel ? ", k-d kernel" : "");
        Row row{label, kInfinity, kd_ms, {}};
        RenderOptions options;
        options.method = m;
        options.accel = accel;
        options.threads = threads;
        options.shade = false;
        SampleBuffer buffer;
        Renderer renderer(scene, tree, threads);  // kept across frames, as a viewer keeps it
        for (int r = 0; r < repeats; ++r) {
          const auto t0 = std::chrono::steady_clock::now();
          renderer.render(view, options, buffer);
          row.ms = std::min(row.ms, ms_since(t0));
        }
        row.ids = id_image(scene, buffer);
        rows.push_back(std::move(row));
      }
      for (EmbreeMethod m : {EmbreeMethod::Single, EmbreeMethod::Packet8, EmbreeMethod::Packet16,
                             EmbreeMethod::Stream}) {
        Row row{embree_name(m), kInfinity, rtc.build_ms, {}};
        std::vector<uint32_t> prim(view.pixels(), kNoPrim);
        for (int r = 0; r < repeats; ++r) {
          tbb::task_arena arena(threads);  // as render_frame does per frame
          const auto t0 = std::chrono::steady_clock::now();
          arena.execute([&] { embree_frame(rtc.scene, view, m, prim); });
          row.ms = std::min(row.ms, ms_since(t0));
        }
        row.ids.resize(prim.size());
        for (size_t i = 0; i < prim.size(); ++i) row.ids[i] = prim[i] == kNoPrim ? kNoPrim : scene.prims[prim[i]].source;
        rows.push_back(std::move(row));
      }

      const double rays = double(view.pixels());
      const double frustum_rate = rays / rows[0].ms, walk_rate = rays / rows[1].ms;  // rays per ms
      for (const Row& row : rows) {
        size_t same = 0;
        for (size_t i = 0; i < row.ids.size(); ++i) same += row.ids[i] == rows[0].ids[i];
        const double agree = 100.0 * double(same) / rays;
        const double rate = rays / row.ms;  // per ms
        const double mrays = rate / 1e3;    // millions per second
        fmt::print("| {} | {} | {}² | {} | {:.1f} | {:.3f} | {:.2f}× | {:.2f}× | {:.3f}% |\n", name,
                   scene.triangles.size(), size, row.method, row.ms, mrays, rate / frustum_rate,
                   rate / walk_rate, agree);
        if (json.is_open()) {
          const nlohmann::json j = {{"scene", name},        {"triangles", scene.triangles.size()},
                                    {"size", size},         {"method", row.method},
                                    {"ms", row.ms},         {"mrays", mrays},
                                    {"build_ms", row.build_ms}, {"agree", agree},
                                    {"threads", threads}};
          json << j.dump() << '\n';
        }
      }
      std::fflush(stdout);
    }
    rtcReleaseScene(rtc.scene);
  }
  rtcReleaseDevice(device);
  fmt::print(
      "\n| scene | triangles | k-d tree build ms | Embree BVH build ms ({}) | Embree / k-d | frontier's Embree BVH "
      "(user boxes, medium, robust) ms |\n",
      quality_name);
  fmt::print("|---|---|---|---|---|---|\n");
  for (const Build& b : builds) {
    fmt::print("| {} | {} | {:.0f} | {:.0f} | {:.3f}× | {:.0f} |\n", b.scene, b.triangles, b.kd_ms, b.embree_ms,
               b.embree_ms / b.kd_ms, b.accel_ms);
  }
  return 0;
}
