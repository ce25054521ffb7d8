// The window's overlay drawing: text, rectangles, lines and strip charts in legacy OpenGL
// (immediate mode and client vertex arrays, which Mesa's llvmpipe runs in Xvfb), in framebuffer
// pixels with the origin at the top left and y pointing down.
//
// Text is stb_easy_font (quads, no texture): ASCII 32..126 only; any other byte is drawn as '?'
// (the font indexes its tables by character, so nothing outside that range may reach it).
//
// REQUIRES for every drawing call: a current GL context on the calling thread and begin() called
// since the last change of GL matrices (begin() sets an orthographic projection and blending).
#pragma once

#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace frontier::hud {

struct Color {
  float r = 1.0f, g = 1.0f, b = 1.0f, a = 1.0f;
};

// Pixel projection over a framebuffer of width x height; blending on, depth and textures off.
void begin(int width, int height);

// Height of one line of text at `scale` (the font's 12-unit line pitch).
float line_height(float scale);
float text_width(std::string_view text, float scale);
// Draws `text` with its top-left corner at (x, y), with a one-pixel dark shadow so that it reads
// over any image. Returns its width.
float text(float x, float y, std::string_view text, float scale, Color color);

void fill_rect(float x, float y, float w, float h, Color color);
void outline_rect(float x, float y, float w, float h, Color color);
void line(float x0, float y0, float x1, float y1, Color color);

// The last `capacity` values of one per-frame quantity, oldest first.
class Series {
 public:
  explicit Series(size_t capacity = 120) : capacity_(capacity) {}
  void push(double value);
  size_t size() const { return size_; }
  size_t capacity() const { return capacity_; }
  // i = 0 is the oldest value kept. REQUIRES: i < size().
  double at(size_t i) const;
  double max() const;

 private:
  size_t capacity_;
  size_t start_ = 0, size_ = 0;
  std::vector<double> values_;
};

struct ChartSeries {
  const Series* series = nullptr;
  Color color;
  std::string legend;  // drawn in `color` after the chart's label (e.g. "paged in 12")
};

// A strip chart of the given series (drawn as lines, newest at the right edge; a series with
// fewer values than its capacity starts part way in) on a translucent panel: `label` and then
// each series' legend on the top line; below it the plot, whose vertical scale (a round number
// at or above every value shown and `reference`) is written at its top left followed by `unit`.
// A positive `reference` (e.g. the pegged frame time or the cache budget) is a dashed line.
void strip_chart(float x, float y, float w, float h, std::span<const ChartSeries> series, double reference,
                 std::string_view label, std::string_view unit, float text_scale);

// The smallest 1, 2 or 5 times a power of ten that is >= value (1 for value <= 0).
double round_up_nice(double value);

}  // namespace frontier::hud
