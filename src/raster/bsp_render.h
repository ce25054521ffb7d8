// Rendering a BspTree (Fuchs, Abram & Grant 1983):
//  * back to front (§2.2.2): the painter's algorithm through frontier's Rasterizer with its
//    depth test off, faces fan-triangulated (convex after splitting) so that the coverage rule
//    is the z-buffer's own and the two images are comparable pixel for pixel;
//  * front to back with an N x N sub-pixel coverage mask per pixel (§4.2, the CT-5's 4 x 4): a
//    face adds colour x (sub-samples it newly covers) / N^2; a pixel whose mask is full is done
//    and later faces skip it (counted: that early-out is the point of the order).
// Colours are flat per face: the material colour under a headlight at the eye (the Shader's
// ambient 0.1 + diffuse), computed once per face and frame.
//
// Coverage in the mask renderer is exact: vertices snap to 1/256 pixel (every sample position
// of N <= 16 is on that lattice), edge functions are 64-bit integers (|values| < 2^60 for screens
// up to 2^20), and the top-left rule gives a sample on an edge shared by two faces to exactly
// one of them. Clipping (near plane, a one-pixel band around the screen) is the Rasterizer's
// (src/raster/clip.h).
//
// Thread safety: one thread drives a frame; the tree is shared read-only; workers are internal.
#pragma once

#include "src/engine/frame_renderer.h"
#include "src/raster/bsp.h"
#include "src/raster/raster.h"
#include "src/core/sample_buffer.h"
#include "src/core/view.h"

#include <glm/mat4x4.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace frontier {

struct BspRenderOptions {
  BspOrder order = BspOrder::BackToFront;  // FrontToBack: the coverage-mask anti-aliasing
  bool cull_back_faces = false;            // §2.2.2: faces looking away are not drawn
  int aa = 4;                              // N of the N x N mask: 1, 2, 4, 8 or 16 (FrontToBack)
  int threads = 0;                         // 0: all cores
  std::vector<glm::dmat4> object_transforms;  // per moving object (identity when missing)
  Vec3 background{0.0};
  bool colors = true;       // shade; false: ids only (back to front)
  bool edge_flags = false;  // FrontToBack: fill BspFrame::mixed
};

struct BspFrameCounters {
  uint64_t nodes_visited = 0;
  uint64_t faces_drawn = 0;         // faces handed to the rasterizer / the mask renderer
  uint64_t faces_culled_back = 0;   // removed by back-face culling (§2.2.2)
  uint64_t triangles_submitted = 0; // back to front: fan triangles
  // Front to back (coverage mask):
  uint64_t pixel_visits = 0;        // (face, pixel) pairs inside a face's bounding box
  uint64_t pixels_skipped_full = 0; // of those, skipped because the pixel's mask was full
  uint64_t faces_skipped_full = 0;  // (face, tile) pairs skipped because the whole tile was full
  uint64_t subsample_tests = 0;     // sub-samples tested individually (partly covered pixels)
  uint64_t pixels_full = 0;         // pixels whose mask filled up
  uint64_t objects_outside_region = 0;  // moving objects not inside their region this frame
  RasterCounters raster;            // back to front
  double traverse_ms = 0.0;
  double raster_ms = 0.0;           // rasterization, or mask setup and coverage
  double total_ms = 0.0;
};

struct BspFrame {
  int width = 0, height = 0;
  // Per pixel, row-major, top row first: the visible face (back to front), or the face covering
  // the most sub-samples (front to back); kNoPrim for background.
  std::vector<uint32_t> ids;
  std::vector<Rgb> colors;      // empty unless options.colors
  std::vector<uint8_t> mixed;   // front to back with edge_flags: 1 where the pixel mixes colours
  BspFrameCounters counters;
};

// Renders one frame of `tree` for `view`. REQUIRES: options.aa in {1, 2, 4, 8, 16}.
BspFrame render_bsp(const BspTree& tree, const View& view, const BspRenderOptions& options);

// Submits the faces of `tree` to `rasterizer` in traversal order (fan triangles, id = face
// index) without flushing. With RasterOptions::depth_test = false and BackToFront this is the
// painter's algorithm; with the depth test on, the same triangles make the z-buffer reference.
BspFrameCounters submit_bsp(const BspTree& tree, Rasterizer& rasterizer, BspOrder order, bool cull_back_faces,
                            std::span<const glm::dmat4> object_transforms = {});

// The flat colour of a face (world-space vertices) seen from `eye`.
Rgb bsp_face_color(const BspTree& tree, uint32_t face, std::span<const Vec3> vertices, const Vec3& eye);

// A BSP tree as a FrameRenderer, rendered with render_bsp. stats: the tree's
// BspStats::to_json() plus method ("bsp"), order, aa (0 for back to front), width, height and
// frame (this frame's counters: nodes_visited, faces_drawn, faces_culled_back, pixel_visits,
// pixels_skipped_full, pixels_full, traverse_ms, raster_ms, ms). REQUIRES: options.aa in
// {1, 2, 4, 8, 16}; options.colors (a Frame has an image).
class BspFrameRenderer final : public FrameRenderer {
 public:
  BspFrameRenderer(BspTree tree, const BspRenderOptions& options);
  const BspTree& tree() const { return tree_; }
  Result<Frame> render(const View& view) override;

 private:
  BspTree tree_;
  BspRenderOptions options_;
};

}  // namespace frontier
