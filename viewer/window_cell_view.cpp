// The window's cell view (window_session.h, key T): a top-down map of the store's cells (those
// resident tinted) with the cells the last image touched and the view frustum's footprint, and
// optionally the touched cells' boxes drawn over the image with the image's own projection.
// Both read only the Walkthrough's model, world and view; they change no rendering state but GL's.
#include "viewer/window_session.h"

#include <fmt/core.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace frontier::window_detail {

namespace {

hud::Color with_alpha(hud::Color c, float a) {
  c.a = a;
  return c;
}

}  // namespace

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
  const MapProjection map{plot, 0.5 * (lo_x + hi_x), 0.5 * (lo_y + hi_y),
                          std::min(double(plot.w) / span_x, double(plot.h) / span_y)};
  const auto footprint = [&](const Aabb& box, float& x0, float& y0, float& x1, float& y1) {
    double lx = kInfinity, hx = -kInfinity, ly = kInfinity, hy = -kInfinity;
    rig_.ground_extent(box, lx, hx, ly, hy);
    x0 = map.x(lx);
    x1 = map.x(hx);
    y0 = map.y(hy);
    y1 = map.y(ly);
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
  if (view.width > 0) draw_view_wedge(map, std::hypot(span_x, span_y) * map.k * 2.0);  // past the plot: clipped
  glDisable(GL_SCISSOR_TEST);
  hud::text(area.x + pad, area.y + pad * 0.5f,
            fmt::format("top view: {} cells touched of {}", touched_.size(), content_cells_), scale, kOrange);
}

void WindowSession::draw_view_wedge(const MapProjection& map, double reach) {
  // The view frustum's footprint: the eye and the rays through the image corners, on the ground,
  // `reach` pixels long.
  const View& view = walk_.view();
  const float ex = map.x(rig_.ground_x(view.eye)), ey = map.y(rig_.ground_y(view.eye));
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

}  // namespace frontier::window_detail
