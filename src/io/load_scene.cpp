// load_scene and SceneBuilder: pull primitives from a SceneReader into an in-memory Scene.
//
// Invariant: the i-th input primitive (0-based, file order) has source id i, whatever becomes
// of it: a polygon's triangles all share its id, and a dropped degenerate primitive still uses
// up its id (so ids match the file, not the scene). Zero-area triangles, polygons with no area,
// cones with a zero-length axis or no radius and spheres of radius 0 are dropped and counted in
// Scene::degenerate_dropped (a dropped polygon counts its n-2 triangles).
#include "src/io/load_scene.h"

#include "src/io/triangulate.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace frontier {
namespace {

// A triangle is degenerate when its doubled area |e1 x e2| is zero or below 1e-14 of the
// square of its longest edge (a needle or a collinear triple).
bool degenerate(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 e0 = b - a, e1 = c - b, e2 = a - c;
  const Vec3 n = glm::cross(e0, -e2);
  const double cross2 = glm::dot(n, n);
  const double longest2 = std::max({glm::dot(e0, e0), glm::dot(e1, e1), glm::dot(e2, e2)});
  // Squared comparison (no sqrt) unless squaring longest2 could overflow.
  if (longest2 < 1e150) return !(cross2 > 0.0) || cross2 < 1e-28 * longest2 * longest2;
  return !(cross2 > 0.0) || std::sqrt(cross2) < 1e-14 * longest2;
}

}  // namespace

void SceneBuilder::add(const InputPrimitive& p, uint32_t source) {
  switch (p.kind) {
    case InputPrimitive::Kind::Polygon: add_polygon(p, source); break;
    case InputPrimitive::Kind::Sphere:
      if (p.sphere.radius > 0.0) {
        scene_.add_sphere(p.sphere, source, p.material);
      } else {
        ++scene_.degenerate_dropped;
      }
      break;
    case InputPrimitive::Kind::Cone: {
      const Cone& c = p.cone;
      if (c.base != c.apex && (c.base_radius > 0.0 || c.apex_radius > 0.0)) {
        scene_.add_cone(c, source, p.material);
      } else {
        ++scene_.degenerate_dropped;
      }
      break;
    }
    case InputPrimitive::Kind::Box: scene_.add_box(p.box, source, p.material); break;
    case InputPrimitive::Kind::Quadric: scene_.add_quadric(p.quadric, source, p.material); break;
  }
}

void SceneBuilder::add_triangle(const InputPrimitive& p, uint32_t a, uint32_t b, uint32_t c, uint32_t source) {
  const Vec3 &va = p.vertices[a], &vb = p.vertices[b], &vc = p.vertices[c];
  if (degenerate(va, vb, vc)) {
    ++scene_.degenerate_dropped;
    return;
  }
  if (p.normals.size() == p.vertices.size()) {
    const std::array<Vec3, 3> n = {p.normals[a], p.normals[b], p.normals[c]};
    scene_.add_triangle({va, vb, vc}, source, p.material, &n);
  } else {
    scene_.add_triangle({va, vb, vc}, source, p.material);
  }
}

void SceneBuilder::add_polygon(const InputPrimitive& p, uint32_t source) {
  const size_t n = p.vertices.size();
  if (n < 3) return;  // readers never hand these out
  if (n == 3) {
    add_triangle(p, 0, 1, 2, source);
    return;
  }
  if (!triangulate_polygon(p.vertices, triangles_)) {
    scene_.degenerate_dropped += n - 2;
    return;
  }
  for (const auto& t : triangles_) add_triangle(p, t[0], t[1], t[2], source);
}

Status no_primitives_error(const std::string& path, uint64_t input_primitives) {
  if (input_primitives == 0) return Status::corruption(fmt::format("{}: the model has no primitives", path));
  return Status::corruption(fmt::format("{}: the model has no primitives left: all {} are degenerate (no area)",
                                        path, input_primitives));
}

Status load_scene(const std::string& path, Scene& scene, std::vector<std::string>* warnings) {
  scene = Scene{};
  auto opened = open_scene_reader(path);
  if (!opened) return opened.status();
  SceneReader& reader = **opened;
  if (const int64_t declared = reader.declared_primitives(); declared > 0) {
    // A hint only: the count was checked against the file size by the reader.
    const auto hint = static_cast<size_t>(std::min<int64_t>(declared, int64_t{1} << 26));
    scene.prims.reserve(hint);
    scene.triangles.reserve(hint);
  }
  SceneBuilder builder(scene);
  InputPrimitive prim;
  uint64_t count = 0;
  Status s;
  for (;;) {
    bool end = false;
    s = reader.next(prim, end);
    if (!s || end) break;
    if (count == UINT32_MAX) {
      s = Status::unsupported(fmt::format("{}: more than {} primitives", path, UINT32_MAX - 1));
      break;
    }
    builder.add(prim, static_cast<uint32_t>(count));
    ++count;
  }
  // Also when reading failed: a skipped header line may explain the error.
  for (const std::string& w : reader.warnings()) {
    if (warnings != nullptr) {
      warnings->push_back(w);
    } else {
      std::fprintf(stderr, "warning: %s\n", w.c_str());
    }
  }
  if (!s) return s;
  if (scene.size() == 0) return no_primitives_error(path, count);
  const SceneHeader& h = reader.header();
  scene.materials = h.materials;
  if (scene.materials.empty()) scene.materials.emplace_back();
  scene.lights = h.lights;
  scene.camera = h.camera;
  scene.background = h.background;
  scene.input_primitives = static_cast<uint32_t>(count);
  return Status::ok();
}

}  // namespace frontier
