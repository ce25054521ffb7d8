// What every FrameRenderer shares: turning scene primitive indices into input ids.
#include "src/engine/frame_renderer.h"

namespace frontier {

std::vector<uint32_t> source_ids(const Scene& scene, std::vector<uint32_t> prim_ids) {
  for (uint32_t& id : prim_ids) {
    if (id != kNoPrim) id = scene.prims[id].source;
  }
  return prim_ids;
}

}  // namespace frontier
