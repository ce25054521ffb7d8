// SampleBuffer, CellMarks and the §5.4 reconstruction.
#include "src/core/sample_buffer.h"

#include <tbb/parallel_for.h>

#include <array>

namespace frontier {

void SampleBuffer::resize(int width, int height) {
  if (width == width_ && height == height_ && stamp_) return;
  width_ = width;
  height_ = height;
  const size_t n = static_cast<size_t>(width) * static_cast<size_t>(height);
  stamp_ = std::make_unique<std::atomic<uint32_t>[]>(n);
  for (size_t i = 0; i < n; ++i) stamp_[i].store(0, std::memory_order_relaxed);
  prim_.assign(n, kNoPrim);
  t_.assign(n, kInfinity);
  color_.assign(n, Rgb{});
  image_.assign(n, Rgb{});
  sky_.marks.assign(n, 0);
  frame_ = 1;
}

size_t SampleBuffer::confirmed_count() const {
  size_t n = 0;
  for (size_t i = 0; i < prim_.size(); ++i) n += confirmed(i) ? 1 : 0;
  return n;
}

void CellMarks::resize(size_t cells) {
  if (cells <= size_ && stamp_) return;  // stamps of earlier frames are stale anyway
  // Geometric: a walk's tree gains cells every frame, and a fresh array per frame cost page
  // faults on every stamp (an exterior orbit's pegged frames at 1280x720).
  size_ = std::max(cells, size_ + size_ / 2);
  cells = size_;
  stamp_ = std::make_unique<std::atomic<uint32_t>[]>(cells);
  for (size_t i = 0; i < cells; ++i) stamp_[i].store(0, std::memory_order_relaxed);
  frame_ = 1;
}

void CellMarks::grow(size_t cells) {
  if (cells <= size_ && stamp_) return;
  cells = std::max(cells, size_ + size_ / 2);  // geometric: a walk grafts a few cells at a time
  auto bigger = std::make_unique<std::atomic<uint32_t>[]>(cells);
  for (size_t i = 0; i < cells; ++i) {
    bigger[i].store(i < size_ ? stamp_[i].load(std::memory_order_relaxed) : 0u, std::memory_order_relaxed);
  }
  stamp_ = std::move(bigger);
  size_ = cells;
}

namespace {

Rgb mix(Rgb a, Rgb b) { return {0.5f * (a.r + b.r), 0.5f * (a.g + b.g), 0.5f * (a.b + b.b)}; }
Rgb mix4(Rgb a, Rgb b, Rgb c, Rgb d) {
  return {0.25f * (a.r + b.r + c.r + d.r), 0.25f * (a.g + b.g + c.g + d.g),
          0.25f * (a.b + b.b + c.b + d.b)};
}

// The recursive interpolation of reconstruct(), as plain calls (a std::function per level cost
// about 30 ns per pixel).
struct Interpolation {
  const SampleBuffer& buf;
  std::vector<Rgb>& img;
  std::vector<uint8_t>& known;
  int w;

  Rgb value(int x, int y) const { return img[static_cast<size_t>(y) * size_t(w) + size_t(x)]; }
  void settle(int x, int y, Rgb interpolated) {
    const size_t i = static_cast<size_t>(y) * size_t(w) + size_t(x);
    if (known[i]) return;
    img[i] = buf.confirmed(i) ? buf.color(i) : interpolated;
    known[i] = 1;
  }
  // The edge midpoints (and the centre) of a rectangle being split, from its corners.
  void settle_midpoints(int x0, int y0, int x1, int y1, int xm, int ym, bool split_x, bool split_y) {
    const Rgb c00 = value(x0, y0), c10 = value(x1, y0), c01 = value(x0, y1), c11 = value(x1, y1);
    if (split_x) {
      settle(xm, y0, mix(c00, c10));
      settle(xm, y1, mix(c01, c11));
    }
    if (split_y) {
      settle(x0, ym, mix(c00, c01));
      settle(x1, ym, mix(c10, c11));
    }
    if (split_x && split_y) settle(xm, ym, mix4(c00, c10, c01, c11));
  }
  // The 1-D recursion fill() runs along a rectangle's edge (the same midpoints and values).
  void fill_edge(int x0, int y0, int x1, int y1) {
    if (y0 == y1) {
      if (x1 - x0 < 2) return;
      const int xm = (x0 + x1) / 2;
      settle(xm, y0, mix(value(x0, y0), value(x1, y0)));
      fill_edge(x0, y0, xm, y0);
      fill_edge(xm, y0, x1, y0);
    } else {
      if (y1 - y0 < 2) return;
      const int ym = (y0 + y1) / 2;
      settle(x0, ym, mix(value(x0, y0), value(x0, y1)));
      fill_edge(x0, y0, x0, ym);
      fill_edge(x0, ym, x0, y1);
    }
  }
  // Recurses like fill() until rectangles have at most `area` pixels, which are collected
  // (their corners settled) instead of filled.
  void split_until(int x0, int y0, int x1, int y1, long area, std::vector<std::array<int, 4>>& out) {
    const bool split_x = x1 - x0 >= 2, split_y = y1 - y0 >= 2;
    if ((!split_x && !split_y) || long(x1 - x0 + 1) * long(y1 - y0 + 1) <= area) {
      out.push_back({x0, y0, x1, y1});
      return;
    }
    const int xm = split_x ? (x0 + x1) / 2 : x0, ym = split_y ? (y0 + y1) / 2 : y0;
    settle_midpoints(x0, y0, x1, y1, xm, ym, split_x, split_y);
    if (split_x && split_y) {
      split_until(x0, y0, xm, ym, area, out);
      split_until(xm, y0, x1, ym, area, out);
      split_until(x0, ym, xm, y1, area, out);
      split_until(xm, ym, x1, y1, area, out);
    } else if (split_x) {
      split_until(x0, y0, xm, y1, area, out);
      split_until(xm, y0, x1, y1, area, out);
    } else {
      split_until(x0, y0, x1, ym, area, out);
      split_until(x0, ym, x1, y1, area, out);
    }
  }
  void fill(int x0, int y0, int x1, int y1) {
    const bool split_x = x1 - x0 >= 2, split_y = y1 - y0 >= 2;
    if (!split_x && !split_y) return;
    const int xm = split_x ? (x0 + x1) / 2 : x0, ym = split_y ? (y0 + y1) / 2 : y0;
    settle_midpoints(x0, y0, x1, y1, xm, ym, split_x, split_y);
    if (split_x && split_y) {
      fill(x0, y0, xm, ym);
      fill(xm, y0, x1, ym);
      fill(x0, ym, xm, y1);
      fill(xm, ym, x1, y1);
    } else if (split_x) {
      fill(x0, y0, xm, y1);
      fill(xm, y0, x1, y1);
    } else {
      fill(x0, y0, x1, ym);
      fill(x0, ym, x1, y1);
    }
  }
};

}  // namespace

void reconstruct(SampleBuffer& buf, Rgb fallback) {
  const int w = buf.width(), h = buf.height();
  if (w == 0 || h == 0) return;
  std::vector<Rgb>& img = buf.image();
  std::vector<uint8_t> known(img.size(), 0);
  // Root corners: confirmed values, else the mean of all confirmed samples.
  Rgb mean = fallback;
  {
    double r = 0, g = 0, b = 0;
    size_t n = 0;
    for (size_t i = 0; i < img.size(); ++i) {
      if (!buf.confirmed(i)) continue;
      const Rgb c = buf.color(i);
      r += c.r;
      g += c.g;
      b += c.b;
      ++n;
    }
    if (n > 0) mean = {float(r / n), float(g / n), float(b / n)};
    if (n == img.size()) {  // a complete frame: nothing to interpolate
      for (size_t i = 0; i < img.size(); ++i) img[i] = buf.color(i);
      return;
    }
  }
  Interpolation ip{buf, img, known, w};
  ip.settle(0, 0, mean);
  ip.settle(w - 1, 0, mean);
  ip.settle(0, h - 1, mean);
  ip.settle(w - 1, h - 1, mean);
  // Tiles of about 32 × 32 are filled in parallel: their edges, which neighbours share, are
  // settled first (by the same 1-D recursion each side would run), so the tiles' writes are
  // disjoint.
  std::vector<std::array<int, 4>> tiles;
  ip.split_until(0, 0, w - 1, h - 1, 1024, tiles);
  for (const auto& t : tiles) {
    ip.fill_edge(t[0], t[1], t[2], t[1]);
    ip.fill_edge(t[0], t[3], t[2], t[3]);
    ip.fill_edge(t[0], t[1], t[0], t[3]);
    ip.fill_edge(t[2], t[1], t[2], t[3]);
  }
  tbb::parallel_for(size_t(0), tiles.size(), [&](size_t k) {
    Interpolation local = ip;
    local.fill(tiles[k][0], tiles[k][1], tiles[k][2], tiles[k][3]);
  });
}

}  // namespace frontier
