// The window's overlay drawing (see hud.h).
#include "viewer/hud.h"

#include <GL/gl.h>
#include <fmt/core.h>
#include <stb/stb_easy_font.h>

#include <algorithm>
#include <cmath>

namespace frontier::hud {

namespace {

// stb_easy_font indexes its tables by (character - 32) and has no bounds check.
std::string printable(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    if (c < 32 || c > 126) c = '?';
  }
  return out;
}

void draw_glyphs(float x, float y, std::string& text, float scale, Color color) {
  // About 270 bytes of vertices per character (the header's estimate); 16 bytes per vertex.
  std::vector<char> vertices(std::max<size_t>(1024, text.size() * 400));
  const int quads = stb_easy_font_print(0.0f, 0.0f, text.data(), nullptr, vertices.data(), int(vertices.size()));
  glPushMatrix();
  glTranslatef(x, y, 0.0f);
  glScalef(scale, scale, 1.0f);
  glColor4f(color.r, color.g, color.b, color.a);
  glEnableClientState(GL_VERTEX_ARRAY);
  glVertexPointer(2, GL_FLOAT, 16, vertices.data());
  glDrawArrays(GL_QUADS, 0, quads * 4);
  glDisableClientState(GL_VERTEX_ARRAY);
  glPopMatrix();
}

}  // namespace

void begin(int width, int height) {
  glViewport(0, 0, width, height);
  glMatrixMode(GL_PROJECTION);
  glLoadIdentity();
  glOrtho(0.0, width, height, 0.0, -1.0, 1.0);
  glMatrixMode(GL_MODELVIEW);
  glLoadIdentity();
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_TEXTURE_2D);
  glDisable(GL_SCISSOR_TEST);
  glEnable(GL_BLEND);
  glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  glLineWidth(1.0f);
}

float line_height(float scale) { return 12.0f * scale; }

float text_width(std::string_view text, float scale) {
  std::string s = printable(text);
  return float(stb_easy_font_width(s.data())) * scale;
}

float text(float x, float y, std::string_view text, float scale, Color color) {
  std::string s = printable(text);
  const float shadow = std::max(1.0f, std::floor(scale * 0.5f));
  draw_glyphs(x + shadow, y + shadow, s, scale, Color{0.0f, 0.0f, 0.0f, 0.8f * color.a});
  draw_glyphs(x, y, s, scale, color);
  return float(stb_easy_font_width(s.data())) * scale;
}

void fill_rect(float x, float y, float w, float h, Color color) {
  glColor4f(color.r, color.g, color.b, color.a);
  glBegin(GL_QUADS);
  glVertex2f(x, y);
  glVertex2f(x + w, y);
  glVertex2f(x + w, y + h);
  glVertex2f(x, y + h);
  glEnd();
}

void outline_rect(float x, float y, float w, float h, Color color) {
  // Half-pixel inset so that one-pixel lines land on pixel centres.
  glColor4f(color.r, color.g, color.b, color.a);
  glBegin(GL_LINE_LOOP);
  glVertex2f(x + 0.5f, y + 0.5f);
  glVertex2f(x + w - 0.5f, y + 0.5f);
  glVertex2f(x + w - 0.5f, y + h - 0.5f);
  glVertex2f(x + 0.5f, y + h - 0.5f);
  glEnd();
}

void line(float x0, float y0, float x1, float y1, Color color) {
  glColor4f(color.r, color.g, color.b, color.a);
  glBegin(GL_LINES);
  glVertex2f(x0, y0);
  glVertex2f(x1, y1);
  glEnd();
}

void Series::push(double value) {
  if (capacity_ == 0) return;
  if (values_.size() < capacity_) values_.resize(capacity_, 0.0);
  if (size_ < capacity_) {
    values_[(start_ + size_) % capacity_] = value;
    ++size_;
  } else {
    values_[start_] = value;
    start_ = (start_ + 1) % capacity_;
  }
}

double Series::at(size_t i) const { return values_[(start_ + i) % capacity_]; }

double Series::max() const {
  double m = 0.0;
  for (size_t i = 0; i < size_; ++i) m = std::max(m, at(i));
  return m;
}

double round_up_nice(double value) {
  if (!(value > 0.0) || !std::isfinite(value)) return 1.0;
  const double decade = std::pow(10.0, std::floor(std::log10(value)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * decade >= value * (1.0 - 1e-12)) return m * decade;
  }
  return 10.0 * decade;
}

void strip_chart(float x, float y, float w, float h, std::span<const ChartSeries> series, double reference,
                 std::string_view label, std::string_view unit, float text_scale) {
  fill_rect(x, y, w, h, Color{0.0f, 0.0f, 0.0f, 0.55f});
  outline_rect(x, y, w, h, Color{1.0f, 1.0f, 1.0f, 0.35f});
  double top = std::max(reference, 0.0);
  for (const ChartSeries& s : series) top = std::max(top, s.series->max());
  top = round_up_nice(top);

  const float text_h = line_height(text_scale);
  const float plot_y = y + text_h + 2.0f, plot_h = h - text_h - 4.0f;
  const auto to_y = [&](double v) { return plot_y + plot_h - float(std::clamp(v / top, 0.0, 1.0)) * plot_h; };
  if (reference > 0.0) {
    glEnable(GL_LINE_STIPPLE);
    glLineStipple(1, 0x0F0F);
    line(x + 1.0f, to_y(reference), x + w - 1.0f, to_y(reference), Color{1.0f, 1.0f, 1.0f, 0.6f});
    glDisable(GL_LINE_STIPPLE);
  }
  for (const ChartSeries& s : series) {
    const Series& v = *s.series;
    if (v.size() == 0 || v.capacity() < 2) continue;
    const float dx = (w - 2.0f) / float(v.capacity() - 1);
    const float x0 = x + 1.0f + dx * float(v.capacity() - v.size());
    glColor4f(s.color.r, s.color.g, s.color.b, s.color.a);
    glBegin(v.size() == 1 ? GL_POINTS : GL_LINE_STRIP);
    for (size_t i = 0; i < v.size(); ++i) glVertex2f(x0 + dx * float(i), to_y(v.at(i)));
    glEnd();
  }
  float label_x = x + 4.0f;
  label_x += text(label_x, y + 2.0f, label, text_scale, Color{1.0f, 1.0f, 1.0f, 0.95f});
  for (const ChartSeries& s : series) {
    if (s.legend.empty()) continue;
    label_x += text(label_x, y + 2.0f, " ", text_scale, s.color);
    label_x += text(label_x, y + 2.0f, s.legend, text_scale, s.color);
  }
  // The scale at the top of the plot, on the left where the oldest values are.
  text(x + 4.0f, plot_y, fmt::format("{:g}{}", top, unit), text_scale, Color{0.7f, 0.7f, 0.7f, 0.8f});
}

}  // namespace frontier::hud
