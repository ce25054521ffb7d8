// The interactive window of frontier-view (window.h): GLFW events, one Walkthrough frame, the
// CPU-rendered image drawn as a texture and the HUD over it, all on the calling thread (the
// Walkthrough runs its own render threads inside frame()). This file holds the frame loop,
// screenshots and run_window; window_session.h lists the files that hold the rest (input,
// drawing, the cell view) and window_rig.h the camera.
//
// The camera is (eye, yaw, pitch) about the start camera's up vector and is turned into a Camera
// the same way every frame, so a camera that did not move is bit-identical to the last one and
// the Walkthrough goes on refining the same image (progressive, paper §5.3). A window whose
// image is complete and whose camera is still waits for events instead of spinning. Scripted
// and path runs move as if every frame took 1/30 s, so they are reproducible. The keys are
// listed at the top of window_input.cpp.
#include "viewer/window.h"

#include "src/io/image.h"
#include "viewer/outputs.h"
#include "viewer/window_session.h"

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

}  // namespace

namespace window_detail {

WindowSession::WindowSession(Walkthrough& walk, const WindowOptions& options, Walker* walker, GLFWwindow* window)
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
  install_input_callbacks(window_, &input_);

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

    const std::vector<int> script_keys = take_input(shown, previous_script_keys);
    if (quit_) break;

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
    if (!options_.ids_dir.empty()) {
      if (Status s = write_ids(frame_file(options_.ids_dir, size_t(shown), "ids"), walk_.ids()); !s) {
        std::fprintf(stderr, "frontier-view: %s\n", s.to_string().c_str());
        return 1;
      }
    }

    if (!shown_) show_window_for(walk_.view().width, walk_.view().height);
    upload_image();
    draw();
    glfwSwapBuffers(window_);
    ++shown;
    // Nothing left to refine and nothing moving: sleep until an event (not in scripted runs).
    idle = !scripted() && options_.frames == 0 && last_.complete && last_.continued;
    if (frames_done(shown)) break;
  }

  return finish(shown, report);
}

int WindowSession::finish(int shown, std::ofstream& report) {
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

}  // namespace window_detail

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
    window_detail::WindowSession s(walk, options, walker, window);
    status = s.run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "frontier-view: window: %s\n", e.what());
    status = 1;
  }
  glfwDestroyWindow(window);
  return status;
}

}  // namespace frontier
