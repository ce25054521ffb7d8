// The Mesa baseline: EGL context set-up and teardown, the camera that matches frontier's pixel
// rays, and the three passes (counting, lit, ids) over client vertex arrays. See the header for
// the contracts.
//
// EGL displays are process-wide (one handle per platform and native display) and eglTerminate
// ends every context on them, so a display is terminated only when the last renderer using it
// goes: a small registry counts the renderers per display.
//
// The driver module (swrast_dri.so: llvmpipe, LLVM) is pinned in memory once a context exists:
// eglTerminate would otherwise dlclose it, and every load/unload cycle strands a few hundred
// bytes the driver allocates at load time and frees never (reported by LeakSanitizer as leaks
// from an unknown module). Pinned, the driver stays loaded for the life of the process, its
// load-time state stays reachable, and the next renderer does not reload LLVM.
#include "viewer/mesa_renderer.h"

// EGL without X11 types: Xlib's `#define Status int` would break frontier::Status.
#define EGL_NO_X11 1
#include <EGL/egl.h>
#include <EGL/eglext.h>
// libOpenGL (GLVND) exports every GL entry point up to 4.6, so the prototypes link directly.
#define GL_GLEXT_PROTOTYPES 1
#include <GL/gl.h>
#include <GL/glext.h>

#include <dlfcn.h>
#include <fmt/format.h>
#include <link.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <tuple>

namespace frontier {

struct MesaRenderer::Context {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  EGLSurface surface = EGL_NO_SURFACE;  // a 1×1 pbuffer only when surfaceless contexts are missing
  GLuint framebuffer = 0, color_buffer = 0, depth_buffer = 0;
  GLuint query = 0;
  bool gl_objects = false;  // the GL objects above exist (the context was made current once)
};

namespace {

constexpr uint32_t kBackgroundId = 0xFFFFFFu;

std::mutex& display_mutex() {
  static std::mutex m;
  return m;
}
std::map<EGLDisplay, int>& display_users() {
  static std::map<EGLDisplay, int> users;
  return users;
}

// Initializes `display` for one more renderer (eglInitialize only for the first).
bool acquire_display(EGLDisplay display) {
  std::lock_guard<std::mutex> lock(display_mutex());
  int& users = display_users()[display];
  if (users == 0) {
    EGLint major = 0, minor = 0;
    if (!eglInitialize(display, &major, &minor)) {
      display_users().erase(display);
      return false;
    }
  }
  ++users;
  return true;
}

void release_display(EGLDisplay display) {
  std::lock_guard<std::mutex> lock(display_mutex());
  auto it = display_users().find(display);
  if (it == display_users().end()) return;
  if (--it->second == 0) {
    display_users().erase(it);
    eglTerminate(display);
  }
}

bool has_extension(const char* list, const char* name) {
  if (list == nullptr) return false;
  const size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n) {
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  }
  return false;
}

// dlopen()s every loaded DRI driver module again with RTLD_NODELETE (and never closes the
// handle), so that eglTerminate cannot unload it. Runs under the display mutex.
void pin_driver_modules() {
  std::vector<std::string> modules;
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void* data) {
        const std::string name = info->dlpi_name != nullptr ? info->dlpi_name : "";
        if (name.find("/dri/") != std::string::npos && name.ends_with("_dri.so")) {
          static_cast<std::vector<std::string>*>(data)->push_back(name);
        }
        return 0;
      },
      &modules);
  for (const std::string& module : modules) dlopen(module.c_str(), RTLD_LAZY | RTLD_NOLOAD | RTLD_NODELETE);
}

std::string egl_error(const char* what) { return fmt::format("{} failed (EGL error 0x{:04x})", what, eglGetError()); }

std::string gl_string(GLenum name) {
  const auto* s = reinterpret_cast<const char*>(glGetString(name));
  return s != nullptr ? s : "(null)";
}

uint8_t to_byte(double v) { return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0)); }

void set_id_color(uint8_t* rgba, uint32_t id) {
  for (int v = 0; v < 3; ++v) {
    rgba[4 * v + 0] = static_cast<uint8_t>(id & 0xFF);
    rgba[4 * v + 1] = static_cast<uint8_t>((id >> 8) & 0xFF);
    rgba[4 * v + 2] = static_cast<uint8_t>((id >> 16) & 0xFF);
    rgba[4 * v + 3] = 255;
  }
}

double elapsed_ms(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

// The display: Mesa's surfaceless platform needs no window system; otherwise whatever the
// default display is (X11 or Wayland when one exists). Sets `surfaceless_platform` to which.
bool open_display(MesaRenderer::Context& c, bool& surfaceless_platform, std::string& error) {
  const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  const bool has_surfaceless = has_extension(client_extensions, "EGL_MESA_platform_surfaceless");
  surfaceless_platform = false;
  if (has_surfaceless) {
    c.display = eglGetPlatformDisplay(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    surfaceless_platform = c.display != EGL_NO_DISPLAY && acquire_display(c.display);
    if (!surfaceless_platform) c.display = EGL_NO_DISPLAY;
  }
  if (c.display != EGL_NO_DISPLAY) return true;
  c.display = eglGetDisplay(EGL_DEFAULT_DISPLAY);
  if (c.display != EGL_NO_DISPLAY && acquire_display(c.display)) return true;
  error = "MesaRenderer: " + egl_error(has_surfaceless
                                           ? "eglInitialize on the surfaceless platform and on the default display"
                                           : "eglInitialize on the default display (no EGL_MESA_platform_surfaceless)");
  c.display = EGL_NO_DISPLAY;  // not acquired: the destructor must not release it
  return false;
}

// A desktop OpenGL context on the display, current on this thread (with a 1x1 pbuffer only
// when surfaceless contexts are missing); then the driver module is pinned.
bool create_context(MesaRenderer::Context& c, std::string& error) {
  if (!eglBindAPI(EGL_OPENGL_API)) {
    error = "MesaRenderer: " + egl_error("eglBindAPI(EGL_OPENGL_API) (no desktop OpenGL in this EGL)");
    return false;
  }
  const EGLint config_attributes[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT,
                                      EGL_RED_SIZE, 8, EGL_GREEN_SIZE, 8, EGL_BLUE_SIZE, 8, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint configs = 0;
  if (!eglChooseConfig(c.display, config_attributes, &config, 1, &configs) || configs < 1) {
    error = "MesaRenderer: " + egl_error("eglChooseConfig (no pbuffer-capable desktop OpenGL config)");
    return false;
  }
  // No version or profile attributes: a legacy context, which is the compatibility profile with
  // the highest version the driver offers (fixed-function lighting needs it).
  const EGLint context_attributes[] = {EGL_NONE};
  c.context = eglCreateContext(c.display, config, EGL_NO_CONTEXT, context_attributes);
  if (c.context == EGL_NO_CONTEXT) {
    error = "MesaRenderer: " + egl_error("eglCreateContext (desktop OpenGL, compatibility)");
    return false;
  }
  const char* display_extensions = eglQueryString(c.display, EGL_EXTENSIONS);
  if (!has_extension(display_extensions, "EGL_KHR_surfaceless_context")) {
    const EGLint pbuffer_attributes[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
    c.surface = eglCreatePbufferSurface(c.display, config, pbuffer_attributes);
    if (c.surface == EGL_NO_SURFACE) {
      error = "MesaRenderer: " + egl_error("eglCreatePbufferSurface (no surfaceless contexts either)");
      return false;
    }
  }
  if (!eglMakeCurrent(c.display, c.surface, c.surface, c.context)) {
    error = "MesaRenderer: " + egl_error("eglMakeCurrent");
    return false;
  }
  std::lock_guard<std::mutex> lock(display_mutex());
  pin_driver_modules();
  return true;
}

// The width x height framebuffer object (RGBA8 colour, 24-bit depth) every pass draws into.
// `renderer` names the driver in the messages.
bool create_framebuffer(MesaRenderer::Context& c, int width, int height, const std::string& renderer,
                        std::string& error) {
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_size);
  if (width > max_size || height > max_size) {
    error = fmt::format("MesaRenderer: framebuffer size {}x{} exceeds GL_MAX_RENDERBUFFER_SIZE {} ({})", width,
                        height, max_size, renderer);
    return false;
  }
  glGenFramebuffers(1, &c.framebuffer);
  glGenRenderbuffers(1, &c.color_buffer);
  glGenRenderbuffers(1, &c.depth_buffer);
  glGenQueries(1, &c.query);
  c.gl_objects = true;
  glBindRenderbuffer(GL_RENDERBUFFER, c.color_buffer);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
  glBindRenderbuffer(GL_RENDERBUFFER, c.depth_buffer);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, width, height);
  glBindFramebuffer(GL_FRAMEBUFFER, c.framebuffer);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, c.color_buffer);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, c.depth_buffer);
  glDrawBuffer(GL_COLOR_ATTACHMENT0);
  glReadBuffer(GL_COLOR_ATTACHMENT0);
  const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
  if (status != GL_FRAMEBUFFER_COMPLETE) {
    error = fmt::format("MesaRenderer: framebuffer {}x{} incomplete (status 0x{:04x}, {})", width, height, status,
                        renderer);
    return false;
  }
  return true;
}

// State every pass shares. Dithering would perturb the id colours.
void set_shared_state(int width, int height) {
  glDisable(GL_DITHER);
  glDisable(GL_BLEND);
  glDisable(GL_MULTISAMPLE);
  glEnable(GL_DEPTH_TEST);
  glFrontFace(GL_CCW);
  glCullFace(GL_BACK);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glViewport(0, 0, width, height);
  glEnableClientState(GL_VERTEX_ARRAY);
}

}  // namespace

std::unique_ptr<MesaRenderer> MesaRenderer::create(int width, int height, std::string& error) {
  if (width < 1 || height < 1) {
    error = fmt::format("MesaRenderer: framebuffer size {}x{} is not positive", width, height);
    return nullptr;
  }
  // On failure `r` goes out of scope: its destructor releases whatever was set up.
  std::unique_ptr<MesaRenderer> r(new MesaRenderer());
  r->width_ = width;
  r->height_ = height;
  r->context_ = std::make_unique<Context>();
  Context& c = *r->context_;
  bool surfaceless_platform = false;
  if (!open_display(c, surfaceless_platform, error) || !create_context(c, error)) return nullptr;

  const std::string renderer = gl_string(GL_RENDERER);
  const std::string version = gl_string(GL_VERSION);
  r->software_ = renderer.find("llvmpipe") != std::string::npos || renderer.find("softpipe") != std::string::npos;
  r->renderer_ = renderer + " / " + version;
  if (!r->software_) r->renderer_ += " [NOT a software rasterizer: hardware or unknown driver]";
  if (!surfaceless_platform) r->renderer_ += " [default EGL display, not surfaceless]";

  if (!create_framebuffer(c, width, height, r->renderer_, error)) return nullptr;
  set_shared_state(width, height);
  if (const GLenum e = glGetError(); e != GL_NO_ERROR) {
    error = fmt::format("MesaRenderer: GL error 0x{:04x} while setting up ({})", e, r->renderer_);
    return nullptr;
  }
  return r;
}

MesaRenderer::~MesaRenderer() {
  if (!context_) return;
  Context& c = *context_;
  if (c.display == EGL_NO_DISPLAY) return;
  if (c.context != EGL_NO_CONTEXT) {
    if (c.gl_objects && eglMakeCurrent(c.display, c.surface, c.surface, c.context)) {
      glDeleteQueries(1, &c.query);
      glDeleteFramebuffers(1, &c.framebuffer);
      glDeleteRenderbuffers(1, &c.color_buffer);
      glDeleteRenderbuffers(1, &c.depth_buffer);
    }
    if (eglGetCurrentContext() == c.context) eglMakeCurrent(c.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(c.display, c.context);
  }
  if (c.surface != EGL_NO_SURFACE) eglDestroySurface(c.display, c.surface);
  release_display(c.display);
  eglReleaseThread();
}

void MesaRenderer::make_current() const {
  const Context& c = *context_;
  if (eglGetCurrentContext() != c.context) eglMakeCurrent(c.display, c.surface, c.surface, c.context);
}

Status MesaRenderer::set_scene(const Scene& scene) {
  const size_t n = scene.prims.size();
  if (n >= 0xFFFFFFFFu) return Status::invalid_argument("MesaRenderer: too many primitives");
  for (size_t i = 0; i < n; ++i) {
    const PrimRef& p = scene.prims[i];
    if (p.kind != PrimKind::Triangle) {
      return Status::invalid_argument(
          fmt::format("MesaRenderer: primitive {} is not a triangle (tessellate the scene first)", i));
    }
    if (p.material >= scene.materials.size()) {
      return Status::invalid_argument(fmt::format("MesaRenderer: primitive {} has material {} of {}", i, p.material,
                                                  scene.materials.size()));
    }
  }
  const bool shading_normals = scene.triangle_normals.size() == scene.triangles.size();
  bounds_ = Aabb();
  for (size_t i = 0; i < n; ++i) {
    const Triangle& t = scene.triangles[scene.prims[i].index];
    bounds_.extend(t.v0);
    bounds_.extend(t.v1);
    bounds_.extend(t.v2);
  }
  origin_ = bounds_.empty() ? Vec3(0.0) : bounds_.center();
  triangle_count_ = n;
  positions_.resize(9 * n);
  normals_.resize(9 * n);
  diffuse_.resize(12 * n);
  material_.resize(n);
  source_.resize(n);
  max_source_ = 0;
  for (size_t i = 0; i < n; ++i) {
    const PrimRef& p = scene.prims[i];
    const Triangle& t = scene.triangles[p.index];
    const Vec3 v[3] = {t.v0, t.v1, t.v2};
    Vec3 geometric = glm::cross(t.v1 - t.v0, t.v2 - t.v0);
    const double length = glm::length(geometric);
    geometric = length > 0.0 ? geometric / length : Vec3(0.0, 0.0, 1.0);
    const Material& m = scene.materials[p.material];
    for (int k = 0; k < 3; ++k) {
      Vec3 normal = geometric;
      if (shading_normals) {
        const Vec3 s = scene.triangle_normals[p.index][k];
        const double l = glm::length(s);
        if (l > 0.0 && std::isfinite(l)) normal = s / l;
      }
      const Vec3 local = v[k] - origin_;
      for (int a = 0; a < 3; ++a) {
        positions_[9 * i + 3 * k + a] = static_cast<float>(local[a]);
        normals_[9 * i + 3 * k + a] = static_cast<float>(normal[a]);
      }
      uint8_t* rgba = &diffuse_[12 * i + 4 * k];
      rgba[0] = to_byte(m.color.x * m.kd);
      rgba[1] = to_byte(m.color.y * m.kd);
      rgba[2] = to_byte(m.color.z * m.kd);
      rgba[3] = 255;
    }
    material_[i] = p.material;
    source_[i] = p.source;
    max_source_ = std::max(max_source_, p.source);
  }
  materials_ = scene.materials;
  lights_ = scene.lights;
  background_ = scene.background;
  return Status::ok();
}

Status MesaRenderer::check(const View& view, const std::vector<uint32_t>* order, const MesaOptions& options) const {
  if (view.width != width_ || view.height != height_) {
    return Status::invalid_argument(
        fmt::format("MesaRenderer: view is {}x{}, framebuffer {}x{}", view.width, view.height, width_, height_));
  }
  if (options.chunk_triangles < 1) return Status::invalid_argument("MesaRenderer: chunk_triangles < 1");
  if (order != nullptr) {
    for (const uint32_t i : *order) {
      if (i >= triangle_count_) {
        return Status::invalid_argument(
            fmt::format("MesaRenderer: order names triangle {} of {}", i, triangle_count_));
      }
    }
  }
  return Status::ok();
}

void MesaRenderer::begin_pass(const View& view, const MesaOptions& options) const {
  if (options.cull_back_faces) {
    glEnable(GL_CULL_FACE);
  } else {
    glDisable(GL_CULL_FACE);
  }
  set_camera(view);
}

void MesaRenderer::set_camera(const View& view) const {
  // Depth range from the scene's bounds. A visible point p has view-axis depth
  // z >= |p - eye| / sqrt(1 + half_w² + half_h²) (the frustum's widest ray), so the distance
  // from the eye to the box bounds every visible depth from below.
  const Vec3& f = view.forward;
  double far = 0.0;
  double nearest = 0.0;  // Euclidean distance from the eye to the bounds, 0 inside
  if (!bounds_.empty()) {
    for (int k = 0; k < 8; ++k) {
      const Vec3 corner(k & 1 ? bounds_.hi.x : bounds_.lo.x, k & 2 ? bounds_.hi.y : bounds_.lo.y,
                        k & 4 ? bounds_.hi.z : bounds_.lo.z);
      far = std::max(far, glm::dot(corner - view.eye, f));
    }
    const Vec3 outside = glm::max(bounds_.lo - view.eye, glm::max(view.eye - bounds_.hi, Vec3(0.0)));
    nearest = glm::length(outside);
  }
  if (!(far > 0.0)) far = 1.0;  // nothing in front: any range will do
  far *= 1.001;
  double near = view.near;
  if (!(near > 0.0)) {
    near = 0.999 * nearest / std::sqrt(1.0 + view.half_w * view.half_w + view.half_h * view.half_h);
    near = std::max(near, far * 1e-4);  // eye inside the bounds: a fraction of the scene's depth
  }
  if (!(far > near)) far = 2.0 * near;

  glMatrixMode(GL_PROJECTION);
  glLoadIdentity();
  glFrustum(-view.half_w * near, view.half_w * near, -view.half_h * near, view.half_h * near, near, far);
  // Eye space: x = right, y = up, z = -forward; vertices are relative to origin_.
  const Vec3 t = origin_ - view.eye;
  const Vec3& x = view.right;
  const Vec3& y = view.up;
  const GLdouble modelview[16] = {x.x, y.x, -f.x, 0.0, x.y, y.y, -f.y, 0.0, x.z, y.z, -f.z, 0.0,
                                  glm::dot(x, t), glm::dot(y, t), -glm::dot(f, t), 1.0};
  glMatrixMode(GL_MODELVIEW);
  glLoadMatrixd(modelview);
}

std::pair<int, int> MesaRenderer::set_lights(const MesaOptions& options) const {
  GLint max_lights = 8;
  glGetIntegerv(GL_MAX_LIGHTS, &max_lights);
  const GLfloat zero[4] = {0.0f, 0.0f, 0.0f, 1.0f};
  const GLfloat ambient[4] = {0.1f, 0.1f, 0.1f, 1.0f};
  glLightModelfv(GL_LIGHT_MODEL_AMBIENT, ambient);
  glLightModeli(GL_LIGHT_MODEL_LOCAL_VIEWER, GL_TRUE);
  glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, options.two_sided_lighting ? GL_TRUE : GL_FALSE);
  for (int k = 0; k < max_lights; ++k) glDisable(GL_LIGHT0 + static_cast<GLenum>(k));

  auto set = [&](int k, const GLfloat position[4], const Vec3& color) {
    const GLenum light = GL_LIGHT0 + static_cast<GLenum>(k);
    const GLfloat c[4] = {static_cast<GLfloat>(color.x), static_cast<GLfloat>(color.y), static_cast<GLfloat>(color.z),
                          1.0f};
    glLightfv(light, GL_AMBIENT, zero);
    glLightfv(light, GL_DIFFUSE, c);
    glLightfv(light, GL_SPECULAR, c);
    glLightfv(light, GL_POSITION, position);
    glLightf(light, GL_CONSTANT_ATTENUATION, 1.0f);
    glLightf(light, GL_LINEAR_ATTENUATION, 0.0f);
    glLightf(light, GL_QUADRATIC_ATTENUATION, 0.0f);
    glEnable(light);
  };
  if (lights_.empty()) {
    // Headlight: positioned in eye space, at the eye.
    glPushMatrix();
    glLoadIdentity();
    const GLfloat at_eye[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    set(0, at_eye, Vec3(1.0));
    glPopMatrix();
    return {1, 0};
  }
  const double scale = 1.0 / std::sqrt(static_cast<double>(lights_.size()));
  const int used = std::min(static_cast<int>(lights_.size()), max_lights);
  for (int k = 0; k < used; ++k) {
    const Vec3 p = lights_[k].position - origin_;
    const GLfloat position[4] = {static_cast<GLfloat>(p.x), static_cast<GLfloat>(p.y), static_cast<GLfloat>(p.z),
                                 1.0f};
    set(k, position, lights_[k].color * scale);
  }
  return {used, static_cast<int>(lights_.size()) - used};
}

void MesaRenderer::set_material(uint32_t material) {
  if (material == current_material_) return;
  current_material_ = material;
  const Material& m = materials_[material];
  const GLfloat ambient[4] = {static_cast<GLfloat>(m.color.x), static_cast<GLfloat>(m.color.y),
                              static_cast<GLfloat>(m.color.z), 1.0f};
  const auto ks = static_cast<GLfloat>(std::clamp(m.ks, 0.0, 1.0));
  const GLfloat specular[4] = {ks, ks, ks, 1.0f};
  const GLfloat emission[4] = {0.0f, 0.0f, 0.0f, 1.0f};
  glMaterialfv(GL_FRONT_AND_BACK, GL_AMBIENT, ambient);
  glMaterialfv(GL_FRONT_AND_BACK, GL_SPECULAR, specular);
  glMaterialfv(GL_FRONT_AND_BACK, GL_EMISSION, emission);
  glMaterialf(GL_FRONT_AND_BACK, GL_SHININESS, static_cast<GLfloat>(std::clamp(m.shine, 0.0, 128.0)));
}

uint64_t MesaRenderer::draw(Pass pass, const std::vector<uint32_t>* order, size_t first, size_t last,
                            const MesaOptions& options) {
  const size_t chunk = static_cast<size_t>(options.chunk_triangles);
  const bool lit = pass == Pass::Lit;
  const bool gather = order != nullptr || pass == Pass::Ids;
  if (gather) {
    const size_t m = std::min(chunk, last - first);
    stage_positions_.resize(9 * m);
    if (lit) stage_normals_.resize(9 * m);
    if (pass != Pass::Count) stage_colors_.resize(12 * m);
  }
  uint64_t calls = 0;
  for (size_t begin = first; begin < last; begin += chunk) {
    const size_t count = std::min(chunk, last - begin);
    const float* positions = &positions_[9 * begin];
    const float* normals = lit ? &normals_[9 * begin] : nullptr;
    const uint8_t* colors = pass != Pass::Count ? &diffuse_[12 * begin] : nullptr;
    if (gather) {
      for (size_t k = 0; k < count; ++k) {
        const size_t i = order != nullptr ? (*order)[begin + k] : begin + k;
        std::memcpy(&stage_positions_[9 * k], &positions_[9 * i], 9 * sizeof(float));
        if (lit) {
          std::memcpy(&stage_normals_[9 * k], &normals_[9 * i], 9 * sizeof(float));
          std::memcpy(&stage_colors_[12 * k], &diffuse_[12 * i], 12);
        } else if (pass == Pass::Ids) {
          set_id_color(&stage_colors_[12 * k],
                       options.id_kind == MesaIdKind::Source ? source_[i] : static_cast<uint32_t>(i));
        }
      }
      positions = stage_positions_.data();
      if (lit) normals = stage_normals_.data();
      if (pass != Pass::Count) colors = stage_colors_.data();
    }
    glVertexPointer(3, GL_FLOAT, 0, positions);
    if (lit) glNormalPointer(GL_FLOAT, 0, normals);
    if (colors != nullptr) glColorPointer(4, GL_UNSIGNED_BYTE, 0, colors);
    if (!lit) {
      glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(3 * count));
      ++calls;
      continue;
    }
    // One draw call per run of one material (specular and shininess are glMaterial state).
    size_t run = 0;
    while (run < count) {
      const auto material_of = [&](size_t k) {
        return material_[order != nullptr ? (*order)[begin + k] : begin + k];
      };
      const uint32_t material = material_of(run);
      size_t end = run + 1;
      while (end < count && material_of(end) == material) ++end;
      set_material(material);
      glDrawArrays(GL_TRIANGLES, static_cast<GLint>(3 * run), static_cast<GLsizei>(3 * (end - run)));
      ++calls;
      run = end;
    }
  }
  return calls;
}

Result<MesaFrame> MesaRenderer::render(const View& view, const std::vector<uint32_t>* order,
                                       const MesaOptions& options) {
  if (Status s = check(view, order, options); !s) return s;
  make_current();
  const Context& c = *context_;
  const size_t count = order != nullptr ? order->size() : triangle_count_;
  MesaFrame frame;
  begin_pass(view, options);

  // Counting pass: every fragment rasterized, none written.
  glDisable(GL_LIGHTING);
  glDisableClientState(GL_NORMAL_ARRAY);
  glDisableClientState(GL_COLOR_ARRAY);
  glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  glDepthMask(GL_FALSE);
  glDepthFunc(GL_ALWAYS);
  glBeginQuery(GL_SAMPLES_PASSED, c.query);
  draw(Pass::Count, order, 0, count, options);
  glEndQuery(GL_SAMPLES_PASSED);
  GLuint64 covered = 0;
  glGetQueryObjectui64v(c.query, GL_QUERY_RESULT, &covered);
  frame.pixels_covered = covered;
  glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  glDepthMask(GL_TRUE);
  glDepthFunc(GL_LESS);

  // The lit pass's state, then one triangle drawn untimed (inside a query too: llvmpipe's
  // fragment variants depend on occlusion counting) so that llvmpipe compiles this state's
  // variants before the clock starts; the timed glClear erases it.
  glEnable(GL_LIGHTING);
  glEnable(GL_COLOR_MATERIAL);
  glColorMaterial(GL_FRONT_AND_BACK, GL_DIFFUSE);
  glShadeModel(GL_SMOOTH);
  glEnableClientState(GL_NORMAL_ARRAY);
  glEnableClientState(GL_COLOR_ARRAY);
  std::tie(frame.lights_used, frame.lights_dropped) = set_lights(options);
  current_material_ = 0xFFFFFFFFu;
  glClearColor(static_cast<GLfloat>(background_.x), static_cast<GLfloat>(background_.y),
               static_cast<GLfloat>(background_.z), 1.0f);
  glClearDepth(1.0);
  if (count > 0) {
    glBeginQuery(GL_SAMPLES_PASSED, c.query);
    draw(Pass::Lit, order, 0, 1, options);
    glEndQuery(GL_SAMPLES_PASSED);
  }
  glFinish();

  const auto start = std::chrono::steady_clock::now();
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  glBeginQuery(GL_SAMPLES_PASSED, c.query);
  frame.draw_calls = draw(Pass::Lit, order, 0, count, options);
  glEndQuery(GL_SAMPLES_PASSED);
  glFinish();
  frame.frame_ms = elapsed_ms(start);

  GLuint64 passed = 0;
  glGetQueryObjectui64v(c.query, GL_QUERY_RESULT, &passed);
  frame.samples_passed = passed;
  frame.triangles_issued = count;
  frame.vertices_lit = 3 * static_cast<uint64_t>(count);

  pixels_.resize(4 * static_cast<size_t>(width_) * static_cast<size_t>(height_));
  glReadPixels(0, 0, width_, height_, GL_RGBA, GL_UNSIGNED_BYTE, pixels_.data());
  frame.colors.resize(static_cast<size_t>(width_) * static_cast<size_t>(height_));
  for (int y = 0; y < height_; ++y) {
    const uint8_t* row = &pixels_[4 * static_cast<size_t>(height_ - 1 - y) * static_cast<size_t>(width_)];
    for (int x = 0; x < width_; ++x) {
      frame.colors[static_cast<size_t>(y) * static_cast<size_t>(width_) + static_cast<size_t>(x)] =
          Rgb{row[4 * x] / 255.0f, row[4 * x + 1] / 255.0f, row[4 * x + 2] / 255.0f};
    }
  }
  glDisable(GL_LIGHTING);
  glDisable(GL_COLOR_MATERIAL);
  if (const GLenum e = glGetError(); e != GL_NO_ERROR) {
    return Status::io_error(fmt::format("MesaRenderer: GL error 0x{:04x} in render()", e));
  }
  return frame;
}

Status MesaRenderer::ids(const View& view, std::vector<uint32_t>& ids, const std::vector<uint32_t>* order,
                         const MesaOptions& options) {
  if (Status s = check(view, order, options); !s) return s;
  if (options.id_kind == MesaIdKind::Source ? (triangle_count_ > 0 && max_source_ >= kBackgroundId)
                                            : triangle_count_ > kBackgroundId) {
    return Status::invalid_argument("MesaRenderer: an id does not fit in 24 bits");
  }
  make_current();
  const size_t count = order != nullptr ? order->size() : triangle_count_;
  begin_pass(view, options);
  glDisable(GL_LIGHTING);
  glDisable(GL_COLOR_MATERIAL);
  glShadeModel(GL_FLAT);
  glDisableClientState(GL_NORMAL_ARRAY);
  glEnableClientState(GL_COLOR_ARRAY);
  glDepthFunc(GL_LESS);
  glClearColor(1.0f, 1.0f, 1.0f, 1.0f);  // 0xFFFFFF: background
  glClearDepth(1.0);
  glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  draw(Pass::Ids, order, 0, count, options);
  pixels_.resize(4 * static_cast<size_t>(width_) * static_cast<size_t>(height_));
  glReadPixels(0, 0, width_, height_, GL_RGBA, GL_UNSIGNED_BYTE, pixels_.data());
  glShadeModel(GL_SMOOTH);
  ids.resize(static_cast<size_t>(width_) * static_cast<size_t>(height_));
  for (int y = 0; y < height_; ++y) {
    const uint8_t* row = &pixels_[4 * static_cast<size_t>(height_ - 1 - y) * static_cast<size_t>(width_)];
    for (int x = 0; x < width_; ++x) {
      const uint32_t id = row[4 * x] | (uint32_t{row[4 * x + 1]} << 8) | (uint32_t{row[4 * x + 2]} << 16);
      ids[static_cast<size_t>(y) * static_cast<size_t>(width_) + static_cast<size_t>(x)] =
          id == kBackgroundId ? kNoPrim : id;
    }
  }
  if (const GLenum e = glGetError(); e != GL_NO_ERROR) {
    return Status::io_error(fmt::format("MesaRenderer: GL error 0x{:04x} in ids()", e));
  }
  return Status::ok();
}

}  // namespace frontier
