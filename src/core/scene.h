// An in-memory scene: primitives of every kind in input order, plus materials, lights,
// camera and background. Every primitive remembers `source`, the index of the input
// primitive it came from (an NFF object or a mesh face before triangulation), which is what
// id images record so that methods can be compared pixel by pixel.
#pragma once

#include "src/core/geometry.h"
#include "src/core/primitives.h"

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

namespace frontier {

enum class PrimKind : uint8_t { Triangle, Sphere, Box, Cone, Quadric };

struct PrimRef {
  PrimKind kind = PrimKind::Triangle;
  uint32_t index = 0;     // into the per-kind array
  uint32_t source = 0;    // input primitive index (what --ids writes)
  uint32_t material = 0;  // into Scene::materials
};

// NFF `f r g b Kd Ks Shine T index_of_refraction`.
struct Material {
  Vec3 color{0.8, 0.8, 0.8};
  double kd = 1.0;
  double ks = 0.0;
  double shine = 1.0;
  double transmittance = 0.0;
  double ior = 1.0;
};

struct PointLight {
  Vec3 position{0.0};
  Vec3 color{1.0, 1.0, 1.0};
};

struct Camera {
  Vec3 eye{0.0, 0.0, 1.0};
  Vec3 look_at{0.0};
  Vec3 up{0.0, 1.0, 0.0};
  double vfov_deg = 45.0;  // full vertical field of view
  double near = 0.0;       // hither: hits closer than this (along the view axis) are ignored
  int width = 0;           // preferred resolution from the file, 0 if none
  int height = 0;
};

struct Scene {
  std::vector<PrimRef> prims;
  std::vector<Triangle> triangles;
  // Either empty or one entry per triangle: per-vertex shading normals (NFF `pp`, PLY/OBJ vn).
  std::vector<std::array<Vec3, 3>> triangle_normals;
  std::vector<Sphere> spheres;
  std::vector<Box> boxes;
  std::vector<Cone> cones;
  std::vector<Quadric> quadrics;

  std::vector<Material> materials;
  std::vector<PointLight> lights;
  std::optional<Camera> camera;
  Vec3 background{0.0, 0.0, 0.0};

  uint32_t input_primitives = 0;     // input primitives read (sources are < this)
  uint64_t degenerate_dropped = 0;   // zero-area triangles dropped while loading

  size_t size() const { return prims.size(); }
  Aabb prim_bounds(uint32_t i) const;
  Aabb bounds() const;
  bool intersect(uint32_t i, const Ray& ray, double tmin, double tmax, double& t) const;
  // A lower bound on the distance from p to primitive i's surface beyond what its bounds give
  // (spheres and cones; 0 for the others). Never more than the true distance.
  double distance_bound(uint32_t i, const Vec3& p) const;
  // Whether primitive i lies wholly on the negative side of the plane through `origin` with
  // `normal` (dot(normal, q - origin) < 0 at every surface point q, by a relative margin).
  // Exact for triangles, spheres and cones (each end circle's farthest point); boxes and
  // quadrics answer false: their bounds are all there is to test.
  bool below_plane(uint32_t i, const Vec3& origin, const Vec3& normal) const;
  // Unit normal at the hit point p on primitive i, facing against ray.dir (shading normal when
  // the primitive has one).
  Vec3 shading_normal(uint32_t i, const Vec3& p, const Ray& ray) const;
  // Triangle `index`'s (scene.triangles) per-vertex normals interpolated at p, barycentrically,
  // not normalized; zero for a degenerate triangle. REQUIRES: triangle_normals is not empty.
  Vec3 interpolated_normal(uint32_t index, const Vec3& p) const;

  // Adders keep the per-kind arrays and `prims` consistent.
  void add_triangle(const Triangle& t, uint32_t source, uint32_t material,
                    const std::array<Vec3, 3>* normals = nullptr);
  void add_sphere(const Sphere& s, uint32_t source, uint32_t material);
  void add_box(const Box& b, uint32_t source, uint32_t material);
  void add_cone(const Cone& c, uint32_t source, uint32_t material);
  void add_quadric(const Quadric& q, uint32_t source, uint32_t material);
  // Appends primitive i of `other` (geometry, normals, source, material).
  void add_from(const Scene& other, uint32_t i);

  // A scene with this one's materials, lights, camera, background and input_primitives but no
  // primitives: the start of a scene derived from this one (tessellated, say) whose sources
  // still name this scene's input primitives.
  Scene without_primitives() const;

  // Moves every primitive, light and the camera by `offset` (tests of far-from-origin input).
  void translate(const Vec3& offset);
};

}  // namespace frontier
