// The interactive window of frontier-view (window.h): GLFW events, one Walkthrough frame, the
// CPU-rendered image drawn as a texture and the HUD over it, all on the calling thread (the
// Walkthrough runs its own render threads inside frame()).
//
// The camera is (eye, yaw, pitch) about the start camera's up vector and is turned into a Camera
// the same way every frame, so a camera that did not move is bit-identical to the last one and
// the Walkthrough goes on refining the same image (progressive, paper §5.3). A window whose
// image is complete and whose camera is still waits for events instead of spinning.
//
// Keys: mouse drag (left button) or M (captured mouse) and the arrow keys look around;
// W A S D move, Shift runs (x4); fly mode: E / Space up, Q / C down; wheel or + - change the
// speed; F toggles walk mode (only with a Walker: each frame's desired eye goes through
// Walker::step); P toggles pegging between frame time and sample count (§5.5), [ ] halve and
// double the pegged value; T cycles the cell view (off, top-down map of the store cells touched
// this frame with the view frustum's footprint, that map plus the touched cells' boxes drawn
// over the image); H hides the HUD; R returns to the start camera; Esc quits.
//
// Walk mode leaves the eye to the Walker; an eye that falls well below the model (outside the
// collision grid there is no floor) is put back where walking started, in fly mode. Scripted
// and path runs move as if every frame took 1/30 s, so they are reproducible.
//
// Pegging: P and [ ] change the Walkthrough's budget (Walkthrough::set_budget) for the next
// frames.
#include "viewer/window.h"

#include "src/io/image.h"
#include "src/paging/walker.h"
#include "viewer/hud.h"

#include <GLFW/glfw3.h>
#include <fmt/core.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <string>
#include <vector>

namespace frontier {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kMaxPitch = 89.0 * kPi / 180.0;
constexpr double kMouseRadiansPerPixel = 0.0035;
constexpr double kKeyRadiansPerSecond = 1.6;
constexpr double kScriptedDt = 1.0 / 30.0;  // scripted and path runs move as if at 30 Hz (reproducible)
constexpr double kMaxDt = 0.25;             // a slow frame does not become a teleport
constexpr double kRunFactor = 4.0;
constexpr double kSpeedStep = 1.25;
constexpr size_t kHistory = 120;
constexpr size_t kMaxMapCells = 20000;      // beyond this the map outlines only the touched cells
constexpr double kMiB = 1024.0 * 1024.0;

std::string grouped(uint64_t n) {
  std::string digits = std::to_string(n), out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

std::string& glfw_error() {
  static std::string message;
  return message;
}

void on_glfw_error(int code, const char* description) {
  glfw_error() = fmt::format("GLFW error {}: {}", code, description ? description : "?");
}

// glfwTerminate on every way out of run_window once glfwInit succeeded.
struct GlfwSession {
  ~GlfwSession() { glfwTerminate(); }
};

// What the GLFW callbacks collect between two frames.
struct Input {
  std::vector<int> pressed;  // key presses (and repeats of the speed keys), in order
  double scroll = 0.0;
  double look_x = 0.0, look_y = 0.0;  // cursor travel while looking, in window pixels
  double cursor_x = 0.0, cursor_y = 0.0;
  bool have_cursor = false;
  bool dragging = false;
  bool captured = false;
};

Input& input_of(GLFWwindow* window) { return *static_cast<Input*>(glfwGetWindowUserPointer(window)); }

void on_key(GLFWwindow* window, int key, int, int action, int) {
  const bool speed_key = key == GLFW_KEY_EQUAL || key == GLFW_KEY_KP_ADD || key == GLFW_KEY_MINUS ||
                         key == GLFW_KEY_KP_SUBTRACT;
  if (action == GLFW_PRESS || (action == GLFW_REPEAT && speed_key)) input_of(window).pressed.push_back(key);
}

void on_mouse_button(GLFWwindow* window, int button, int action, int) {
  if (button == GLFW_MOUSE_BUTTON_LEFT) input_of(window).dragging = action == GLFW_PRESS;
}

void on_cursor(GLFWwindow* window, double x, double y) {
  Input& in = input_of(window);
  if (in.have_cursor && (in.dragging || in.captured)) {
    in.look_x += x - in.cursor_x;
    in.look_y += y - in.cursor_y;
  }
  in.cursor_x = x;
  in.cursor_y = y;
  in.have_cursor = true;
}

void on_scroll(GLFWwindow* window, double, double dy) { input_of(window).scroll += dy; }

// The viewer's camera: an eye and yaw / pitch about a fixed up vector, with e1, e2 spanning the
// ground plane (e2 = up x e1, so the top-down map is not mirrored).
class Rig {
 public:
  explicit Rig(const Camera& start) : base_(start) {
    up_ = glm::length(start.up) > 0.0 ? glm::normalize(start.up) : Vec3(0.0, 0.0, 1.0);
    // e1: the world axis farthest from up, made perpendicular to it.
    const Vec3 axes[3] = {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
    Vec3 best = axes[0];
    for (const Vec3& a : axes) {
      if (std::abs(glm::dot(a, up_)) < std::abs(glm::dot(best, up_))) best = a;
    }
    e1_ = glm::normalize(best - glm::dot(best, up_) * up_);
    e2_ = glm::cross(up_, e1_);
    reset();
  }

  void reset() {
    eye = base_.eye;
    heading(base_.look_at - base_.eye, yaw, pitch);
    pitch = std::clamp(pitch, -kMaxPitch, kMaxPitch);
  }

  // Yaw and pitch of a direction (0, 0 for a zero one).
  void heading(const Vec3& direction, double& yaw_out, double& pitch_out) const {
    const double length = glm::length(direction);
    yaw_out = pitch_out = 0.0;
    if (!(length > 0.0)) return;
    const Vec3 f = direction / length;
    pitch_out = std::asin(std::clamp(glm::dot(f, up_), -1.0, 1.0));
    const Vec3 h = f - glm::dot(f, up_) * up_;
    if (glm::length(h) > 1e-12) yaw_out = std::atan2(glm::dot(h, e2_), glm::dot(h, e1_));
  }

  void look(double dyaw, double dpitch) {
    yaw = std::remainder(yaw + dyaw, 2.0 * kPi);
    pitch = std::clamp(pitch + dpitch, -kMaxPitch, kMaxPitch);
  }

  Vec3 level_forward() const { return std::cos(yaw) * e1_ + std::sin(yaw) * e2_; }
  Vec3 forward() const { return std::cos(pitch) * level_forward() + std::sin(pitch) * up_; }
  Vec3 right() const { return glm::cross(level_forward(), up_); }
  const Vec3& up() const { return up_; }
  // Ground-plane coordinates of a point (the map's axes).
  double ground_x(const Vec3& p) const { return glm::dot(p, e1_); }
  double ground_y(const Vec3& p) const { return glm::dot(p, e2_); }
  // The ground-plane rectangle a box projects to (grown into lo/hi).
  void ground_extent(const Aabb& box, double& lo_x, double& hi_x, double& lo_y, double& hi_y) const {
    for (int k = 0; k < 8; ++k) {
      const Vec3 p(k & 1 ? box.hi.x : box.lo.x, k & 2 ? box.hi.y : box.lo.y, k & 4 ? box.hi.z : box.lo.z);
      lo_x = std::min(lo_x, ground_x(p));
      hi_x = std::max(hi_x, ground_x(p));
      lo_y = std::min(lo_y, ground_y(p));
      hi_y = std::max(hi_y, ground_y(p));
    }
  }

  Camera camera() const {
    Camera c = base_;
    c.eye = eye;
    c.look_at = eye + forward();
    c.up = up_;
    return c;
  }

  Vec3 eye{0.0};
  double yaw = 0.0, pitch = 0.0;

 private:
  Camera base_;
  Vec3 up_, e1_, e2_;
};

enum class Peg { Complete, Time, Samples };
enum class CellView { Off, Map, MapAndBoxes };

struct History {
  hud::Series frame_ms{kHistory}, stall_ms{kHistory}, samples{kHistory}, touched{kHistory}, paged_in{kHistory},
      resident_mib{kHistory}, read_mib{kHistory};

  void push(const FrameReport& r) {
    frame_ms.push(r.frame_ms);
    stall_ms.push(r.stall_ms);
    samples.push(double(r.samples));
    touched.push(double(r.cells_touched));
    paged_in.push(double(r.cells_paged_in));
    resident_mib.push(double(r.resident_bytes) / kMiB);
    read_mib.push(double(r.bytes_read) / kMiB);
  }
};

// Pixel rectangle, y down.
struct Rect {
  float x = 0, y = 0, w = 0, h = 0;
};

const hud::Color kWhite{1.0f, 1.0f, 1.0f, 1.0f};
const hud::Color kGrey{0.75f, 0.75f, 0.75f, 1.0f};
const hud::Color kYellow{1.0f, 0.9f, 0.3f, 1.0f};
const hud::Color kOrange{1.0f, 0.55f, 0.15f, 1.0f};
const hud::Color kCyan{0.35f, 0.9f, 1.0f, 1.0f};
const hud::Color kGreen{0.45f, 1.0f, 0.45f, 1.0f};
const hud::Color kBlue{0.45f, 0.6f, 1.0f, 1.0f};
const hud::Color kRed{1.0f, 0.35f, 0.35f, 1.0f};
const hud::Color kMagenta{1.0f, 0.45f, 0.9f, 1.0f};
const hud::Color kPanel{0.0f, 0.0f, 0.0f, 0.55f};

hud::Color with_alpha(hud::Color c, float a) {
  c.a = a;
  return c;
}

class WindowSession {
 public:
  WindowSession(Walkthrough& walk, const WindowOptions& options, Walker* walker, GLFWwindow* window)
      : walk_(walk), options_(options), walker_(walker), window_(window), rig_(options.start), speed_(options.speed) {
    if (!(speed_ > 0.0) || !std::isfinite(speed_)) speed_ = 1.0;
    walking_ = options.start_walking && walker_ != nullptr;
    walk_start_eye_ = rig_.eye;
    budget_ = options.budget;
    peg_ = budget_.ms > 0.0 ? Peg::Time : budget_.samples > 0 ? Peg::Samples : Peg::Complete;
    peg_ms_ = budget_.ms > 0.0 ? budget_.ms : 1000.0 / 30.0;
    peg_samples_ = budget_.samples;  // 0: a quarter of the image, once its size is known
    const auto& cells = walk_.model().cells();
    for (const StoreCell& c : cells) {
      if (c.page == StoreCell::kNoPage || c.content.empty()) continue;
      extend_map(c.content);
      ++content_cells_;
    }
    if (content_cells_ == 0) extend_map(walk_.model().info().bounds);
    const Aabb& bounds = walk_.model().info().bounds;
    if (!bounds.empty()) {
      lowest_ = kInfinity;
      for (int k = 0; k < 8; ++k) {
        const Vec3 p(k & 1 ? bounds.hi.x : bounds.lo.x, k & 2 ? bounds.hi.y : bounds.lo.y, k & 4 ? bounds.hi.z : bounds.lo.z);
        lowest_ = std::min(lowest_, glm::dot(p, rig_.up()));
      }
    }
    glGenTextures(1, &texture_);
  }

  ~WindowSession() { glDeleteTextures(1, &texture_); }

  int run();

 private:
  void extend_map(const Aabb& box) { rig_.ground_extent(box, map_lo_x_, map_hi_x_, map_lo_y_, map_hi_y_); }

  bool frames_done(int shown) const {
    if (options_.frames > 0) return shown >= options_.frames;
    return !options_.path.empty() && size_t(shown) >= options_.path.size();
  }
  bool scripted() const { return static_cast<bool>(options_.script) || !options_.path.empty(); }

  void handle_key(int key);
  void set_walking(bool on);
  void check_fell_out();
  void toggle_peg();
  void scale_peg(double factor);
  Camera next_camera(int frame, const std::vector<int>& script_keys, double dt);
  void show_window_for(int image_w, int image_h);
  void draw();
  void upload_image();
  void draw_text_panel(float scale);
  void draw_charts(int fb_w, int fb_h, float scale);
  void draw_map(const Rect& area, float scale);
  void draw_boxes(const Rect& image_rect, int fb_h);
  void notice(std::string text) {
    notice_ = std::move(text);
    notice_until_ = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  }
  Status screenshot(const std::string& path);

  Walkthrough& walk_;
  const WindowOptions& options_;
  Walker* walker_;
  GLFWwindow* window_;
  Input input_;
  Rig rig_;
  double speed_;
  bool walking_ = false;
  bool walker_settled_ = false;
  Vec3 walk_start_eye_{0.0};
  double lowest_ = -kInfinity;  // the model's lowest point along up
  FrameBudget budget_;
  Peg peg_ = Peg::Complete;
  double peg_ms_ = 0.0;
  uint64_t peg_samples_ = 0;
  CellView cell_view_ = CellView::Map;
  bool show_hud_ = true;
  bool quit_ = false;
  bool shown_ = false;
  FrameReport last_;
  History history_;
  std::vector<uint32_t> touched_;
  std::string notice_;
  std::chrono::steady_clock::time_point notice_until_;
  unsigned texture_ = 0;
  int texture_w_ = 0, texture_h_ = 0;
  double map_lo_x_ = kInfinity, map_hi_x_ = -kInfinity, map_lo_y_ = kInfinity, map_hi_y_ = -kInfinity;
  size_t content_cells_ = 0;
};

void WindowSession::set_walking(bool on) {
  if (on && walker_ == nullptr) {
    notice("no walk mode: the store has no collision grid (frontier-build --walkable)");
    return;
  }
  walking_ = on;
  walker_settled_ = false;
  walk_start_eye_ = rig_.eye;
  if (walker_ != nullptr) walker_->reset();
}

void WindowSession::check_fell_out() {
  // Outside the collision grid there is no floor and the walker falls for ever (walker.h leaves
  // it to the caller): well below the model, go back to where walking started, flying.
  if (!walking_ || walker_->on_floor()) return;
  const double limit = lowest_ - 4.0 * walker_->params().eye_height;
  if (glm::dot(rig_.eye, rig_.up()) >= limit) return;
  rig_.eye = walk_start_eye_;
  set_walking(false);
  notice("fell out of the model: back to fly mode where walking started");
}

void WindowSession::toggle_peg() {
  peg_ = peg_ == Peg::Time ? Peg::Samples : Peg::Time;
  scale_peg(1.0);
}

void WindowSession::scale_peg(double factor) {
  FrameBudget b;
  if (peg_ == Peg::Time) {
    peg_ms_ = std::clamp(peg_ms_ * factor, 1.0, 60000.0);
    b.ms = peg_ms_;
  } else if (peg_ == Peg::Samples) {
    peg_samples_ = std::clamp<uint64_t>(uint64_t(double(peg_samples_) * factor + 0.5), 1000, 1ull << 32);
    b.samples = peg_samples_;
  } else {
    return;
  }
  budget_ = b;
  walk_.set_budget(budget_);
}

void WindowSession::handle_key(int key) {
  switch (key) {
    case GLFW_KEY_ESCAPE: quit_ = true; break;
    case GLFW_KEY_F: set_walking(!walking_); break;
    case GLFW_KEY_P: toggle_peg(); break;
    case GLFW_KEY_LEFT_BRACKET: scale_peg(0.5); break;
    case GLFW_KEY_RIGHT_BRACKET: scale_peg(2.0); break;
    case GLFW_KEY_T:
      cell_view_ = cell_view_ == CellView::Off ? CellView::Map
                   : cell_view_ == CellView::Map ? CellView::MapAndBoxes : CellView::Off;
      break;
    case GLFW_KEY_H: show_hud_ = !show_hud_; break;
    case GLFW_KEY_R:
      rig_.reset();
      set_walking(walking_);
      break;
    case GLFW_KEY_M:
      input_.captured = !input_.captured;
      glfwSetInputMode(window_, GLFW_CURSOR, input_.captured ? GLFW_CURSOR_DISABLED : GLFW_CURSOR_NORMAL);
      if (glfwRawMouseMotionSupported()) glfwSetInputMode(window_, GLFW_RAW_MOUSE_MOTION, input_.captured);
      break;
    case GLFW_KEY_EQUAL:
    case GLFW_KEY_KP_ADD: speed_ = std::min(speed_ * kSpeedStep, 1e6); break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT: speed_ = std::max(speed_ / kSpeedStep, 1e-3); break;
    default: break;
  }
}

Camera WindowSession::next_camera(int frame, const std::vector<int>& script_keys, double dt) {
  const auto held = [&](int key) {
    return glfwGetKey(window_, key) == GLFW_PRESS ||
           std::find(script_keys.begin(), script_keys.end(), key) != script_keys.end();
  };
  if (!options_.path.empty()) {
    // Replay: the path gives the camera (in walk mode, the eye the walker wants, as headless).
    Camera cam = options_.path[std::min(size_t(frame), options_.path.size() - 1)];
    if (walking_) {
      const Vec3 look = cam.look_at - cam.eye;
      rig_.eye = walker_settled_ ? walker_->step(rig_.eye, cam.eye, dt) : walker_->step(cam.eye, cam.eye, 0.0);
      walker_settled_ = true;
      cam.eye = rig_.eye;
      cam.look_at = rig_.eye + look;
    }
    return cam;
  }

  // Look.
  double dyaw = -input_.look_x * kMouseRadiansPerPixel, dpitch = -input_.look_y * kMouseRadiansPerPixel;
  input_.look_x = input_.look_y = 0.0;
  if (held(GLFW_KEY_LEFT)) dyaw += kKeyRadiansPerSecond * dt;
  if (held(GLFW_KEY_RIGHT)) dyaw -= kKeyRadiansPerSecond * dt;
  if (held(GLFW_KEY_UP)) dpitch += kKeyRadiansPerSecond * dt;
  if (held(GLFW_KEY_DOWN)) dpitch -= kKeyRadiansPerSecond * dt;
  if (dyaw != 0.0 || dpitch != 0.0) rig_.look(dyaw, dpitch);

  // Move: in fly mode along the view direction and up; in walk mode on the ground plane, and
  // the walker decides where the eye really goes.
  const Vec3 forward = walking_ ? rig_.level_forward() : rig_.forward();
  Vec3 move(0.0);
  if (held(GLFW_KEY_W)) move += forward;
  if (held(GLFW_KEY_S)) move -= forward;
  if (held(GLFW_KEY_D)) move += rig_.right();
  if (held(GLFW_KEY_A)) move -= rig_.right();
  if (!walking_) {
    if (held(GLFW_KEY_E) || held(GLFW_KEY_SPACE)) move += rig_.up();
    if (held(GLFW_KEY_Q) || held(GLFW_KEY_C)) move -= rig_.up();
  }
  if (glm::length(move) > 0.0) {
    const bool run = held(GLFW_KEY_LEFT_SHIFT) || held(GLFW_KEY_RIGHT_SHIFT);
    move = glm::normalize(move) * (speed_ * (run ? kRunFactor : 1.0) * dt);
  }
  if (walking_) {
    if (!walker_settled_) {
      rig_.eye = walker_->step(rig_.eye, rig_.eye, 0.0);
      walker_settled_ = true;
    }
    rig_.eye = walker_->step(rig_.eye, rig_.eye + move, dt);
    check_fell_out();
  } else {
    rig_.eye += move;
  }
  return rig_.camera();
}

void WindowSession::show_window_for(int image_w, int image_h) {
  // Twice the image when the screen has room for it (a 640x480 image is small on a desktop).
  int area_x = 0, area_y = 0, area_w = 0, area_h = 0;
  if (GLFWmonitor* monitor = glfwGetPrimaryMonitor()) glfwGetMonitorWorkarea(monitor, &area_x, &area_y, &area_w, &area_h);
  int w = image_w, h = image_h;
  if (area_w > 0 && area_h > 0) {
    if (2 * image_w <= area_w && 2 * image_h + 40 <= area_h) {
      w = 2 * image_w;
      h = 2 * image_h;
    } else if (image_w > area_w || image_h + 40 > area_h) {
      const double s = std::min(double(area_w) / image_w, double(area_h - 40) / image_h);
      w = std::max(1, int(image_w * s));
      h = std::max(1, int(image_h * s));
    }
  }
  glfwSetWindowSize(window_, w, h);
  glfwShowWindow(window_);
  shown_ = true;
}

void WindowSession::upload_image() {
  const int w = walk_.view().width, h = walk_.view().height;
  const std::vector<Rgb>& image = walk_.image();
  if (w <= 0 || h <= 0 || image.size() != size_t(w) * size_t(h)) return;
  glBindTexture(GL_TEXTURE_2D, texture_);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 4);  // rows of 12-byte pixels
  if (w != texture_w_ || h != texture_h_) {
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB8, w, h, 0, GL_RGB, GL_FLOAT, image.data());
    texture_w_ = w;
    texture_h_ = h;
  } else {
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_RGB, GL_FLOAT, image.data());
  }
}

void WindowSession::draw() {
  int fb_w = 0, fb_h = 0;
  glfwGetFramebufferSize(window_, &fb_w, &fb_h);
  if (fb_w <= 0 || fb_h <= 0) return;  // minimized
  glClearColor(0.08f, 0.08f, 0.09f, 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  hud::begin(fb_w, fb_h);

  // The image, as large as fits with its aspect kept; row 0 (the top row) at texture t = 0.
  Rect image_rect;
  if (texture_w_ > 0) {
    const float s = std::min(float(fb_w) / float(texture_w_), float(fb_h) / float(texture_h_));
    image_rect.w = float(texture_w_) * s;
    image_rect.h = float(texture_h_) * s;
    image_rect.x = std::floor((float(fb_w) - image_rect.w) * 0.5f);
    image_rect.y = std::floor((float(fb_h) - image_rect.h) * 0.5f);
    glEnable(GL_TEXTURE_2D);
    glBindTexture(GL_TEXTURE_2D, texture_);
    glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_REPLACE);
    glDisable(GL_BLEND);
    glBegin(GL_QUADS);
    glTexCoord2f(0.0f, 0.0f);
    glVertex2f(image_rect.x, image_rect.y);
    glTexCoord2f(1.0f, 0.0f);
    glVertex2f(image_rect.x + image_rect.w, image_rect.y);
    glTexCoord2f(1.0f, 1.0f);
    glVertex2f(image_rect.x + image_rect.w, image_rect.y + image_rect.h);
    glTexCoord2f(0.0f, 1.0f);
    glVertex2f(image_rect.x, image_rect.y + image_rect.h);
    glEnd();
    glDisable(GL_TEXTURE_2D);
    glEnable(GL_BLEND);
  }
  if (cell_view_ == CellView::MapAndBoxes && texture_w_ > 0) {
    draw_boxes(image_rect, fb_h);
    hud::begin(fb_w, fb_h);
  }
  if (!show_hud_) return;
  const float scale = fb_h >= 700 ? 2.0f : 1.0f;
  draw_text_panel(scale);
  draw_charts(fb_w, fb_h, scale);
  if (cell_view_ != CellView::Off) {
    const float side = std::floor(std::min(float(fb_w) * 0.34f, float(fb_h) * 0.42f));
    draw_map(Rect{float(fb_w) - side - 8.0f, 8.0f, side, side}, scale);
  }
}

void WindowSession::draw_text_panel(float scale) {
  const FrameReport& r = last_;
  std::vector<std::pair<std::string, hud::Color>> lines;
  std::string peg;
  switch (peg_) {
    case Peg::Time: peg = fmt::format("peg frame time {:.0f} ms", peg_ms_); break;
    case Peg::Samples: peg = fmt::format("peg samples {}", grouped(budget_.samples)); break;
    case Peg::Complete: peg = "no peg: complete images"; break;
  }
  std::string mode = walking_ ? "WALK" : "FLY";
  if (walking_) mode += walker_->on_floor() ? " (on floor)" : " (falling)";
  if (r.visibility != Visibility::kFrustumAdvance) {
    // The rasterizing classes render complete frames whatever the peg.
    peg = fmt::format("{}: complete frames", visibility_name(r.visibility));
  }
  lines.emplace_back(fmt::format("{}  {:.2g} m/s  {}", mode, speed_, peg), walking_ ? kGreen : kYellow);
  if (r.cull) {
    lines.emplace_back(fmt::format("nodes {}  primitives touched {}  rasterized {}  fragments {}", grouped(r.nodes_touched),
                                   grouped(r.primitives_touched), grouped(r.cull->primitives_rasterized),
                                   grouped(r.pixels_rasterized)),
                       kWhite);
  }
  const double filled = r.pixels ? 100.0 * double(r.image_samples) / double(r.pixels) : 0.0;
  lines.emplace_back(fmt::format("frame {}  {:.1f} ms (stall {:.1f}{})  samples {}  image {:.0f}%{}", r.frame,
                                 r.frame_ms, r.stall_ms,
                                 r.floor_ms > 0.0 ? fmt::format(", sample floor +{:.1f}", r.floor_ms) : "",
                                 grouped(r.samples), filled,
                                 r.complete ? (r.shadows ? " complete+shadows" : " complete") : ""),
                     kWhite);
  lines.emplace_back(fmt::format("cells touched {}  paged in {}  evicted {}  parked {}{}", grouped(r.cells_touched),
                                 grouped(r.cells_paged_in), grouped(r.cells_evicted), grouped(r.parked),
                                 r.page_errors ? fmt::format("  PAGE ERRORS {}", r.page_errors) : ""),
                     r.page_errors ? kRed : kWhite);
  lines.emplace_back(fmt::format("resident {:.1f} of {:.0f} MiB ({} cells)  read {:.2f} MiB", double(r.resident_bytes) / kMiB,
                                 double(r.cache_budget) / kMiB, grouped(r.resident_cells), double(r.bytes_read) / kMiB),
                     kWhite);
  if (walker_ != nullptr) {
    // Walk mode's collision grid, paged on its own budget (--collision-cache).
    const CollisionGrid::Counters c = walker_->grid().counters();
    lines.emplace_back(fmt::format("collision {:.1f} of {:.0f} MiB ({} of {} bricks, {} read){}",
                                   double(c.resident_bytes) / kMiB, double(c.budget_bytes) / kMiB, grouped(c.resident),
                                   grouped(c.bricks), grouped(c.loads),
                                   c.errors ? fmt::format("  BRICK ERRORS {}", c.errors) : ""),
                       c.errors ? kRed : kWhite);
  }
  const View& view = walk_.view();
  double yaw = 0.0, pitch = 0.0;
  rig_.heading(view.forward, yaw, pitch);  // of the image shown (a replayed path moves it, not the rig)
  lines.emplace_back(fmt::format("eye {:.2f} {:.2f} {:.2f}  yaw {:.0f}  pitch {:.0f}", view.eye.x, view.eye.y,
                                 view.eye.z, yaw * 180.0 / kPi, pitch * 180.0 / kPi),
                     kGrey);
  if (!notice_.empty() && std::chrono::steady_clock::now() < notice_until_) lines.emplace_back(notice_, kRed);

  const float lh = hud::line_height(scale), pad = 4.0f * scale;
  float width = 0.0f;
  for (const auto& [text, color] : lines) width = std::max(width, hud::text_width(text, scale));
  hud::fill_rect(8.0f, 8.0f, width + 2.0f * pad, lh * float(lines.size()) + 2.0f * pad - 2.0f * scale, kPanel);
  float y = 8.0f + pad;
  for (const auto& [text, color] : lines) {
    hud::text(8.0f + pad, y, text, scale, color);
    y += lh;
  }
}

void WindowSession::draw_charts(int fb_w, int fb_h, float scale) {
  const FrameReport& r = last_;
  const float lh = hud::line_height(scale), margin = 8.0f;
  // Key help along the bottom: one line when it fits, else two.
  const std::string help1 = walking_ ? "WASD walk  Shift run  drag/arrows look  M capture mouse  wheel/+- speed  F fly"
                                     : "WASD fly  E/Space up  Q/C down  Shift run  drag/arrows look  M capture mouse  wheel/+- speed  F walk";
  const std::string help2 = "P peg time/samples  [ ] peg value  T cells view  H hud  R reset  Esc quit";
  const bool one_line = hud::text_width(help1 + "  " + help2, scale) + 2.0f * margin <= float(fb_w);
  const float help_h = lh * (one_line ? 1.0f : 2.0f) + 2.0f;
  {
    float y = float(fb_h) - margin - help_h + 4.0f;
    if (one_line) {
      hud::text(margin, y, help1 + "  " + help2, scale, kGrey);
    } else {
      hud::text(margin, y, help1, scale, kGrey);
      hud::text(margin, y + lh, help2, scale, kGrey);
    }
  }
  const float h = std::floor(lh * 4.5f);
  const int n = 5;
  const float w = std::floor((float(fb_w) - margin * float(n + 1)) / float(n));
  const float y = float(fb_h) - margin - h - help_h;
  float x = margin;
  const auto next = [&] {
    const float at = x;
    x += w + margin;
    return at;
  };
  {
    const hud::ChartSeries s[] = {{&history_.frame_ms, kYellow, fmt::format("{:.1f}", r.frame_ms)},
                                  {&history_.stall_ms, kRed, fmt::format("stall {:.1f}", r.stall_ms)}};
    hud::strip_chart(next(), y, w, h, s, peg_ == Peg::Time ? peg_ms_ : 0.0, "ms", "", scale);
  }
  {
    const hud::ChartSeries s[] = {{&history_.samples, kGreen, grouped(r.samples)}};
    hud::strip_chart(next(), y, w, h, s, peg_ == Peg::Samples ? double(budget_.samples) : 0.0, "samples", "", scale);
  }
  {
    const hud::ChartSeries s[] = {{&history_.touched, kOrange, fmt::format("touched {}", r.cells_touched)},
                                  {&history_.paged_in, kCyan, fmt::format("in {}", r.cells_paged_in)}};
    hud::strip_chart(next(), y, w, h, s, 0.0, "cells", "", scale);
  }
  {
    const hud::ChartSeries s[] = {{&history_.resident_mib, kBlue, fmt::format("{:.1f}", double(r.resident_bytes) / kMiB)}};
    hud::strip_chart(next(), y, w, h, s, double(r.cache_budget) / kMiB, "resident", " MiB", scale);
  }
  {
    const hud::ChartSeries s[] = {{&history_.read_mib, kMagenta, fmt::format("{:.2f}", double(r.bytes_read) / kMiB)}};
    hud::strip_chart(next(), y, w, h, s, 0.0, "read", " MiB", scale);
  }
}

void WindowSession::draw_map(const Rect& area, float scale) {
  const float lh = hud::line_height(scale), pad = 4.0f;
  hud::fill_rect(area.x, area.y, area.w, area.h, hud::Color{0.0f, 0.0f, 0.0f, 0.85f});
  hud::outline_rect(area.x, area.y, area.w, area.h, with_alpha(kWhite, 0.5f));
  const Rect plot{area.x + pad, area.y + lh + pad, area.w - 2.0f * pad, area.h - lh - 2.0f * pad};
  const View& view = walk_.view();
  // The model's extent and the eye, centred in the plot at one scale, with a margin.
  double lo_x = map_lo_x_, hi_x = map_hi_x_, lo_y = map_lo_y_, hi_y = map_hi_y_;
  if (view.width > 0) {
    lo_x = std::min(lo_x, rig_.ground_x(view.eye));
    hi_x = std::max(hi_x, rig_.ground_x(view.eye));
    lo_y = std::min(lo_y, rig_.ground_y(view.eye));
    hi_y = std::max(hi_y, rig_.ground_y(view.eye));
  }
  if (!(hi_x >= lo_x) || !(hi_y >= lo_y)) return;
  const double span_x = std::max(hi_x - lo_x, 1e-9) * 1.04, span_y = std::max(hi_y - lo_y, 1e-9) * 1.04;
  const double k = std::min(double(plot.w) / span_x, double(plot.h) / span_y);
  const double cx = 0.5 * (lo_x + hi_x), cy = 0.5 * (lo_y + hi_y);
  const auto px = [&](double gx) { return float(double(plot.x) + 0.5 * plot.w + (gx - cx) * k); };
  const auto py = [&](double gy) { return float(double(plot.y) + 0.5 * plot.h - (gy - cy) * k); };
  const auto footprint = [&](const Aabb& box, float& x0, float& y0, float& x1, float& y1) {
    double lx = kInfinity, hx = -kInfinity, ly = kInfinity, hy = -kInfinity;
    rig_.ground_extent(box, lx, hx, ly, hy);
    x0 = px(lx);
    x1 = px(hx);
    y0 = py(hy);
    y1 = py(ly);
  };

  int fb_w = 0, fb_h = 0;
  glfwGetFramebufferSize(window_, &fb_w, &fb_h);
  glEnable(GL_SCISSOR_TEST);
  glScissor(int(plot.x), fb_h - int(plot.y + plot.h), int(plot.w), int(plot.h));

  const auto& cells = walk_.model().cells();
  // Every cell with content, faintly; resident ones tinted.
  if (cells.size() <= kMaxMapCells) {
    for (uint32_t c = 0; c < cells.size(); ++c) {
      if (cells[c].page == StoreCell::kNoPage) continue;
      float x0, y0, x1, y1;
      footprint(cells[c].bounds, x0, y0, x1, y1);
      if (walk_.world().resident(c)) hud::fill_rect(x0, y0, x1 - x0, y1 - y0, with_alpha(kBlue, 0.12f));
      hud::outline_rect(x0, y0, x1 - x0, y1 - y0, hud::Color{0.6f, 0.6f, 0.6f, 0.25f});
    }
  }
  // The cells this image touched.
  for (uint32_t c : touched_) {
    if (c >= cells.size()) continue;
    float x0, y0, x1, y1;
    footprint(cells[c].bounds, x0, y0, x1, y1);
    hud::fill_rect(x0, y0, x1 - x0, y1 - y0, with_alpha(kOrange, 0.18f));
    hud::outline_rect(x0, y0, x1 - x0, y1 - y0, with_alpha(kOrange, 0.9f));
  }
  // The view frustum's footprint: the eye and the rays through the image corners, on the ground.
  if (view.width > 0) {
    const float ex = px(rig_.ground_x(view.eye)), ey = py(rig_.ground_y(view.eye));
    const double reach = std::hypot(span_x, span_y) * k * 2.0;  // past the plot: clipped
    std::vector<std::pair<float, float>> ends;
    for (int c = 0; c < 4; ++c) {
      const Vec3 d = view.forward + (c & 1 ? 1.0 : -1.0) * view.half_w * view.right + (c & 2 ? 1.0 : -1.0) * view.half_h * view.up;
      const double gx = rig_.ground_x(d), gy = rig_.ground_y(d), len = std::hypot(gx, gy);
      if (len < 1e-9) continue;
      ends.emplace_back(float(ex + gx / len * reach), float(ey - gy / len * reach));
    }
    // The wedge between the two outermost corner rays (as seen from above).
    const double fx = rig_.ground_x(view.forward), fy = rig_.ground_y(view.forward);
    if (std::hypot(fx, fy) > 1e-6 && ends.size() == 4) {
      const double base = std::atan2(fy, fx);
      size_t lo = 0, hi = 0;
      double alo = kInfinity, ahi = -kInfinity;
      for (size_t i = 0; i < ends.size(); ++i) {
        const double a = std::remainder(std::atan2(-(ends[i].second - ey), ends[i].first - ex) - base, 2.0 * kPi);
        if (a < alo) alo = a, lo = i;
        if (a > ahi) ahi = a, hi = i;
      }
      glColor4f(kYellow.r, kYellow.g, kYellow.b, 0.12f);
      glBegin(GL_TRIANGLES);
      glVertex2f(ex, ey);
      glVertex2f(ends[lo].first, ends[lo].second);
      glVertex2f(ends[hi].first, ends[hi].second);
      glEnd();
      hud::line(ex, ey, ends[lo].first, ends[lo].second, kYellow);
      hud::line(ex, ey, ends[hi].first, ends[hi].second, kYellow);
    } else {
      for (const auto& [x, y] : ends) hud::line(ex, ey, x, y, kYellow);
    }
    hud::fill_rect(ex - 3.0f, ey - 3.0f, 6.0f, 6.0f, kYellow);
  }
  glDisable(GL_SCISSOR_TEST);
  hud::text(area.x + pad, area.y + pad * 0.5f,
            fmt::format("top view: {} cells touched of {}", touched_.size(), content_cells_), scale, kOrange);
}

void WindowSession::draw_boxes(const Rect& image_rect, int fb_h) {
  // The touched cells' boxes over the image, with the image's own projection (eye-relative
  // coordinates so that models far from the origin keep their precision).
  const View& view = walk_.view();
  if (view.width <= 0 || touched_.empty()) return;
  glViewport(int(image_rect.x), fb_h - int(image_rect.y + image_rect.h), int(image_rect.w), int(image_rect.h));
  const double near = 1e-3 * std::max(1.0, std::hypot(map_hi_x_ - map_lo_x_, map_hi_y_ - map_lo_y_));
  glMatrixMode(GL_PROJECTION);
  glLoadIdentity();
  glFrustum(-view.half_w * near, view.half_w * near, -view.half_h * near, view.half_h * near, near, near * 1e7);
  glMatrixMode(GL_MODELVIEW);
  const double m[16] = {view.right.x, view.up.x, -view.forward.x, 0.0, view.right.y, view.up.y, -view.forward.y, 0.0,
                        view.right.z, view.up.z, -view.forward.z, 0.0, 0.0,         0.0,       0.0,             1.0};
  glLoadMatrixd(m);
  const auto& cells = walk_.model().cells();
  glColor4f(kOrange.r, kOrange.g, kOrange.b, 0.55f);
  glBegin(GL_LINES);
  for (uint32_t c : touched_) {
    if (c >= cells.size()) continue;
    const Vec3 lo = cells[c].bounds.lo - view.eye, hi = cells[c].bounds.hi - view.eye;
    const auto corner = [&](int k) { return Vec3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z); };
    for (int a = 0; a < 8; ++a) {
      for (int bit = 1; bit < 8; bit <<= 1) {
        if (a & bit) continue;
        const Vec3 p = corner(a), q = corner(a | bit);
        glVertex3d(p.x, p.y, p.z);
        glVertex3d(q.x, q.y, q.z);
      }
    }
  }
  glEnd();
}

Status WindowSession::screenshot(const std::string& path) {
  int fb_w = 0, fb_h = 0;
  glfwGetFramebufferSize(window_, &fb_w, &fb_h);
  if (fb_w <= 0 || fb_h <= 0) return Status::io_error(path + ": the window has no pixels (minimized)");
  draw();  // the last frame again, into the back buffer, HUD included
  glFinish();
  std::vector<uint8_t> bytes(size_t(fb_w) * size_t(fb_h) * 3);
  glReadBuffer(GL_BACK);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, fb_w, fb_h, GL_RGB, GL_UNSIGNED_BYTE, bytes.data());
  std::vector<Rgb> pixels(size_t(fb_w) * size_t(fb_h));
  for (int y = 0; y < fb_h; ++y) {
    const uint8_t* row = &bytes[size_t(fb_h - 1 - y) * size_t(fb_w) * 3];  // GL rows start at the bottom
    for (int x = 0; x < fb_w; ++x) {
      pixels[size_t(y) * size_t(fb_w) + size_t(x)] = Rgb{row[3 * x] / 255.0f, row[3 * x + 1] / 255.0f, row[3 * x + 2] / 255.0f};
    }
  }
  return write_png(path, fb_w, fb_h, pixels);
}

int WindowSession::run() {
  glfwSetWindowUserPointer(window_, &input_);
  glfwSetKeyCallback(window_, on_key);
  glfwSetMouseButtonCallback(window_, on_mouse_button);
  glfwSetCursorPosCallback(window_, on_cursor);
  glfwSetScrollCallback(window_, on_scroll);

  std::ofstream report;
  if (!options_.report.empty()) {
    report.open(options_.report);
    if (!report) {
      std::fprintf(stderr, "frontier-view: %s: cannot write\n", options_.report.c_str());
      return 1;
    }
  }
  std::vector<int> previous_script_keys;
  auto last_time = std::chrono::steady_clock::now();
  bool idle = false;
  int shown = 0;
  while (!quit_) {
    if (idle) {
      glfwWaitEventsTimeout(0.1);
    } else {
      glfwPollEvents();
    }
    if (glfwWindowShouldClose(window_)) break;

    // Keys: presses from the callbacks, and scripted keys (a key counts as pressed on the first
    // frame of a run of frames that list it, held on every one).
    const std::vector<int> script_keys = options_.script ? options_.script(shown) : std::vector<int>{};
    std::vector<int> presses = std::move(input_.pressed);
    input_.pressed.clear();
    for (int key : script_keys) {
      if (std::find(previous_script_keys.begin(), previous_script_keys.end(), key) == previous_script_keys.end()) {
        presses.push_back(key);
      }
    }
    previous_script_keys = script_keys;
    for (int key : presses) handle_key(key);
    if (quit_) break;
    if (input_.scroll != 0.0) {
      speed_ = std::clamp(speed_ * std::pow(kSpeedStep, input_.scroll), 1e-3, 1e6);
      input_.scroll = 0.0;
    }

    const auto now = std::chrono::steady_clock::now();
    const double dt = scripted() ? kScriptedDt
                                 : std::clamp(std::chrono::duration<double>(now - last_time).count(), 0.0, kMaxDt);
    last_time = now;
    const Camera camera = next_camera(shown, script_keys, dt);

    last_ = walk_.frame(camera);
    if (walker_ != nullptr) last_.add_walk_counters(*walker_);
    touched_ = walk_.touched_cells();
    history_.push(last_);
    if (peg_samples_ == 0) peg_samples_ = std::max<uint64_t>(1000, walk_.view().pixels() / 4);
    if (report.is_open()) report << last_.to_json().dump() << "\n";

    if (!shown_) show_window_for(walk_.view().width, walk_.view().height);
    upload_image();
    draw();
    glfwSwapBuffers(window_);
    ++shown;
    // Nothing left to refine and nothing moving: sleep until an event (not in scripted runs).
    idle = !scripted() && options_.frames == 0 && last_.complete && last_.continued;
    if (frames_done(shown)) break;
  }

  int status = 0;
  if (!options_.screenshot.empty()) {
    if (shown == 0) {
      std::fprintf(stderr, "frontier-view: %s: no frame was shown\n", options_.screenshot.c_str());
      status = 1;
    } else if (Status s = screenshot(options_.screenshot); !s) {
      std::fprintf(stderr, "frontier-view: %s\n", s.to_string().c_str());
      status = 1;
    }
  }
  if (report.is_open()) {
    report.flush();
    if (!report) {
      std::fprintf(stderr, "frontier-view: %s: cannot write\n", options_.report.c_str());
      status = 1;
    }
  }
  return status;
}

}  // namespace

int run_window(Walkthrough& walk, const WindowOptions& options, Walker* walker) {
  glfwSetErrorCallback(on_glfw_error);
  if (!glfwInit()) {
    std::fprintf(stderr, "frontier-view: no display (DISPLAY unset or unusable): use --headless (%s)\n",
                 glfw_error().c_str());
    return 1;
  }
  GlfwSession session;
  glfwWindowHint(GLFW_VISIBLE, GLFW_FALSE);  // shown once the first frame gives the image size
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 2);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
  const std::string title = "frontier-view: " + walk.model().reader().name();
  GLFWwindow* window = glfwCreateWindow(640, 480, title.c_str(), nullptr, nullptr);
  if (window == nullptr) {
    std::fprintf(stderr, "frontier-view: no display (DISPLAY unset or unusable): use --headless (%s)\n",
                 glfw_error().c_str());
    return 1;
  }
  glfwMakeContextCurrent(window);
  glfwSwapInterval(0);  // the CPU renderer wants every millisecond; no waiting for vsync
  int status = 0;
  try {
    WindowSession s(walk, options, walker, window);
    status = s.run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "frontier-view: window: %s\n", e.what());
    status = 1;
  }
  glfwDestroyWindow(window);
  return status;
}

}  // namespace frontier
