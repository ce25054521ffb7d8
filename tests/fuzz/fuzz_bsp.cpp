// libFuzzer target for BSP trees: the input's first byte picks the candidate count and seed,
// the rest is decoded into an adversarial polygon soup (decode_polygon_soup: lattice triangles,
// coplanar stacks, near-coplanar fans, slivers, n-gons). The build must succeed, terminate and
// pass BspTree::validate() (faces on their planes and on the right side of every ancestor, area
// preserved, depth and size within their bounds); both renderers then draw a small frame.
// Any crash, sanitizer report, hang or abort is a finding. The same property runs over fixed
// seeds in CI as BspFuzzSeeds.DecodedSoupsBuildValidTrees (tests/test_bsp.cpp).
#include "src/raster/bsp.h"
#include "src/raster/bsp_render.h"

#include <cstdint>
#include <cstdio>
#include <cstdlib>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  using namespace frontier;
  const PolygonSoup soup = decode_polygon_soup({data + 1, size - 1});
  BspBuildOptions options;
  options.candidates = int(data[0] % 4) * 2;  // 0 (all), 2, 4, 6
  options.seed = data[0];
  auto tree = BspTree::build(soup, options);
  if (!tree.is_ok()) {
    std::fprintf(stderr, "build failed: %s\n", tree.status().to_string().c_str());
    std::abort();
  }
  if (Status s = tree->validate(); !s) {
    std::fprintf(stderr, "invalid tree: %s\n", s.to_string().c_str());
    std::abort();
  }
  Camera camera;
  camera.eye = Vec3(double(data[0] % 7) - 3.0, 5.0, 7.0);
  camera.look_at = Vec3(0.0);
  const View view(camera, 16, 12);
  BspRenderOptions render;
  render.threads = 1;
  render.cull_back_faces = (data[0] & 1) != 0;
  (void)render_bsp(*tree, view, render);
  render.order = BspOrder::FrontToBack;
  render.aa = 4;
  (void)render_bsp(*tree, view, render);
  return 0;
}
