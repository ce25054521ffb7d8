// The window's session (window.h), shared by the files that implement it and by nothing else:
// window.cpp (the frame loop, screenshots, run_window), window_input.cpp (GLFW callbacks, keys,
// the camera each frame), window_draw.cpp (the image as a texture, the HUD's text panel and
// charts) and window_cell_view.cpp (the top-down map of store cells and the cell boxes over the
// image). Everything here runs on the thread that owns the GL context.
#pragma once

#include "src/walk/walker.h"
#include "viewer/hud.h"
#include "viewer/window.h"
#include "viewer/window_rig.h"

#include <GLFW/glfw3.h>

#include <chrono>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

namespace frontier::window_detail {

constexpr double kMouseRadiansPerPixel = 0.0035;
constexpr double kKeyRadiansPerSecond = 1.6;
constexpr double kScriptedDt = 1.0 / 30.0;  // scripted and path runs move as if at 30 Hz (reproducible)
constexpr double kMaxDt = 0.25;             // a slow frame does not become a teleport
constexpr double kRunFactor = 4.0;
constexpr double kSpeedStep = 1.25;
constexpr size_t kHistory = 120;
constexpr size_t kMaxMapCells = 20000;      // beyond this the map outlines only the touched cells
constexpr double kMiB = 1024.0 * 1024.0;

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

// Points the window's callbacks at `input` (which must outlive the window's event polling).
void install_input_callbacks(GLFWwindow* window, Input* input);

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

// The map's ground-plane coordinates (Rig::ground_x, ground_y) to pixels: centre (cx, cy) at
// the middle of `plot`, `k` pixels per model unit, ground y up the screen.
struct MapProjection {
  Rect plot;
  double cx = 0.0, cy = 0.0, k = 1.0;
  float x(double gx) const { return float(double(plot.x) + 0.5 * plot.w + (gx - cx) * k); }
  float y(double gy) const { return float(double(plot.y) + 0.5 * plot.h - (gy - cy) * k); }
};

inline constexpr hud::Color kWhite{1.0f, 1.0f, 1.0f, 1.0f};
inline constexpr hud::Color kGrey{0.75f, 0.75f, 0.75f, 1.0f};
inline constexpr hud::Color kYellow{1.0f, 0.9f, 0.3f, 1.0f};
inline constexpr hud::Color kOrange{1.0f, 0.55f, 0.15f, 1.0f};
inline constexpr hud::Color kCyan{0.35f, 0.9f, 1.0f, 1.0f};
inline constexpr hud::Color kGreen{0.45f, 1.0f, 0.45f, 1.0f};
inline constexpr hud::Color kBlue{0.45f, 0.6f, 1.0f, 1.0f};
inline constexpr hud::Color kRed{1.0f, 0.35f, 0.35f, 1.0f};
inline constexpr hud::Color kMagenta{1.0f, 0.45f, 0.9f, 1.0f};
inline constexpr hud::Color kPanel{0.0f, 0.0f, 0.0f, 0.55f};

class WindowSession {
 public:
  // REQUIRES: `window`'s GL context is current on this thread.
  WindowSession(Walkthrough& walk, const WindowOptions& options, Walker* walker, GLFWwindow* window);
  ~WindowSession() { glDeleteTextures(1, &texture_); }

  // The frame loop (window.cpp); returns run_window's exit status.
  int run();

 private:
  void extend_map(const Aabb& box) { rig_.ground_extent(box, map_lo_x_, map_hi_x_, map_lo_y_, map_hi_y_); }

  bool frames_done(int shown) const {
    if (options_.frames > 0) return shown >= options_.frames;
    return !options_.path.empty() && size_t(shown) >= options_.path.size();
  }
  bool scripted() const { return static_cast<bool>(options_.script) || !options_.path.empty(); }

  // The end of run(): the screenshot and the report's last check; the exit status.
  int finish(int shown, std::ofstream& report);
  // window_input.cpp
  // Acts on this frame's key presses and wheel travel; returns the scripted keys held in this
  // frame (those of options_.script, pressed when they were not held in the frame before).
  std::vector<int> take_input(int frame, std::vector<int>& previous_script_keys);
  void handle_key(int key);
  void set_walking(bool on);
  void check_fell_out();
  void toggle_peg();
  void scale_peg(double factor);
  Camera next_camera(int frame, const std::vector<int>& script_keys, double dt);
  // window_draw.cpp
  void show_window_for(int image_w, int image_h);
  void draw();
  void upload_image();
  void draw_text_panel(float scale);
  void draw_charts(int fb_w, int fb_h, float scale);
  // window_cell_view.cpp
  void draw_map(const Rect& area, float scale);
  void draw_view_wedge(const MapProjection& map, double reach);
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

}  // namespace frontier::window_detail
