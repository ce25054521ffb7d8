// BSP trees (Fuchs, Abram & Grant 1983) against simple references:
//  * build: area preserved to 1e-9 and every fragment on its source plane (checked here from the
//    input triangles, independently of BspTree::validate), the 'all candidates' root cuts fewest,
//    seeds make builds reproducible, adversarial sets (coplanar stacks, near-coplanar fans,
//    slivers) terminate with bounded trees, bad input is refused;
//  * the fuzz decoder over a fixed set of seeds (what tests/fuzz/fuzz_bsp.cpp runs unbounded);
//  * painter's rendering equals the z-buffer render of the same faces at every pixel but depth
//    ties, with and without back-face removal, from outside and from inside;
//  * front to back is back to front reversed; the coverage mask partitions sub-samples exactly,
//    measures area, fills pixels (the early-out) and its edge error falls with N;
//  * a moving object renders correctly at several transforms without rebuilding the tree.
#include "src/raster/bsp.h"
#include "src/raster/bsp_render.h"
#include "src/raster/raster.h"
#include "src/core/tessellate.h"
#include "src/core/view.h"
#include "tests/engine_util.h"

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <random>

namespace frontier {
namespace {

using testing::camera_at;

// Random triangles in [-1,1]^3, interpenetrating (so the tree must split), some large.
PolygonSoup random_soup(std::mt19937_64& rng, int count, const Aabb* avoid = nullptr) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), size(0.1, 0.6);
  std::uniform_int_distribution<int> large(0, 9);
  PolygonSoup soup;
  soup.material_colors = {Vec3(0.9, 0.3, 0.2), Vec3(0.2, 0.8, 0.3), Vec3(0.3, 0.4, 0.9)};
  while (int(soup.size()) < count) {
    const Vec3 c(u(rng), u(rng), u(rng));
    const double s = large(rng) == 0 ? 1.5 : size(rng);
    const Triangle t{c, c + s * Vec3(u(rng), u(rng), u(rng)), c + s * Vec3(u(rng), u(rng), u(rng))};
    if (avoid != nullptr && bounds_of(t).overlaps(*avoid)) continue;
    soup.add_triangle(t, uint32_t(soup.size()), uint32_t(soup.size() % 3));
  }
  return soup;
}

double polygon_area(std::span<const Vec3> v) {
  Vec3 n(0.0);
  for (size_t i = 1; i + 1 < v.size(); ++i) n += glm::cross(v[i] - v[0], v[i + 1] - v[0]);
  return 0.5 * glm::length(n);
}

// Area and source-plane checks from the input, not from the tree's own bookkeeping.
void expect_area_and_planes(const PolygonSoup& soup, const BspTree& tree, const std::string& what) {
  double in = 0.0, out = 0.0;
  for (size_t i = 0; i < soup.size(); ++i) in += polygon_area(soup.polygon(i));
  double worst = 0.0;
  for (uint32_t f = 0; f < tree.static_faces(); ++f) {
    const std::span<const Vec3> v = tree.face_vertices(f);
    out += polygon_area(v);
    const std::span<const Vec3> src = soup.polygon(tree.faces()[f].origin);
    const Vec3 n = glm::normalize(glm::cross(src[1] - src[0], src[2] - src[0]));
    for (const Vec3& p : v) worst = std::max(worst, std::abs(glm::dot(n, p - src[0])));
  }
  const BspStats& s = tree.stats();
  EXPECT_NEAR(out + s.degenerate_area, in, 1e-9 * in) << what;
  EXPECT_NEAR(out, in, 1e-9 * in) << what << ": degenerate area " << s.degenerate_area;
  EXPECT_LE(worst, 2.0 * tree.tolerance()) << what << ": a fragment leaves its source plane";
}

TEST(BspBuild, SplittingPreservesAreaAndKeepsFragmentsOnTheirPlanes) {
  std::mt19937_64 rng(3);
  const PolygonSoup soup = random_soup(rng, 300);
  uint64_t splits = 0;
  for (int k : {1, 3, 5, 15, 0}) {
    BspBuildOptions options;
    options.candidates = k;
    auto tree = BspTree::build(soup, options);
    ASSERT_TRUE(tree.is_ok()) << tree.status().to_string();
    EXPECT_TRUE(tree->validate().is_ok()) << tree->validate().to_string();
    expect_area_and_planes(soup, *tree, "k=" + std::to_string(k));
    const BspStats& s = tree->stats();
    EXPECT_EQ(s.input_polygons, 300u);
    EXPECT_EQ(s.output_polygons, tree->faces().size());
    EXPECT_GE(s.output_polygons + s.degenerate_fragments, 300u + s.splits);
    EXPECT_LE(s.max_depth, 300u);
    splits += s.splits;
  }
  EXPECT_GT(splits, 0u) << "the scene should need splitting";
}

TEST(BspBuild, AllCandidatesPicksTheRootThatCutsFewest) {
  std::mt19937_64 rng(5);
  const PolygonSoup soup = random_soup(rng, 120);
  BspBuildOptions options;
  options.candidates = 0;
  auto tree = BspTree::build(soup, options);
  ASSERT_TRUE(tree.is_ok());
  // Brute force: how many others each input polygon's plane cuts; the first minimum wins.
  const double tol = tree->tolerance();
  size_t best = 0, best_cuts = SIZE_MAX;
  for (size_t i = 0; i < soup.size(); ++i) {
    const std::span<const Vec3> p = soup.polygon(i);
    const Vec3 n = glm::normalize(glm::cross(p[1] - p[0], p[2] - p[0]));
    size_t cuts = 0;
    for (size_t j = 0; j < soup.size(); ++j) {
      bool front = false, back = false;
      for (const Vec3& v : soup.polygon(j)) {
        const double d = glm::dot(n, v - p[0]);
        front |= d > tol;
        back |= d < -tol;
      }
      cuts += (j != i && front && back) ? 1 : 0;
    }
    if (cuts < best_cuts) {
      best_cuts = cuts;
      best = i;
    }
  }
  const BspNode& root = tree->nodes()[tree->root()];
  ASSERT_GT(root.face_count, 0u);
  EXPECT_EQ(tree->faces()[root.first_face].origin, best);
}

TEST(BspBuild, SeedsReproduceAndMoreCandidatesGiveSmallerTrees) {
  std::mt19937_64 rng(9);
  const PolygonSoup soup = random_soup(rng, 400);
  auto size = [&](int k, uint64_t seed) {
    BspBuildOptions options;
    options.candidates = k;
    options.seed = seed;
    auto tree = BspTree::build(soup, options);
    EXPECT_TRUE(tree.is_ok());
    return tree->stats().output_polygons;
  };
  EXPECT_EQ(size(3, 17), size(3, 17));
  double one = 0.0, fifteen = 0.0;
  for (uint64_t seed = 1; seed <= 4; ++seed) {
    one += double(size(1, seed));
    fifteen += double(size(15, seed));
  }
  EXPECT_LT(fifteen, one) << "fewest cuts among 15 candidates should beat a random root (Table 1)";
}

TEST(BspBuild, CoplanarStackIsOneNode) {
  PolygonSoup soup;
  for (int i = 0; i < 20; ++i) {
    const double o = 0.05 * i;
    soup.add_triangle({Vec3(o, 0, 0), Vec3(1 + o, 0, 0), Vec3(o, 1, 0)}, uint32_t(i), 0);
  }
  soup.add_triangle({Vec3(0, 0, 1), Vec3(0, 1, 1), Vec3(1, 0, 1)}, 20, 0);  // parallel, flipped
  auto tree = BspTree::build(soup, {});
  ASSERT_TRUE(tree.is_ok());
  EXPECT_TRUE(tree->validate().is_ok());
  EXPECT_EQ(tree->stats().output_polygons, 21u);
  EXPECT_EQ(tree->stats().splits, 0u);
  EXPECT_LE(tree->stats().nodes, 2u);
}

TEST(BspBuild, AdversarialSetsTerminateWithBoundedTrees) {
  const double pi = 3.14159265358979323846;
  for (double tilt : {0.0, 1e-15, 1e-12, 1e-10, 1e-9, 1e-8, 1e-6, 1e-3}) {
    PolygonSoup soup;
    // A near-coplanar fan, a stack of near-coplanar copies, and slivers across them.
    for (int i = 0; i < 24; ++i) {
      const double a0 = 2 * pi * i / 24, a1 = 2 * pi * (i + 1) / 24;
      soup.add_triangle({Vec3(0.0), Vec3(std::cos(a0), std::sin(a0), (i % 2 ? tilt : -tilt)),
                         Vec3(std::cos(a1), std::sin(a1), (i % 2 ? -tilt : tilt))},
                        uint32_t(soup.size()), 0);
    }
    for (int i = 1; i <= 8; ++i) {
      const double z = i * tilt;
      soup.add_triangle({Vec3(-0.5, -0.5, z), Vec3(0.7, -0.4, z), Vec3(0.1, 0.8, z + tilt)}, uint32_t(soup.size()), 0);
    }
    for (int i = 0; i < 8; ++i) {
      const double e = std::pow(10.0, -2.0 * i);
      soup.add_triangle({Vec3(-1, -1 + 0.25 * i, -0.5), Vec3(1, 1 - 0.25 * i, 0.5), Vec3(0, 0.25 * i - 1 + e, e)},
                        uint32_t(soup.size()), 0);
    }
    for (int k : {1, 5, 0}) {
      BspBuildOptions options;
      options.candidates = k;
      auto tree = BspTree::build(soup, options);
      ASSERT_TRUE(tree.is_ok()) << tree.status().to_string();
      EXPECT_TRUE(tree->validate().is_ok()) << "tilt " << tilt << ": " << tree->validate().to_string();
      const double n = double(soup.size());
      EXPECT_LE(double(tree->stats().output_polygons), n * n) << "tilt " << tilt;
      EXPECT_LE(tree->stats().max_depth, soup.size());
    }
  }
}

TEST(BspBuild, RefusesBadInputAndHonoursTheTimeBudget) {
  PolygonSoup bent;
  const Vec3 quad[4] = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0.1), Vec3(0, 1, 0)};
  bent.add(quad, 0, 0);
  EXPECT_EQ(BspTree::build(bent).status().code(), Status::Code::InvalidArgument);
  PolygonSoup concave;
  const Vec3 dart[4] = {Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(0.5, 0.5, 0), Vec3(0, 2, 0)};
  concave.add(dart, 0, 0);
  EXPECT_EQ(BspTree::build(concave).status().code(), Status::Code::InvalidArgument);
  PolygonSoup nan;
  nan.add_triangle({Vec3(0.0), Vec3(1.0, 0.0, 0.0), Vec3(0.0, std::nan(""), 0.0)}, 0, 0);
  EXPECT_EQ(BspTree::build(nan).status().code(), Status::Code::InvalidArgument);
  PolygonSoup flat;  // zero area: dropped and counted, not an error
  flat.add_triangle({Vec3(0.0), Vec3(1.0, 0.0, 0.0), Vec3(2.0, 0.0, 0.0)}, 0, 0);
  auto tree = BspTree::build(flat);
  ASSERT_TRUE(tree.is_ok());
  EXPECT_EQ(tree->stats().degenerate_input, 1u);
  EXPECT_EQ(tree->stats().output_polygons, 0u);

  std::mt19937_64 rng(1);
  const PolygonSoup big = random_soup(rng, 3000);
  BspBuildOptions options;
  options.candidates = 0;
  options.time_budget_ms = 1e-3;
  EXPECT_EQ(BspTree::build(big, options).status().code(), Status::Code::Unsupported);
}

// The fuzz target's property over fixed seeds: random bytes and hand-made ones.
TEST(BspFuzzSeeds, DecodedSoupsBuildValidTrees) {
  std::vector<std::vector<uint8_t>> seeds = {
      {},
      {1, 10, 20, 30, 40, 50, 60, 70, 80, 90, 1, 2, 3, 5, 9},       // coplanar stack, offsets 1e-9
      {2, 128, 128, 128, 2, 7, 100, 9, 2, 130, 120, 126, 0, 5, 12},  // near-coplanar fans
      {3, 0, 0, 0, 255, 255, 255, 1, 2, 3, 128, 15, 3, 0, 255, 0, 255, 0, 0, 9, 9, 9, 64, 19},  // slivers
      {4, 128, 128, 128, 5, 40, 10, 20, 4, 128, 128, 128, 5, 40, 10, 20},  // identical n-gons
  };
  std::mt19937_64 rng(2024);
  for (int i = 0; i < 150; ++i) {
    std::vector<uint8_t> bytes(size_t(rng() % 600));
    for (uint8_t& b : bytes) b = uint8_t(rng());
    seeds.push_back(std::move(bytes));
  }
  for (size_t i = 0; i < seeds.size(); ++i) {
    const PolygonSoup soup = decode_polygon_soup(seeds[i]);
    ASSERT_LE(soup.size(), kDecodeMaxPolygons);
    BspBuildOptions options;
    options.candidates = int(i % 4) * 2;  // 0 (all), 2, 4, 6
    options.seed = i;
    auto tree = BspTree::build(soup, options);
    ASSERT_TRUE(tree.is_ok()) << "seed " << i << ": " << tree.status().to_string();
    const Status valid = tree->validate();
    ASSERT_TRUE(valid.is_ok()) << "seed " << i << ": " << valid.to_string();
  }
}

// ---- rendering ----

struct Comparison {
  size_t mismatches = 0, ties = 0, covered = 0;
  std::string first;
};

// Painter's (depth test off, back to front) against the z-buffer of the very same triangles.
Comparison painter_vs_zbuffer(const BspTree& tree, const View& view, bool cull,
                              std::span<const glm::dmat4> transforms = {}) {
  RasterOptions painter_options;
  painter_options.threads = 2;
  painter_options.depth_test = false;
  Rasterizer painter(view, painter_options);
  submit_bsp(tree, painter, BspOrder::BackToFront, cull, transforms);
  RasterOptions z_options;
  z_options.threads = 2;
  z_options.cull_back_faces = cull;
  Rasterizer zbuffer(view, z_options);
  // Any order will do for the z-buffer; front to back exercises that order too.
  submit_bsp(tree, zbuffer, BspOrder::FrontToBack, false, transforms);
  Comparison c;
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      const uint32_t a = painter.id(x, y), b = zbuffer.id(x, y);
      c.covered += b != kNoPrim;
      if (a == b) continue;
      const double ta = painter.depth(x, y), tb = zbuffer.depth(x, y);
      if (a != kNoPrim && b != kNoPrim && std::abs(ta - tb) <= 1e-6 * std::max(ta, tb)) {
        ++c.ties;
        continue;
      }
      if (c.mismatches++ == 0) {
        c.first = "pixel (" + std::to_string(x) + "," + std::to_string(y) + "): painter face " + std::to_string(int64_t(a)) +
                  " at " + std::to_string(ta) + ", z-buffer face " + std::to_string(int64_t(b)) + " at " + std::to_string(tb);
      }
    }
  }
  return c;
}

TEST(BspRender, PaintersEqualsZBufferExceptTies) {
  std::mt19937_64 rng(11);
  const PolygonSoup soup = random_soup(rng, 250);
  auto tree = BspTree::build(soup, {});
  ASSERT_TRUE(tree.is_ok());
  const Camera cameras[] = {camera_at(Vec3(2.5, 1.5, 3.0), Vec3(0.0), 50.0), camera_at(Vec3(-3.0, 0.5, -1.0), Vec3(0.0), 45.0),
                            camera_at(Vec3(0.1, -0.2, 0.05), Vec3(1.0, 0.3, 0.2), 80.0),   // inside, near-plane cuts
                            camera_at(Vec3(-0.3, 0.4, 0.2), Vec3(-1.0, -1.0, 0.0), 70.0)};
  for (const Camera& camera : cameras) {
    const View view(camera, 96, 72);
    for (bool cull : {false, true}) {
      const Comparison c = painter_vs_zbuffer(*tree, view, cull);
      EXPECT_EQ(c.mismatches, 0u) << (cull ? "culled: " : "") << c.first;
      EXPECT_LE(c.ties, view.pixels() / 100);
      EXPECT_GT(c.covered, view.pixels() / 10);
    }
  }
}

TEST(BspRender, TessellatedSceneMatchesTheSceneZBuffer) {
  // Closed meshes (tessellated spheres, boxes, cones): painter's in source ids against the
  // z-buffer of the unsplit scene. Splitting moves no edge, so only ties and centres on the
  // original edges (within rounding of a split point) may differ.
  std::mt19937_64 rng(4);
  const Scene scene = testing::random_scene(rng, 40);
  const PolygonSoup soup = polygon_soup(scene, 12);
  auto tree = BspTree::build(soup, {});
  ASSERT_TRUE(tree.is_ok());
  EXPECT_TRUE(tree->validate().is_ok());
  const Scene triangles = tessellate(scene, [] { TessellateOptions o; o.segments = 12; o.smooth_normals = false; return o; }());
  const View view(camera_at(Vec3(2.0, -2.5, 1.5), Vec3(0.0), 50.0), 128, 96);
  RasterOptions zo;
  zo.threads = 2;
  Rasterizer zbuffer(view, zo);
  rasterize_scene(triangles, zbuffer);
  BspRenderOptions options;
  options.threads = 2;
  const BspFrame frame = render_bsp(*tree, view, options);
  size_t differ = 0;
  for (int y = 0; y < view.height; ++y) {
    for (int x = 0; x < view.width; ++x) {
      const uint32_t z = zbuffer.id(x, y), b = frame.ids[size_t(y) * size_t(view.width) + size_t(x)];
      const uint32_t zs = z == kNoPrim ? kNoPrim : triangles.prims[z].source;
      const uint32_t bs = b == kNoPrim ? kNoPrim : tree->faces()[b].source;
      differ += zs != bs;
    }
  }
  EXPECT_LE(differ, view.pixels() / 200) << "pixels whose source differs from the unsplit z-buffer";
  EXPECT_EQ(frame.counters.faces_drawn, tree->faces().size());
  EXPECT_FALSE(frame.colors.empty());
}

TEST(BspRender, FrontToBackIsBackToFrontReversedNodeByNode) {
  std::mt19937_64 rng(13);
  const PolygonSoup soup = random_soup(rng, 200);
  auto tree = BspTree::build(soup, {});
  ASSERT_TRUE(tree.is_ok());
  for (const Vec3& eye : {Vec3(3, 2, 1), Vec3(0.1, 0.0, -0.2), Vec3(-2, -4, 0.5)}) {
    std::vector<uint32_t> back_to_front, front_to_back;
    auto nodes = [&](BspOrder order, std::vector<uint32_t>& out) {
      tree->traverse(eye, order, false, {}, [&](uint32_t f, std::span<const Vec3>) {
        const uint32_t node = tree->faces()[f].node;
        if (out.empty() || out.back() != node) out.push_back(node);
      });
    };
    nodes(BspOrder::BackToFront, back_to_front);
    nodes(BspOrder::FrontToBack, front_to_back);
    std::reverse(front_to_back.begin(), front_to_back.end());
    EXPECT_EQ(front_to_back, back_to_front);
    uint64_t culled = 0, drawn = 0;
    tree->traverse(eye, BspOrder::BackToFront, true, {}, [&](uint32_t, std::span<const Vec3>) { ++drawn; }, &culled);
    EXPECT_EQ(drawn + culled, tree->faces().size());
    EXPECT_GT(culled, 0u);
  }
}

// A screen-filling wall of two coplanar triangles, with triangles hidden behind it.
PolygonSoup wall_scene() {
  PolygonSoup soup;
  soup.material_colors = {Vec3(1.0), Vec3(0.5)};
  soup.add_triangle({Vec3(-10, -10, 0), Vec3(10, -10, 0), Vec3(10, 10, 0)}, 0, 0);
  soup.add_triangle({Vec3(-10, -10, 0), Vec3(10, 10, 0), Vec3(-10, 10, 0)}, 1, 0);
  for (int i = 0; i < 10; ++i) {
    const double z = -1.0 - i;
    soup.add_triangle({Vec3(-1, -1, z), Vec3(1, -1, z), Vec3(0, 1, z + 0.3)}, uint32_t(2 + i), 1);
  }
  return soup;
}

TEST(BspRender, CoverageMaskPartitionsSamplesAndStopsWhenFull) {
  auto tree = BspTree::build(wall_scene(), {});
  ASSERT_TRUE(tree.is_ok());
  const View view(camera_at(Vec3(0.3, 0.2, 5.0), Vec3(0.1, 0.0, 0.0), 60.0), 80, 60);
  for (int n : {1, 2, 4, 8, 16}) {
    BspRenderOptions options;
    options.order = BspOrder::FrontToBack;
    options.aa = n;
    options.threads = 2;
    options.edge_flags = true;
    const BspFrame frame = render_bsp(*tree, view, options);
    // The diagonal shared by the two wall triangles: no gap, no double cover.
    EXPECT_EQ(frame.counters.pixels_full, view.pixels()) << "N=" << n;
    EXPECT_GT(frame.counters.faces_skipped_full, 0u) << "hidden faces should be skipped in full tiles";
    for (const Rgb& c : frame.colors) ASSERT_LE(std::abs(c.r - frame.colors[0].r), 0.02f);
    for (uint32_t id : frame.ids) ASSERT_LE(tree->faces()[id].source, 1u);
  }
}

// Sum over pixels of the coverage of a single triangle on black equals its projected area.
TEST(BspRender, CoverageMaskMeasuresArea) {
  PolygonSoup soup;
  soup.material_colors = {Vec3(1.0)};
  const Triangle tri{Vec3(-1.3, -0.7, 0), Vec3(1.1, -0.9, 0), Vec3(0.2, 1.2, 0)};
  soup.add_triangle(tri, 0, 0);
  auto tree = BspTree::build(soup, {});
  ASSERT_TRUE(tree.is_ok());
  const View view(camera_at(Vec3(0.0, 0.0, 4.0), Vec3(0.0), 50.0), 64, 64);
  // Exact projected area in pixels.
  auto project = [&](const Vec3& p) {
    const Vec3 d = p - view.eye;
    const double w = glm::dot(d, view.forward);
    return glm::dvec2((glm::dot(d, view.right) / w + view.half_w) * view.width / (2 * view.half_w) - 0.5,
                      (view.half_h - glm::dot(d, view.up) / w) * view.height / (2 * view.half_h) - 0.5);
  };
  const glm::dvec2 a = project(tri.v0), b = project(tri.v1), c = project(tri.v2);
  const double area = 0.5 * std::abs((b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y));
  const double perimeter = glm::length(b - a) + glm::length(c - b) + glm::length(a - c);
  const Rgb shade = bsp_face_color(*tree, 0, tree->face_vertices(0), view.eye);
  for (int n : {1, 4, 16}) {
    BspRenderOptions options;
    options.order = BspOrder::FrontToBack;
    options.aa = n;
    const BspFrame frame = render_bsp(*tree, view, options);
    double covered = 0.0;
    for (const Rgb& p : frame.colors) covered += double(p.r) / double(shade.r);
    EXPECT_NEAR(covered, area, 0.5 * perimeter / n + 1.0) << "N=" << n;
  }
}

TEST(BspRender, EdgeErrorFallsWithMaskSize) {
  std::mt19937_64 rng(21);
  const PolygonSoup soup = random_soup(rng, 60);
  auto tree = BspTree::build(soup, {});
  ASSERT_TRUE(tree.is_ok());
  const View view(camera_at(Vec3(2.5, 1.5, 3.0), Vec3(0.0), 50.0), 64, 48);
  BspRenderOptions options;
  options.order = BspOrder::FrontToBack;
  options.threads = 2;
  options.aa = 16;
  options.edge_flags = true;
  const BspFrame reference = render_bsp(*tree, view, options);
  std::vector<double> error;
  for (int n : {1, 2, 4, 8}) {
    options.aa = n;
    const BspFrame frame = render_bsp(*tree, view, options);
    double sum = 0.0;
    size_t edges = 0;
    for (size_t p = 0; p < view.pixels(); ++p) {
      if (!reference.mixed[p]) continue;
      ++edges;
      sum += std::abs(frame.colors[p].r - reference.colors[p].r) + std::abs(frame.colors[p].g - reference.colors[p].g) +
             std::abs(frame.colors[p].b - reference.colors[p].b);
    }
    ASSERT_GT(edges, 50u);
    error.push_back(sum / double(3 * edges));
  }
  EXPECT_LT(error[2], error[0]);
  EXPECT_LT(error[3], error[1]);
  EXPECT_LT(error[2], 0.05);
}

// ---- moving objects (§4.1) ----

PolygonSoup cube_soup(double h) {
  PolygonSoup soup;
  soup.material_colors = {Vec3(0.9, 0.9, 0.1)};
  const Vec3 c[8] = {Vec3(-h, -h, -h), Vec3(h, -h, -h), Vec3(h, h, -h), Vec3(-h, h, -h),
                     Vec3(-h, -h, h),  Vec3(h, -h, h),  Vec3(h, h, h),  Vec3(-h, h, h)};
  const int quads[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {0, 4, 7, 3}};
  for (int q = 0; q < 6; ++q) {
    const Vec3 v[4] = {c[quads[q][0]], c[quads[q][1]], c[quads[q][2]], c[quads[q][3]]};
    soup.add(v, uint32_t(1000 + q), 0);
  }
  // A fin through the cube: the object's own tree must split.
  const Vec3 fin[3] = {Vec3(-1.4 * h, 0.1 * h, -0.2 * h), Vec3(1.4 * h, -0.2 * h, 0.3 * h), Vec3(0.0, 1.3 * h, 0.0)};
  soup.add(fin, 1006, 0);
  return soup;
}

TEST(BspMovingObject, RendersCorrectlyAtSeveralTransformsWithoutRebuilding) {
  const Aabb region(Vec3(-0.45, -0.45, -0.45), Vec3(0.45, 0.45, 0.45));
  std::mt19937_64 rng(31);
  const Aabb keep_out(region.lo - Vec3(0.01), region.hi + Vec3(0.01));
  PolygonSoup statics = random_soup(rng, 200, &keep_out);
  std::vector<BspMovingObject> objects(1);
  objects[0].polygons = cube_soup(0.15);
  objects[0].region = BspRegion::box(region);
  auto tree = BspTree::build(statics, {}, objects);
  ASSERT_TRUE(tree.is_ok()) << tree.status().to_string();
  EXPECT_TRUE(tree->validate().is_ok()) << tree->validate().to_string();
  EXPECT_EQ(tree->stats().object_polygons, tree->object_face_count(0));
  EXPECT_GE(tree->object_face_count(0), 8u);

  const Camera cameras[] = {camera_at(Vec3(2.0, 1.4, 1.2), Vec3(0.0), 55.0), camera_at(Vec3(-1.6, -1.7, -0.4), Vec3(0.0), 60.0)};
  int frames = 0;
  size_t object_pixels = 0;
  for (int step = 0; step < 6; ++step) {
    // Rigid motion inside the region: the cube (radius 0.26 with the fin) stays inside.
    glm::dmat4 t = glm::translate(glm::dmat4(1.0), Vec3(0.15 * std::sin(step), 0.15 * std::cos(1.7 * step), 0.1 * (step % 3 - 1)));
    t = glm::rotate(t, 0.7 * step, glm::normalize(Vec3(1.0, 2.0, 0.5 + step)));
    const glm::dmat4 transforms[1] = {t};
    for (const Camera& camera : cameras) {
      const View view(camera, 96, 72);
      for (bool cull : {false, true}) {
        const Comparison c = painter_vs_zbuffer(*tree, view, cull, transforms);
        EXPECT_EQ(c.mismatches, 0u) << "step " << step << (cull ? " culled: " : ": ") << c.first;
        EXPECT_LE(c.ties, view.pixels() / 100);
      }
      BspRenderOptions options;
      options.object_transforms = {t};
      options.threads = 2;
      const BspFrame frame = render_bsp(*tree, view, options);
      EXPECT_EQ(frame.counters.objects_outside_region, 0u);
      for (uint32_t id : frame.ids) object_pixels += id != kNoPrim && tree->face_object(id) == 0;
      ++frames;
    }
  }
  EXPECT_EQ(frames, 12);
  EXPECT_GT(object_pixels, 200u) << "the object should be visible";
  // Out of its region the object is counted.
  BspRenderOptions options;
  options.object_transforms = {glm::translate(glm::dmat4(1.0), Vec3(2.0, 0.0, 0.0))};
  EXPECT_EQ(render_bsp(*tree, View(cameras[0], 32, 24), options).counters.objects_outside_region, 1u);
}

TEST(BspMovingObject, RefusesGeometryInsideARegionAndOverlappingRegions) {
  PolygonSoup statics;
  statics.add_triangle({Vec3(-0.1, -0.1, 0.0), Vec3(0.1, -0.1, 0.0), Vec3(0.0, 0.1, 0.0)}, 0, 0);
  statics.add_triangle({Vec3(3, 3, 3), Vec3(4, 3, 3), Vec3(3, 4, 3)}, 1, 0);
  std::vector<BspMovingObject> objects(1);
  objects[0].polygons = cube_soup(0.1);
  objects[0].region = BspRegion::box(Aabb(Vec3(-1.0), Vec3(1.0)));
  EXPECT_EQ(BspTree::build(statics, {}, objects).status().code(), Status::Code::InvalidArgument);

  PolygonSoup outside;
  outside.add_triangle({Vec3(3, 3, 3), Vec3(4, 3, 3), Vec3(3, 4, 3)}, 1, 0);
  objects.resize(2);
  objects[1].polygons = cube_soup(0.1);
  objects[1].region = BspRegion::box(Aabb(Vec3(0.5), Vec3(1.5)));
  EXPECT_EQ(BspTree::build(outside, {}, objects).status().code(), Status::Code::InvalidArgument);
  objects[1].region = BspRegion::box(Aabb(Vec3(1.5), Vec3(2.5)));  // separable: fine
  auto tree = BspTree::build(outside, {}, objects);
  ASSERT_TRUE(tree.is_ok()) << tree.status().to_string();
  EXPECT_TRUE(tree->validate().is_ok());
  EXPECT_EQ(tree->object_count(), 2u);
}

TEST(BspStats, JsonAndTextReport) {
  std::mt19937_64 rng(2);
  auto tree = BspTree::build(random_soup(rng, 50), {});
  ASSERT_TRUE(tree.is_ok());
  const nlohmann::json j = nlohmann::json::parse(tree->stats().to_json());
  EXPECT_EQ(j["input_polygons"], 50);
  EXPECT_EQ(j["output_polygons"], tree->faces().size());
  for (const char* key : {"nodes", "splits", "max_depth", "mean_depth", "build_ms", "memory_bytes"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_GT(j["memory_bytes"].get<uint64_t>(), 0u);
  EXPECT_NE(tree->stats().to_text().find("output polygons"), std::string::npos);
}

}  // namespace
}  // namespace frontier
