// CellGate: out-of-core rendering's view of which cells' geometry is in memory (PagedWorld
// implements it). Work that reaches a missing cell waits for it instead of treating it as
// empty: frustum casting parks the frustum or pixel, a shadow ray reports that it cannot decide
// (occlusion() in ray_walk.h), and want() asks for the cell. Nothing is ever resolved past a
// missing cell, so every confirmed sample stays exact.
// Threads: both calls come from render worker threads while a frame slice runs.
#pragma once

#include <cstdint>

namespace frontier {

class CellGate {
 public:
  virtual ~CellGate() = default;
  virtual bool missing(int32_t cell) const = 0;
  virtual void want(int32_t cell) = 0;
};

}  // namespace frontier
