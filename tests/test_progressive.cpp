// The job queue under a budget (§5.2) and reconstruction (§5.4): an interrupted frame is
// complete after reconstruction, a resumed frame equals the full render, and effects the scene
// does not declare cost nothing (counters prove it).
#include "tests/engine_util.h"

#include "src/engine/frustum.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace frontier {
namespace {

Scene lit_scene(bool with_lights, bool specular) {
  std::mt19937_64 rng(99);
  Scene scene = testing::random_scene(rng, 150);
  scene.materials[0].ks = specular ? 0.5 : 0.0;
  scene.materials[0].shine = 20.0;
  if (with_lights) {
    scene.lights.push_back({Vec3(3, -3, 4), Vec3(1.0)});
    scene.lights.push_back({Vec3(-4, -2, 2), Vec3(1.0)});
  }
  return scene;
}

Camera front_camera() {
  Camera c;
  c.eye = Vec3(0.2, -3.5, 0.5);
  c.look_at = Vec3(0.0);
  c.up = Vec3(0, 0, 1);
  c.vfov_deg = 50.0;
  return c;
}

TEST(Progressive, InterruptedFrameIsCompleteAndResumesToTheFullRender) {
  const Scene scene = lit_scene(true, true);
  const KdTree tree = KdTree::build(scene, {});
  const View view(front_camera(), 97, 81);
  const Shader shader(scene, tree);

  SampleBuffer full;
  RenderOptions options;
  options.threads = 2;
  render_frame(scene, tree, view, options, full);
  ASSERT_EQ(full.confirmed_count(), view.pixels());

  for (uint64_t k : {1ull, 50ull, 500ull, 3000ull}) {
    SampleBuffer buffer;
    CellMarks marks;
    FrustumCaster caster(scene, tree, shader, 2);
    caster.begin(view, buffer, marks, true, true);
    Counters counters;
    FrameBudget budget;
    budget.samples = k;
    const bool done = caster.run(budget, counters);
    EXPECT_FALSE(done) << "a budget of " << k << " samples should interrupt the frame";
    EXPECT_GE(counters.samples, k);
    EXPECT_LT(buffer.confirmed_count(), view.pixels());
    // Reconstruction fills every pixel: mark the image with NaN first and look for leftovers.
    for (Rgb& c : buffer.image()) c = {NAN, NAN, NAN};
    reconstruct(buffer, shader.background());
    size_t unset = 0;
    for (const Rgb& c : buffer.image()) unset += std::isnan(c.r) ? 1 : 0;
    EXPECT_EQ(unset, 0u) << "after " << k << " samples";
    // Resume to completion: the same ids and colours as the uninterrupted render.
    while (!caster.run(FrameBudget{}, counters)) {
    }
    ASSERT_EQ(buffer.confirmed_count(), view.pixels());
    size_t differ = 0;
    for (size_t i = 0; i < view.pixels(); ++i) {
      differ += buffer.prim(i) != full.prim(i) ? 1 : 0;
      const Rgb a = buffer.color(i), b = full.color(i);
      differ += std::abs(a.r - b.r) + std::abs(a.g - b.g) + std::abs(a.b - b.b) > 1e-5f ? 1 : 0;
    }
    EXPECT_EQ(differ, 0u) << "after resuming from " << k << " samples";
  }
}

// A bumpy height field of triangles (packets apply), seen at an angle.
Scene bumpy_terrain(int n) {
  Scene scene;
  scene.materials.push_back({});
  auto z = [](int x, int y) { return 0.3 * std::sin(0.7 * x) * std::cos(0.5 * y) + 0.05 * ((x * 7 + y * 3) % 5); };
  uint32_t id = 0;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const Vec3 a(x, y, z(x, y)), b(x + 1, y, z(x + 1, y)), c(x, y + 1, z(x, y + 1)), d(x + 1, y + 1, z(x + 1, y + 1));
      scene.add_triangle({a, b, d}, id++, 0);
      scene.add_triangle({a, d, c}, id++, 0);
    }
  }
  return scene;
}

// Previews (FrustumCaster::set_preview): a budgeted frame first traces each leaf frustum at
// points a few pixels apart and comes back for the rest. Stopped once every leaf has its
// preview, no block of 8 × 8 pixels over the terrain is without a sample (the anchors alone
// are 32 pixels apart); every sample is the complete render's, and the frame resumed to the
// end equals it pixel for pixel.
TEST(Progressive, PreviewSamplesEveryLeafAFewPixelsApartAndStaysExact) {
  const Scene scene = bumpy_terrain(48);
  const KdTree tree = KdTree::build(scene, {});
  const View view(testing::camera_at(Vec3(-4.0, -4.0, 7.0), Vec3(20.0, 20.0, 0.0), 50.0), 256, 192);
  const Shader shader(scene, tree);
  SampleBuffer full;
  {
    CellMarks marks;
    FrustumCaster caster(scene, tree, shader, 2);
    caster.set_leaf_pixels(32);
    caster.begin(view, full, marks, true, false);
    Counters counters;
    ASSERT_TRUE(caster.run(FrameBudget{}, counters));
  }
  size_t geometry = 0;
  for (size_t i = 0; i < view.pixels(); ++i) geometry += full.prim(i) != kNoPrim ? 1 : 0;
  ASSERT_GT(geometry, view.pixels() / 2) << "the terrain should fill most of the view";

  for (const bool preview : {false, true}) {
    SampleBuffer buffer;
    CellMarks marks;
    FrustumCaster caster(scene, tree, shader, 2);
    caster.set_leaf_pixels(32);
    caster.set_preview(preview);
    caster.begin(view, buffer, marks, true, false);
    EXPECT_EQ(caster.preview(), preview);
    Counters counters;
    // One sample at a time: run() stops after each job; stop at the first moment a quarter of
    // the pixels are confirmed.
    FrameBudget budget;
    budget.samples = 1;
    while (buffer.confirmed_count() < view.pixels() / 4 && !caster.run(budget, counters)) {
    }
    ASSERT_LT(buffer.confirmed_count(), view.pixels() / 2) << "preview " << preview;
    size_t empty = 0, blocks = 0;
    for (int by = 0; by + 8 <= view.height; by += 8) {
      for (int bx = 0; bx + 8 <= view.width; bx += 8) {
        size_t n = 0, g = 0;
        for (int y = by; y < by + 8; ++y) {
          for (int x = bx; x < bx + 8; ++x) {
            const size_t i = size_t(y) * size_t(view.width) + size_t(x);
            n += buffer.confirmed(i) ? 1 : 0;
            g += full.prim(i) != kNoPrim ? 1 : 0;
          }
        }
        if (g < 64) continue;  // only blocks wholly on the terrain
        ++blocks;
        empty += n == 0 ? 1 : 0;
      }
    }
    ASSERT_GT(blocks, 100u);
    if (preview) {
      EXPECT_EQ(empty, 0u) << "of " << blocks << " blocks of 8 × 8 pixels on the terrain";
    } else {
      EXPECT_GT(empty, blocks / 10) << "without previews whole leaves are still open (the test's premise)";
    }
    size_t differ = 0;
    for (size_t i = 0; i < view.pixels(); ++i) differ += buffer.confirmed(i) && buffer.prim(i) != full.prim(i) ? 1 : 0;
    EXPECT_EQ(differ, 0u) << "preview " << preview;
    while (!caster.run(FrameBudget{}, counters)) {
    }
    ASSERT_EQ(buffer.confirmed_count(), view.pixels());
    differ = 0;
    for (size_t i = 0; i < view.pixels(); ++i) differ += buffer.prim(i) != full.prim(i) ? 1 : 0;
    EXPECT_EQ(differ, 0u) << "resumed, preview " << preview;
  }
}

TEST(Progressive, SampleBudgetLeavesSamplesSpreadOverTheScreen) {
  const Scene scene = lit_scene(true, false);
  const KdTree tree = KdTree::build(scene, {});
  const View view(front_camera(), 129, 129);
  const Shader shader(scene, tree);
  SampleBuffer buffer;
  CellMarks marks;
  FrustumCaster caster(scene, tree, shader, 2);
  caster.begin(view, buffer, marks, true, true);
  Counters counters;
  FrameBudget budget;
  budget.samples = view.pixels() / 4;
  caster.run(budget, counters);
  // Interleaved order: every quarter of the screen got samples.
  size_t quarter[4] = {0, 0, 0, 0};
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      if (buffer.confirmed(size_t(y) * 129 + size_t(x))) ++quarter[(y >= 64 ? 2 : 0) + (x >= 64 ? 1 : 0)];
    }
  }
  for (size_t q : quarter) EXPECT_GT(q, 0u);
}

// A small budget still spreads exact samples over the whole screen: the reconstruction anchors
// (corners and midpoints of the quadrant subdivision) are walked before the frusta, which
// would otherwise spend the budget on a few whole blocks (background fills of 16×16 pixels).
TEST(Progressive, SmallBudgetConfirmsSamplesInEveryBlock) {
  const Scene scene = lit_scene(true, false);
  const KdTree tree = KdTree::build(scene, {});
  const View view(front_camera(), 257, 257);
  const Shader shader(scene, tree);
  SampleBuffer full;
  RenderOptions options;
  options.threads = 2;
  render_frame(scene, tree, view, options, full);
  SampleBuffer buffer;
  CellMarks marks;
  FrustumCaster caster(scene, tree, shader, 2);
  caster.begin(view, buffer, marks, true, true);
  Counters counters;
  FrameBudget budget;
  budget.samples = view.pixels() / 50;  // 2 %
  caster.run(budget, counters);
  ASSERT_LT(buffer.confirmed_count(), view.pixels() / 10);
  int empty_blocks = 0;
  for (int by = 0; by < 8; ++by) {
    for (int bx = 0; bx < 8; ++bx) {
      size_t n = 0;
      for (int y = 32 * by; y < 32 * by + 32; ++y) {
        for (int x = 32 * bx; x < 32 * bx + 32; ++x) n += buffer.confirmed(size_t(y) * 257 + size_t(x)) ? 1 : 0;
      }
      empty_blocks += n == 0 ? 1 : 0;
    }
  }
  EXPECT_EQ(empty_blocks, 0) << "of 64 blocks of 32×32 pixels";
  // Exact samples: every confirmed pixel shows what the complete render shows there.
  size_t differ = 0;
  for (size_t i = 0; i < view.pixels(); ++i) differ += buffer.confirmed(i) && buffer.prim(i) != full.prim(i) ? 1 : 0;
  EXPECT_EQ(differ, 0u);
}

// The §5.4 recursion written plainly (sequential, one rectangle at a time): reconstruct() fills
// tiles in parallel and must give exactly this, for every size and sample pattern.
void reference_fill(const SampleBuffer& buf, std::vector<Rgb>& img, std::vector<uint8_t>& known, int w, int x0,
                    int y0, int x1, int y1) {
  auto at = [&](int x, int y) { return size_t(y) * size_t(w) + size_t(x); };
  auto settle = [&](int x, int y, Rgb v) {
    const size_t i = at(x, y);
    if (known[i]) return;
    img[i] = buf.confirmed(i) ? buf.color(i) : v;
    known[i] = 1;
  };
  auto mix = [](Rgb a, Rgb b) { return Rgb{0.5f * (a.r + b.r), 0.5f * (a.g + b.g), 0.5f * (a.b + b.b)}; };
  const bool sx = x1 - x0 >= 2, sy = y1 - y0 >= 2;
  if (!sx && !sy) return;
  const int xm = sx ? (x0 + x1) / 2 : x0, ym = sy ? (y0 + y1) / 2 : y0;
  const Rgb a = img[at(x0, y0)], b = img[at(x1, y0)], c = img[at(x0, y1)], d = img[at(x1, y1)];
  if (sx) {
    settle(xm, y0, mix(a, b));
    settle(xm, y1, mix(c, d));
  }
  if (sy) {
    settle(x0, ym, mix(a, c));
    settle(x1, ym, mix(b, d));
  }
  if (sx && sy) {
    settle(xm, ym, Rgb{0.25f * (a.r + b.r + c.r + d.r), 0.25f * (a.g + b.g + c.g + d.g), 0.25f * (a.b + b.b + c.b + d.b)});
    reference_fill(buf, img, known, w, x0, y0, xm, ym);
    reference_fill(buf, img, known, w, xm, y0, x1, ym);
    reference_fill(buf, img, known, w, x0, ym, xm, y1);
    reference_fill(buf, img, known, w, xm, ym, x1, y1);
  } else if (sx) {
    reference_fill(buf, img, known, w, x0, y0, xm, y1);
    reference_fill(buf, img, known, w, xm, y0, x1, y1);
  } else {
    reference_fill(buf, img, known, w, x0, y0, x1, ym);
    reference_fill(buf, img, known, w, x0, ym, x1, y1);
  }
}

// The sky marks of set_background(): a pixel filled with the sky colour is skipped when filled
// again, but a pixel something else wrote since (geometry, another colour) is written again, and
// a new sky colour forgets every mark.
TEST(SampleBuffer, SkyMarksNeverHideAPixelWrittenSince) {
  SampleBuffer b;
  b.resize(4, 1);
  const Rgb sky{0.2f, 0.3f, 0.4f}, other{1.0f, 0.0f, 0.0f};
  b.set_sky(sky);
  for (size_t i = 0; i < 4; ++i) b.set_background(i, sky);
  b.set(1, 7, 2.5, Rgb{0.5f, 0.5f, 0.5f});  // geometry over the sky
  b.set_background(2, other);               // not the sky colour
  for (size_t i = 0; i < 4; ++i) b.set_background(i, sky);
  for (size_t i = 0; i < 4; ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(b.prim(i), kNoPrim);
    EXPECT_EQ(b.t(i), kInfinity);
    EXPECT_EQ(b.color(i).r, sky.r);
    EXPECT_EQ(b.color(i).b, sky.b);
  }
  // Another sky: the old marks say nothing about it.
  b.set_sky(other);
  b.set_background(3, other);
  EXPECT_EQ(b.color(3).r, other.r);
  EXPECT_EQ(b.color(0).r, sky.r);  // untouched
}

TEST(Reconstruct, ParallelTilesEqualTheSequentialRecursion) {
  std::mt19937_64 rng(5);
  for (const auto& [w, h] : std::vector<std::pair<int, int>>{{640, 480}, {97, 301}, {1, 50}, {3, 2}, {257, 129}}) {
    for (double density : {0.001, 0.05, 0.5}) {
      SampleBuffer buf;
      buf.resize(w, h);
      buf.begin_frame();
      std::uniform_real_distribution<double> u(0.0, 1.0);
      double r = 0, g = 0, bsum = 0;
      size_t n = 0;
      for (size_t i = 0; i < buf.size(); ++i) {
        if (u(rng) >= density || !buf.claim(i)) continue;
        const Rgb c{float(u(rng)), float(u(rng)), float(u(rng))};
        buf.set(i, 0, 1.0, c);
        r += c.r;
        g += c.g;
        bsum += c.b;
        ++n;
      }
      const Rgb fallback{0.1f, 0.2f, 0.3f};
      const Rgb mean = n ? Rgb{float(r / n), float(g / n), float(bsum / n)} : fallback;
      std::vector<Rgb> expect(buf.size());
      std::vector<uint8_t> known(buf.size(), 0);
      auto corner = [&](int x, int y) {
        const size_t i = size_t(y) * size_t(w) + size_t(x);
        if (known[i]) return;
        expect[i] = buf.confirmed(i) ? buf.color(i) : mean;
        known[i] = 1;
      };
      corner(0, 0);
      corner(w - 1, 0);
      corner(0, h - 1);
      corner(w - 1, h - 1);
      reference_fill(buf, expect, known, w, 0, 0, w - 1, h - 1);
      reconstruct(buf, fallback);
      for (size_t i = 0; i < buf.size(); ++i) {
        ASSERT_TRUE(known[i]) << "reference left pixel " << i;
        ASSERT_EQ(buf.image()[i].r, expect[i].r) << w << "x" << h << " density " << density << " pixel " << i;
        ASSERT_EQ(buf.image()[i].g, expect[i].g);
        ASSERT_EQ(buf.image()[i].b, expect[i].b);
      }
    }
  }
}

TEST(Effects, NoLightsMeansHeadlightAndNoShadowRays) {
  const Scene scene = lit_scene(false, false);
  const KdTree tree = KdTree::build(scene, {});
  const View view(front_camera(), 65, 65);
  for (Method m : {Method::RayWalk, Method::Frustum}) {
    SampleBuffer buffer;
    RenderOptions options;
    options.method = m;
    const Counters c = render_frame(scene, tree, view, options, buffer);
    EXPECT_EQ(c.shadow_rays, 0u);
    EXPECT_EQ(c.specular_ops, 0u);
    EXPECT_GT(c.shading_ops, 0u);
    EXPECT_TRUE(Effects::declared_by(scene).headlight);
  }
}

TEST(Effects, DeclaredLightsCastShadowRaysAndSpecularOnlyWhenAsked) {
  const Scene lit = lit_scene(true, true);
  const KdTree tree = KdTree::build(lit, {});
  const View view(front_camera(), 65, 65);
  SampleBuffer buffer;
  RenderOptions options;
  const Counters c = render_frame(lit, tree, view, options, buffer);
  EXPECT_GT(c.shadow_rays, 0u);
  EXPECT_GT(c.specular_ops, 0u);
  options.shadows = false;
  const Counters immediate = render_frame(lit, tree, view, options, buffer);
  EXPECT_EQ(immediate.shadow_rays, 0u) << "shadows are deferred: an immediate-only frame casts none";
  options.shade = false;
  const Counters visibility = render_frame(lit, tree, view, options, buffer);
  EXPECT_EQ(visibility.shading_ops, 0u);
}

}  // namespace
}  // namespace frontier

namespace frontier {
namespace {

TEST(Shading, HeadlightFastPathEqualsTheGeneralPathWithAndWithoutShadingNormals) {
  // Triangles under the headlight alone take a short path (shading.cpp); it must colour every
  // hit as lit() does with the shading normal, flat triangles and interpolated normals alike.
  for (const bool normals : {false, true}) {
    Scene scene;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int i = 0; i < 40; ++i) {
      const Vec3 c(u(rng) * 5, u(rng) * 5, u(rng) * 5);
      const Triangle t{c + Vec3(u(rng), u(rng), u(rng)), c + Vec3(u(rng), u(rng), u(rng)), c + Vec3(u(rng), u(rng), u(rng))};
      std::array<Vec3, 3> n = {glm::normalize(Vec3(u(rng), u(rng), u(rng))),
                               glm::normalize(Vec3(u(rng), u(rng), u(rng))),
                               glm::normalize(Vec3(u(rng), u(rng), u(rng)))};
      if (i % 5 == 0) n = {n[0], n[0], n[0]};  // one normal for the whole triangle (a short cut)
      scene.add_triangle(t, uint32_t(i), 0, normals ? &n : nullptr);
    }
    const KdTree tree = KdTree::build(scene, {});
    const Shader shader(scene, tree);
    ASSERT_TRUE(shader.effects().headlight);
    ASSERT_FALSE(shader.effects().specular);
    int compared = 0;
    for (uint32_t i = 0; i < scene.size(); ++i) {
      const Triangle& t = scene.triangles[scene.prims[i].index];
      for (int k = 0; k < 5; ++k) {
        double a = std::abs(u(rng)), b = std::abs(u(rng));
        if (a + b > 1.0) a = 1.0 - a, b = 1.0 - b;
        const Vec3 p = t.v0 + a * (t.v1 - t.v0) + b * (t.v2 - t.v0);
        const Vec3 eye(u(rng) * 20, u(rng) * 20, 20.0 + u(rng));
        const Ray ray(eye, p - eye);
        const double hit_t = glm::length(p - eye);
        Counters counters;
        const Rgb fast = shader.shade(i, ray, hit_t, false, counters);
        const Rgb general =
            shader.shade_surface(scene.prims[i].material, scene.shading_normal(i, p, ray), ray, hit_t, counters);
        EXPECT_NEAR(fast.r, general.r, 1e-5) << "normals " << normals << " prim " << i;
        EXPECT_NEAR(fast.g, general.g, 1e-5);
        EXPECT_NEAR(fast.b, general.b, 1e-5);
        ++compared;
      }
    }
    EXPECT_EQ(compared, 200);
  }
}

}  // namespace
}  // namespace frontier
