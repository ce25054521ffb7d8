// Phong shading with optional shadow rays.
#include "src/engine/shading.h"

#include "src/engine/ray_walk.h"

#include <cmath>

namespace frontier {

Effects Effects::declared_by(const Scene& scene) {
  Effects e;
  e.headlight = scene.lights.empty();
  e.shadows = !scene.lights.empty();
  for (const Material& m : scene.materials) e.specular = e.specular || m.ks > 0.0;
  return e;
}

Shader::Shader(const Scene& scene, const KdTree& tree) : scene_(scene), tree_(tree) {
  effects_ = Effects::declared_by(scene);
  // NFF convention: light intensity 1/sqrt(number of lights).
  light_scale_ = scene.lights.empty() ? 1.0 : 1.0 / std::sqrt(static_cast<double>(scene.lights.size()));
  epsilon_ = 1e-7 * (glm::length(tree.bounds().extent()) + tree.bounds().magnitude());
}

Rgb Shader::background() const {
  return {float(scene_.background.x), float(scene_.background.y), float(scene_.background.z)};
}

// Scene::shading_normal's direction for triangle `index` at p (unnormalized, either way round):
// the same barycentric interpolation, without the face normal it falls back on unless the
// triangle is degenerate or its normals cancel; a flat triangle's (three equal normals, as a
// paged world gives the cells' triangles beside proxies with normals) taken as it is.
Vec3 Shader::interpolated_normal(uint32_t index, const Vec3& p) const {
  const auto& vn = scene_.triangle_normals[index];
  if (vn[0] == vn[1] && vn[1] == vn[2] && glm::dot(vn[0], vn[0]) > 0.0) return vn[0];
  const Vec3 s = scene_.interpolated_normal(index, p);
  if (glm::dot(s, s) > 0.0) return s;
  const Triangle& tri = scene_.triangles[index];
  return glm::cross(tri.v1 - tri.v0, tri.v2 - tri.v0);
}

Rgb Shader::shade(uint32_t prim, const Ray& ray, double t, bool with_shadows, Counters& counters,
                  ShadowCells* cells) const {
  if (prim == kNoPrim) return background();
  const PrimRef& ref = scene_.prims[prim];
  static const Material kDefault;
  const Material& m = ref.material < scene_.materials.size() ? scene_.materials[ref.material] : kDefault;
  if (effects_.headlight && !effects_.specular && ref.kind == PrimKind::Triangle) {
    // What lit() computes for a triangle under the headlight alone, without its general
    // machinery (a third of a fill's time per pixel): the normal faces the ray, so n · (-d) is
    // |n · d| for the unit n (a degenerate triangle's normal is +z, as normal_of says). With
    // shading normals, n is shading_normal()'s (interpolated at the hit).
    ++counters.shading_ops;
    const Triangle& tri = scene_.triangles[ref.index];
    const Vec3 n = scene_.triangle_normals.empty() ? glm::cross(tri.v1 - tri.v0, tri.v2 - tri.v0)
                                                   : interpolated_normal(ref.index, ray.at(t));
    const double len = glm::length(n);
    const double ndotl = len > 0.0 ? std::abs(glm::dot(n, ray.dir)) / len : std::abs(ray.dir.z);
    Vec3 color = 0.1 * m.color;
    if (ndotl > 0.0) color += m.kd * ndotl * m.color;
    color = glm::clamp(color, Vec3(0.0), Vec3(1.0));
    return {float(color.x), float(color.y), float(color.z)};
  }
  const Vec3 p = ray.at(t);
  return lit(m, p, scene_.shading_normal(prim, p, ray), ray, t, with_shadows, counters, cells);
}

Rgb Shader::shade_surface(uint32_t material, const Vec3& normal, const Ray& ray, double t, Counters& counters) const {
  static const Material kDefault;
  const Material& m = material < scene_.materials.size() ? scene_.materials[material] : kDefault;
  const Vec3 n = glm::dot(normal, ray.dir) > 0.0 ? -normal : normal;
  return lit(m, ray.at(t), n, ray, t, false, counters, nullptr);
}

Rgb Shader::lit(const Material& m, const Vec3& p, const Vec3& n, const Ray& ray, double t, bool with_shadows,
                Counters& counters, ShadowCells* cells) const {
  const Vec3 v = -ray.dir;
  Vec3 color = 0.1 * m.color;  // a little ambient so unlit faces stay readable
  auto add_light = [&](const Vec3& to_light, const Vec3& light_color, double scale) {
    ++counters.shading_ops;
    const double ndotl = glm::dot(n, to_light);
    if (ndotl <= 0.0) return;
    color += scale * m.kd * ndotl * m.color * light_color;
    if (effects_.specular && m.ks > 0.0) {
      ++counters.specular_ops;
      const Vec3 r = 2.0 * ndotl * n - to_light;
      const double rv = glm::dot(r, v);
      if (rv > 0.0) color += scale * m.ks * std::pow(rv, m.shine) * light_color;
    }
  };
  if (effects_.headlight) {
    add_light(v, Vec3(1.0), 1.0);
  } else {
    for (const PointLight& light : scene_.lights) {
      Vec3 to_light = light.position - p;
      const double dist = glm::length(to_light);
      if (dist <= 0.0) continue;
      to_light /= dist;
      if (with_shadows && effects_.shadows && glm::dot(n, to_light) > 0.0) {
        const Ray shadow(p, to_light);
        const Occlusion o = occlusion(scene_, tree_, shadow, epsilon_ * (1.0 + t), dist - epsilon_, counters,
                                      cells ? cells->gate : nullptr, cells ? cells->marks : nullptr);
        if (o == Occlusion::kBlocked) continue;
        if (o == Occlusion::kMissing) cells->missing = true;  // lit for now; the caller waits
      }
      add_light(to_light, light.color, light_scale_);
    }
  }
  color = glm::clamp(color, Vec3(0.0), Vec3(1.0));
  return {float(color.x), float(color.y), float(color.z)};
}

}  // namespace frontier
