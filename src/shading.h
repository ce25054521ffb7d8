// Per-pixel Phong shading assembled from what the scene declares (frustum-casting paper §5.3):
// - no lights declared -> one headlight at the eye and no shadow rays at all;
// - point lights -> diffuse + specular per light, shadow rays only as a deferred effect;
// - specular terms only for materials with ks > 0.
// The Effects record says which parts run; counters prove what ran.
#pragma once

#include "src/counters.h"
#include "src/kdtree.h"
#include "src/sample_buffer.h"
#include "src/scene.h"

namespace frontier {

struct Effects {
  bool headlight = false;  // scene declares no lights
  bool specular = false;   // some material has ks > 0
  bool shadows = false;    // scene has point lights (shadow rays are possible)

  static Effects declared_by(const Scene& scene);
};

class Shader {
 public:
  Shader(const Scene& scene, const KdTree& tree);
  const Effects& effects() const { return effects_; }
  // Colour of a primary-ray sample. `with_shadows` selects the deferred shadow effect (it is
  // ignored when the scene declares no shadow-casting light).
  Rgb shade(uint32_t prim, const Ray& ray, double t, bool with_shadows, Counters& counters) const;
  Rgb background() const;

 private:
  const Scene& scene_;
  const KdTree& tree_;
  Effects effects_;
  double light_scale_ = 1.0;
  double epsilon_ = 1e-9;
};

}  // namespace frontier
