// Scene: per-kind dispatch of bounds, ray tests and normals; adders that keep arrays in step.
#include "src/core/scene.h"

namespace frontier {
namespace {

// Appends `item` to its per-kind array and its reference to `prims`.
template <class T>
void append(std::vector<PrimRef>& prims, PrimKind kind, std::vector<T>& items, const T& item, uint32_t source,
            uint32_t material) {
  prims.push_back({kind, static_cast<uint32_t>(items.size()), source, material});
  items.push_back(item);
}

}  // namespace

Aabb Scene::prim_bounds(uint32_t i) const {
  const PrimRef& p = prims[i];
  switch (p.kind) {
    case PrimKind::Triangle: return bounds_of(triangles[p.index]);
    case PrimKind::Sphere: return bounds_of(spheres[p.index]);
    case PrimKind::Box: return bounds_of(boxes[p.index]);
    case PrimKind::Cone: return bounds_of(cones[p.index]);
    case PrimKind::Quadric: return bounds_of(quadrics[p.index]);
  }
  return {};
}

Aabb Scene::bounds() const {
  Aabb b;
  for (uint32_t i = 0; i < prims.size(); ++i) b.extend(prim_bounds(i));
  return b;
}

bool Scene::intersect(uint32_t i, const Ray& ray, double tmin, double tmax, double& t) const {
  const PrimRef& p = prims[i];
  switch (p.kind) {
    case PrimKind::Triangle: return intersect_triangle(triangles[p.index], ray, tmin, tmax, t);
    case PrimKind::Sphere: return intersect_sphere(spheres[p.index], ray, tmin, tmax, t);
    case PrimKind::Box: return intersect_box(boxes[p.index], ray, tmin, tmax, t);
    case PrimKind::Cone: return intersect_cone(cones[p.index], ray, tmin, tmax, t);
    case PrimKind::Quadric: return intersect_quadric(quadrics[p.index], ray, tmin, tmax, t);
  }
  return false;
}

double Scene::distance_bound(uint32_t i, const Vec3& p) const {
  const PrimRef& r = prims[i];
  switch (r.kind) {
    case PrimKind::Sphere: return frontier::distance_bound(spheres[r.index], p);
    case PrimKind::Cone: return frontier::distance_bound(cones[r.index], p);
    default: return 0.0;
  }
}

bool Scene::below_plane(uint32_t i, const Vec3& origin, const Vec3& normal) const {
  const PrimRef& r = prims[i];
  // The largest signed distance, and the size of what it is computed from: the margin covers
  // the rounding of q - origin far from the world's origin and of the dot product.
  double top = -kInfinity, scale = 0.0;
  const double n_length = glm::length(normal);
  auto point = [&](const Vec3& q, double reach) {
    const Vec3 d = q - origin;
    top = std::max(top, glm::dot(normal, d) + reach);
    scale = std::max(scale, n_length * (glm::length(d) + 1e-6 * glm::length(q)) + reach);
  };
  switch (r.kind) {
    case PrimKind::Triangle: {
      const Triangle& t = triangles[r.index];
      point(t.v0, 0.0);
      point(t.v1, 0.0);
      point(t.v2, 0.0);
      break;
    }
    case PrimKind::Sphere: {
      const Sphere& s = spheres[r.index];
      point(s.center, std::abs(s.radius) * n_length);
      break;
    }
    case PrimKind::Cone: {
      // The surface lies in the hull of its two end circles; a circle's farthest point from
      // the plane is its centre's distance plus radius × |normal| × sin(angle to the axis).
      const Cone& c = cones[r.index];
      const Vec3 axis = c.apex - c.base;
      const double length = glm::length(axis);
      const double nn = n_length * n_length;
      double across = n_length;
      if (length > 0.0) {
        const double along = glm::dot(normal, axis) / length;
        // The difference cancels when the normal runs along the axis: 1e-12 nn covers it.
        across = std::sqrt(std::max(0.0, nn - along * along) + 1e-12 * nn);
      }
      point(c.base, std::abs(c.base_radius) * across);
      point(c.apex, std::abs(c.apex_radius) * across);
      break;
    }
    default: return false;
  }
  return top < -1e-9 * scale;
}

Vec3 Scene::interpolated_normal(uint32_t index, const Vec3& p) const {
  const Triangle& tri = triangles[index];
  const Vec3 e1 = tri.v1 - tri.v0, e2 = tri.v2 - tri.v0, h = p - tri.v0;
  const double d00 = glm::dot(e1, e1), d01 = glm::dot(e1, e2), d11 = glm::dot(e2, e2);
  const double d20 = glm::dot(h, e1), d21 = glm::dot(h, e2);
  const double den = d00 * d11 - d01 * d01;
  if (!(den > 0.0)) return Vec3(0.0);
  const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
  const auto& vn = triangle_normals[index];
  return (1.0 - v - w) * vn[0] + v * vn[1] + w * vn[2];
}

Vec3 Scene::shading_normal(uint32_t i, const Vec3& hit, const Ray& ray) const {
  const PrimRef& p = prims[i];
  Vec3 n{0.0, 0.0, 1.0};
  switch (p.kind) {
    case PrimKind::Triangle: {
      const Triangle& tri = triangles[p.index];
      n = normal_of(tri, hit);
      if (!triangle_normals.empty()) {
        const Vec3 s = interpolated_normal(p.index, hit);
        if (glm::dot(s, s) > 0.0) n = glm::normalize(s);
      }
      break;
    }
    case PrimKind::Sphere: n = normal_of(spheres[p.index], hit); break;
    case PrimKind::Box: n = normal_of(boxes[p.index], hit); break;
    case PrimKind::Cone: n = normal_of(cones[p.index], hit); break;
    case PrimKind::Quadric: n = normal_of(quadrics[p.index], hit); break;
  }
  return glm::dot(n, ray.dir) > 0.0 ? -n : n;
}

void Scene::add_from(const Scene& other, uint32_t i) {
  const PrimRef& p = other.prims[i];
  switch (p.kind) {
    case PrimKind::Triangle:
      add_triangle(other.triangles[p.index], p.source, p.material,
                   other.triangle_normals.empty() ? nullptr : &other.triangle_normals[p.index]);
      break;
    case PrimKind::Sphere: add_sphere(other.spheres[p.index], p.source, p.material); break;
    case PrimKind::Box: add_box(other.boxes[p.index], p.source, p.material); break;
    case PrimKind::Cone: add_cone(other.cones[p.index], p.source, p.material); break;
    case PrimKind::Quadric: add_quadric(other.quadrics[p.index], p.source, p.material); break;
  }
}

void Scene::add_triangle(const Triangle& t, uint32_t source, uint32_t material,
                         const std::array<Vec3, 3>* normals) {
  if (normals != nullptr && triangle_normals.size() < triangles.size()) {
    // First triangle with normals: give the earlier ones their geometric normal.
    for (size_t k = triangle_normals.size(); k < triangles.size(); ++k) {
      const Vec3 n = normal_of(triangles[k], triangles[k].v0);
      triangle_normals.push_back({n, n, n});
    }
  }
  if (!triangle_normals.empty() || normals != nullptr) {
    if (normals != nullptr) {
      triangle_normals.push_back(*normals);
    } else {
      const Vec3 n = normal_of(t, t.v0);
      triangle_normals.push_back({n, n, n});
    }
  }
  append(prims, PrimKind::Triangle, triangles, t, source, material);
}

void Scene::add_sphere(const Sphere& s, uint32_t source, uint32_t material) {
  append(prims, PrimKind::Sphere, spheres, s, source, material);
}

void Scene::add_box(const Box& b, uint32_t source, uint32_t material) {
  append(prims, PrimKind::Box, boxes, b, source, material);
}

void Scene::add_cone(const Cone& c, uint32_t source, uint32_t material) {
  append(prims, PrimKind::Cone, cones, c, source, material);
}

void Scene::add_quadric(const Quadric& q, uint32_t source, uint32_t material) {
  append(prims, PrimKind::Quadric, quadrics, q, source, material);
}

Scene Scene::without_primitives() const {
  Scene out;
  out.materials = materials;
  out.lights = lights;
  out.camera = camera;
  out.background = background;
  out.input_primitives = input_primitives;
  return out;
}

void Scene::translate(const Vec3& d) {
  for (Triangle& t : triangles) { t.v0 += d; t.v1 += d; t.v2 += d; }
  for (Sphere& s : spheres) s.center += d;
  for (Box& b : boxes) { b.bounds.lo += d; b.bounds.hi += d; }
  for (Cone& c : cones) { c.base += d; c.apex += d; }
  for (Quadric& q : quadrics) {
    // Substitute x -> x - d in the implicit form and in the clip planes.
    const auto& c = q.coeff;
    const double A = c[0], B = c[1], C = c[2], D = c[3], E = c[4], F = c[5];
    const double G = c[6], H = c[7], I = c[8], J = c[9];
    const double x = d.x, y = d.y, z = d.z;
    std::array<double, 10> n = c;
    n[6] = G - 2 * A * x - D * y - F * z;
    n[7] = H - 2 * B * y - D * x - E * z;
    n[8] = I - 2 * C * z - E * y - F * x;
    n[9] = J + A * x * x + B * y * y + C * z * z + D * x * y + E * y * z + F * x * z - G * x -
           H * y - I * z;
    q.coeff = n;
    for (int k = 0; k < q.clip_count; ++k) {
      Vec4& p = q.clip[k];
      p.w -= p.x * x + p.y * y + p.z * z;
    }
    q.bounds.lo += d;
    q.bounds.hi += d;
  }
  for (PointLight& l : lights) l.position += d;
  if (camera) {
    camera->eye += d;
    camera->look_at += d;
  }
}

}  // namespace frontier
