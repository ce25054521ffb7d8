// Ray packets through the k-d tree (see packet.h): the traversal, the edge filter and the exact
// tests. The lane loops run over all kPacketRays lanes with masks, four lanes to a vector; the
// kernel (packet_lanes.inc) is compiled for the baseline, AVX2 and AVX-512, and the first trace
// picks the one the CPU runs.
#include "src/engine/packet.h"

#include "src/engine/prim_accel.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <immintrin.h>
#include <limits>

namespace frontier {

namespace {

constexpr int N = kPacketRays;
using Mask = uint32_t;
static_assert(N < 32, "a lane mask is a uint32_t and make_soa shifts 1 by the lane count");

// The edge filter's margin, relative to max|d| · max|corner|²: the rounding of d · (b × c) is
// below 40 ulps of that and the watertight test's (shear, 2-D cross products) below 60, so a
// value beyond 1e-12 of it has the same sign in both.
constexpr double kEdgeMargin = 1e-12;

struct Lanes {
  alignas(64) double v[N];
};

// The helpers below pass vectors by value and are always inlined: no call crosses the ABI GCC
// warns about (-Wpsabi: AVX vectors returned without AVX enabled, as in the baseline copy).
#pragma GCC diagnostic ignored "-Wpsabi"

// Four lanes as one vector (GCC's vector extension: AVX registers in the AVX copies, SSE2
// pairs in the baseline), for the traversal's per-node step; a comparison gives 0 or -1 per
// lane.
using V4 = double __attribute__((vector_size(32)));
using M4 = long long __attribute__((vector_size(32)));
constexpr int kQuads = N / 4;
static_assert(N % 4 == 0, "the node step takes the lanes four at a time");

[[gnu::always_inline]] inline V4 quad(const Lanes& a, int q) {
  V4 r;
  __builtin_memcpy(&r, a.v + 4 * q, sizeof r);
  return r;
}
[[gnu::always_inline]] inline void set_quad(Lanes& a, int q, V4 x) { __builtin_memcpy(a.v + 4 * q, &x, sizeof x); }

}  // namespace

struct PacketStackEntry {
  int32_t node;
  Mask mask;
  Lanes near, far;
};

PacketLayout::PacketLayout(const Scene& scene, const KdTree& tree) {
  leaves_.resize(tree.cells().size());
  constexpr double kDoubleUlp = 0x1p-52;
  for (size_t c = 0; c < leaves_.size(); ++c) {
    const KdTree::Cell& cell = tree.cell(int32_t(c));
    Leaf& leaf = leaves_[c];
    const Vec3 base = cell.bounds.center();
    leaf.base[0] = base.x;
    leaf.base[1] = base.y;
    leaf.base[2] = base.z;
    leaf.first_block = uint32_t(blocks_.size());
    leaf.first_other = uint32_t(others_.size());
    leaf.tris = 0;
    for (uint32_t r = cell.first; r < cell.first + cell.count; ++r) {
      const uint32_t prim = tree.ref(r);
      const PrimRef& p = scene.prims[prim];
      if (p.kind != PrimKind::Triangle) {
        others_.push_back(prim);
        continue;
      }
      const int k = int(leaf.tris % kBlock);
      if (k == 0) blocks_.emplace_back();
      Block& b = blocks_.back();
      const Triangle& tri = scene.triangles[p.index];
      b.prim[k] = prim;
      b.index[k] = p.index;
      double error = 0.0;
      const Vec3* corners[3] = {&tri.v0, &tri.v1, &tri.v2};
      for (int corner = 0; corner < 3; ++corner) {
        const Vec3 local = *corners[corner] - base;  // rounded: off by at most an ulp of itself
        for (int a = 0; a < 3; ++a) {
          const auto f = float(local[a]);
          b.v[3 * corner + a][k] = f;
          error = std::max(error, std::abs(double(f) - local[a]) + kDoubleUlp * std::abs(local[a]));
        }
      }
      // Rounded up to float (a NaN or infinite corner gives an infinite bound: never rejected).
      const auto e = float(error);
      b.error[k] = std::isfinite(error) ? (double(e) >= error ? e : std::nextafter(e, INFINITY)) : INFINITY;
      ++leaf.tris;
    }
    // Unused slots of the last block: zero corners, never tested (the leaf's count says so).
    leaf.others = uint32_t(others_.size()) - leaf.first_other;
  }
}

size_t PacketLayout::bytes() const {
  return leaves_.capacity() * sizeof(Leaf) + blocks_.capacity() * sizeof(Block) +
         others_.capacity() * sizeof(uint32_t);
}

PacketTracer::PacketTracer(const Scene& scene, const KdTree& tree, CellMarks* marks, CellGate* gate,
                           const PacketLayout* layout, const PrimAccel* accel, KernelChoice* choice)
    : scene_(scene), tree_(tree), marks_(marks), gate_(gate), layout_(layout), accel_(accel), choice_(choice) {
  tree_changed();
}
PacketTracer::~PacketTracer() = default;
PacketTracer::PacketTracer(PacketTracer&&) noexcept = default;

void PacketTracer::tree_changed() {
  slack_scale_ = glm::length(tree_.bounds().extent()) + tree_.bounds().magnitude();
}

namespace {

// The packet in structure-of-arrays form, with what the traversal and the filter need.
struct Soa {
  Vec3 origin;
  Lanes d[3], inv[3];
  double dmax = 0.0;            // the largest |direction component| of any lane
  Mask lanes = 0;               // lanes in use
  int negative[3] = {0, 0, 0};  // per axis: every lane's component < 0
};

// False when the lanes disagree on a component's sign (zero counts as positive).
bool make_soa(const RayPacket& p, Soa& s) {
  s.origin = p.rays[0].origin;
  s.lanes = (Mask{1} << p.count) - 1;
  for (int a = 0; a < 3; ++a) {
    int neg = 0;
    for (int l = 0; l < N; ++l) {
      const Ray& r = p.rays[l < p.count ? l : 0];
      s.d[a].v[l] = r.dir[a];
      s.inv[a].v[l] = r.inv_dir[a];
      neg += r.dir[a] < 0.0 ? 1 : 0;
      s.dmax = std::max(s.dmax, std::abs(r.dir[a]));
    }
    if (neg != 0 && neg != N) return false;
    s.negative[a] = neg == N ? 1 : 0;
  }
  return true;
}

// The kernel (edge filter and traversal), once per instruction set: each copy in a namespace
// of its own, the AVX ones under a target pragma (every header is included before it, so no
// inline function shared with the rest of the program is compiled for AVX). PacketTracer::trace
// picks the copy the CPU runs when the program first traces a packet.
namespace lanes_baseline {
#include "src/engine/packet_lanes.inc"
}  // namespace lanes_baseline

#pragma GCC push_options
#pragma GCC target("avx2")
namespace lanes_avx2 {
#define FRONTIER_LANES_MOVEMASK 1
#include "src/engine/packet_lanes.inc"
#undef FRONTIER_LANES_MOVEMASK
}  // namespace lanes_avx2
#pragma GCC pop_options

#pragma GCC push_options
#pragma GCC target("avx512f")
namespace lanes_avx512 {
#define FRONTIER_LANES_MOVEMASK 1
#include "src/engine/packet_lanes.inc"
#undef FRONTIER_LANES_MOVEMASK
}  // namespace lanes_avx512
#pragma GCC pop_options

using TraceLanes = decltype(&lanes_baseline::trace_lanes);

TraceLanes kernel_for(PacketIsa isa) {
  switch (isa) {
    case PacketIsa::Avx512: return lanes_avx512::trace_lanes;
    case PacketIsa::Avx2: return lanes_avx2::trace_lanes;
    case PacketIsa::Baseline: break;
  }
  return lanes_baseline::trace_lanes;
}

PacketIsa best_isa() {
  for (const PacketIsa isa : {PacketIsa::Avx512, PacketIsa::Avx2}) {
    if (packet_isa_supported(isa)) return isa;
  }
  return PacketIsa::Baseline;
}

// The copy in use: the best the CPU runs, or what use_packet_isa() chose.
std::atomic<TraceLanes> chosen_kernel{nullptr};

}  // namespace

bool PacketTracer::trace(const RayPacket& packet, PacketResult& out, Counters& counters) {
  if (packet.count <= 0) return false;
  if (accel_ != nullptr && gate_ == nullptr) {
    if (choice_ == nullptr) {
      if (trace_accel(packet, out, counters)) return true;
    } else {
      // The kernel KernelChoice picks for this packet, timed when it asks.
      bool timed = false;
      const bool accel = choice_->use_accel(packets_++, timed);
      const auto t0 = timed ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point();
      bool traced = accel ? trace_accel(packet, out, counters) : trace_kd(packet, out, counters);
      if (traced && timed) {
        const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0);
        choice_->record(accel, uint64_t(ns.count()), uint64_t(packet.count));
      }
      if (traced) return true;
      if (accel) return trace_kd(packet, out, counters);
      return trace_accel(packet, out, counters);  // the k-d kernel refused it (mixed signs)
    }
  }
  return trace_kd(packet, out, counters);
}

bool PacketTracer::trace_kd(const RayPacket& packet, PacketResult& out, Counters& counters) {
  Soa s;
  if (!make_soa(packet, s)) return false;
  TraceLanes kernel = chosen_kernel.load(std::memory_order_relaxed);
  if (kernel == nullptr) {
    kernel = kernel_for(best_isa());
    chosen_kernel.store(kernel, std::memory_order_relaxed);
  }
  kernel(scene_, tree_, layout_, marks_, gate_, slack_scale_, stack_, s, packet, out, counters);
  counters.packet_rays += uint64_t(packet.count);
  return true;
}

// Each lane through Embree's BVH over the tree's bounds (where the k-d kernel would look: from
// its tmin up to its exit from the root, plus the slack); false, nothing traced, when Embree's
// float rays may stray beyond the accelerator's margin for some lane (then the k-d kernel).
bool PacketTracer::trace_accel(const RayPacket& packet, PacketResult& out, Counters& counters) {
  double t0[kPacketRays], t1[kPacketRays];
  bool inside[kPacketRays];
  double reach = 0.0, dmax = 0.0;
  for (int l = 0; l < packet.count; ++l) {
    const Ray& r = packet.rays[l];
    inside[l] = ray_box_interval(r, tree_.bounds(), t0[l], t1[l]) && std::max(t0[l], packet.tmin[l]) <= t1[l];
    if (!inside[l]) continue;
    t1[l] += cell_slack(t1[l], slack_scale_);
    reach = std::max(reach, t1[l]);
    dmax = std::max({dmax, std::abs(r.dir.x), std::abs(r.dir.y), std::abs(r.dir.z)});
  }
  if (!accel_->usable(packet.rays[0].origin, dmax, reach)) return false;
  out.parked = 0;
  for (int l = 0; l < packet.count; ++l) {
    out.hit[l] = {};
    if (inside[l]) accel_->trace(scene_, packet.rays[l], packet.tmin[l], t1[l], out.hit[l], counters);
  }
  counters.packet_rays += uint64_t(packet.count);
  return true;
}

bool packet_isa_supported(PacketIsa isa) {
  __builtin_cpu_init();
  switch (isa) {
    case PacketIsa::Avx512: return __builtin_cpu_supports("avx512f");
    case PacketIsa::Avx2: return __builtin_cpu_supports("avx2");
    case PacketIsa::Baseline: break;
  }
  return true;
}

PacketIsa packet_isa() {
  const TraceLanes kernel = chosen_kernel.load(std::memory_order_relaxed);
  for (const PacketIsa isa : {PacketIsa::Avx512, PacketIsa::Avx2, PacketIsa::Baseline}) {
    if (kernel == kernel_for(isa)) return isa;
  }
  return best_isa();
}

bool use_packet_isa(PacketIsa isa) {
  if (!packet_isa_supported(isa)) return false;
  chosen_kernel.store(kernel_for(isa), std::memory_order_relaxed);
  return true;
}

}  // namespace frontier
