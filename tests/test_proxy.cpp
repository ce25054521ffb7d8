// Proxies (src/lod/proxy.h) and the store's `proxies` section: every interior node of a built
// terrain and building has a proxy page; the stored bound holds against the subtree's original
// geometry (brute-force point-triangle distances, both ways); bounds grow towards the root; proxy
// sizes stay within the target; degenerate, coplanar, sphere-only and far-from-origin input; and
// damaged proxy pages are reported naming the node and the page.
#include "preprocess/build.h"
#include "src/codec/cell_tree.h"
#include "src/core/tessellate.h"
#include "src/lod/proxy.h"
#include "src/lod/proxy_distance.h"
#include "src/lod/proxy_shell.h"
#include "src/paging/store_model.h"
#include "store/page_file.h"
#include "store/store_file.h"
#include "tests/input_files.h"
#include "tests/process_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>
#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <random>
#include <tuple>

namespace frontier {
namespace {

namespace fs = std::filesystem;
using proc::run_binary;

const fs::path& scratch() { return testing::scratch_dir("frontier_proxy"); }

// An n x n vertex heightfield (two triangles a square) at `origin`, heights from `height(x, y)`.
template <typename Height>
std::string heightfield(const std::string& name, int n, const Vec3& origin, Height height) {
  testing::TriangleMesh m = testing::grid_mesh(n);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) m.vertices[static_cast<size_t>(y * n + x)] = origin + Vec3(x, y, height(x, y));
  }
  return testing::write_file(scratch() / name, testing::off_text(m));
}

std::string generated(const std::string& kind, uint64_t triangles) {
  const fs::path path = scratch() / (kind + "_" + std::to_string(triangles) + ".ply");
  if (!fs::exists(path)) {
    const auto r = run_binary(proc::gen_binary(),
                              {kind, "--triangles", std::to_string(triangles), "-o", path.string(), "--quiet"}, scratch());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    fs::remove(fs::path(path).replace_extension(".json"));  // no sidecar: no grid, no portals
  }
  return path.string();
}

std::unique_ptr<StoreModel> build(const std::string& input, const std::string& name, uint32_t target,
                                  uint32_t cell_prims = 64, CellCodec codec = CellCodec::Draco,
                                  uint64_t part_primitives = 0) {
  BuildOptions o;
  o.inputs = {input};
  o.output = (scratch() / name).string();
  o.quiet = true;
  o.threads = 2;
  o.codec = codec;
  o.cell_prims = cell_prims;
  o.proxy_triangles = target;
  o.part_primitives = part_primitives;
  auto report = build_store(o);
  EXPECT_TRUE(report) << report.status().to_string();
  if (!report) return nullptr;
  auto model = StoreModel::open(o.output);
  EXPECT_TRUE(model) << model.status().to_string();
  return model ? std::move(*model) : nullptr;
}

// The geometry a node stands for, as the store holds it: triangles (curved primitives as
// their surface) and points sampled on every primitive.
struct Original {
  std::vector<Triangle> triangles;
  std::vector<Sphere> spheres;
  std::vector<Vec3> points;  // triangle vertices and points on the spheres
};

// Per node, one past the last node of its subtree (preorder: subtrees are contiguous).
std::vector<uint32_t> subtree_ends(const std::vector<KdTree::Node>& nodes) {
  std::vector<uint32_t> end(nodes.size());
  for (size_t i = nodes.size(); i-- > 0;) end[i] = nodes[i].is_leaf() ? static_cast<uint32_t>(i + 1) : end[nodes[i].child];
  return end;
}

Original original_of(const StoreModel& model, const std::vector<Scene>& cells, uint32_t first, uint32_t end) {
  Original o;
  for (uint32_t n = first; n < end; ++n) {
    if (!model.nodes()[n].is_leaf()) continue;
    const Scene& cell = cells[model.nodes()[n].child];
    for (uint32_t i = 0; i < cell.size(); ++i) {
      const PrimRef& p = cell.prims[i];
      if (p.kind == PrimKind::Triangle) {
        const Triangle& t = cell.triangles[p.index];
        o.triangles.push_back(t);
        o.points.insert(o.points.end(), {t.v0, t.v1, t.v2});
      } else if (p.kind == PrimKind::Sphere) {
        const Sphere& s = cell.spheres[p.index];
        o.spheres.push_back(s);
        std::mt19937 rng(i);
        std::normal_distribution<double> g;
        for (int k = 0; k < 64; ++k) o.points.push_back(s.center + s.radius * glm::normalize(Vec3(g(rng), g(rng), g(rng))));
      }
    }
  }
  return o;
}

double distance_to_triangles(const Vec3& p, const std::vector<Triangle>& tris) {
  double best = kInfinity;
  for (const Triangle& t : tris) best = std::min(best, point_triangle_distance(p, t.v0, t.v1, t.v2));
  return best;
}

double distance_to_original(const Vec3& p, const Original& o) {
  double best = distance_to_triangles(p, o.triangles);
  for (const Sphere& s : o.spheres) best = std::min(best, std::abs(glm::length(p - s.center) - s.radius));
  return best;
}

// Checks every proxy of `model` against its subtree (brute force): both directions within the
// bound, bounds growing towards the root, sizes within the target. Returns the proxies checked.
size_t check_proxies(const StoreModel& model, uint32_t target) {
  std::vector<Scene> cells(model.cells().size());
  for (uint32_t c = 0; c < cells.size(); ++c) EXPECT_TRUE(model.read_cell(c, cells[c]));
  const std::vector<uint32_t> end = subtree_ends(model.nodes());
  const double tolerance = 1e-9 * glm::length(model.info().bounds.extent());
  EXPECT_EQ(model.proxies().size(), model.nodes().size());
  size_t checked = 0;
  for (uint32_t n = 0; n < model.nodes().size(); ++n) {
    const KdTree::Node& node = model.nodes()[n];
    const StoreProxy& record = model.proxies()[n];
    EXPECT_TRUE(std::isfinite(record.error)) << n;
    if (node.is_leaf()) {
      EXPECT_EQ(model.proxy(n), nullptr);
      continue;
    }
    // Weakly growing towards the root.
    for (uint32_t child : {n + 1, node.child}) EXPECT_GE(record.error, model.proxies()[child].error) << n;
    const Original original = original_of(model, cells, n, end[n]);
    if (original.points.empty()) continue;
    const StoreProxy* proxy = model.proxy(n);
    EXPECT_NE(proxy, nullptr) << "interior node " << n << " has geometry but no proxy";
    if (proxy == nullptr) continue;
    EXPECT_LE(proxy->triangles, 4ull * target) << n;
    EXPECT_LE(proxy->triangles, std::max<uint64_t>(proxy->subtree_triangles, 1)) << n;
    Scene decoded;
    EXPECT_TRUE(model.read_proxy(n, decoded)) << n;
    EXPECT_EQ(decoded.size(), proxy->triangles);
    for (const Vec3& p : original.points) {
      const double d = distance_to_triangles(p, decoded.triangles);
      if (d > record.error + tolerance) {
        ADD_FAILURE() << "node " << n << ": original point (" << p.x << ", " << p.y << ", " << p.z << ") lies " << d
                      << " from the proxy, bound " << record.error;
        return checked;
      }
    }
    for (const Triangle& t : decoded.triangles) {
      for (const Vec3& p : {t.v0, t.v1, t.v2, (t.v0 + t.v1 + t.v2) / 3.0}) {
        const double d = distance_to_original(p, original);
        if (d > record.error + tolerance) {
          ADD_FAILURE() << "node " << n << ": proxy point lies " << d << " from the original, bound " << record.error;
          return checked;
        }
      }
    }
    ++checked;
  }
  return checked;
}

// `count` unconnected triangles of unit size scattered over [-5, 5]^3.
void scattered_triangles(std::mt19937& rng, uint32_t count, std::vector<Vec3>& positions,
                         std::vector<uint32_t>& indices) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (uint32_t t = 0; t < count; ++t) {
    const Vec3 c(u(rng) * 5, u(rng) * 5, u(rng) * 5);
    for (int k = 0; k < 3; ++k) {
      positions.push_back(c + Vec3(u(rng), u(rng), u(rng)));
      indices.push_back(static_cast<uint32_t>(positions.size() - 1));
    }
  }
}

TEST(ProxyDistance, PointTriangleDistanceMatchesDenseSamplingAndTheBvhBruteForce) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> positions;
  std::vector<uint32_t> indices;
  scattered_triangles(rng, 200, positions, indices);
  positions[1] = positions[0];  // a degenerate one (a segment)
  const TriangleBvh bvh(positions, indices);
  for (int q = 0; q < 100; ++q) {
    const Vec3 p(u(rng) * 7, u(rng) * 7, u(rng) * 7);
    double brute = kInfinity;
    for (size_t t = 0; t < indices.size(); t += 3) {
      const Vec3 &a = positions[indices[t]], &b = positions[indices[t + 1]], &c = positions[indices[t + 2]];
      const double d = point_triangle_distance(p, a, b, c);
      brute = std::min(brute, d);
      if (t < 30) {  // no point of the triangle is nearer than the exact distance
        double sampled = kInfinity;
        for (int i = 0; i <= 40; ++i) {
          for (int j = 0; i + j <= 40; ++j) {
            sampled = std::min(sampled, glm::length(p - (a + (b - a) * (i / 40.0) + (c - a) * (j / 40.0))));
          }
        }
        EXPECT_LE(d, sampled + 1e-12);
        EXPECT_GE(d, sampled - 0.1);
      }
    }
    EXPECT_DOUBLE_EQ(bvh.distance(p), brute);
  }
  EXPECT_EQ(TriangleBvh({}, {}).distance(Vec3(0.0)), kInfinity);
}

TEST(ProxyDistance, FarthestSampleWithPruningEqualsTheMaximumOfExactDistances) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> positions;
  std::vector<uint32_t> indices;
  for (uint32_t t = 0; t < 300; ++t) {
    const Vec3 c(u(rng) * 5, u(rng) * 5, 0.2 * u(rng));
    for (int k = 0; k < 3; ++k) {
      positions.push_back(c + Vec3(u(rng), u(rng), 0.1 * u(rng)));
      indices.push_back(static_cast<uint32_t>(positions.size() - 1));
    }
  }
  const TriangleBvh bvh(positions, indices);
  for (int round = 0; round < 20; ++round) {
    std::vector<Vec3> samples;
    for (int q = 0; q < 50; ++q) samples.emplace_back(u(rng) * 6, u(rng) * 6, u(rng) * (round % 4 + 1));
    double exact = 0.0;
    for (const Vec3& p : samples) exact = std::max(exact, bvh.distance(p));
    EXPECT_DOUBLE_EQ(farthest_sample(samples, bvh), exact);
    for (const Vec3& p : samples) {  // the pruned query: exact above the floor, at most it below
      const double d = bvh.distance(p), floor = 0.5 * (round % 5);
      if (d > floor) {
        EXPECT_DOUBLE_EQ(bvh.distance_above(p, floor), d);
      } else {
        EXPECT_LE(bvh.distance_above(p, floor), floor);
      }
    }
  }
}

TEST(Proxy, MergeWeldsAndDropsTrianglesStoredInBothChildren) {
  Scene a, b;
  a.add_triangle({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, 1, 0);
  a.add_triangle({Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)}, 2, 0);  // straddles: in both
  b.add_triangle({Vec3(1, 1, 0), Vec3(0, 1, 0), Vec3(1, 0, 0)}, 2, 0);  // the same, rotated
  b.add_triangle({Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(1, 1, 0)}, 3, 0);  // reversed: kept
  const ProxyMesh merged = merge_proxies(proxy_input(a, {}), proxy_input(b, {}));
  EXPECT_EQ(merged.triangle_count(), 3u);
  EXPECT_EQ(merged.positions.size(), 4u);
  EXPECT_EQ(merged.subtree_triangles, 3u);
  EXPECT_EQ(merged.error, 0.0);
}

TEST(Proxy, SimplifiedGridKeepsItsBoundAndTarget) {
  // A bumpy 41 x 41 heightfield far from the origin, simplified in memory.
  for (const Vec3 origin : {Vec3(0.0), Vec3(1e6, -1e6, 1e6)}) {
    Scene s;
    auto z = [](int x, int y) { return std::sin(x * 0.3) * std::cos(y * 0.2) * 2.0; };
    for (int y = 0; y < 40; ++y) {
      for (int x = 0; x < 40; ++x) {
        const Vec3 a = origin + Vec3(x, y, z(x, y)), b = origin + Vec3(x + 1, y, z(x + 1, y));
        const Vec3 c = origin + Vec3(x + 1, y + 1, z(x + 1, y + 1)), d = origin + Vec3(x, y + 1, z(x, y + 1));
        s.add_triangle({a, b, c}, static_cast<uint32_t>(s.size()), 0);
        s.add_triangle({a, c, d}, static_cast<uint32_t>(s.size()), 0);
      }
    }
    ProxyOptions options;
    options.target_triangles = 200;
    const ProxyMesh input = proxy_input(s, options);
    ProxySimplifyStats stats;
    const ProxyMesh proxy = simplify_proxy(input, options, &stats);
    EXPECT_TRUE(stats.simplified);
    EXPECT_LE(proxy.triangle_count(), 2u * options.target_triangles);
    EXPECT_GT(proxy.error, 0.0);
    EXPECT_TRUE(std::isfinite(proxy.error));
    std::vector<Triangle> proxy_tris;
    for (const Triangle& t : proxy_scene(proxy).triangles) proxy_tris.push_back(t);
    for (const Triangle& t : s.triangles) {
      for (const Vec3& p : {t.v0, t.v1, t.v2}) EXPECT_LE(distance_to_triangles(p, proxy_tris), proxy.error * (1 + 1e-9));
    }
    for (uint32_t i = 0; i < proxy.triangle_count(); ++i) EXPECT_LT(proxy.sources[i], s.size());
  }
}

// A smooth bump field z = 2 sin(0.3 x) cos(0.2 y) over [0, n]^2 at `origin`, two triangles a
// unit square; with `flip`, every other triangle reversed (a soup without consistent winding).
Scene bump_field(const Vec3& origin, int n, bool flip) {
  Scene s;
  auto z = [](double x, double y) { return std::sin(x * 0.3) * std::cos(y * 0.2) * 2.0; };
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const Vec3 a = origin + Vec3(x, y, z(x, y)), b = origin + Vec3(x + 1, y, z(x + 1, y));
      const Vec3 c = origin + Vec3(x + 1, y + 1, z(x + 1, y + 1)), d = origin + Vec3(x, y + 1, z(x, y + 1));
      s.add_triangle({a, b, c}, static_cast<uint32_t>(s.size()), 0);
      if (flip && (x + y) % 2 == 0) {
        s.add_triangle({a, d, c}, static_cast<uint32_t>(s.size()), 0);
      } else {
        s.add_triangle({a, c, d}, static_cast<uint32_t>(s.size()), 0);
      }
    }
  }
  return s;
}

Vec3 bump_normal(const Vec3& p) {  // the surface's unit normal at p (relative to its origin)
  const double dx = 0.3 * std::cos(p.x * 0.3) * std::cos(p.y * 0.2) * 2.0;
  const double dy = -0.2 * std::sin(p.x * 0.3) * std::sin(p.y * 0.2) * 2.0;
  return glm::normalize(Vec3(-dx, -dy, 1.0));
}

TEST(Proxy, ShadingNormalsFollowTheSurfaceTheProxyReplaces) {
  // A coarse proxy of a smooth surface: its corner normals lie closer to the surface's normals
  // than its flat faces do, are unit, and say the same far from the origin and for a soup whose
  // triangles disagree on their winding.
  for (const bool flip : {false, true}) {
    for (const Vec3 origin : {Vec3(0.0), Vec3(1e6, -1e6, 1e6)}) {
      const Scene s = bump_field(origin, 40, flip);
      ProxyOptions options;
      options.target_triangles = 60;
      const ProxyMesh input = proxy_input(s, options);
      EXPECT_TRUE(input.normals.empty());
      ProxyMesh proxy = simplify_proxy(input, options);
      ASSERT_GT(input.triangle_count(), proxy.triangle_count());
      shade_proxy(input, proxy);
      ASSERT_EQ(proxy.normals.size(), 3 * proxy.triangle_count());
      double shaded = 0.0, flat = 0.0;
      for (size_t t = 0; t < proxy.triangle_count(); ++t) {
        const Vec3 &a = proxy.positions[proxy.indices[3 * t]], &b = proxy.positions[proxy.indices[3 * t + 1]],
                   &c = proxy.positions[proxy.indices[3 * t + 2]];
        const Vec3 face = glm::normalize(glm::cross(b - a, c - a));
        const Vec3* corners[3] = {&a, &b, &c};
        for (int k = 0; k < 3; ++k) {
          const Vec3& n = proxy.normals[3 * t + size_t(k)];
          EXPECT_NEAR(glm::length(n), 1.0, 1e-9);
          EXPECT_GT(glm::dot(n, face), 0.0) << "a corner normal turned away from its face";
          const Vec3 truth = bump_normal(*corners[k] - origin);
          shaded += std::acos(std::min(1.0, std::abs(glm::dot(n, truth))));
          flat += std::acos(std::min(1.0, std::abs(glm::dot(face, truth))));
        }
      }
      // (0.42 and 0.77 when written: meshoptimizer takes a soup's every reversed edge for a
      // border and simplifies it worse, so its faces are farther off to begin with.)
      EXPECT_LT(shaded, (flip ? 0.85 : 0.6) * flat) << "flip " << flip << " origin " << origin.x;
      // Through a page's scene: one normal triple per triangle, the same ones.
      const Scene scene = proxy_scene(proxy);
      ASSERT_EQ(scene.triangle_normals.size(), scene.triangles.size());
      EXPECT_EQ(scene.triangle_normals[0][1], proxy.normals[1]);
    }
  }
}

TEST(Proxy, ShadingNormalsKeepABoxsEdgesSharp) {
  // A box whose faces are 8 x 8 grids, simplified: flat faces meeting at right angles stay flat.
  for (const bool flip : {false, true}) {
    Scene s;
    const auto face = [&](const Vec3& o, const Vec3& u, const Vec3& v) {
      for (int i = 0; i < 8; ++i) {
        for (int j = 0; j < 8; ++j) {
          const Vec3 a = o + u * (i / 8.0) + v * (j / 8.0), b = o + u * ((i + 1) / 8.0) + v * (j / 8.0);
          const Vec3 c = o + u * ((i + 1) / 8.0) + v * ((j + 1) / 8.0), d = o + u * (i / 8.0) + v * ((j + 1) / 8.0);
          s.add_triangle({a, b, c}, 0, 0);
          if (flip && (i + j) % 2 == 0) {
            s.add_triangle({a, d, c}, 0, 0);
          } else {
            s.add_triangle({a, c, d}, 0, 0);
          }
        }
      }
    };
    const Vec3 X(4, 0, 0), Y(0, 3, 0), Z(0, 0, 2), O(10, 20, 30);
    face(O, Y, X);
    face(O + Z, X, Y);
    face(O, X, Z);
    face(O + Y, Z, X);
    face(O, Z, Y);
    face(O + X, Y, Z);
    ProxyOptions options;
    options.target_triangles = 24;
    const ProxyMesh input = proxy_input(s, options);
    ProxyMesh proxy = simplify_proxy(input, options);
    ASSERT_LT(proxy.triangle_count(), input.triangle_count());
    shade_proxy(input, proxy);
    ASSERT_EQ(proxy.normals.size(), 3 * proxy.triangle_count());
    // Reversed triangles make meshoptimizer cut corners (see above): there every corner normal
    // stays within the crease angle of its face; without, every one is its face's.
    const double crease = std::cos(kProxyCreaseDegrees * M_PI / 180.0);
    for (size_t t = 0; t < proxy.triangle_count(); ++t) {
      const Vec3 &a = proxy.positions[proxy.indices[3 * t]], &b = proxy.positions[proxy.indices[3 * t + 1]],
                 &c = proxy.positions[proxy.indices[3 * t + 2]];
      const Vec3 f = glm::normalize(glm::cross(b - a, c - a));
      for (int k = 0; k < 3; ++k) {
        const double agree = glm::dot(proxy.normals[3 * t + size_t(k)], f);
        EXPECT_GE(agree, crease - 1e-12) << "flip " << flip;
        if (!flip) {
          EXPECT_GT(agree, 1.0 - 1e-9);
        }
      }
    }
  }
}

TEST(Proxy, MergeKeepsNormalsAndGivesFaceNormalsToMeshesWithout) {
  Scene a, b;
  a.add_triangle({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, 1, 0);
  b.add_triangle({Vec3(1, 0, 0), Vec3(1, 1, 1), Vec3(0, 1, 0)}, 2, 0);
  ProxyMesh with = proxy_input(a, {});
  const Vec3 tilted = glm::normalize(Vec3(0.1, 0.2, 1.0));
  with.normals = {tilted, tilted, tilted};
  const ProxyMesh merged = merge_proxies(with, proxy_input(b, {}));
  ASSERT_EQ(merged.triangle_count(), 2u);
  ASSERT_EQ(merged.normals.size(), 6u);
  EXPECT_EQ(merged.normals[0], tilted);
  const Vec3 face = glm::normalize(glm::cross(Vec3(0, 1, 1), Vec3(-1, 1, 0)));
  for (int k = 3; k < 6; ++k) EXPECT_NEAR(glm::dot(merged.normals[size_t(k)], face), 1.0, 1e-12);
  EXPECT_TRUE(merge_proxies(proxy_input(a, {}), proxy_input(b, {})).normals.empty());
}

TEST(Proxy, DegenerateInputGivesFiniteBounds) {
  ProxyOptions options;
  options.target_triangles = 4;
  Scene flat;  // coplanar: every collapse is free
  for (int y = 0; y < 10; ++y) {
    for (int x = 0; x < 10; ++x) {
      flat.add_triangle({Vec3(x, y, 0), Vec3(x + 1, y, 0), Vec3(x + 1, y + 1, 0)}, 0, 0);
      flat.add_triangle({Vec3(x, y, 0), Vec3(x + 1, y + 1, 0), Vec3(x, y + 1, 0)}, 0, 0);
    }
  }
  // With room for the locked border (40 vertices) the flat grid simplifies without error: its
  // bound is the measurement's slack at most (0.1% of the diagonal, proxy.h).
  ProxyOptions roomy = options;
  roomy.target_triangles = 64;
  const ProxyMesh p = simplify_proxy(proxy_input(flat, roomy), roomy);
  EXPECT_FALSE(p.empty());
  EXPECT_LE(p.triangle_count(), 2u * roomy.target_triangles);
  EXPECT_LE(p.error, 1e-3 * std::sqrt(200.0));
  // Without it, the border unlocked (no clustering, which would open holes): a coarser proxy
  // whose bound says how far it strays.
  ProxySimplifyStats stats;
  const ProxyMesh tight = simplify_proxy(proxy_input(flat, options), options, &stats);
  EXPECT_TRUE(stats.unlocked);
  EXPECT_FALSE(stats.sloppy);
  EXPECT_LE(tight.triangle_count(), 2u * options.target_triangles);
  EXPECT_FALSE(tight.empty());
  EXPECT_TRUE(std::isfinite(tight.error));
  EXPECT_GE(tight.error, stats.measured);
  Scene one;
  one.add_triangle({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)}, 0, 0);
  const ProxyMesh q = simplify_proxy(proxy_input(one, options), options);
  EXPECT_EQ(q.triangle_count(), 1u);
  EXPECT_EQ(q.error, 0.0);
  Scene sliver;  // zero area: dropped, an empty proxy without NaN
  sliver.add_triangle({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)}, 0, 0);
  const ProxyMesh r = simplify_proxy(proxy_input(sliver, options), options);
  EXPECT_EQ(r.error, 0.0);
  Scene ball;  // a sphere's tessellation is within its measured chord error
  ball.add_sphere({Vec3(3, 4, 5), 2.0}, 0, 0);
  const ProxyMesh b = proxy_input(ball, options);
  EXPECT_GT(b.error, 0.0);
  EXPECT_LT(b.error, 0.3 * 2.0);  // proxies tessellate with 6 segments: a quarter of the radius
  std::vector<Triangle> tris = proxy_scene(b).triangles;
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  for (int k = 0; k < 500; ++k) {
    const Vec3 on = Vec3(3, 4, 5) + 2.0 * glm::normalize(Vec3(g(rng), g(rng), g(rng)));
    EXPECT_LE(distance_to_triangles(on, tris), b.error * (1 + 1e-9));
  }
}

// A box from lo to hi as 12 triangles (outward), source `source`.
void add_box(Scene& s, const Vec3& lo, const Vec3& hi, uint32_t source) {
  const Vec3 c[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z},
                     {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
  const int f[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {2, 3, 7, 6}, {1, 2, 6, 5}, {3, 0, 4, 7}};
  for (const auto& q : f) {
    s.add_triangle({c[q[0]], c[q[1]], c[q[2]]}, source, 0);
    s.add_triangle({c[q[0]], c[q[2]], c[q[3]]}, source, 0);
  }
}

// A closed two-room house of thin slabs (walls 0.1, floor and roof 0.15) at `o`: 10 x 8 x 3.
Scene thin_house(const Vec3& o) {
  Scene s;
  add_box(s, o + Vec3(0, 0, 0), o + Vec3(10, 8, 0.15), 0);      // floor
  add_box(s, o + Vec3(0, 0, 2.85), o + Vec3(10, 8, 3), 1);      // roof
  add_box(s, o + Vec3(0, 0, 0.15), o + Vec3(0.1, 8, 2.85), 2);  // walls
  add_box(s, o + Vec3(9.9, 0, 0.15), o + Vec3(10, 8, 2.85), 3);
  add_box(s, o + Vec3(0.1, 0, 0.15), o + Vec3(9.9, 0.1, 2.85), 4);
  add_box(s, o + Vec3(0.1, 7.9, 0.15), o + Vec3(9.9, 8, 2.85), 5);
  add_box(s, o + Vec3(4.95, 0.1, 0.15), o + Vec3(5.05, 7.9, 2.85), 6);  // the partition
  return s;
}

TEST(ProxyShell, ThinWalledHouseGivesOneClosedOutwardShellAroundItsRooms) {
  for (const Vec3 origin : {Vec3(0.0), Vec3(1e6, -2e6, 5e5)}) {
    const Scene house = thin_house(origin);
    const ProxyMesh input = proxy_input(house, {});
    const Aabb region{origin, origin + Vec3(10, 8, 3)};
    const VoxelShell shell = voxel_shell(input.positions, input.indices, 32, &region, std::nullopt);
    ASSERT_FALSE(shell.indices.empty());
    EXPECT_NEAR(shell.voxel, 10.0 / 32, 1e-12);
    // Closed: every edge is used by exactly two triangles, once in each direction.
    std::map<std::pair<uint32_t, uint32_t>, int> edges;
    for (size_t i = 0; i < shell.indices.size(); i += 3) {
      for (int k = 0; k < 3; ++k) ++edges[{shell.indices[i + k], shell.indices[i + (k + 1) % 3]}];
    }
    for (const auto& [e, n] : edges) {
      EXPECT_EQ(n, 1);
      EXPECT_EQ(edges.count({e.second, e.first}), 1u);
    }
    // Outward and solid: the signed volume is the house's (rooms filled, not surfaced inside),
    // a shell of the walls alone would enclose about 40 m^3 at most.
    double volume = 0.0;
    for (size_t i = 0; i < shell.indices.size(); i += 3) {
      const Vec3 a = shell.positions[shell.indices[i]] - origin, b = shell.positions[shell.indices[i + 1]] - origin,
                 c = shell.positions[shell.indices[i + 2]] - origin;
      volume += glm::dot(a, glm::cross(b, c)) / 6.0;
    }
    EXPECT_GT(volume, 0.85 * 240.0);
    EXPECT_LE(volume, 240.0 * (1 + 1e-9));  // kept inside the region
    // Near the house: every shell vertex lies within the region and within two voxels of a wall,
    // and every corner of the house within two voxels of the shell.
    std::vector<Triangle> shell_tris, house_tris(house.triangles.begin(), house.triangles.end());
    for (size_t i = 0; i < shell.indices.size(); i += 3) {
      shell_tris.push_back({shell.positions[shell.indices[i]], shell.positions[shell.indices[i + 1]],
                            shell.positions[shell.indices[i + 2]]});
    }
    for (const Vec3& p : shell.positions) {
      EXPECT_TRUE(region.contains(p)) << p.x << " " << p.y << " " << p.z;
      EXPECT_LE(distance_to_triangles(p, house_tris), 2.0 * shell.voxel);
    }
    for (const Vec3& p : {origin, origin + Vec3(10, 8, 3), origin + Vec3(10, 0, 3), origin + Vec3(0, 8, 0)}) {
      EXPECT_LE(distance_to_triangles(p, shell_tris), 2.0 * shell.voxel);
    }
  }
  // Nothing to enclose: no shell.
  EXPECT_TRUE(voxel_shell({}, {}, 32, nullptr, std::nullopt).indices.empty());
  const std::vector<Vec3> point = {Vec3(1, 1, 1)};
  EXPECT_TRUE(voxel_shell(point, std::vector<uint32_t>{0, 0, 0}, 32, nullptr, std::nullopt).indices.empty());
}

TEST(Proxy, ThinWallsTheSimplifierWouldRemoveGiveWayToAShellWithinItsBound) {
  // A street of 24 thin-walled houses: meshopt_simplify, its error unbounded, reaches 64
  // triangles by deleting whole walls and houses; the shell keeps every house's outside.
  Scene street;
  for (int i = 0; i < 24; ++i) {
    const Scene h = thin_house(Vec3(12.0 * (i % 6), 10.0 * (i / 6), 0));
    for (const Triangle& t : h.triangles) street.add_triangle(t, static_cast<uint32_t>(street.size()), 0);
  }
  ProxyOptions options;
  options.target_triangles = 64;
  const ProxyMesh input = proxy_input(street, options);
  ProxySimplifyStats with_shell, without_shell;
  const ProxyMesh proxy = simplify_proxy(input, options, &with_shell);
  ProxyOptions no_shell = options;
  no_shell.shell_resolution = 0;
  const ProxyMesh plain = simplify_proxy(input, no_shell, &without_shell);
  EXPECT_TRUE(with_shell.shell);
  EXPECT_FALSE(without_shell.shell);
  EXPECT_LT(proxy.error, 0.5 * plain.error) << proxy.error << " vs " << plain.error;
  EXPECT_LE(proxy.triangle_count(), 6u * options.target_triangles);
  // The bound holds both ways (brute force): input corners to the proxy, proxy corners to the input.
  const std::vector<Triangle> proxy_tris = proxy_scene(proxy).triangles;
  const std::vector<Triangle> input_tris(street.triangles.begin(), street.triangles.end());
  for (const Triangle& t : input_tris) {
    for (const Vec3& p : {t.v0, t.v1, t.v2}) EXPECT_LE(distance_to_triangles(p, proxy_tris), proxy.error * (1 + 1e-9));
  }
  for (const Triangle& t : proxy_tris) {
    for (const Vec3& p : {t.v0, t.v1, t.v2, (t.v0 + t.v1 + t.v2) / 3.0}) {
      EXPECT_LE(distance_to_triangles(p, input_tris), proxy.error * (1 + 1e-9));
    }
  }
  // Each shell triangle names a primitive of the input (the nearest one).
  for (uint32_t i = 0; i < proxy.triangle_count(); ++i) EXPECT_LT(proxy.sources[i], street.size());
}

TEST(ProxyDistance, NearestNamesATriangleAtTheDistance) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> positions;
  std::vector<uint32_t> indices;
  scattered_triangles(rng, 150, positions, indices);
  const TriangleBvh bvh(positions, indices);
  for (int q = 0; q < 100; ++q) {
    const Vec3 p(u(rng) * 7, u(rng) * 7, u(rng) * 7);
    const uint32_t t = bvh.nearest(p);
    ASSERT_LT(t, indices.size() / 3);
    EXPECT_DOUBLE_EQ(point_triangle_distance(p, positions[indices[3 * t]], positions[indices[3 * t + 1]],
                                             positions[indices[3 * t + 2]]),
                     bvh.distance(p));
  }
  EXPECT_EQ(TriangleBvh({}, {}).nearest(Vec3(0.0)), UINT32_MAX);
}

// The largest distance from points of a triangle mesh to `bvh`, on a dense barycentric grid of
// every triangle (n per side), by brute force.
double dense_farthest(const std::vector<Vec3>& positions, const std::vector<uint32_t>& indices, const TriangleBvh& bvh,
                      int n) {
  double farthest = 0.0;
  for (size_t t = 0; t + 2 < indices.size(); t += 3) {
    const Vec3 &a = positions[indices[t]], &b = positions[indices[t + 1]], &c = positions[indices[t + 2]];
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) {
        farthest = std::max(farthest, bvh.distance(a + (b - a) * (double(i) / n) + (c - a) * (double(j) / n)));
      }
    }
  }
  return farthest;
}

TEST(ProxyDistance, FarthestPointFindsTheLargestDistanceInsideATriangleNotOnlyAtItsCorners) {
  for (const double offset : {0.0, 1e6}) {
    const Vec3 o(offset, -offset, offset);
    // A flat triangle over a valley whose two slopes rise to its corners: every corner lies on
    // the valley (distance 0) while its middle hangs above the crease.
    const std::vector<Vec3> flat = {o + Vec3(-1, -1, 1), o + Vec3(1, -1, 1), o + Vec3(-1, 1, 1)};
    const std::vector<uint32_t> flat_indices = {0, 1, 2};
    const std::vector<Vec3> valley = {o + Vec3(-2, -2, 2), o + Vec3(-2, 2, 2), o + Vec3(0, -2, 0), o + Vec3(0, 2, 0),
                                      o + Vec3(2, -2, 2),  o + Vec3(2, 2, 2)};
    const std::vector<uint32_t> valley_indices = {0, 2, 1, 1, 2, 3, 2, 4, 3, 3, 4, 5};
    const TriangleBvh bvh(valley, valley_indices);
    EXPECT_LT(farthest_sample(flat, bvh), 1e-9 * std::max(1.0, offset)) << "the corners lie on the valley";
    const double dense = dense_farthest(flat, flat_indices, bvh, 200);
    EXPECT_NEAR(dense, std::sqrt(0.5), 1e-6);  // (0, -1, 1), one above the crease
    const double slack = 1e-3;
    const double bound = farthest_triangle_point(flat, flat_indices, bvh, 0.0, slack);
    const double margin = 2.0 / 200 / std::sqrt(3.0);  // how far a point lies from the dense grid
    EXPECT_GE(bound, dense - 1e-9 * std::max(1.0, offset)) << "an upper bound, not a sample";
    EXPECT_LE(bound, 1.05 * dense + slack + margin) << "and a tight one";
    // A floor above the answer returns the floor.
    EXPECT_EQ(farthest_triangle_point(flat, flat_indices, bvh, 5.0, slack), 5.0);
  }
}

TEST(ProxyDistance, ATriangleStraddlingAnEdgeOfItsMeshIsBoundedOnEachSide) {
  for (const double offset : {0.0, 1e6}) {
    const Vec3 o(offset, offset, -offset);
    // A square of two triangles, flat, and then folded along its diagonal (a ridge of height h).
    for (const double h : {0.0, 0.5}) {
      const std::vector<Vec3> square = {o + Vec3(0, 0, 0), o + Vec3(4, 0, h), o + Vec3(4, 4, 0), o + Vec3(0, 4, -h)};
      const std::vector<uint32_t> square_indices = {0, 1, 2, 0, 2, 3};
      const TriangleBvh bvh(square, square_indices);
      // A small triangle lying on the square across its diagonal (corners on either side).
      const Vec3 a = o + Vec3(1.5, 1.0, 0), b = o + Vec3(2.5, 2.0, 0), c = o + Vec3(1.2, 2.2, 0);
      const std::vector<Vec3> small = {a, b, c};
      const double dense = dense_farthest(small, {0, 1, 2}, bvh, 300);
      const double bound = bvh.farthest_on_triangle(a, b, c, 0.0, 0.0);
      const double eps = 1e-9 * std::max(1.0, offset);
      EXPECT_GE(bound, dense - eps) << h;
      // Flat, each side lies on its own triangle: exactly 0, which no split of the triangle
      // reaches (a piece across the diagonal is never inside one triangle).
      if (h == 0.0) {
        EXPECT_LE(bound, eps);
      }
      EXPECT_LE(bound, dense + 1.0 / 300 + eps) << h;
    }
  }
}

TEST(ProxyDistance, FarthestPointBoundsABumpyGridAgainstACoarseOneFromAbove) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> bump(-0.2, 0.2);
  auto grid = [&](int n, bool bumpy, std::vector<Vec3>& positions, std::vector<uint32_t>& indices) {
    for (int y = 0; y <= n; ++y) {
      for (int x = 0; x <= n; ++x) positions.push_back(Vec3(8.0 * x / n, 8.0 * y / n, bumpy ? bump(rng) : 0.0));
    }
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const auto v = static_cast<uint32_t>(y * (n + 1) + x);
        indices.insert(indices.end(), {v, v + 1, v + n + 2, v, v + n + 2, v + n + 1});
      }
    }
  };
  std::vector<Vec3> fine, coarse;
  std::vector<uint32_t> fine_indices, coarse_indices;
  grid(16, true, fine, fine_indices);
  grid(3, false, coarse, coarse_indices);
  const TriangleBvh bvh(coarse, coarse_indices);
  const double dense = dense_farthest(fine, fine_indices, bvh, 24);
  const double bound = farthest_triangle_point(fine, fine_indices, bvh, 0.0, 1e-3);
  EXPECT_GE(bound, dense - 1e-12);
  EXPECT_LE(bound, 1.05 * dense + 1e-3 + 0.5 / 24);
  EXPECT_EQ(farthest_triangle_point(fine, {}, bvh, 0.0, 1e-3), 0.0);
}

TEST(BuildStoreProxy, EveryInteriorNodeOfATerrainHasAProxyWithinItsBound) {
  // Split on disk too (part_primitives): the plan's nodes above the parts get proxies as well.
  auto model = build(generated("terrain", 6000), "terrain.frontier", 48, 64, CellCodec::Draco, 1500);
  ASSERT_TRUE(model);
  ASSERT_GT(model->nodes().size(), 15u);
  EXPECT_GT(check_proxies(*model, 48), 7u);
  const StoreProxy* root = model->proxy(0);
  ASSERT_NE(root, nullptr);
  EXPECT_GT(root->error, 0.0);
  EXPECT_LT(root->error, glm::length(model->info().bounds.extent()));
  EXPECT_GT(root->subtree_triangles, 48u);
}

TEST(BuildStoreProxy, EveryInteriorNodeOfABuildingHasAProxyWithinItsBound) {
  auto model = build(generated("building", 6000), "building.frontier", 64, 128);
  ASSERT_TRUE(model);
  EXPECT_GT(check_proxies(*model, 64), 3u);
}

TEST(BuildStoreProxy, FlatFarAndSphereOnlyInputBuildProxiesWithinTheirBounds) {
  // Coplanar, far from the origin, axis-parallel.
  auto flat = build(heightfield("flat.off", 30, Vec3(1e6, 1e6, 1e6), [](int, int) { return 0.0; }), "flat.frontier", 16,
                    32, CellCodec::Raw);
  ASSERT_TRUE(flat);
  EXPECT_GT(check_proxies(*flat, 16), 2u);
  auto far = build(heightfield("far.off", 30, Vec3(1e6, -2e6, 1e6), [](int x, int y) { return std::sin(x * 0.5 + y); }),
                   "far.frontier", 16, 32);
  ASSERT_TRUE(far);
  EXPECT_GT(check_proxies(*far, 16), 2u);
  // Spheres only: tessellated for proxies, the chord error in the bound.
  std::string nff = "v\nfrom 0 0 20\nat 0 0 0\nup 0 1 0\nangle 45\nhither 1\nresolution 64 64\nf 1 1 1 1 0 1 0 1\n";
  for (int i = 0; i < 64; ++i) nff += fmt::format("s {} {} {} {}\n", i % 8 * 3.0, i / 8 * 3.0, (i % 3) * 0.5, 1.0 + (i % 5) * 0.1);
  auto spheres = build(testing::write_file(scratch() / "spheres.nff", nff), "spheres.frontier", 32, 8);
  ASSERT_TRUE(spheres);
  EXPECT_GT(check_proxies(*spheres, 32), 2u);
  // One triangle: a single leaf, no interior node, a section with one record.
  auto one = build(testing::write_file(scratch() / "one.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"), "one.frontier", 16);
  ASSERT_TRUE(one);
  ASSERT_EQ(one->proxies().size(), 1u);
  EXPECT_EQ(one->proxy(0), nullptr);
}

// Points on the triangle abc: a barycentric grid of `n` steps along each edge (corners included).
void dense_points(const Triangle& t, int n, std::vector<Vec3>& out) {
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; i + j <= n; ++j) {
      const double u = static_cast<double>(i) / n, v = static_cast<double>(j) / n;
      out.push_back(t.v0 + u * (t.v1 - t.v0) + v * (t.v2 - t.v0));
    }
  }
}

// Every interior node's stored bound against its subtree's original triangles, measured by brute
// force: a dense sample of every original triangle to the proxy's triangles, and the proxy's
// vertices, edge midpoints and centroids to the original (exact nearest distances); bounds weakly
// growing towards the root. Returns the nodes checked.
size_t check_dense_bounds(const StoreModel& model) {
  std::vector<Scene> cells(model.cells().size());
  for (uint32_t c = 0; c < cells.size(); ++c) EXPECT_TRUE(model.read_cell(c, cells[c]));
  const std::vector<uint32_t> end = subtree_ends(model.nodes());
  const double tolerance = 1e-9 * glm::length(model.info().bounds.extent());
  size_t checked = 0;
  for (uint32_t n = 0; n < model.nodes().size(); ++n) {
    const KdTree::Node& node = model.nodes()[n];
    const StoreProxy* proxy = model.proxy(n);
    if (node.is_leaf() || proxy == nullptr) continue;
    for (uint32_t child : {n + 1, node.child}) EXPECT_GE(proxy->error, model.proxies()[child].error) << n;
    const Original original = original_of(model, cells, n, end[n]);
    Scene decoded;
    EXPECT_TRUE(model.read_proxy(n, decoded)) << n;
    double farthest_original = 0.0, farthest_proxy = 0.0;
    std::vector<Vec3> points;
    for (const Triangle& t : original.triangles) {
      points.clear();
      dense_points(t, 4, points);
      for (const Vec3& p : points) farthest_original = std::max(farthest_original, distance_to_triangles(p, decoded.triangles));
    }
    std::vector<Vec3> positions;
    std::vector<uint32_t> indices;
    for (const Triangle& t : original.triangles) {
      for (const Vec3& v : {t.v0, t.v1, t.v2}) {
        indices.push_back(static_cast<uint32_t>(positions.size()));
        positions.push_back(v);
      }
    }
    const TriangleBvh original_bvh(positions, indices);
    for (const Triangle& t : decoded.triangles) {
      for (const Vec3& p : {t.v0, t.v1, t.v2, (t.v0 + t.v1 + t.v2) / 3.0, 0.5 * (t.v0 + t.v1), 0.5 * (t.v1 + t.v2),
                            0.5 * (t.v2 + t.v0)}) {
        farthest_proxy = std::max(farthest_proxy, original_bvh.distance(p));
      }
    }
    EXPECT_GE(proxy->error + tolerance, farthest_original) << "node " << n << ": an original point lies farther";
    EXPECT_GE(proxy->error + tolerance, farthest_proxy) << "node " << n << ": a proxy sample lies farther";
    ++checked;
  }
  return checked;
}

TEST(BuildStoreProxy, StoredBoundsHoldAgainstADenseSampleOfTheOriginalAndGrowTowardsTheRoot) {
  // Split on disk (part_primitives): nodes above the parts measure through the parts' kept levels.
  auto terrain = build(generated("terrain", 6000), "dense_terrain.frontier", 48, 64, CellCodec::Draco, 1500);
  ASSERT_TRUE(terrain);
  EXPECT_GT(check_dense_bounds(*terrain), 15u);
  auto building = build(generated("building", 6000), "dense_building.frontier", 64, 128, CellCodec::Draco, 2000);
  ASSERT_TRUE(building);
  EXPECT_GT(check_dense_bounds(*building), 7u);
}

TEST(BuildStoreProxy, ATerrainsRootBoundIsBelowItsHeightRange) {
  // Bounds measured against the original, not summed down the tree: a terrain's root proxy lies
  // within its height range of every point of it (the sum of the levels' errors did not).
  auto model = build(generated("terrain", 6000), "root_bound.frontier", 48, 64, CellCodec::Draco, 1500);
  ASSERT_TRUE(model);
  const Vec3 extent = model->info().bounds.extent();
  const double height = std::min({extent.x, extent.y, extent.z});
  ASSERT_NE(model->proxy(0), nullptr);
  EXPECT_LT(model->proxies()[0].error, height) << "extent " << extent.x << " " << extent.y << " " << extent.z;
  EXPECT_GT(model->proxies()[0].error, 0.0);
}

// A Hausdorff bound lets a proxy have holes up to twice its bound wide, and proxies simplified
// from their children's proxies widened them level by level (a 20 M terrain's root proxy was
// fragments over a quarter of the terrain, 215 from it). Every proxy of a deep terrain covers its
// node's region seen from above: at least 90 % of a 32x32 grid of points over the region lie
// under one of its triangles, at every depth, in and above the parts. (Its own suite name keeps
// this 200 k-triangle build out of the sanitized subset.)
TEST(ProxyHierarchy, ADeepTerrainsProxiesCoverTheirRegions) {
  auto model = build(generated("terrain", 200000), "cover.frontier", 128, 64, CellCodec::Draco, 20000);
  ASSERT_TRUE(model);
  const auto& nodes = model->nodes();
  std::vector<int> depth(nodes.size(), 0);
  double worst = 1.0;
  uint32_t worst_node = 0, checked = 0;
  for (uint32_t n = 0; n < nodes.size(); ++n) {
    if (nodes[n].is_leaf()) continue;
    depth[n + 1] = depth[nodes[n].child] = depth[n] + 1;
    if (depth[n] > 8 || model->proxy(n) == nullptr) continue;
    Scene proxy;
    ASSERT_TRUE(model->read_proxy(n, proxy)) << n;
    const Aabb region = model->node_region(n);
    constexpr int kGrid = 32;
    int covered = 0;
    for (int i = 0; i < kGrid; ++i) {
      for (int j = 0; j < kGrid; ++j) {
        const double x = region.lo.x + (i + 0.5) / kGrid * (region.hi.x - region.lo.x);
        const double y = region.lo.y + (j + 0.5) / kGrid * (region.hi.y - region.lo.y);
        for (const Triangle& t : proxy.triangles) {
          const auto side = [&](const Vec3& a, const Vec3& b) { return (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x); };
          const double d0 = side(t.v0, t.v1), d1 = side(t.v1, t.v2), d2 = side(t.v2, t.v0);
          if ((d0 >= 0 && d1 >= 0 && d2 >= 0) || (d0 <= 0 && d1 <= 0 && d2 <= 0)) {
            ++covered;
            break;
          }
        }
      }
    }
    const double share = double(covered) / (kGrid * kGrid);
    if (share < worst) {
      worst = share;
      worst_node = n;
    }
    ++checked;
  }
  EXPECT_GT(checked, 100u);
  EXPECT_GE(worst, 0.9) << "node " << worst_node << " at depth " << depth[worst_node];
  const Vec3 extent = model->info().bounds.extent();
  // Below its height range (it was 8.6 on a height range of 6.9 when proxies were simplified
  // from their children's).
  EXPECT_LT(model->proxies()[0].error, std::min({extent.x, extent.y, extent.z}));
}

// The codec tag of a page (without the in-page tree bit).
CellCodec page_codec(const StoreModel& model, uint64_t page) {
  auto p = model.reader().read_page(page);
  EXPECT_TRUE(p) << p.status().to_string();
  return p ? static_cast<CellCodec>(p->codec & ~kCellTreeFlag) : CellCodec::Raw;
}

TEST(BuildStoreProxy, ProxyPagesOfADracoStoreAreMeshoptByDefaultWithTheSameTrianglesAsDraco) {
  const std::string input = generated("terrain", 6000);
  BuildOptions o;
  o.inputs = {input};
  o.quiet = true;
  o.threads = 2;
  o.cell_prims = 64;
  o.proxy_triangles = 48;
  EXPECT_EQ(proxy_codec(o), CellCodec::Meshopt);
  o.output = (scratch() / "proxy_meshopt.frontier").string();
  ASSERT_TRUE(build_store(o));
  o.proxy_codec = CellCodec::Draco;
  o.output = (scratch() / "proxy_draco.frontier").string();
  ASSERT_TRUE(build_store(o));
  auto meshopt = StoreModel::open((scratch() / "proxy_meshopt.frontier").string());
  auto draco = StoreModel::open((scratch() / "proxy_draco.frontier").string());
  ASSERT_TRUE(meshopt && draco);
  ASSERT_EQ((*meshopt)->proxies().size(), (*draco)->proxies().size());
  size_t compared = 0, with_normals = 0;
  for (uint32_t n = 0; n < (*meshopt)->nodes().size(); ++n) {
    const StoreProxy* a = (*meshopt)->proxy(n);
    const StoreProxy* b = (*draco)->proxy(n);
    ASSERT_EQ(a == nullptr, b == nullptr) << "node " << n;
    if (a == nullptr) continue;
    EXPECT_EQ(page_codec(**meshopt, a->page), CellCodec::Meshopt) << "node " << n;
    EXPECT_EQ(page_codec(**draco, b->page), CellCodec::Draco) << "node " << n;
    EXPECT_EQ(a->error, b->error) << "node " << n;
    // The same lattice points: the same triangles (as sets of corners and sources; the codecs
    // order them their own way), and each page's tree loads.
    Scene sa, sb;
    const KdBuildOptions options = proxy_tree_options(*(*meshopt)->info().cell_tree);
    std::optional<KdTree> ta, tb;
    ASSERT_TRUE((*meshopt)->read_proxy(n, sa, &options, ta));
    ASSERT_TRUE((*draco)->read_proxy(n, sb, &options, tb));
    EXPECT_TRUE(ta.has_value() && tb.has_value()) << "node " << n;
    const auto corners = [](const Scene& s) {
      std::vector<std::array<double, 10>> out;
      for (const PrimRef& p : s.prims) {
        const Triangle& t = s.triangles[p.index];
        std::array<Vec3, 3> v = {t.v0, t.v1, t.v2};
        // Rotated so the smallest corner leads (a codec may start a triangle at another corner).
        const auto less = [](const Vec3& x, const Vec3& y) {
          return std::tie(x.x, x.y, x.z) < std::tie(y.x, y.y, y.z);
        };
        const size_t first = size_t(std::min_element(v.begin(), v.end(), less) - v.begin());
        std::rotate(v.begin(), v.begin() + std::ptrdiff_t(first), v.end());
        out.push_back({v[0].x, v[0].y, v[0].z, v[1].x, v[1].y, v[1].z, v[2].x, v[2].y, v[2].z, double(p.source)});
      }
      std::sort(out.begin(), out.end());
      return out;
    };
    EXPECT_EQ(corners(sa), corners(sb)) << "node " << n;
    // Simplified proxies carry shading normals (proxy.h, shade_proxy): unit, one per corner.
    for (const Scene* s : {&sa, &sb}) {
      if (s->triangle_normals.empty()) continue;
      ASSERT_EQ(s->triangle_normals.size(), s->triangles.size()) << "node " << n;
      for (const auto& tn : s->triangle_normals) {
        for (const Vec3& v : tn) EXPECT_NEAR(glm::length(v), 1.0, 1e-2) << "node " << n;
      }
      ++with_normals;
    }
    ++compared;
  }
  EXPECT_GT(compared, 7u);
  EXPECT_GT(with_normals, 2u);
  // The cells keep the store's codec.
  for (const StoreCell& c : (*meshopt)->cells()) {
    if (c.page == StoreCell::kNoPage) continue;
    EXPECT_EQ(page_codec(**meshopt, c.page), CellCodec::Draco);
  }
  // A lattice codec for proxies needs a lattice store.
  o.codec = CellCodec::Raw;
  o.proxy_codec.reset();
  EXPECT_EQ(proxy_codec(o), CellCodec::Raw);
  o.proxy_codec = CellCodec::Meshopt;
  o.output = (scratch() / "proxy_raw.frontier").string();
  const auto refused = build_store(o);
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.status().code(), Status::Code::InvalidArgument);
  EXPECT_NE(refused.status().message().find("--proxy-codec meshopt"), std::string::npos) << refused.status().message();
  EXPECT_FALSE(std::filesystem::exists(o.output));
}

TEST(BuildStoreProxy, NoProxiesWithZeroTarget) {
  auto model = build(generated("terrain", 6000), "none.frontier", 0);
  ASSERT_TRUE(model);
  EXPECT_TRUE(model->proxies().empty());
  EXPECT_FALSE(model->reader().section(kProxiesSection).has_value());
  EXPECT_EQ(model->proxy(0), nullptr);
}

// Rewrites page `page` of a store file with `edit` applied to its payload; with `fix_checksum`
// the block's checksum is recomputed (a page that passes the store's checks but decodes wrong).
template <typename Edit>
void damage_page(const std::string& path, uint64_t page, bool fix_checksum, Edit edit) {
  store::PosixFileSystem fs;
  store::Handle h;
  {
    auto reader = store::StoreReader::open(fs, path);
    ASSERT_TRUE(reader);
    h = (*reader)->page_handle(page);
  }
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  std::vector<uint8_t> block(h.size);
  f.seekg(static_cast<std::streamoff>(h.offset));
  f.read(reinterpret_cast<char*>(block.data()), static_cast<std::streamsize>(block.size()));
  edit(std::span<uint8_t>(block.data(), block.size() - store::kBlockTrailerSize));
  if (fix_checksum) {
    const uint64_t sum = XXH64(block.data(), block.size() - 8, 0);
    for (int i = 0; i < 8; ++i) block[block.size() - 8 + static_cast<size_t>(i)] = static_cast<uint8_t>(sum >> (8 * i));
  }
  f.seekp(static_cast<std::streamoff>(h.offset));
  f.write(reinterpret_cast<const char*>(block.data()), static_cast<std::streamsize>(block.size()));
}

TEST(BuildStoreProxy, DamagedProxyPagesAreReportedNamingTheNodeAndPage) {
  const std::string input = generated("terrain", 6000);
  for (const bool fix_checksum : {false, true}) {
    const std::string name = fix_checksum ? "bad_content.frontier" : "bad_checksum.frontier";
    uint64_t page = 0;
    {
      auto model = build(input, name, 48);
      ASSERT_TRUE(model);
      ASSERT_NE(model->proxy(0), nullptr);
      page = model->proxy(0)->page;
    }
    const std::string path = (scratch() / name).string();
    // The checksum case flips a byte in the middle; the content case (checksum fixed) the
    // payload's magic/version byte, which no codec accepts.
    damage_page(path, page, fix_checksum, [&](std::span<uint8_t> payload) {
      payload[fix_checksum ? 0 : payload.size() / 3] ^= 0x5a;
    });
    auto model = StoreModel::open(path);
    ASSERT_TRUE(model) << model.status().to_string();
    Scene out;
    const Status s = (*model)->read_proxy(0, out);
    ASSERT_FALSE(s);
    EXPECT_EQ(s.code(), Status::Code::Corruption);
    EXPECT_NE(s.message().find(fmt::format("proxy of node 0 page {}", page)), std::string::npos) << s.message();
    EXPECT_EQ(out.size(), 0u);
    const auto r = run_binary(FRONTIER_STORE_PATH, {"verify", path}, scratch());
    EXPECT_EQ(r.exit_code, 1) << r.out << r.err;
    const std::string named = fix_checksum ? fmt::format("proxy of node 0 page {}", page)
                                           : fmt::format("page at offset {}", (*model)->reader().page_handle(page).offset);
    EXPECT_NE(r.err.find(named), std::string::npos) << r.err;
  }
}

TEST(StoreCommand, InfoAndVerifyShowProxies) {
  auto model = build(generated("terrain", 6000), "info.frontier", 48);
  ASSERT_TRUE(model);
  const std::string path = (scratch() / "info.frontier").string();
  const auto info = run_binary(FRONTIER_STORE_PATH, {"info", path}, scratch());
  EXPECT_EQ(info.exit_code, 0) << info.err;
  uint64_t pages = 0;
  for (uint32_t n = 0; n < model->nodes().size(); ++n) pages += model->proxy(n) != nullptr ? 1 : 0;
  EXPECT_NE(info.out.find(fmt::format("proxies     {} pages", pages)), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("depth   0  error"), std::string::npos) << info.out;
  const auto verify = run_binary(FRONTIER_STORE_PATH, {"verify", path}, scratch());
  EXPECT_EQ(verify.exit_code, 0) << verify.err;
  EXPECT_NE(verify.out.find(fmt::format("{} proxies", pages)), std::string::npos) << verify.out;
  // One node's proxy as a PLY mesh: as many triangles as its page; a node without one, or past
  // the tree, is refused (exit 2).
  const std::string ply = (scratch() / "root_proxy.ply").string();
  const auto exported = run_binary(FRONTIER_STORE_PATH, {"proxy", path, "0", "-o", ply}, scratch());
  EXPECT_EQ(exported.exit_code, 0) << exported.err;
  const StoreProxy* root = model->proxy(0);
  ASSERT_NE(root, nullptr);
  EXPECT_NE(exported.out.find(fmt::format("node 0: {} triangles", root->triangles)), std::string::npos) << exported.out;
  std::ifstream in(ply, std::ios::binary);
  std::string header((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(header.find(fmt::format("element face {}", root->triangles)), std::string::npos);
  uint32_t leaf = 0;
  while (leaf < model->nodes().size() && !model->nodes()[leaf].is_leaf()) ++leaf;
  for (const std::string& node : {std::to_string(leaf), std::to_string(model->nodes().size())}) {
    const auto refused = run_binary(FRONTIER_STORE_PATH, {"proxy", path, node, "-o", ply + ".x"}, scratch());
    EXPECT_EQ(refused.exit_code, 2) << node << refused.err;
    EXPECT_NE(refused.err.find("node " + node), std::string::npos) << refused.err;
    EXPECT_FALSE(fs::exists(ply + ".x"));
  }
}

}  // namespace
}  // namespace frontier
