// The "Mesa" baseline of the immediate-mode ray-casting paper (Alex & Teller 1999, §4): unmodified
// OpenGL rendering tessellated objects with fixed-function per-vertex lighting, here through the
// Mesa driver the machine has (llvmpipe on a machine without a GPU), offscreen via EGL.
//
// Invariants:
//  * Same camera as frontier: GL pixel (x, height - 1 - y) has its centre exactly on
//    View::ray(x, y) (glFrustum spans ±half_w·n, ±half_h·n); every image this class returns is
//    row-major with the top row first, like frontier's.
//  * The vertex data is fixed by set_scene() (float positions relative to the scene's centre, so
//    precision does not depend on how far from the origin the scene sits; the per-view
//    translation is composed in double). Nothing is kept on the GPU side: every frame sends its
//    vertices from client arrays (glVertexPointer/glNormalPointer/glColorPointer +
//    glDrawArrays(GL_TRIANGLES)), as immediate mode did, so the transfer is part of the frame.
//  * Triangles are issued in the caller's order, in draw calls of at most
//    MesaOptions::chunk_triangles, split where the material changes.
//
// Thread safety: a MesaRenderer's GL context is made current on the calling thread by every
// method; use one renderer from one thread at a time, and do not use it from a thread while
// another thread still has it current (a thread keeps it current until another renderer is used
// on that thread or the renderer is destroyed). Several renderers may exist at once.
#pragma once

#include "src/core/sample_buffer.h"
#include "src/core/scene.h"
#include "src/core/status.h"
#include "src/core/view.h"

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace frontier {

// What the id pass writes per pixel (24 bits through an RGBA8 framebuffer; kNoPrim = background).
enum class MesaIdKind : uint8_t {
  Source,     // PrimRef::source: comparable with the ray caster's id images
  Primitive,  // index into Scene::prims: comparable with rasterize_scene's ids
};

struct MesaOptions {
  bool cull_back_faces = false;  // glCullFace(GL_BACK), front = counter-clockwise seen from the eye
  // GL_LIGHT_MODEL_TWO_SIDE: back faces are lit with the negated normal (frontier's shading also
  // turns the normal towards the viewer). Off: back faces are lit as seen from the front.
  bool two_sided_lighting = true;
  int chunk_triangles = 4096;  // triangles per glDrawArrays at most (>= 1)
  MesaIdKind id_kind = MesaIdKind::Source;
};

struct MesaFrame {
  // Lit colours, top row first, width*height, each channel in [0, 1] (an 8-bit framebuffer).
  std::vector<Rgb> colors;
  // Wall time of the lit pass: gathering the caller's order into the client arrays, glClear,
  // every draw call and glFinish. Excludes set_scene(), the counting pass and the read-back.
  double frame_ms = 0.0;
  uint64_t triangles_issued = 0;  // triangles sent to GL in the lit pass
  uint64_t vertices_lit = 0;      // vertices through fixed-function lighting (3 per triangle)
  uint64_t draw_calls = 0;        // glDrawArrays calls of the lit pass
  // Fragments rasterized (GL_SAMPLES_PASSED in a separate pass with depth func GL_ALWAYS, depth
  // writes off, same culling): what the paper calls pixels covered, depth complexity × pixels.
  uint64_t pixels_covered = 0;
  // Fragments that passed the depth test in the lit pass (GL_SAMPLES_PASSED around its draws).
  uint64_t samples_passed = 0;
  int lights_used = 0;     // GL lights enabled (a headlight at the eye when the scene has none)
  int lights_dropped = 0;  // scene lights beyond GL_MAX_LIGHTS, not rendered
};

class MesaRenderer {
 public:
  // An EGL context (desktop OpenGL, compatibility profile) on Mesa's surfaceless platform, or on
  // the default display with a pbuffer when that platform is missing, rendering into a
  // width×height framebuffer object (RGBA8 colour, 24-bit depth). No window system needed.
  // Returns nullptr and sets `error` (which step failed, with the EGL/GL error code) on failure:
  // a size outside [1, GL_MAX_RENDERBUFFER_SIZE], no EGL, no usable config or context.
  // Side effect: the first success pins the Mesa driver module (…_dri.so) in memory for the rest
  // of the process (see mesa_renderer.cpp: unloading it leaks and reloading LLVM is slow).
  static std::unique_ptr<MesaRenderer> create(int width, int height, std::string& error);
  ~MesaRenderer();
  MesaRenderer(const MesaRenderer&) = delete;
  MesaRenderer& operator=(const MesaRenderer&) = delete;

  int width() const { return width_; }
  int height() const { return height_; }
  // "GL_RENDERER / GL_VERSION", e.g. "llvmpipe (LLVM 15.0.6, 256 bits) / 4.5 (Compatibility
  // Profile) Mesa 22.3.6"; when the renderer is not a Mesa software rasterizer the text ends in
  // " [NOT a software rasterizer: hardware or unknown driver]".
  const std::string& renderer() const { return renderer_; }
  // GL_RENDERER names llvmpipe or softpipe.
  bool is_software() const { return software_; }

  // Copies the scene's triangles (positions, per-vertex normals from Scene::triangle_normals or
  // the geometric normal when it has none, materials, sources) into the client arrays every
  // later render() and ids() draw from, plus its lights and background. Returns
  // InvalidArgument when the scene has a primitive that is not a triangle (tessellate() it
  // first) or a material index out of range. The Scene is not referenced afterwards.
  Status set_scene(const Scene& scene);
  size_t triangles() const { return triangle_count_; }

  // Renders the scene set by set_scene() from `view` with fixed-function lighting: the first
  // GL_MAX_LIGHTS (8) Scene::lights as positional lights without attenuation, each of intensity
  // colour/sqrt(number of scene lights) (the NFF convention frontier's shader follows; lights
  // beyond the eighth are dropped and counted), or one white headlight at the eye when the
  // scene has none; global ambient 0.1; material ambient = colour, diffuse = colour·kd,
  // specular = ks (Blinn-Phong, GL's), shininess = NFF shine clamped to [0, 128]; smooth
  // shading, depth test GL_LESS, background from the scene.
  // `order`: primitive indices to issue, in that order (each at most once for meaningful
  // counters); null issues all triangles in scene order.
  // The first frame with a new GL state (lights, culling, two-sidedness) makes llvmpipe compile
  // shader variants; render() draws the first triangle once before starting the clock (then
  // clears), so frame_ms does not include that compilation.
  // Returns InvalidArgument when view.width/height differ from width()/height(), when an index
  // in `order` is not < triangles(), or when options.chunk_triangles < 1.
  Result<MesaFrame> render(const View& view, const std::vector<uint32_t>* order = nullptr,
                           const MesaOptions& options = {});

  // The id pass: the same geometry and camera with lighting off and each triangle drawn in a
  // flat colour encoding its id (MesaOptions::id_kind, 24 bits), read back into `ids` (resized
  // to width*height, top row first, kNoPrim for background). Returns InvalidArgument as render()
  // does, and when an id does not fit in 24 bits (>= 0xFFFFFF, which is reserved for background).
  Status ids(const View& view, std::vector<uint32_t>& ids, const std::vector<uint32_t>* order = nullptr,
             const MesaOptions& options = {});

  struct Context;  // EGL objects (mesa_renderer.cpp)

 private:
  MesaRenderer() = default;
  void make_current() const;
  Status check(const View& view, const std::vector<uint32_t>* order, const MesaOptions& options) const;
  // The state every pass shares (after make_current): culling and the camera.
  void begin_pass(const View& view, const MesaOptions& options) const;
  void set_camera(const View& view) const;
  // Lights (after set_camera: positions go through the modelview); returns {used, dropped}.
  std::pair<int, int> set_lights(const MesaOptions& options) const;
  void set_material(uint32_t material);
  // Issues triangles [first, last) of `order` (or of scene order when null) in chunks; `pass`
  // selects which arrays are bound. Returns the glDrawArrays calls made.
  enum class Pass { Lit, Ids, Count };
  uint64_t draw(Pass pass, const std::vector<uint32_t>* order, size_t first, size_t last, const MesaOptions& options);

  std::unique_ptr<Context> context_;
  int width_ = 0, height_ = 0;
  std::string renderer_;
  bool software_ = false;

  // Scene data per primitive index: 3 vertices of 3 floats (positions relative to origin_,
  // unit normals), 3 RGBA8 diffuse colours (colour·kd), the material and the source.
  Vec3 origin_{0.0};
  Aabb bounds_;
  size_t triangle_count_ = 0;
  uint32_t max_source_ = 0;
  std::vector<float> positions_, normals_;
  std::vector<uint8_t> diffuse_;
  std::vector<uint32_t> material_, source_;
  std::vector<Material> materials_;
  std::vector<PointLight> lights_;
  Vec3 background_{0.0};
  // Staging arrays the caller's order is gathered into, one chunk at a time.
  std::vector<float> stage_positions_, stage_normals_;
  std::vector<uint8_t> stage_colors_;
  std::vector<uint8_t> pixels_;  // glReadPixels target, RGBA8, bottom row first
  uint32_t current_material_ = 0xFFFFFFFFu;  // glMaterial state of the lit pass
};

}  // namespace frontier
