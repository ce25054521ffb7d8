// Per-pixel Phong shading assembled from what the scene declares (frustum-casting paper §5.3):
// - no lights declared -> one headlight at the eye and no shadow rays at all;
// - point lights -> diffuse + specular per light, shadow rays only as a deferred effect;
// - specular terms only for materials with ks > 0.
// The Effects record says which parts run; counters prove what ran.
#pragma once

#include "src/core/counters.h"
#include "src/engine/cell_gate.h"
#include "src/engine/kdtree.h"
#include "src/core/sample_buffer.h"
#include "src/core/scene.h"

namespace frontier {

struct Effects {
  bool headlight = false;  // scene declares no lights
  bool specular = false;   // some material has ks > 0
  bool shadows = false;    // scene has point lights (shadow rays are possible)

  static Effects declared_by(const Scene& scene);
};

// Shadow rays in a paged tree: the gate that says which cells are missing and the frame's cell
// marks (either may be null). After shade(), `missing` says that a shadow ray crossed a missing
// cell without meeting a blocker: the colour is not final, the cells are wanted, and the
// sample must wait for them (frustum casting parks the pixel).
struct ShadowCells {
  CellGate* gate = nullptr;
  CellMarks* marks = nullptr;
  bool missing = false;
};

class Shader {
 public:
  Shader(const Scene& scene, const KdTree& tree);
  const Effects& effects() const { return effects_; }
  // Colour of a primary-ray sample. `with_shadows` selects the deferred shadow effect (it is
  // ignored when the scene declares no shadow-casting light). With `cells`, shadow rays go
  // through occlusion() with its gate (see ShadowCells).
  Rgb shade(uint32_t prim, const Ray& ray, double t, bool with_shadows, Counters& counters,
            ShadowCells* cells = nullptr) const;
  // The same shading for a surface point given by its material and unit normal (facing the
  // ray or not: flipped as shade() does), without shadows: what renderers that keep no scene
  // index per pixel (the rasterizing culling classes) use.
  Rgb shade_surface(uint32_t material, const Vec3& normal, const Ray& ray, double t, Counters& counters) const;
  Rgb background() const;

 private:
  Vec3 interpolated_normal(uint32_t index, const Vec3& p) const;
  const Scene& scene_;
  const KdTree& tree_;
  Rgb lit(const Material& m, const Vec3& p, const Vec3& n, const Ray& ray, double t, bool with_shadows,
          Counters& counters, ShadowCells* cells) const;
  Effects effects_;
  double light_scale_ = 1.0;
  double epsilon_ = 1e-9;
};

}  // namespace frontier
