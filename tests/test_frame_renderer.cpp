// The FrameRenderer interface (src/engine/frame_renderer.h) over every method: a frame has an
// image and an id image of the view's size; its ids are input ids (PrimRef::source, here
// deliberately not the primitive indices), equal to brute force's at every pixel but ties for
// the exact methods (ray casting, the rasterizing classes, immediate-mode ray casting); the
// approximate ones (tessellated, Mesa, BSP) see only input ids that exist; and the stats name
// the method.
#include "src/core/tessellate.h"
#include "src/engine/frame_renderer.h"
#include "src/engine/render.h"
#include "src/raster/bsp_render.h"
#include "src/raster/gouraud.h"
#include "src/raster/imr.h"
#include "src/raster/visibility.h"
#include "tests/engine_util.h"
#include "viewer/mesa_frame_renderer.h"

#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <set>

namespace frontier {
namespace {

// A random scene whose input ids are 5 i + 3 for primitive i.
Scene scene_with_sources() {
  std::mt19937_64 rng(11);
  Scene scene = testing::random_scene(rng, 60);
  for (size_t i = 0; i < scene.prims.size(); ++i) scene.prims[i].source = uint32_t(5 * i + 3);
  scene.input_primitives = uint32_t(5 * scene.prims.size() + 3);
  return scene;
}

View test_view() { return View(testing::camera_at(Vec3(3.0, 2.5, 2.0), Vec3(0.0)), 64, 48); }

Frame render(FrameRenderer& renderer, const View& view) {
  auto frame = renderer.render(view);
  EXPECT_TRUE(frame.is_ok()) << frame.status().to_string();
  if (!frame) return {};
  EXPECT_EQ(frame->colors.size(), view.pixels());
  EXPECT_EQ(frame->ids.size(), view.pixels());
  EXPECT_TRUE(frame->stats.is_object());
  return std::move(*frame);
}

void expect_brute_force_ids(const Scene& scene, const View& view, const Frame& frame, const std::string& what) {
  std::vector<uint32_t> reference;
  std::vector<uint8_t> tie;
  testing::brute_reference(scene, view, reference, tie);
  const testing::Comparison c = testing::compare_ids(reference, tie, frame.ids, view.width);
  EXPECT_EQ(c.mismatches, 0u) << what << ": " << c.first_mismatch;
  size_t background = 0;
  for (uint32_t id : reference) background += id == kNoPrim;
  EXPECT_LT(background, reference.size()) << "the view shows nothing";
}

void expect_existing_ids(const Scene& scene, const Frame& frame, const std::string& what) {
  std::set<uint32_t> sources;
  for (const PrimRef& p : scene.prims) sources.insert(p.source);
  size_t shown = 0;
  for (uint32_t id : frame.ids) {
    if (id == kNoPrim) continue;
    ++shown;
    ASSERT_TRUE(sources.count(id)) << what << ": id " << id << " is no input id";
  }
  EXPECT_GT(shown, 0u) << what;
}

RenderOptions ray_casting(Method method) {
  RenderOptions options;
  options.method = method;
  options.threads = 2;
  return options;
}

CullOptions rasterizing(Visibility visibility) {
  CullOptions options;
  options.visibility = visibility;
  options.threads = 2;
  return options;
}

TEST(FrameRenderer, ExactMethodsGiveBruteForceInputIds) {
  const Scene scene = scene_with_sources();
  const KdTree tree = KdTree::build(scene);
  const Scene triangles = tessellate(scene);  // the rasterizing classes draw triangles
  const KdTree triangle_tree = KdTree::build(triangles);
  ImrOptions imr;
  imr.threads = 2;
  struct Exact {
    std::string name;  // the stats' "method" or "visibility"
    const Scene& scene;
    std::unique_ptr<FrameRenderer> renderer;
  };
  std::vector<Exact> exact;
  for (const Method m : {Method::Brute, Method::RayWalk, Method::Frustum}) {
    exact.push_back({method_name(m), scene, std::make_unique<RayCastFrameRenderer>(scene, tree, ray_casting(m))});
  }
  exact.push_back({"imr", scene, std::make_unique<ImrFrameRenderer>(scene, imr)});
  for (const Visibility v : {Visibility::kExhaustive, Visibility::kFrustumCull, Visibility::kOcclusionCull}) {
    exact.push_back(
        {visibility_name(v), triangles, std::make_unique<CullingFrameRenderer>(triangles, triangle_tree, rasterizing(v))});
  }
  const View view = test_view();
  for (Exact& e : exact) {
    const Frame frame = render(*e.renderer, view);
    expect_brute_force_ids(e.scene, view, frame, e.name);
    EXPECT_EQ(frame.stats.value("method", frame.stats.value("visibility", "")), e.name);
  }
}

TEST(FrameRenderer, TessellatedMesaAndBspShowInputIds) {
  const Scene scene = scene_with_sources();
  const View view = test_view();
  TessellatedOptions tessellated;
  tessellated.threads = 2;
  TessellatedFrameRenderer gouraud(scene, tessellated);
  const Frame on_frontier = render(gouraud, view);
  expect_existing_ids(scene, on_frontier, "tessellated");
  EXPECT_EQ(on_frontier.stats["method"], "tessellated");

  std::string error;
  auto mesa = MesaRenderer::create(view.width, view.height, error);
  ASSERT_NE(mesa, nullptr) << error;
  auto through_gl = MesaFrameRenderer::create(scene, tessellated, std::move(mesa));
  ASSERT_TRUE(through_gl.is_ok()) << through_gl.status().to_string();
  const Frame on_mesa = render(**through_gl, view);
  expect_existing_ids(scene, on_mesa, "mesa");
  EXPECT_EQ(on_mesa.stats["triangles"], on_frontier.stats["triangles"]);  // one tessellation
  size_t same = 0;
  for (size_t i = 0; i < view.pixels(); ++i) same += on_mesa.ids[i] == on_frontier.ids[i];
  EXPECT_GE(double(same), 0.9 * double(view.pixels()));  // two rasterizers, one triangle stream

  auto tree = BspTree::build(polygon_soup(scene, 8));
  ASSERT_TRUE(tree.is_ok()) << tree.status().to_string();
  BspRenderOptions bsp;
  bsp.threads = 2;
  for (const BspOrder order : {BspOrder::BackToFront, BspOrder::FrontToBack}) {
    bsp.order = order;
    BspFrameRenderer renderer(*tree, bsp);
    const Frame frame = render(renderer, view);
    expect_existing_ids(scene, frame, "bsp");
    EXPECT_EQ(frame.stats["aa"].get<int>(), order == BspOrder::FrontToBack ? bsp.aa : 0);
  }
}

}  // namespace
}  // namespace frontier
