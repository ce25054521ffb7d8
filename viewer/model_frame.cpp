// One frame of a model in memory: load, build the tree, frame the camera, then the picked
// method's renderer. A file that cannot be read is reported before options that do not fit
// the method (exit code 1 before 2).
#include "viewer/model_frame.h"

#include "src/engine/kdtree.h"
#include "src/core/scene.h"
#include "src/io/load_scene.h"
#include "src/paging/store_model.h"
#include "viewer/methods.h"
#include "viewer/outputs.h"

#include <fmt/core.h>

#include <chrono>

namespace frontier {
namespace {

double ms_between(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

struct Model {
  Scene scene;
  // What the automatic camera frames: the scene's bounds, or for a store the bounds it records,
  // those of the model it was built from, as the paged frame uses (a Draco or meshopt store's
  // decoded triangles sit on its lattice, within half a step of them: framing those moved the
  // camera, and edges between triangles, by a fraction of a pixel).
  Aabb framed;
  KdTree tree;
  double load_ms = 0.0, build_ms = 0.0;
};

// A model file read and its tree built, or a store's pages decoded (its tree comes with it).
Status load_model(const ViewerOptions& o, bool store, Model& m) {
  KdBuildOptions build;
  build.max_cell_prims = o.cell_prims;
  build.min_cell_prims = o.min_cell_prims;
  const auto t0 = std::chrono::steady_clock::now();
  if (store) {
    auto model = StoreModel::open(o.scene_path);
    if (Status s = model ? (*model)->load_all(m.scene, m.tree, build) : model.status(); !s) return s;
    m.framed = (*model)->info().bounds;
  } else {
    if (Status s = load_scene(o.scene_path, m.scene); !s) return s;
    m.framed = m.scene.bounds();
  }
  const auto t1 = std::chrono::steady_clock::now();
  if (!store) m.tree = KdTree::build(m.scene, build);
  const auto t2 = std::chrono::steady_clock::now();
  m.load_ms = ms_between(t0, t1);
  m.build_ms = ms_between(t1, t2);
  return Status::ok();
}

// The model's camera at its resolution (else one framing the whole model, 512x512); --size wins.
View model_view(const ViewerOptions& o, const Model& model) {
  const Scene& scene = model.scene;
  const Camera camera = scene.camera ? *scene.camera : automatic_camera(model.framed);
  int width = camera.width > 0 ? camera.width : 512, height = camera.height > 0 ? camera.height : 512;
  if (o.width > 0) {
    width = o.width;
    height = o.height;
  }
  return View(camera, width, height);
}

}  // namespace

int render_model(const ViewerOptions& o, bool store) {
  Model model;
  if (Status s = load_model(o, store, model); !s) return fail(s);
  const View view = model_view(o, model);
  const ViewMethod& method = pick_method(o);
  if (method.check != nullptr) {
    if (const std::string why = method.check(o); !why.empty()) return bad_option(why);
  }
  const MethodInput input{o, model.scene, model.tree, view, model.load_ms, model.build_ms};
  auto renderer = method.make(input);
  if (!renderer) return fail(renderer.status());
  auto frame = (*renderer)->render(view);
  if (!frame) return fail(frame.status());
  fmt::print(stderr, "{}", method.summary(input, *frame));
  return write_frame_files(o, view.width, view.height, *frame);
}

}  // namespace frontier
