// Shared helpers for engine tests: random scenes and the comparison of a method's id image
// against brute force with the tie rule (two hits within 1e-6 relative distance).
#pragma once

#include "src/engine/kdtree.h"
#include "src/engine/ray_walk.h"
#include "src/engine/render.h"
#include "src/core/scene.h"
#include "src/core/view.h"

#include <tbb/parallel_for.h>

#include <random>
#include <string>

namespace frontier::testing {

struct Comparison {
  size_t pixels = 0;
  size_t mismatches = 0;  // differing ids that are not ties: must be zero
  size_t ties = 0;        // differing ids at tie pixels
  std::string first_mismatch;
};

// A camera at `eye` looking at `at` (up: z, or y when looking along z).
inline Camera camera_at(const Vec3& eye, const Vec3& at, double fov = 60.0, double near = 0.0) {
  Camera c;
  c.eye = eye;
  c.look_at = at;
  c.up = std::abs(glm::normalize(at - eye).z) > 0.99 ? Vec3(0, 1, 0) : Vec3(0, 0, 1);
  c.vfov_deg = fov;
  c.near = near;
  return c;
}

// Brute-force ids with tie flags.
inline void brute_reference(const Scene& scene, const View& view, std::vector<uint32_t>& ids,
                            std::vector<uint8_t>& tie) {
  ids.assign(view.pixels(), kNoPrim);
  tie.assign(view.pixels(), 0);
  tbb::parallel_for(0, view.height, [&](int y) {
    Counters c;
    for (int x = 0; x < view.width; ++x) {
      const Ray ray = view.ray(x, y);
      double second = kInfinity;
      const RayHit hit = brute_force_hit(scene, ray, view.tmin(ray), c, &second);
      const size_t i = size_t(y) * size_t(view.width) + size_t(x);
      if (hit.hit()) {
        ids[i] = scene.prims[hit.prim].source;
        tie[i] = (second - hit.t) <= 1e-6 * std::max(hit.t, 1e-12) ? 1 : 0;
      }
    }
  });
}

inline Comparison compare_ids(const std::vector<uint32_t>& reference, const std::vector<uint8_t>& tie,
                              const std::vector<uint32_t>& ids, int width) {
  Comparison c;
  c.pixels = reference.size();
  for (size_t i = 0; i < reference.size(); ++i) {
    if (reference[i] == ids[i]) continue;
    if (tie[i]) {
      ++c.ties;
    } else {
      if (c.mismatches == 0) {
        c.first_mismatch = "pixel (" + std::to_string(i % size_t(width)) + "," + std::to_string(i / size_t(width)) +
                           "): brute " + std::to_string(int64_t(reference[i] == kNoPrim ? -1 : reference[i])) +
                           " method " + std::to_string(int64_t(ids[i] == kNoPrim ? -1 : ids[i]));
      }
      ++c.mismatches;
    }
  }
  return c;
}

// `accel`: frustum casting's and packets' rays through Embree's BVH (the default), else the k-d tree.
inline std::vector<uint32_t> render_ids(const Scene& scene, const KdTree& tree, const View& view, Method method,
                                        int threads = 2, int leaf_pixels = FrustumCaster::kDefaultLeafPixels,
                                        bool accel = true) {
  RenderOptions options;
  options.method = method;
  options.accel = accel;
  options.leaf_pixels = leaf_pixels;
  options.threads = threads;
  options.shade = false;
  SampleBuffer buffer;
  render_frame(scene, tree, view, options, buffer);
  return id_image(scene, buffer);
}

// A random scene of spheres, triangles, boxes and cones inside [-1,1]^3 (some larger).
inline Scene random_scene(std::mt19937_64& rng, int count) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), size(0.02, 0.4);
  std::uniform_int_distribution<int> kind(0, 9);
  Scene scene;
  scene.materials.push_back({});
  for (int i = 0; i < count; ++i) {
    const Vec3 c(u(rng), u(rng), u(rng));
    const double s = size(rng);
    switch (kind(rng)) {
      case 0: case 1: case 2:
        scene.add_sphere({c, s}, uint32_t(i), 0);
        break;
      case 3: case 4: case 5: case 6: {
        const Vec3 a = c + s * Vec3(u(rng), u(rng), u(rng)), b = c + s * Vec3(u(rng), u(rng), u(rng));
        scene.add_triangle({c, a, b}, uint32_t(i), 0);
        break;
      }
      case 7:
        scene.add_box({Aabb(c, c + s * Vec3(std::abs(u(rng)) + 0.1, std::abs(u(rng)) + 0.1, std::abs(u(rng)) + 0.1))},
                      uint32_t(i), 0);
        break;
      default: {
        const Vec3 d(u(rng), u(rng), u(rng));
        if (glm::length(d) < 0.1) {
          scene.add_sphere({c, s}, uint32_t(i), 0);
        } else {
          scene.add_cone({c, s * 0.5, c + 2.0 * s * glm::normalize(d), s * 0.3 * (kind(rng) % 2)}, uint32_t(i), 0);
        }
        break;
      }
    }
  }
  scene.input_primitives = uint32_t(count);
  return scene;
}

}  // namespace frontier::testing
