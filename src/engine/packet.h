// Ray packets: up to kPacketRays rays from one origin (a block of primary rays from the eye)
// traced together through the k-d tree, Wald's coherent traversal (2001): one descent from the
// root for all of them, each lane with its own interval, the near child first in the direction
// the lanes share, a node left as soon as no lane still needs it. A leaf's nodes, references
// and triangles are read once for the packet instead of once per ray, and its triangles are
// first tested against every lane at once by a conservative edge test (the sign of d · (b × c)
// for the triangle's corners seen from the origin) that rejects only rays surely outside;
// the lanes it leaves get the exact watertight test ray walking uses (intersect_triangle).
//
// Exactness: the hit of each lane is the one walk_ray finds — the nearest, ties to the lower
// primitive — because leaves are visited in each lane's order along its ray, a hit counts only
// before the lane's exit from the leaf (plus the same slack), and the filter's margin only
// rejects rays the exact test would miss: 1e-12 of the corners' magnitudes (~10^4 times the
// rounding of either test) where it runs in double precision, and 128 units of float rounding
// (about 4 times what its single-precision arithmetic can lose) plus the corners' own rounding
// where it runs on the leaf layout's float corners, eight triangles to an instruction. A lane
// reaching a missing cell (CellGate) before any hit stops there, parked, as a lone walk is.
//
// Packets need the lanes to agree on the sign of each direction component (so "near child"
// means the same for all); trace() refuses the rare packet that does not (a block across the
// view axis' projection when it is parallel to a world axis), and the caller walks its rays.
#pragma once

#include "src/core/counters.h"
#include "src/core/geometry.h"
#include "src/core/sample_buffer.h"
#include "src/core/scene.h"
#include "src/engine/cell_gate.h"
#include "src/engine/kdtree.h"
#include "src/engine/ray_walk.h"

#include <cstdint>
#include <vector>

namespace frontier {

constexpr int kPacketRays = 16;

struct RayPacket {
  int count = 0;
  Ray rays[kPacketRays];
  double tmin[kPacketRays];
  // Adds a ray from the packet's origin (the first ray's); false when the packet is full or the
  // ray starts elsewhere.
  bool add(const Ray& ray, double t_min) {
    if (count == kPacketRays || (count > 0 && ray.origin != rays[0].origin)) return false;
    rays[count] = ray;
    tmin[count] = t_min;
    ++count;
    return true;
  }
};

struct PacketResult {
  RayHit hit[kPacketRays];
  uint32_t parked = 0;  // lanes stopped by a missing cell before a hit (bit k: lane k)
};

struct PacketStackEntry;
class PrimAccel;
class KernelChoice;

// The instruction sets the packet kernel is compiled for; the best one the CPU runs is used
// unless use_packet_isa() says otherwise. Every one gives the same hits (tests run each one the
// CPU has against brute force).
enum class PacketIsa { Baseline, Avx2, Avx512 };
bool packet_isa_supported(PacketIsa isa);
// The kernel traces use from now on (all threads); false, changing nothing, when the CPU lacks it.
bool use_packet_isa(PacketIsa isa);
PacketIsa packet_isa();

// The tree's leaves laid out for packets: per cell a header (a base point, its blocks of
// triangles and its other primitives) and its triangles in blocks of kBlock, structure of
// arrays: corners in float relative to the base, each triangle with a bound on that rounding,
// its primitive and triangle index. The edge filter reads a block contiguously and tests its
// triangles side by side in single precision, instead of following reference → primitive →
// triangle per triangle; the exact test still reads the scene's own triangle. Built once per
// tree (a pass over its references).
class PacketLayout {
 public:
  static constexpr int kBlock = 8;
  PacketLayout(const Scene& scene, const KdTree& tree);
  struct Leaf {
    double base[3];
    uint32_t first_block, tris, first_other, others;
  };
  struct Block {
    float v[9][kBlock];    // corner k's component a at [3k + a]: minus the base
    float error[kBlock];   // bound on |float corner - exact corner| (per component)
    uint32_t prim[kBlock];   // scene primitive
    uint32_t index[kBlock];  // scene.triangles index
  };
  const Leaf& leaf(int32_t cell) const { return leaves_[size_t(cell)]; }
  const Block* blocks() const { return blocks_.data(); }
  const uint32_t* others() const { return others_.data(); }
  size_t cells() const { return leaves_.size(); }
  size_t bytes() const;

 private:
  std::vector<Leaf> leaves_;
  std::vector<Block> blocks_;
  std::vector<uint32_t> others_;
};

// Traces packets through one tree; holds the traversal stack (one tracer per thread).
class PacketTracer {
 public:
  // `gate` and `marks` may be null (every cell present; no working set kept).
  // With `layout` (built from the same scene and tree) leaves are read from it. With `accel`
  // (over the same scene) and no gate, each ray is traced through Embree's BVH with the same
  // exact tests instead, where PrimAccel::usable() allows (prim_accel.h; no cell is marked);
  // with `choice` too, for the packets it gives to Embree's BVH (the faster kernel, measured).
  PacketTracer(const Scene& scene, const KdTree& tree, CellMarks* marks = nullptr, CellGate* gate = nullptr,
               const PacketLayout* layout = nullptr, const PrimAccel* accel = nullptr,
               KernelChoice* choice = nullptr);
  ~PacketTracer();
  PacketTracer(PacketTracer&&) noexcept;
  // Where the next traces mark cells, ask for missing ones, and read leaves (see the constructor).
  void bind(CellMarks* marks, CellGate* gate, const PacketLayout* layout, const PrimAccel* accel = nullptr,
            KernelChoice* choice = nullptr) {
    marks_ = marks;
    gate_ = gate;
    layout_ = layout;
    accel_ = accel;
    choice_ = choice;
  }
  // Traces every lane; false (nothing traced, `out` untouched) when the lanes disagree on the
  // sign of a direction component (through the k-d tree; Embree's BVH takes any packet). Counters: cell_visits per lane and cell, cells_touched,
  // primitives_tested per lane and reference, ray_primitive_tests and hits of the exact tests,
  // packet_filter_tests (lane × triangle edge tests) and packet_rays.
  bool trace(const RayPacket& packet, PacketResult& out, Counters& counters);
  // The tree changed (PagedWorld grafted or unlinked cells): the slack scale is taken again.
  void tree_changed();

 private:
  bool trace_accel(const RayPacket& packet, PacketResult& out, Counters& counters);
  bool trace_kd(const RayPacket& packet, PacketResult& out, Counters& counters);
  const Scene& scene_;
  const KdTree& tree_;
  CellMarks* marks_;
  CellGate* gate_;
  const PacketLayout* layout_;
  const PrimAccel* accel_;
  KernelChoice* choice_;
  uint64_t packets_ = 0;  // traced so far (KernelChoice::use_accel)
  double slack_scale_ = 1.0;
  std::vector<PacketStackEntry> stack_;
};

}  // namespace frontier
