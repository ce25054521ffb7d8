// Tables 1–10 of the immediate-mode ray-casting paper (Alex & Teller 1999, §4), measured on the
// three SPD scenes with every method side by side in one run:
//   RC          frontier's ray walking (the paper's RC: per-pixel rays walking a spatial subdivision)
//   frustum     frontier's frustum casting (beside RC)
//   tessellated objects tessellated to ~90% silhouette coverage, per-vertex lighting, frontier's rasterizer
//   Mesa        the same triangles through real OpenGL (Mesa llvmpipe, offscreen EGL), fixed-function lighting
//   IMR         tessellated bounds rasterized, a ray cast per bound fragment that passes the depth test
// at 129² and 513², unordered (a seeded random object order) and front to back (k-d tree).
// Then Tables 9–10 (bound silhouette accuracy against tessellation value for a sphere and a
// cylinder) and what accuracy costs in time: silhouette and depth error of the tessellated
// scene against frame time per tessellation level, with IMR's exact point.
//
//   bench_imr --spd ../shared/data/spd --json imr.json          (Markdown tables on stdout)
#include "src/io/load_scene.h"
#include "src/raster/gouraud.h"
#include "src/raster/imr.h"
#include "src/engine/kdtree.h"
#include "src/engine/render.h"
#include "src/core/scene.h"
#include "src/core/view.h"
#include "viewer/mesa_renderer.h"

#include <CLI/CLI.hpp>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <functional>
#include <map>
#include <string>
#include <vector>

using namespace frontier;
using nlohmann::json;

namespace {

double ms_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// Median wall time of `repeats` calls (the paper averaged repeated frames of a fixed view).
double median_ms(int repeats, const std::function<void()>& frame) {
  std::vector<double> ms;
  for (int r = 0; r < repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    frame();
    ms.push_back(ms_since(start));
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

struct Exact {
  std::vector<uint32_t> ids;  // sources
  std::vector<double> t;
  uint64_t object_pixels = 0;
};

// Silhouette accuracy: the share of the exact image's object pixels showing the same object;
// depth error: mean relative |t - t_exact| over those pixels.
void accuracy(const Exact& exact, const std::vector<uint32_t>& ids, const std::vector<double>& t, double& silhouette,
              double& depth) {
  uint64_t same = 0;
  double error = 0.0;
  for (size_t i = 0; i < ids.size(); ++i) {
    if (exact.ids[i] == kNoPrim || ids[i] != exact.ids[i]) continue;
    ++same;
    error += std::abs(t[i] - exact.t[i]) / exact.t[i];
  }
  silhouette = exact.object_pixels ? double(same) / double(exact.object_pixels) : 1.0;
  depth = same ? error / double(same) : 0.0;
}

std::vector<uint32_t> to_sources(const Scene& scene, std::vector<uint32_t> ids) {
  for (uint32_t& id : ids) {
    if (id != kNoPrim) id = scene.prims[id].source;
  }
  return ids;
}

std::string si(double v) {
  if (v >= 1e6) return fmt::format("{:.2f}M", v / 1e6);
  if (v >= 1e4) return fmt::format("{:.1f}K", v / 1e3);
  return fmt::format("{:.0f}", v);
}

// One unit sphere, or a cylinder of radius 0.5 and length 2 along z, at the origin.
Scene lone_object(bool cylinder) {
  Scene scene;
  scene.materials.push_back({});
  if (cylinder) {
    scene.add_cone({Vec3(0, 0, -1), 0.5, Vec3(0, 0, 1), 0.5}, 0, 0);
  } else {
    scene.add_sphere({Vec3(0), 1.0}, 0, 0);
  }
  return scene;
}

// The paper's tessellation rule (§4.1): a tessellated object must cover about 90% of the pixels
// its ray-cast equivalent covers. Measured on one sphere and one cylinder seen alone, large
// (~13,000 pixels), so it does not depend on the image size; the scene's level is the smallest
// whose every curved kind present reaches `coverage`.
double isolated_coverage(bool cylinder, int level) {
  const Scene scene = lone_object(cylinder);
  Camera cam;
  cam.eye = cylinder ? Vec3(4.0, 1.5, 1.0) : Vec3(0, 0, 4.0);
  cam.up = cylinder ? Vec3(0, 0, 1) : Vec3(0, 1, 0);
  cam.vfov_deg = 30.0;
  const View view(cam, 160, 160);
  uint64_t exact = 0, tess = 0;
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      double t;
      exact += scene.intersect(0, view.ray(x, y), 0.0, kInfinity, t);
    }
  }
  TessellatedOptions to;
  to.segments = level;
  TessellatedRenderer r(scene, to);
  r.render(view);
  for (uint32_t id : r.prim_ids()) tess += id == 0;
  return double(tess) / double(std::max<uint64_t>(exact, 1));
}

// Tables 9–10: a single object of the given kind, centred, seen at three footprints; the
// bound's pixels (rasterized, front faces) against the object's (exact ray casting).
json bound_accuracy(bool cylinder, const std::vector<int>& levels, const std::vector<int>& sizes_px) {
  json rows = json::array();
  const Scene scene = lone_object(cylinder);
  for (const int target : sizes_px) {
    // Image size so the object covers about `target` pixels at a 30° field of view.
    Camera cam;
    cam.eye = cylinder ? Vec3(4.0, 1.5, 1.0) : Vec3(0, 0, 4.0);
    cam.look_at = Vec3(0);
    cam.up = Vec3(0, 0, 1);
    if (!cylinder) cam.up = Vec3(0, 1, 0);
    cam.vfov_deg = 30.0;
    int size = 16;
    uint64_t exact = 0;
    for (;;) {
      const View view(cam, size, size);
      exact = 0;
      for (int y = 0; y < size; ++y) {
        for (int x = 0; x < size; ++x) {
          double t;
          exact += scene.intersect(0, view.ray(x, y), 0.0, kInfinity, t);
        }
      }
      if (double(exact) >= target || size > 4096) break;
      size = std::max(size + 1, int(size * std::sqrt(double(target) / std::max<double>(double(exact), 1.0)) * 0.999));
    }
    const View view(cam, size, size);
    for (const int level : levels) {
      const BoundingPolyhedron b = bounding_polyhedron(scene, 0, level, level);
      ImplicitSurface s;
      implicit_surface_of(scene, 0, s);
      RasterOptions ro;
      ro.cull_back_faces = true;
      Rasterizer r(view, ro);
      for (const auto& f : b.faces) {
        r.submit(Triangle{b.vertices[f[0]] + s.origin, b.vertices[f[1]] + s.origin, b.vertices[f[2]] + s.origin}, 0);
      }
      const auto& ids = r.ids();
      const uint64_t bound = uint64_t(std::count(ids.begin(), ids.end(), 0u));
      rows.push_back({{"object", cylinder ? "cylinder" : "sphere"},
                      {"level", level},
                      {"object_pixels", exact},
                      {"bound_pixels", bound},
                      {"accuracy", bound ? 100.0 * double(exact) / double(bound) : 0.0},
                      {"image", size}});
    }
  }
  return rows;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Immediate-mode ray casting against RC, frustum casting, tessellation and Mesa (Tables 1-10)"};
  std::string spd_dir = "../shared/data/spd", json_path;
  std::vector<std::string> scenes = {"rings", "tree", "shells"};
  std::vector<int> sizes = {129, 513};
  int repeats = 3, threads = 0, slices = ImrOptions{}.slices;
  double coverage = 0.90;
  std::vector<int> levels = {3, 4, 5, 6, 8, 10, 12, 16, 24, 32};
  uint64_t max_triangles = 4'000'000;
  bool no_mesa = false;
  app.add_option("--spd", spd_dir, "directory of the SPD scenes");
  app.add_option("--scenes", scenes, "scenes (names in --spd)");
  app.add_option("--sizes", sizes, "square image sizes (the first is 'lo', the last 'hi')");
  app.add_option("--repeat", repeats, "frames per timing (median)")->check(CLI::PositiveNumber);
  app.add_option("--threads", threads, "threads (0: all cores)");
  app.add_option("--slices", slices, "IMR bound tessellation value (sphere slices = stacks * 2, cone sides)");
  app.add_option("--coverage", coverage, "share of an object's exact pixels its tessellation must cover (paper: 0.9)");
  app.add_option("--levels", levels, "tessellation levels for the accuracy-time curve");
  app.add_option("--max-triangles", max_triangles, "skip tessellation levels above this many triangles");
  app.add_flag("--no-mesa", no_mesa, "skip the Mesa (OpenGL) baseline");
  app.add_option("--json", json_path, "write every figure as JSON");
  CLI11_PARSE(app, argc, argv);

  json out;
  out["threads"] = threads;
  out["repeat"] = repeats;
  out["imr_slices"] = slices;
  std::string mesa_name = "skipped";
  json runs = json::array(), curve = json::array();

  for (const std::string& name : scenes) {
    Scene scene;
    const Status st = load_scene(spd_dir + "/" + name + ".nff", scene);
    if (!st.is_ok()) {
      fmt::print(stderr, "bench_imr: {}\n", st.message());
      return 1;
    }
    const KdTree tree = KdTree::build(scene);
    const Camera camera = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
    ImrOptions io;
    io.slices = slices;
    io.threads = threads;
    io.order = IssueOrder::kRandom;
    ImrRenderer imr_unordered(scene, io);
    io.order = IssueOrder::kFrontToBack;
    ImrRenderer imr_ordered(scene, io);
    Renderer renderer(scene, tree, threads);
    std::map<int, std::unique_ptr<TessellatedRenderer>> tessellations;  // by level, unordered

    for (const int size : sizes) {
      const View view(camera, size, size);
      json run = {{"scene", name}, {"size", size}};
      // RC and frustum casting, lit once per pixel, no shadows (no method here casts them).
      SampleBuffer buffer;
      Exact exact;
      for (const Method method : {Method::RayWalk, Method::Frustum}) {
        RenderOptions ro;
        ro.method = method;
        ro.shadows = false;
        Counters c;
        const double ms = median_ms(repeats, [&] { c = renderer.render(view, ro, buffer); });
        const char* key = method == Method::RayWalk ? "rc" : "frustum";
        run[key] = {{"ms", ms},
                    {"ray_object_tests", c.ray_primitive_tests},
                    {"hits", c.hits},
                    {"cell_walks", c.cell_visits},
                    {"lit", c.shading_ops},
                    {"rays", c.rays}};
        if (method == Method::RayWalk) {
          exact.ids = id_image(scene, buffer);
          exact.t.resize(buffer.size());
          uint64_t lit = 0;
          for (size_t i = 0; i < buffer.size(); ++i) {
            exact.t[i] = buffer.t(i);
            if (exact.ids[i] != kNoPrim) ++exact.object_pixels, ++lit;
          }
          run[key]["lit_samples"] = lit;
        }
      }

      // The accuracy-time curve of the tessellated scene, and the level reaching `coverage`.
      bool spheres = false, cones = false;
      for (const PrimRef& p : scene.prims) {
        spheres |= p.kind == PrimKind::Sphere;
        cones |= p.kind == PrimKind::Cone;
      }
      int chosen = -1;
      for (const int level : levels) {
        auto& t = tessellations[level];
        if (!t) {
          TessellatedOptions to;
          to.segments = level;
          to.threads = threads;
          to.order = IssueOrder::kRandom;
          t = std::make_unique<TessellatedRenderer>(scene, to);
        }
        if (t->triangles() > max_triangles) {
          tessellations.erase(level);
          break;
        }
        TessellatedCounters c;
        const double ms = median_ms(repeats, [&] { c = t->render(view); });
        double silhouette, depth;
        accuracy(exact, to_sources(scene, t->prim_ids()), t->rasterizer().depth_image(), silhouette, depth);
        curve.push_back({{"scene", name}, {"size", size}, {"method", "tessellated"}, {"level", level},
                         {"triangles", t->triangles()}, {"ms", ms}, {"silhouette", silhouette}, {"depth_error", depth}});
        if (chosen < 0 && (!spheres || isolated_coverage(false, level) >= coverage) &&
            (!cones || isolated_coverage(true, level) >= coverage)) {
          chosen = level;
        }
      }
      if (chosen < 0) chosen = tessellations.rbegin()->first;
      run["tess_level"] = chosen;

      TessellatedRenderer& tess = *tessellations[chosen];
      TessellatedOptions to = tess.options();
      to.order = IssueOrder::kFrontToBack;
      TessellatedRenderer tess_ordered(scene, to);
      for (TessellatedRenderer* t : {&tess, &tess_ordered}) {
        TessellatedCounters c;
        const double ms = median_ms(repeats, [&] { c = t->render(view); });
        const std::string key = t == &tess ? "tess_unordered" : "tess_ordered";
        run[key] = c.to_json();
        run[key]["ms"] = ms;
      }

      if (!no_mesa) {
        std::string error;
        auto mesa = MesaRenderer::create(size, size, error);
        if (!mesa) {
          fmt::print(stderr, "bench_imr: Mesa: {}\n", error);
          return 1;
        }
        mesa_name = mesa->renderer();
        const Scene triangles = tess.tessellated_scene();
        if (const Status s = mesa->set_scene(triangles); !s.is_ok()) {
          fmt::print(stderr, "bench_imr: Mesa: {}\n", s.message());
          return 1;
        }
        for (TessellatedRenderer* t : {&tess, &tess_ordered}) {
          const std::vector<uint32_t> order = t->triangle_order(view);
          MesaFrame frame;
          std::vector<double> ms;
          for (int r = 0; r < repeats; ++r) {
            auto f = mesa->render(view, &order);
            if (!f.is_ok()) {
              fmt::print(stderr, "bench_imr: Mesa: {}\n", f.status().message());
              return 1;
            }
            frame = std::move(f.value());
            ms.push_back(frame.frame_ms);
          }
          std::sort(ms.begin(), ms.end());
          const std::string key = t == &tess ? "mesa_unordered" : "mesa_ordered";
          run[key] = {{"ms", ms[ms.size() / 2]},
                      {"triangles_issued", frame.triangles_issued},
                      {"vertices_lit", frame.vertices_lit},
                      {"pixels_covered", frame.pixels_covered},
                      {"samples_passed", frame.samples_passed},
                      {"lights_used", frame.lights_used},
                      {"lights_dropped", frame.lights_dropped}};
        }
        std::vector<uint32_t> ids;
        if (mesa->ids(view, ids).is_ok()) {
          double silhouette, depth;
          accuracy(exact, ids, std::vector<double>(ids.size(), 0.0), silhouette, depth);
          run["mesa_silhouette"] = silhouette;
        }
      }

      for (ImrRenderer* imr : {&imr_unordered, &imr_ordered}) {
        ImrCounters c;
        const double ms = median_ms(repeats, [&] { c = imr->render(view); });
        const std::string key = imr == &imr_unordered ? "imr_unordered" : "imr_ordered";
        run[key] = c.to_json();
        run[key]["ms"] = ms;
        double silhouette, depth;
        accuracy(exact, to_sources(scene, imr->rasterizer().ids()), imr->rasterizer().depth_image(), silhouette, depth);
        run[key]["silhouette"] = silhouette;
        run[key]["depth_error"] = depth;
        if (imr == &imr_ordered && size == sizes.back()) {
          curve.push_back({{"scene", name}, {"size", size}, {"method", "imr"}, {"level", slices},
                           {"triangles", imr->bound_triangles()}, {"ms", ms}, {"silhouette", silhouette},
                           {"depth_error", depth}});
        }
      }
      runs.push_back(run);
      fmt::print(stderr, "bench_imr: {} {}² done\n", name, size);
    }
  }
  out["mesa"] = mesa_name;
  out["runs"] = runs;
  out["curve"] = curve;
  out["table9"] = bound_accuracy(false, {4, 7, 10, 15, 20, 25}, {113, 2933, 13457});
  out["table10"] = bound_accuracy(true, {4, 7, 11, 15}, {135, 6707, 14339});

  // Markdown, the paper's layout.
  auto find = [&](const std::string& scene, int size) -> const json& {
    for (const json& r : runs) {
      if (r["scene"] == scene && r["size"] == size) return r;
    }
    static const json none;
    return none;
  };
  const int lo = sizes.front(), hi = sizes.back();
  auto label = [&](const std::string& scene, int size) { return fmt::format("{} {}²", scene, size); };
  fmt::print("Renderer: {}\n\n", mesa_name);
  fmt::print("Table 1: triangles per frame\n\n| scene | tessellation (level) | IMR bounds (slices {}) | savings |\n|---|---|---|---|\n", slices);
  for (const json& r : runs) {
    const double tess = r["tess_unordered"]["triangles_issued"], imr = r["imr_unordered"]["triangles_issued"];
    fmt::print("| {} | {} ({}) | {} | {:.1f}x |\n", label(r["scene"], r["size"]), si(tess), int(r["tess_level"]), si(imr), tess / imr);
  }
  fmt::print("\nTable 2: pixels covered (fragments) per frame, unordered\n\n| scene | tessellated | Mesa | IMR | IMR increase over tessellated |\n|---|---|---|---|---|\n");
  for (const json& r : runs) {
    const double tess = r["tess_unordered"]["pixels_covered"], imr = r["imr_unordered"]["pixels_covered"];
    const std::string mesa = r.contains("mesa_unordered") ? si(r["mesa_unordered"]["pixels_covered"]) : "-";
    fmt::print("| {} | {} | {} | {} | {:+.0f}% |\n", label(r["scene"], r["size"]), si(tess), mesa, si(imr), 100.0 * (imr / tess - 1.0));
  }
  fmt::print("\nTable 3: ray-object tests (RC: + ray-cell walks; IMR front-to-back/unordered)\n\n| scene | RC total (objects, cell walks) | frustum objects | IMR objects | IMR object savings | IMR total savings |\n|---|---|---|---|---|---|\n");
  for (const json& r : runs) {
    const double rc_obj = r["rc"]["ray_object_tests"], rc_walk = r["rc"]["cell_walks"];
    const double imr_o = r["imr_ordered"]["ray_object_tests"], imr_u = r["imr_unordered"]["ray_object_tests"];
    fmt::print("| {} | {} ({}, {}) | {} | {}/{} | {:.1f}x | {:.1f}x |\n", label(r["scene"], r["size"]), si(rc_obj + rc_walk), si(rc_obj),
               si(rc_walk), si(r["frustum"]["ray_object_tests"]), si(imr_o), si(imr_u), rc_obj / imr_o, (rc_obj + rc_walk) / imr_o);
  }
  fmt::print("\nTable 4: ray-object hits per test, %\n\n| scene | RC | frustum | IMR front-to-back | IMR unordered |\n|---|---|---|---|---|\n");
  for (const json& r : runs) {
    auto pct = [](const json& j, const char* hits, const char* tests) { return 100.0 * double(j[hits]) / std::max(1.0, double(j[tests])); };
    fmt::print("| {} | {:.1f} | {:.1f} | {:.1f} | {:.1f} |\n", label(r["scene"], r["size"]), pct(r["rc"], "hits", "ray_object_tests"),
               pct(r["frustum"], "hits", "ray_object_tests"), pct(r["imr_ordered"], "ray_object_hits", "ray_object_tests"),
               pct(r["imr_unordered"], "ray_object_hits", "ray_object_tests"));
  }
  fmt::print("\nTable 5: lighting operations (RC: lit samples; tessellated/Mesa: vertices lit; IMR: fragments written, i.e. lit by an immediate pipeline, front-to-back/unordered)\n\n| scene | RC | tessellated (vs RC) | IMR (vs RC) | IMR lit here (deferred) |\n|---|---|---|---|---|\n");
  for (const json& r : runs) {
    const double rc = r["rc"]["lit_samples"], tess = r["tess_unordered"]["vertices_lit"];
    const double io = r["imr_ordered"]["immediate_lighting"], iu = r["imr_unordered"]["immediate_lighting"];
    fmt::print("| {} | {} | {} ({:.1f}x) | {}/{} ({:.2f}x) | {} |\n", label(r["scene"], r["size"]), si(rc), si(tess), tess / rc, si(io), si(iu),
               io / rc, si(r["imr_ordered"]["lit_pixels"]));
  }
  fmt::print("\nTable 6: frame time, ms (front-to-back/unordered)\n\n| scene | RC | frustum | tessellated | Mesa | IMR |\n|---|---|---|---|---|---|\n");
  for (const json& r : runs) {
    const std::string mesa = r.contains("mesa_ordered")
                                 ? fmt::format("{:.1f}/{:.1f}", double(r["mesa_ordered"]["ms"]), double(r["mesa_unordered"]["ms"]))
                                 : "-";
    fmt::print("| {} | {:.1f} | {:.1f} | {:.1f}/{:.1f} | {} | {:.1f}/{:.1f} |\n", label(r["scene"], r["size"]), double(r["rc"]["ms"]),
               double(r["frustum"]["ms"]), double(r["tess_ordered"]["ms"]), double(r["tess_unordered"]["ms"]), mesa,
               double(r["imr_ordered"]["ms"]), double(r["imr_unordered"]["ms"]));
  }
  if (lo != hi) {
    const double pixels = double(hi) * hi / (double(lo) * lo);
    fmt::print("\nTable 7: ray-casting work increase from {}² to {}² ({:.1f}x the pixels)\n\n| scene | RC ray-object | RC total | IMR front-to-back/unordered |\n|---|---|---|---|\n", lo, hi, pixels);
    for (const std::string& name : scenes) {
      const json &a = find(name, lo), &b = find(name, hi);
      if (a.is_null() || b.is_null()) continue;
      auto f = [&](const json& x, const json& y) { return double(y) / std::max(1.0, double(x)); };
      fmt::print("| {} | {:.1f} | {:.1f} | {:.1f}/{:.1f} |\n", name, f(a["rc"]["ray_object_tests"], b["rc"]["ray_object_tests"]),
                 (double(b["rc"]["ray_object_tests"]) + double(b["rc"]["cell_walks"])) /
                     (double(a["rc"]["ray_object_tests"]) + double(a["rc"]["cell_walks"])),
                 f(a["imr_ordered"]["ray_object_tests"], b["imr_ordered"]["ray_object_tests"]),
                 f(a["imr_unordered"]["ray_object_tests"], b["imr_unordered"]["ray_object_tests"]));
    }
    fmt::print("\nTable 8: frame-time slowdown from {}² to {}² (front-to-back/unordered)\n\n| scene | RC | frustum | tessellated | Mesa | IMR |\n|---|---|---|---|---|---|\n", lo, hi);
    for (const std::string& name : scenes) {
      const json &a = find(name, lo), &b = find(name, hi);
      if (a.is_null() || b.is_null()) continue;
      auto f = [&](const char* key) { return double(b[key]["ms"]) / double(a[key]["ms"]); };
      const std::string mesa = a.contains("mesa_ordered") ? fmt::format("{:.2f}/{:.2f}", f("mesa_ordered"), f("mesa_unordered")) : "-";
      fmt::print("| {} | {:.2f} | {:.2f} | {:.2f}/{:.2f} | {} | {:.2f}/{:.2f} |\n", name, f("rc"), f("frustum"), f("tess_ordered"),
                 f("tess_unordered"), mesa, f("imr_ordered"), f("imr_unordered"));
    }
  }
  for (const char* table : {"table9", "table10"}) {
    const bool cyl = std::string(table) == "table10";
    fmt::print("\nTable {}: bound silhouette accuracy for a {} (object pixels / bound pixels, %)\n\n", cyl ? 10 : 9, cyl ? "cylinder" : "sphere");
    std::vector<uint64_t> footprints;
    for (const json& row : out[table]) {
      if (std::find(footprints.begin(), footprints.end(), uint64_t(row["object_pixels"])) == footprints.end()) {
        footprints.push_back(row["object_pixels"]);
      }
    }
    fmt::print("| tessellation |");
    for (uint64_t f : footprints) fmt::print(" {} px |", f);
    fmt::print("\n|---|");
    for (size_t k = 0; k < footprints.size(); ++k) fmt::print("---|");
    fmt::print("\n");
    std::map<int, std::map<uint64_t, double>> grid;
    for (const json& row : out[table]) grid[row["level"]][row["object_pixels"]] = row["accuracy"];
    for (const auto& [level, cells] : grid) {
      fmt::print("| {} |", level);
      for (uint64_t f : footprints) fmt::print(" {:.2f} |", cells.at(f));
      fmt::print("\n");
    }
  }
  fmt::print("\nAccuracy against time at {}² (tessellated levels; IMR exact)\n\n| scene | method | level | triangles | ms | silhouette % | depth error |\n|---|---|---|---|---|---|---|\n", hi);
  for (const json& p : curve) {
    if (p["size"] != hi) continue;
    fmt::print("| {} | {} | {} | {} | {:.1f} | {:.2f} | {:.2e} |\n", std::string(p["scene"]), std::string(p["method"]), int(p["level"]),
               si(p["triangles"]), double(p["ms"]), 100.0 * double(p["silhouette"]), double(p["depth_error"]));
  }
  if (!json_path.empty()) {
    std::ofstream(json_path) << out.dump(1) << "\n";
  }
  return 0;
}
