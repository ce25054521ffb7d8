// The Mesa baseline (viewer/mesa_renderer): the context comes up on a software rasterizer with
// no display; its camera matches frontier's pixel rays (Mesa's id image of a tessellated sphere
// equals frontier's own rasterizer's except on edge pixels); lighting is per vertex and follows
// the light; the counters count what they claim (fragments, depth passes, order effects); bad
// sizes and non-triangle scenes are refused; renderers come and go in one process.
#include "viewer/mesa_renderer.h"

#include "src/raster/raster.h"
#include "src/core/tessellate.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <numeric>
#include <string>

namespace frontier {
namespace {

constexpr int kSize = 129;

Scene sphere_scene(const Vec3& light) {
  Scene scene;
  Material m;
  m.color = Vec3(0.9, 0.6, 0.3);
  m.kd = 0.8;
  m.ks = 0.2;
  m.shine = 20.0;
  scene.materials.push_back(m);
  scene.add_sphere(Sphere{Vec3(0.3, -0.2, 0.1), 1.0}, 0, 0);
  scene.lights.push_back(PointLight{light, Vec3(1.0)});
  scene.background = Vec3(0.1, 0.2, 0.3);
  Camera camera;
  camera.eye = Vec3(0.5, 0.4, 4.0);
  camera.look_at = Vec3(0.3, -0.2, 0.1);
  camera.up = Vec3(0.0, 1.0, 0.0);
  camera.vfov_deg = 40.0;
  scene.camera = camera;
  scene.input_primitives = 1;
  TessellateOptions options;
  options.segments = 48;
  return tessellate(scene, options);
}

std::unique_ptr<MesaRenderer> make(int w, int h) {
  std::string error;
  auto r = MesaRenderer::create(w, h, error);
  EXPECT_NE(r, nullptr) << "MesaRenderer::create failed: " << error;
  return r;
}

// Pixels where `a` and `b` differ; each must lie on an edge of `a` or of `b` (an 8-neighbour
// with another value in the same image).
struct Difference {
  size_t differing = 0;
  size_t off_edge = 0;  // differing pixels with no such neighbour in either image
};

Difference compare(const std::vector<uint32_t>& a, const std::vector<uint32_t>& b, int w, int h) {
  Difference d;
  auto on_edge = [&](const std::vector<uint32_t>& img, int x, int y) {
    const uint32_t v = img[static_cast<size_t>(y) * w + x];
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = x + dx, ny = y + dy;
        if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
        if (img[static_cast<size_t>(ny) * w + nx] != v) return true;
      }
    }
    return false;
  };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      if (a[i] == b[i]) continue;
      ++d.differing;
      if (!on_edge(a, x, y) && !on_edge(b, x, y)) ++d.off_edge;
    }
  }
  return d;
}

size_t covered(const std::vector<uint32_t>& ids) {
  return static_cast<size_t>(std::count_if(ids.begin(), ids.end(), [](uint32_t id) { return id != kNoPrim; }));
}

float luminance(const Rgb& c) { return 0.3f * c.r + 0.59f * c.g + 0.11f * c.b; }

TEST(Mesa, ContextIsSoftwareWithoutDisplay) {
  auto r = make(64, 48);
  ASSERT_NE(r, nullptr);
  EXPECT_TRUE(r->is_software()) << "GL_RENDERER is not llvmpipe/softpipe: " << r->renderer();
  EXPECT_NE(r->renderer().find("Mesa"), std::string::npos) << r->renderer();
  EXPECT_EQ(r->width(), 64);
  EXPECT_EQ(r->height(), 48);
}

TEST(Mesa, ZeroSizeIsRefused) {
  std::string error;
  EXPECT_EQ(MesaRenderer::create(0, 10, error), nullptr);
  EXPECT_NE(error.find("not positive"), std::string::npos) << error;
  error.clear();
  EXPECT_EQ(MesaRenderer::create(10, -1, error), nullptr);
  EXPECT_FALSE(error.empty());
}

TEST(Mesa, RefusesNonTriangleScenesAndMismatchedViews) {
  auto r = make(32, 32);
  ASSERT_NE(r, nullptr);
  Scene spheres;
  spheres.materials.emplace_back();
  spheres.add_sphere(Sphere{Vec3(0.0), 1.0}, 0, 0);
  EXPECT_EQ(r->set_scene(spheres).code(), Status::Code::InvalidArgument);

  const Scene scene = sphere_scene(Vec3(5.0));
  ASSERT_TRUE(r->set_scene(scene));
  const View wrong(*scene.camera, 33, 32);
  EXPECT_FALSE(r->render(wrong).is_ok());
  const View view(*scene.camera, 32, 32);
  const std::vector<uint32_t> bad_order = {0, static_cast<uint32_t>(scene.size())};
  EXPECT_EQ(r->render(view, &bad_order).status().code(), Status::Code::InvalidArgument);
  std::vector<uint32_t> ids;
  EXPECT_TRUE(r->ids(view, ids));
}

// Mesa's rasterization of the tessellated sphere against frontier's exact rasterizer with the
// same camera: equal except where a pixel centre lies (within float rounding) on an edge.
TEST(Mesa, IdImageMatchesFrontierRasterizer) {
  const Scene scene = sphere_scene(Vec3(5.0, 5.0, 5.0));
  const View view(*scene.camera, kSize, kSize);
  Rasterizer rasterizer(view);
  rasterize_scene(scene, rasterizer);
  const std::vector<uint32_t> frontier_prims = rasterizer.ids();
  std::vector<uint32_t> frontier_sources(frontier_prims.size());
  for (size_t i = 0; i < frontier_prims.size(); ++i) {
    frontier_sources[i] = frontier_prims[i] == kNoPrim ? kNoPrim : scene.prims[frontier_prims[i]].source;
  }
  const size_t frontier_covered = covered(frontier_prims);
  ASSERT_GT(frontier_covered, size_t{kSize * kSize / 10});

  auto r = make(kSize, kSize);
  ASSERT_NE(r, nullptr);
  ASSERT_TRUE(r->set_scene(scene));
  std::vector<uint32_t> mesa_sources, mesa_prims;
  ASSERT_TRUE(r->ids(view, mesa_sources));
  MesaOptions by_prim;
  by_prim.id_kind = MesaIdKind::Primitive;
  ASSERT_TRUE(r->ids(view, mesa_prims, nullptr, by_prim));

  const size_t pixels = view.pixels();
  const Difference silhouette = compare(frontier_sources, mesa_sources, kSize, kSize);
  EXPECT_LE(silhouette.differing, pixels / 100) << "coverage differs at " << silhouette.differing << " pixels";
  EXPECT_EQ(silhouette.off_edge, 0u) << "coverage differs away from the silhouette";
  const Difference triangles = compare(frontier_prims, mesa_prims, kSize, kSize);
  EXPECT_LE(triangles.differing, pixels / 100) << "triangle ids differ at " << triangles.differing << " pixels";
  EXPECT_EQ(triangles.off_edge, 0u) << "triangle ids differ away from triangle edges";

  auto frame = r->render(view);
  ASSERT_TRUE(frame.is_ok()) << frame.status().to_string();
  EXPECT_EQ(frame->triangles_issued, scene.size());
  EXPECT_EQ(frame->vertices_lit, 3 * scene.size());
  EXPECT_GE(frame->pixels_covered, frontier_covered);
  EXPECT_GE(frame->samples_passed, covered(mesa_sources));
  EXPECT_LE(frame->samples_passed, frame->pixels_covered);
  EXPECT_EQ(frame->lights_used, 1);
  EXPECT_GT(frame->frame_ms, 0.0);
  // Background where the id pass saw none, something else on the sphere.
  ASSERT_EQ(frame->colors.size(), pixels);
  for (size_t i = 0; i < pixels; ++i) {
    if (mesa_sources[i] != kNoPrim) continue;
    ASSERT_NEAR(frame->colors[i].r, 0.1f, 1.0f / 255.0f) << "pixel " << i;
    ASSERT_NEAR(frame->colors[i].b, 0.3f, 1.0f / 255.0f) << "pixel " << i;
  }
}

// A convex closed mesh drawn front to back passes the depth test about once per covered pixel,
// back to front about twice; rasterized fragments are the same either way; culling back faces
// halves them.
TEST(Mesa, CountersFollowOrderAndCulling) {
  const Scene scene = sphere_scene(Vec3(5.0, 5.0, 5.0));
  const View view(*scene.camera, kSize, kSize);
  auto r = make(kSize, kSize);
  ASSERT_NE(r, nullptr);
  ASSERT_TRUE(r->set_scene(scene));
  std::vector<uint32_t> ids;
  ASSERT_TRUE(r->ids(view, ids));
  const size_t visible = covered(ids);

  std::vector<uint32_t> order(scene.size());
  std::iota(order.begin(), order.end(), 0u);
  auto distance = [&](uint32_t i) {
    const Triangle& t = scene.triangles[scene.prims[i].index];
    return glm::length((t.v0 + t.v1 + t.v2) / 3.0 - view.eye);
  };
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return distance(a) < distance(b); });
  MesaOptions small_chunks;
  small_chunks.chunk_triangles = 7;
  auto front_to_back = r->render(view, &order, small_chunks);
  std::reverse(order.begin(), order.end());
  auto back_to_front = r->render(view, &order);
  ASSERT_TRUE(front_to_back.is_ok() && back_to_front.is_ok());
  EXPECT_EQ(front_to_back->pixels_covered, back_to_front->pixels_covered);
  EXPECT_GE(front_to_back->draw_calls, (scene.size() + 6) / 7);
  EXPECT_GE(front_to_back->samples_passed, visible);
  EXPECT_LE(front_to_back->samples_passed, visible + visible / 50);
  EXPECT_GE(back_to_front->samples_passed, visible + visible * 3 / 4);
  EXPECT_GE(front_to_back->pixels_covered, 2 * visible - visible / 50);

  MesaOptions cull;
  cull.cull_back_faces = true;
  auto culled = r->render(view, nullptr, cull);
  ASSERT_TRUE(culled.is_ok());
  EXPECT_LE(culled->pixels_covered, visible + visible / 50);
  EXPECT_GE(culled->pixels_covered, visible);
  std::vector<uint32_t> culled_ids;
  ASSERT_TRUE(r->ids(view, culled_ids, nullptr, cull));
  EXPECT_EQ(covered(culled_ids), visible);
}

// The side of the sphere facing the light is brighter than the side facing away, and moving
// the light to the other side swaps them.
TEST(Mesa, LightingFollowsTheLight) {
  for (const double side : {1.0, -1.0}) {
    const Scene scene = sphere_scene(Vec3(0.3 + 6.0 * side, -0.2, 0.1));
    const View view(*scene.camera, kSize, kSize);
    auto r = make(kSize, kSize);
    ASSERT_NE(r, nullptr);
    ASSERT_TRUE(r->set_scene(scene));
    auto frame = r->render(view);
    ASSERT_TRUE(frame.is_ok());
    std::vector<uint32_t> ids;
    ASSERT_TRUE(r->ids(view, ids));
    // The leftmost and rightmost sphere pixels of the middle row, moved 4 pixels inwards.
    const int y = kSize / 2;
    int left = -1, right = -1;
    for (int x = 0; x < kSize; ++x) {
      if (ids[static_cast<size_t>(y) * kSize + x] == kNoPrim) continue;
      if (left < 0) left = x;
      right = x;
    }
    ASSERT_GE(left, 0);
    ASSERT_GT(right - left, 20);
    const float l = luminance(frame->colors[static_cast<size_t>(y) * kSize + left + 4]);
    const float rr = luminance(frame->colors[static_cast<size_t>(y) * kSize + right - 4]);
    if (side > 0) {
      EXPECT_GT(rr, l + 0.2f) << "light on the right: right " << rr << " left " << l;
    } else {
      EXPECT_GT(l, rr + 0.2f) << "light on the left: right " << rr << " left " << l;
    }
  }
}

// Per-vertex, not per-pixel: a square of two triangles with a light just above its centre.
// Per-pixel lighting would make the centre nearly white; Gouraud shading interpolates the
// corners' grazing light, so the centre is as dark as the corners (ambient 0.1 + n·l ≈ 0.07).
TEST(Mesa, LightingIsPerVertex) {
  Scene scene;
  Material m;
  m.color = Vec3(1.0);
  m.kd = 1.0;
  m.ks = 0.0;
  scene.materials.push_back(m);
  const std::array<Vec3, 3> up = {Vec3(0, 0, 1), Vec3(0, 0, 1), Vec3(0, 0, 1)};
  scene.add_triangle(Triangle{Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(1, 1, 0)}, 0, 0, &up);
  scene.add_triangle(Triangle{Vec3(-1, -1, 0), Vec3(1, 1, 0), Vec3(-1, 1, 0)}, 1, 0, &up);
  scene.lights.push_back(PointLight{Vec3(0.0, 0.0, 0.1), Vec3(1.0)});
  Camera camera;
  camera.eye = Vec3(0.0, 0.0, 3.0);
  camera.look_at = Vec3(0.0);
  camera.vfov_deg = 30.0;
  const View view(camera, 65, 65);
  auto r = make(65, 65);
  ASSERT_NE(r, nullptr);
  ASSERT_TRUE(r->set_scene(scene));
  auto frame = r->render(view);
  ASSERT_TRUE(frame.is_ok());
  const double corner = 0.1 + 0.1 / std::sqrt(2.01);  // ambient + n·l at a corner
  const Rgb centre = frame->colors[32 * 65 + 32];
  EXPECT_NEAR(centre.r, corner, 0.02) << "centre is lit per pixel?";
  EXPECT_NEAR(centre.g, corner, 0.02);
}

// A paper-sized frame: ~100k triangles (46 spheres of 48 segments in a 3D grid) at 513².
// Front-to-back order passes fewer fragments through the depth test than back-to-front while
// rasterizing the same fragments; the lit frame time is recorded (Mesa.*.frame_ms properties).
TEST(Mesa, HundredThousandTrianglesAt513) {
  Scene curved;
  Material m;
  m.color = Vec3(0.7, 0.7, 0.9);
  m.ks = 0.3;
  m.shine = 30.0;
  curved.materials.push_back(m);
  uint32_t source = 0;
  for (int z = 0; z < 4 && source < 46; ++z) {
    for (int y = 0; y < 4 && source < 46; ++y) {
      for (int x = 0; x < 4 && source < 46; ++x, ++source) {
        curved.add_sphere(Sphere{Vec3(2.0 * x, 2.0 * y, -2.0 * z), 0.8}, source, 0);
      }
    }
  }
  curved.input_primitives = source;
  curved.lights.push_back(PointLight{Vec3(10.0, 10.0, 10.0), Vec3(1.0)});
  curved.lights.push_back(PointLight{Vec3(-10.0, 5.0, 10.0), Vec3(0.5, 0.5, 1.0)});
  TessellateOptions options;
  options.segments = 48;
  const Scene scene = tessellate(curved, options);
  ASSERT_GE(scene.size(), 100000u);
  Camera camera;
  camera.eye = Vec3(3.0, 3.0, 9.0);
  camera.look_at = Vec3(3.0, 3.0, -3.0);
  camera.vfov_deg = 50.0;
  const View view(camera, 513, 513);
  auto r = make(513, 513);
  ASSERT_NE(r, nullptr);
  ASSERT_TRUE(r->set_scene(scene));

  // Object by object, nearest object first (the paper's rough front-to-back order), and the
  // objects reversed; each object's triangles keep their order.
  std::vector<uint32_t> front_order(scene.size());
  std::iota(front_order.begin(), front_order.end(), 0u);
  std::stable_sort(front_order.begin(), front_order.end(), [&](uint32_t a, uint32_t b) {
    return scene.prims[a].source < scene.prims[b].source;  // sources grow away from the eye
  });
  std::vector<uint32_t> back_order = front_order;
  std::stable_sort(back_order.begin(), back_order.end(), [&](uint32_t a, uint32_t b) {
    return scene.prims[a].source > scene.prims[b].source;
  });
  // The fastest of three frames each (the machine may be busy).
  auto best_of_three = [&](const std::vector<uint32_t>* order) {
    Result<MesaFrame> best = r->render(view, order);
    for (int k = 0; k < 2 && best.is_ok(); ++k) {
      Result<MesaFrame> next = r->render(view, order);
      if (next.is_ok() && next->frame_ms < best->frame_ms) best = std::move(next);
    }
    return best;
  };
  auto front_to_back = best_of_three(&front_order);
  auto back_to_front = best_of_three(&back_order);
  auto in_order = best_of_three(nullptr);
  ASSERT_TRUE(front_to_back.is_ok() && back_to_front.is_ok() && in_order.is_ok());
  EXPECT_EQ(front_to_back->triangles_issued, scene.size());
  EXPECT_EQ(front_to_back->pixels_covered, back_to_front->pixels_covered);
  EXPECT_LT(front_to_back->samples_passed, back_to_front->samples_passed);
  EXPECT_LE(back_to_front->samples_passed, back_to_front->pixels_covered);
  ::testing::Test::RecordProperty("triangles", static_cast<int>(scene.size()));
  ::testing::Test::RecordProperty("front_to_back_ms", std::to_string(front_to_back->frame_ms));
  ::testing::Test::RecordProperty("back_to_front_ms", std::to_string(back_to_front->frame_ms));
  ::testing::Test::RecordProperty("in_order_ms", std::to_string(in_order->frame_ms));
  std::printf("[ mesa     ] %zu triangles at 513x513 on %s: %.1f ms front-to-back, %.1f ms back-to-front, "
              "%.1f ms scene order; %llu fragments, %llu / %llu passed depth\n",
              scene.size(), r->renderer().c_str(), front_to_back->frame_ms, back_to_front->frame_ms,
              in_order->frame_ms, static_cast<unsigned long long>(front_to_back->pixels_covered),
              static_cast<unsigned long long>(front_to_back->samples_passed),
              static_cast<unsigned long long>(back_to_front->samples_passed));
}

TEST(Mesa, RenderersComeAndGo) {
  const Scene scene = sphere_scene(Vec3(5.0));
  const View view(*scene.camera, 40, 30);
  std::vector<uint32_t> first;
  for (int k = 0; k < 3; ++k) {
    auto r = make(40, 30);
    ASSERT_NE(r, nullptr);
    ASSERT_TRUE(r->set_scene(scene));
    std::vector<uint32_t> ids;
    ASSERT_TRUE(r->ids(view, ids));
    if (k == 0) first = ids;
    EXPECT_EQ(ids, first) << "renderer " << k;
  }
  // Two at once, used alternately.
  auto a = make(40, 30);
  auto b = make(40, 30);
  ASSERT_NE(a, nullptr);
  ASSERT_NE(b, nullptr);
  ASSERT_TRUE(a->set_scene(scene));
  ASSERT_TRUE(b->set_scene(scene));
  std::vector<uint32_t> ids_a, ids_b;
  ASSERT_TRUE(a->ids(view, ids_a));
  ASSERT_TRUE(b->ids(view, ids_b));
  a.reset();
  ASSERT_TRUE(b->ids(view, ids_b));
  EXPECT_EQ(ids_a, first);
  EXPECT_EQ(ids_b, first);
}

}  // namespace
}  // namespace frontier
