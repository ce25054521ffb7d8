// The window's drawing (window_session.h): the window sized for the first image, the
// Walkthrough's image uploaded as a texture and drawn as large as fits with its aspect kept,
// and over it the HUD: the text panel (mode, peg, counters, camera), the strip charts of the
// last frames and the key help along the bottom. The cell view is window_cell_view.cpp.
#include "viewer/window_session.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace frontier::window_detail {

namespace {

std::string grouped(uint64_t n) {
  std::string digits = std::to_string(n), out;
  for (size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

}  // namespace

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
  if (walk_.world().has_proxies()) {
    // Level of detail: the pixel error, the share of the image on proxies, the cut's nodes drawn
    // by proxies (and those the rays entered), and what the cut asked for that is not in yet.
    const double proxy = r.pixels ? 100.0 * double(r.proxy_pixels) / double(r.pixels) : 0.0;
    lines.emplace_back(fmt::format("pixel error {:.3g} (, .)  proxy {:.0f}% of the image  cut {} nodes ({} drawn)  "
                                   "requests {}",
                                   walk_.pixel_error(), proxy, grouped(r.cut_nodes), grouped(r.proxy_nodes),
                                   grouped(r.requests)),
                       r.parked > 0 ? kOrange : kWhite);
  }
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
  const std::string help2 = "P peg time/samples  [ ] peg value  , . pixel error  T cells view  H hud  R reset  Esc quit";
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

}  // namespace frontier::window_detail
