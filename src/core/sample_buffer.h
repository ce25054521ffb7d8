// Per-pixel sample storage for progressive rendering. Nothing is cleared between frames:
// every pixel carries the frame stamp of its last confirmation, and a pixel whose stamp is
// not the current frame's counts as unsampled (frustum-casting paper §5.4).
// Thread safety: claim() is atomic, so when two frusta share a boundary pixel exactly one of
// them writes it; values are read only after the workers of a frame have joined.
#pragma once

#include "src/core/geometry.h"

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

namespace frontier {

inline constexpr uint32_t kNoPrim = 0xFFFFFFFFu;

struct Rgb {
  float r = 0.0f, g = 0.0f, b = 0.0f;
  bool operator==(const Rgb&) const = default;
};

class SampleBuffer {
 public:
  void resize(int width, int height);
  // Starts a new frame: every pixel becomes unsampled in O(1).
  void begin_frame() { ++frame_; }
  uint32_t frame() const { return frame_; }
  int width() const { return width_; }
  int height() const { return height_; }
  size_t size() const { return prim_.size(); }

  bool confirmed(size_t i) const { return stamp_[i].load(std::memory_order_relaxed) == frame_; }
  // Returns true for exactly one caller per pixel and frame; that caller must then set().
  bool claim(size_t i) {
    uint32_t seen = stamp_[i].load(std::memory_order_relaxed);
    while (seen != frame_) {
      if (stamp_[i].compare_exchange_weak(seen, frame_, std::memory_order_acq_rel)) return true;
    }
    return false;
  }
  // The same for a caller that no other thread can race on pixel i in this frame (no atomic
  // read-modify-write).
  bool claim_exclusive(size_t i) {
    if (stamp_[i].load(std::memory_order_relaxed) == frame_) return false;
    stamp_[i].store(frame_, std::memory_order_relaxed);
    return true;
  }
  // Makes a confirmed pixel unsampled again in this frame. Only while no thread claims.
  void unconfirm(size_t i) { stamp_[i].store(frame_ - 1, std::memory_order_relaxed); }
  void set(size_t i, uint32_t prim, double t, Rgb color) {
    prim_[i] = prim;
    t_[i] = t;
    color_[i] = color;
    sky_.marks[i] = 0;
  }
  // The colour set_background() is mostly called with (the scene's background). Not while
  // workers write.
  void set_sky(Rgb bg) {
    if (bg == sky_.colour) return;
    sky_.colour = bg;
    std::fill(sky_.marks.begin(), sky_.marks.end(), uint8_t{0});
  }
  // set(i, kNoPrim, kInfinity, bg), writing nothing where the pixel already holds exactly that
  // (the sky of a walk stays sky from frame to frame). One byte a pixel says so for the sky
  // colour: reading the pixel's 24 bytes of values made filling the sky of a 1280x720 terrain
  // orbit (nine tenths of the pixels) a quarter of its frame time, bound by memory.
  void set_background(size_t i, Rgb bg) {
    const bool sky = bg == sky_.colour;
    if (sky && sky_.marks[i] != 0) return;
    if (!(prim_[i] == kNoPrim && color_[i] == bg && t_[i] == kInfinity)) {
      prim_[i] = kNoPrim;
      t_[i] = kInfinity;
      color_[i] = bg;
    }
    sky_.marks[i] = sky ? 1 : 0;
  }

  // Pixel i holds the sky colour and no primitive (set_background() with set_sky()'s colour, and
  // nothing written since): a pass over the frame's primitives may skip it after one byte.
  bool sky(size_t i) const { return sky_.marks[i] != 0; }
  // Values of confirmed pixels.
  uint32_t prim(size_t i) const { return prim_[i]; }
  double t(size_t i) const { return t_[i]; }
  Rgb color(size_t i) const { return color_[i]; }

  // Reconstruction output: the displayed colour of every pixel (§5.4).
  const std::vector<Rgb>& image() const { return image_; }
  std::vector<Rgb>& image() { return image_; }
  size_t confirmed_count() const;

 private:
  int width_ = 0, height_ = 0;
  uint32_t frame_ = 1;
  std::unique_ptr<std::atomic<uint32_t>[]> stamp_;
  std::vector<uint32_t> prim_;
  std::vector<double> t_;
  std::vector<Rgb> color_;
  std::vector<Rgb> image_;
  // marks[i] != 0: pixel i holds (kNoPrim, kInfinity, colour), set by set_background().
  struct Sky {
    Rgb colour;
    std::vector<uint8_t> marks;
  } sky_;
};

// Frame-stamped marks on cells, for counting distinct cells touched per frame.
class CellMarks {
 public:
  void resize(size_t cells);
  // Makes room for at least `cells` cells keeping this frame's marks (a tree that grew between
  // two slices of one frame).
  void grow(size_t cells);
  size_t size() const { return size_; }
  void begin_frame() { ++frame_; }
  // True the first time cell c is marked in this frame.
  bool mark(int32_t c) {
    std::atomic<uint32_t>& s = stamp_[static_cast<size_t>(c)];
    if (s.load(std::memory_order_relaxed) == frame_) return false;
    return s.exchange(frame_, std::memory_order_relaxed) != frame_;
  }
  bool marked(int32_t c) const {
    return stamp_[static_cast<size_t>(c)].load(std::memory_order_relaxed) == frame_;
  }

 private:
  uint32_t frame_ = 1;
  size_t size_ = 0;
  std::unique_ptr<std::atomic<uint32_t>[]> stamp_;
};

// Fills every unconfirmed pixel of `buffer.image()` by recursive interpolation over the same
// quadrant subdivision frusta use: corners, then edge midpoints, then centres (§5.4).
// Confirmed pixels keep their values. `fallback` colours the image when nothing is confirmed.
void reconstruct(SampleBuffer& buffer, Rgb fallback);

}  // namespace frontier
