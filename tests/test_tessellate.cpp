// Tessellation: meshes lie on the true surfaces, spheres and boxes are closed and wound
// outward, areas converge, the chord-error mode picks the fewest segments that meet the error,
// sources and materials survive, and a tessellated SPD scene renders by frustum casting exactly
// as brute force does (and close to the curved original, pixel for pixel by source id).
#include "src/core/tessellate.h"

#include "src/io/load_scene.h"
#include "tests/engine_util.h"
#include "tests/test_files.h"

#include <gtest/gtest.h>

#include <map>
#include <numbers>
#include <random>
#include <set>
#include <tuple>

namespace frontier {
namespace {

using testing::brute_reference;
using testing::compare_ids;
using testing::render_ids;
using testing::spd;

constexpr double kPi = std::numbers::pi;

using Point = std::tuple<double, double, double>;
Point key(const Vec3& p) { return {p.x, p.y, p.z}; }

// Directed edges, keyed by exact vertex positions.
std::map<std::pair<Point, Point>, int> directed_edges(const std::vector<Triangle>& tris) {
  std::map<std::pair<Point, Point>, int> edges;
  for (const Triangle& t : tris) {
    const Vec3 v[3] = {t.v0, t.v1, t.v2};
    for (int k = 0; k < 3; ++k) ++edges[{key(v[k]), key(v[(k + 1) % 3])}];
  }
  return edges;
}

// Closed and consistently wound: every directed edge appears once and its reverse once, so every
// undirected edge is shared by exactly two triangles. Returns the number of offending edges.
size_t open_edges(const std::vector<Triangle>& tris) {
  const auto edges = directed_edges(tris);
  size_t bad = 0;
  for (const auto& [edge, count] : edges) {
    const auto reverse = edges.find({edge.second, edge.first});
    if (count != 1 || reverse == edges.end() || reverse->second != 1) ++bad;
  }
  return bad;
}

double area(const std::vector<Triangle>& tris) {
  double a = 0.0;
  for (const Triangle& t : tris) a += 0.5 * glm::length(glm::cross(t.v1 - t.v0, t.v2 - t.v0));
  return a;
}

// Positive for a closed mesh wound counter-clockwise seen from outside.
double signed_volume(const std::vector<Triangle>& tris, const Vec3& origin) {
  double v = 0.0;
  for (const Triangle& t : tris) v += glm::dot(t.v0 - origin, glm::cross(t.v1 - origin, t.v2 - origin)) / 6.0;
  return v;
}

std::vector<Triangle> mesh_of(const Scene& scene, const TessellateOptions& options = {},
                              std::vector<std::array<Vec3, 3>>* normals = nullptr) {
  std::vector<Triangle> tris;
  for (uint32_t i = 0; i < scene.size(); ++i) tessellate_primitive(tris, normals, scene, i, options);
  return tris;
}

Scene one_sphere(const Vec3& c, double r) {
  Scene s;
  s.materials.push_back({});
  s.add_sphere({c, r}, 0, 0);
  s.input_primitives = 1;
  return s;
}

TEST(TessellateSphere, VerticesLieOnTheSphereAndNormalsAreRadial) {
  for (const auto& [c, r] : {std::pair{Vec3(1.5, -2.0, 0.25), 0.7}, std::pair{Vec3(3, 4, 5), 1000.0},
                             std::pair{Vec3(0.0), 1e-3}}) {
    for (int segments : {3, 7, 24, 100}) {
      TessellateOptions o;
      o.segments = segments;
      std::vector<std::array<Vec3, 3>> normals;
      const auto tris = mesh_of(one_sphere(c, r), o, &normals);
      const int lat = std::max(3, (segments + 1) / 2);
      ASSERT_EQ(tris.size(), size_t(2 * segments * (lat - 1))) << segments;
      ASSERT_EQ(normals.size(), tris.size());
      double worst = 0.0, worst_normal = 0.0;
      for (size_t k = 0; k < tris.size(); ++k) {
        const Vec3 v[3] = {tris[k].v0, tris[k].v1, tris[k].v2};
        for (int j = 0; j < 3; ++j) {
          worst = std::max(worst, std::abs(glm::length(v[j] - c) - r) / r);
          worst_normal = std::max(worst_normal, glm::length(normals[k][size_t(j)] - (v[j] - c) / r));
        }
      }
      EXPECT_LE(worst, 1e-12) << "r " << r << " segments " << segments;
      EXPECT_LE(worst_normal, 1e-9) << "r " << r << " segments " << segments;
    }
  }
}

TEST(TessellateSphere, MeshIsClosedAndWoundOutward) {
  for (int segments : {3, 4, 5, 24, 61}) {
    TessellateOptions o;
    o.segments = segments;
    const Vec3 c(0.5, -1.0, 2.0);
    const auto tris = mesh_of(one_sphere(c, 2.0), o);
    EXPECT_EQ(open_edges(tris), 0u) << segments;
    EXPECT_GT(signed_volume(tris, c), 0.0) << segments;
    // Every triangle individually faces away from the centre.
    size_t inward = 0;
    for (const Triangle& t : tris) inward += glm::dot(glm::cross(t.v1 - t.v0, t.v2 - t.v0), t.v0 - c) <= 0.0;
    EXPECT_EQ(inward, 0u) << segments;
  }
}

TEST(TessellateSphere, AreaAndVolumeApproachTheSphereFromInside) {
  const double r = 1.3;
  double last_error = kInfinity;
  for (int segments : {6, 12, 24, 48, 96, 192}) {
    TessellateOptions o;
    o.segments = segments;
    const auto tris = mesh_of(one_sphere(Vec3(0.0), r), o);
    const double a = area(tris), exact = 4.0 * kPi * r * r;
    EXPECT_LT(a, exact) << segments;  // inscribed
    const double error = (exact - a) / exact;
    EXPECT_LT(error, 0.5 * last_error) << segments;  // about quadratic convergence
    last_error = error;
    EXPECT_LT(signed_volume(tris, Vec3(0.0)), 4.0 / 3.0 * kPi * r * r * r);
  }
  EXPECT_LT(last_error, 3e-4);
}

TEST(TessellateChordError, FewestSegmentsThatMeetTheError) {
  TessellateOptions o;
  o.max_chord_error = 0.01;
  for (double r : {0.05, 0.3, 1.0, 7.0}) {
    const int n = tessellation_segments(r, o);
    EXPECT_LE(r * (1.0 - std::cos(kPi / n)), o.max_chord_error) << r;
    if (n > o.min_segments) {
      EXPECT_GT(r * (1.0 - std::cos(kPi / (n - 1))), o.max_chord_error) << r;
    }
  }
  EXPECT_EQ(tessellation_segments(0.001, o), o.min_segments);  // smaller than the error
  EXPECT_EQ(tessellation_segments(1e6, o), o.max_segments);    // capped
  o.max_chord_error = 0.0;
  o.segments = 2;
  EXPECT_EQ(tessellation_segments(1.0, o), 3);
}

TEST(TessellateChordError, SphereMeshStaysWithinTheError) {
  TessellateOptions o;
  o.max_chord_error = 0.002;
  const Vec3 c(1, 2, 3);
  const double r = 0.8;
  const auto tris = mesh_of(one_sphere(c, r), o);
  // The mesh is inscribed: its farthest points from the sphere are inside triangles.
  double worst = 0.0;
  for (const Triangle& t : tris) {
    for (double u = 0.0; u <= 1.0; u += 0.125) {
      for (double v = 0.0; u + v <= 1.0; v += 0.125) {
        const Vec3 p = t.v0 + u * (t.v1 - t.v0) + v * (t.v2 - t.v0);
        worst = std::max(worst, r - glm::length(p - c));
      }
    }
  }
  EXPECT_LE(worst, o.max_chord_error);
  EXPECT_GT(worst, 0.25 * o.max_chord_error);  // not wastefully fine either
}

TEST(TessellateCone, OpenSidesOnTheConeWithSlantNormals) {
  Scene s;
  s.materials.push_back({});
  const Cone truncated{Vec3(0.2, 0.1, -1.0), 0.5, Vec3(1.0, 0.7, 1.5), 0.2};
  const Cone pointed{Vec3(0.0), 0.4, Vec3(0.0, 0.0, 2.0), 0.0};
  s.add_cone(truncated, 0, 0);
  s.add_cone(pointed, 1, 0);
  TessellateOptions o;
  o.segments = 16;
  for (uint32_t i = 0; i < 2; ++i) {
    const Cone& cone = i == 0 ? truncated : pointed;
    std::vector<Triangle> tris;
    std::vector<std::array<Vec3, 3>> normals;
    tessellate_primitive(tris, &normals, s, i, o);
    ASSERT_EQ(tris.size(), size_t(i == 0 ? 32 : 16));
    const Vec3 axis = cone.apex - cone.base;
    const double len = glm::length(axis);
    const Vec3 slant_dir = axis / len;
    for (size_t k = 0; k < tris.size(); ++k) {
      const Vec3 v[3] = {tris[k].v0, tris[k].v1, tris[k].v2};
      for (int j = 0; j < 3; ++j) {
        // On the surface: distance to the axis equals the radius interpolated along it.
        const double s_along = glm::dot(v[j] - cone.base, slant_dir) / len;
        const double radius = cone.base_radius + s_along * (cone.apex_radius - cone.base_radius);
        const Vec3 off_axis = v[j] - cone.base - s_along * axis;
        EXPECT_NEAR(glm::length(off_axis), radius, 1e-12);
        const Vec3 n = normals[k][size_t(j)];
        EXPECT_NEAR(glm::length(n), 1.0, 1e-12);
        // The normal is perpendicular to the side's slant line through the vertex.
        if (radius > 0.0) {
          const Vec3 slant = axis + (cone.apex_radius - cone.base_radius) * off_axis / radius;
          EXPECT_NEAR(glm::dot(n, glm::normalize(slant)), 0.0, 1e-12);
          EXPECT_GT(glm::dot(n, off_axis), 0.0);  // outward
        }
      }
    }
    // Open ends: the rims are the only boundary (n edges per rim of non-zero radius), the rest
    // is shared by exactly two triangles.
    const auto edges = directed_edges(tris);
    size_t boundary = 0;
    for (const auto& [edge, count] : edges) {
      EXPECT_EQ(count, 1);
      boundary += edges.count({edge.second, edge.first}) == 0;
    }
    EXPECT_EQ(boundary, size_t(i == 0 ? 32 : 16));
  }
}

TEST(TessellateCone, LateralAreaConverges) {
  Scene s;
  const Cone c{Vec3(0.0), 1.0, Vec3(0.0, 3.0, 0.0), 0.5};
  s.add_cone(c, 0, 0);
  const double exact = kPi * (1.0 + 0.5) * std::sqrt(9.0 + 0.25);
  TessellateOptions o;
  o.segments = 256;
  const double a = area(mesh_of(s, o));
  EXPECT_LT(a, exact);
  EXPECT_NEAR(a / exact, 1.0, 1e-4);
}

TEST(TessellateBox, TwelveTrianglesClosedOutwardWithTheBoxArea) {
  Scene s;
  const Aabb b(Vec3(-1.0, 0.5, 2.0), Vec3(0.5, 2.5, 2.25));
  s.add_box({b}, 0, 0);
  const auto tris = mesh_of(s);
  ASSERT_EQ(tris.size(), 12u);
  EXPECT_EQ(open_edges(tris), 0u);
  const Vec3 e = b.extent();
  EXPECT_NEAR(signed_volume(tris, Vec3(0.0)), e.x * e.y * e.z, 1e-12);
  EXPECT_NEAR(area(tris), b.surface_area(), 1e-12);
}

TEST(TessellateScene, SourcesMaterialsAndBoundsSurvive) {
  std::mt19937_64 rng(11);
  Scene in = testing::random_scene(rng, 300);
  in.materials.resize(4);
  for (PrimRef& p : in.prims) p.material = p.source % 4;
  Quadric q;
  q.coeff = {1, 1, 1, 0, 0, 0, 0, 0, 0, -0.25};
  q.bounds = Aabb(Vec3(-0.5), Vec3(0.5));
  in.add_quadric(q, 300, 1);
  in.input_primitives = 301;

  TessellateStats stats;
  const Scene out = tessellate(in, {}, &stats);
  EXPECT_EQ(stats.quadrics_as_boxes, 1u);
  EXPECT_EQ(stats.triangles_out, out.triangles.size());
  EXPECT_EQ(out.input_primitives, in.input_primitives);
  EXPECT_EQ(out.materials.size(), in.materials.size());
  ASSERT_EQ(out.triangle_normals.size(), out.triangles.size());  // smooth normals by default
  std::map<uint32_t, uint32_t> input_of_source;
  for (uint32_t i = 0; i < in.size(); ++i) input_of_source[in.prims[i].source] = i;
  std::set<uint32_t> seen;
  size_t outside = 0;
  for (uint32_t k = 0; k < out.size(); ++k) {
    const PrimRef& p = out.prims[k];
    ASSERT_EQ(p.kind, PrimKind::Triangle);
    ASSERT_TRUE(input_of_source.count(p.source)) << p.source;
    const uint32_t i = input_of_source[p.source];
    EXPECT_EQ(p.material, in.prims[i].material);
    seen.insert(p.source);
    // Each triangle lies within its own input primitive's bounds (the meshes are inscribed).
    Aabb b = in.prim_bounds(i);
    b.lo -= Vec3(1e-9);
    b.hi += Vec3(1e-9);
    const Aabb t = bounds_of(out.triangles[p.index]);
    outside += !(b.contains(t.lo) && b.contains(t.hi));
  }
  EXPECT_EQ(outside, 0u);
  EXPECT_EQ(seen.size(), in.size());  // every input primitive produced triangles
  size_t passed_through = 0;
  for (const PrimRef& p : in.prims) passed_through += p.kind == PrimKind::Triangle;
  EXPECT_EQ(stats.triangles_in, passed_through);
}

TEST(TessellateScene, FlatBoxesLoseOnlyTheirZeroAreaTriangles) {
  Scene in;
  in.add_box({Aabb(Vec3(0.0), Vec3(1.0, 1.0, 0.0))}, 0, 0);  // a square, flat in z
  TessellateStats stats;
  const Scene out = tessellate(in, {}, &stats);
  EXPECT_EQ(out.triangles.size(), 4u);  // top and bottom, two each
  EXPECT_EQ(stats.degenerate_dropped, 8u);
  EXPECT_TRUE(out.triangle_normals.empty());  // nothing curved: flat, as if loaded
}

// The engine's guarantee holds on tessellated input: frustum casting and ray walking give
// exactly brute force's ids (ties aside) on a tessellated SPD scene.
TEST(TessellateRender, TessellatedSpdSceneFrustumEqualsBrute) {
  RecordProperty("methods", "frustum casting, ray walking on tessellated rings.nff: ids against brute force");
  Scene curved;
  ASSERT_TRUE(load_scene(spd("rings"), curved).is_ok());
  TessellateOptions o;
  o.segments = 6;
  const Scene scene = tessellate(curved, o);
  ASSERT_GT(scene.triangles.size(), 100000u);
  const KdTree tree = KdTree::build(scene);
  const Camera camera = scene.camera ? *scene.camera : automatic_camera(scene.bounds());
  const View view(camera, 33, 33);
  std::vector<uint32_t> ref;
  std::vector<uint8_t> tie;
  brute_reference(scene, view, ref, tie);
  size_t background = 0;
  for (uint32_t id : ref) background += id == kNoPrim;
  EXPECT_LT(background, ref.size());  // the view sees the model
  for (Method m : {Method::Frustum, Method::RayWalk}) {
    const auto c = compare_ids(ref, tie, render_ids(scene, tree, view, m), view.width);
    EXPECT_EQ(c.mismatches, 0u) << method_name(m) << ": " << c.first_mismatch;
  }
}

// Ids stay comparable: the tessellated scene shows the same input primitive as the curved one
// at nearly every pixel (the differences are silhouettes, where the inscribed mesh is smaller).
TEST(TessellateRender, TessellatedIdsMatchTheCurvedScene) {
  Scene curved;
  // Not shells: its tessellation (overlapping spheres) makes KdTree::build exceed 20 GB.
  ASSERT_TRUE(load_scene(spd("tree"), curved).is_ok());
  TessellateOptions o;
  o.segments = 12;  // 0.5 M triangles: coarse, to keep the test quick
  const Scene mesh = tessellate(curved, o);
  const Camera camera = curved.camera ? *curved.camera : automatic_camera(curved.bounds());
  const View view(camera, 129, 129);
  const auto a = render_ids(curved, KdTree::build(curved), view, Method::Frustum);
  const auto b = render_ids(mesh, KdTree::build(mesh), view, Method::Frustum);
  size_t same = 0, hits = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    same += a[i] == b[i];
    hits += a[i] != kNoPrim;
  }
  EXPECT_GT(hits, a.size() / 4);
  EXPECT_GT(double(same) / double(a.size()), 0.95);
}

}  // namespace
}  // namespace frontier
