// The window's input (window_session.h): GLFW callbacks collect key presses, wheel and cursor
// travel into Input between frames; handle_key acts on presses (modes, pegging, cell view,
// speed) and next_camera turns held keys and cursor travel into this frame's camera.
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
// collision grid there is no floor) is put back where walking started, in fly mode. Movement
// scales with dt, which the frame loop fixes at 1/30 s in scripted and path runs.
//
// Pegging: P and [ ] change the Walkthrough's budget (Walkthrough::set_budget) for the next
// frames.
#include "viewer/window_session.h"

#include <algorithm>
#include <cmath>

namespace frontier::window_detail {

namespace {

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

}  // namespace

void install_input_callbacks(GLFWwindow* window, Input* input) {
  glfwSetWindowUserPointer(window, input);
  glfwSetKeyCallback(window, on_key);
  glfwSetMouseButtonCallback(window, on_mouse_button);
  glfwSetCursorPosCallback(window, on_cursor);
  glfwSetScrollCallback(window, on_scroll);
}

std::vector<int> WindowSession::take_input(int frame, std::vector<int>& previous_script_keys) {
  // Presses from the callbacks, and scripted keys (a key counts as pressed on the first frame of
  // a run of frames that list it, held on every one).
  const std::vector<int> script_keys = options_.script ? options_.script(frame) : std::vector<int>{};
  std::vector<int> presses = std::move(input_.pressed);
  input_.pressed.clear();
  for (int key : script_keys) {
    if (std::find(previous_script_keys.begin(), previous_script_keys.end(), key) == previous_script_keys.end()) {
      presses.push_back(key);
    }
  }
  previous_script_keys = script_keys;
  for (int key : presses) handle_key(key);
  if (quit_) return script_keys;
  if (input_.scroll != 0.0) {
    speed_ = std::clamp(speed_ * std::pow(kSpeedStep, input_.scroll), 1e-3, 1e6);
    input_.scroll = 0.0;
  }
  return script_keys;
}

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
    // Pixel error (stores with proxies): , halves it (below 0.25: 0, exact), . doubles it (from 0: 0.5).
    case GLFW_KEY_COMMA: {
      const double t = walk_.pixel_error() / 2.0;
      walk_.set_pixel_error(t < 0.25 ? 0.0 : t);
      break;
    }
    case GLFW_KEY_PERIOD: {
      const double t = walk_.pixel_error();
      walk_.set_pixel_error(t <= 0.0 ? 0.5 : std::min(t * 2.0, 1024.0));
      break;
    }
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

}  // namespace frontier::window_detail
