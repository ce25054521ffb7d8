// Ray packets through the k-d tree (see packet.h): the traversal, the edge filter and the exact
// tests. The lane loops run over all kPacketRays lanes with masks so that the compiler makes
// them vector code; the body is compiled for AVX-512, AVX2 and the baseline and the CPU picks
// one when the program starts (target_clones).
#include "src/engine/packet.h"

#include <algorithm>
#include <bit>
#include <cmath>

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
                           const PacketLayout* layout)
    : scene_(scene), tree_(tree), marks_(marks), gate_(gate), layout_(layout) {
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

// Lanes whose rays meet the triangle's three edge planes (through the origin) on mixed sides by
// more than the margin: rays the exact test surely misses. a, b, c are rounded exactly as
// intersect_triangle rounds them.
[[gnu::always_inline]] inline Mask edge_reject(const Soa& s, const Triangle& tri) {
  const Vec3 a = tri.v0 - s.origin, b = tri.v1 - s.origin, c = tri.v2 - s.origin;
  const Vec3 n0 = glm::cross(b, c), n1 = glm::cross(c, a), n2 = glm::cross(a, b);
  const auto inf_norm = [](const Vec3& v) { return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)}); };
  const double m = std::max({inf_norm(a), inf_norm(b), inf_norm(c)});
  const double margin = kEdgeMargin * s.dmax * m * m;
  Mask reject = 0;
  for (int l = 0; l < N; ++l) {
    const double dx = s.d[0].v[l], dy = s.d[1].v[l], dz = s.d[2].v[l];
    const double e0 = dx * n0.x + dy * n0.y + dz * n0.z;
    const double e1 = dx * n1.x + dy * n1.y + dz * n1.z;
    const double e2 = dx * n2.x + dy * n2.y + dz * n2.z;
    const bool pos = (e0 > margin) | (e1 > margin) | (e2 > margin);
    const bool neg = (e0 < -margin) | (e1 < -margin) | (e2 < -margin);
    reject |= Mask(pos & neg) << l;
  }
  return reject;
}

// The edge normals of a block's triangles seen from the origin (in the leaf's frame), with
// their margins: a block at a time, side by side. The corners are float, relative to the leaf's
// base, so each margin also covers their rounding (error), the origin's in the base's frame and
// the differences'.
struct BlockEdges {
  static constexpr int K = PacketLayout::kBlock;
  alignas(64) double n[9][K];  // edge e's normal component a at [3e + a]
  alignas(64) double margin[K];
};

[[gnu::always_inline]] inline void block_edges(const PacketLayout::Block& b, const Vec3& o, double dmax,
                                               BlockEdges& out) {
  constexpr int K = PacketLayout::kBlock;
  constexpr double kDoubleUlp = 0x1p-52;
  const double o_norm = std::max({std::abs(o.x), std::abs(o.y), std::abs(o.z)});
  for (int k = 0; k < K; ++k) {
    const double ax = double(b.v[0][k]) - o.x, ay = double(b.v[1][k]) - o.y, az = double(b.v[2][k]) - o.z;
    const double bx = double(b.v[3][k]) - o.x, by = double(b.v[4][k]) - o.y, bz = double(b.v[5][k]) - o.z;
    const double cx = double(b.v[6][k]) - o.x, cy = double(b.v[7][k]) - o.y, cz = double(b.v[8][k]) - o.z;
    // n0 = b × c, n1 = c × a, n2 = a × b
    out.n[0][k] = by * cz - bz * cy;
    out.n[1][k] = bz * cx - bx * cz;
    out.n[2][k] = bx * cy - by * cx;
    out.n[3][k] = cy * az - cz * ay;
    out.n[4][k] = cz * ax - cx * az;
    out.n[5][k] = cx * ay - cy * ax;
    out.n[6][k] = ay * bz - az * by;
    out.n[7][k] = az * bx - ax * bz;
    out.n[8][k] = ax * by - ay * bx;
    const double m0 = std::max(std::max(std::max(std::abs(ax), std::abs(ay)), std::max(std::abs(az), std::abs(bx))),
                               std::max(std::max(std::abs(by), std::abs(bz)),
                                        std::max(std::max(std::abs(cx), std::abs(cy)), std::abs(cz))));
    // Per component, how far a, b, c may lie from the exact corner minus origin.
    const double delta = double(b.error[k]) + kDoubleUlp * (o_norm + m0);
    const double m = m0 + delta;
    // Each edge value is d · (p × q): three components of two products each. Moving p and q by
    // delta moves it by at most 3 · dmax · 2 · delta · m (the factor 2 again for safety).
    out.margin[k] = dmax * (kEdgeMargin * m * m + 12.0 * delta * m);
  }
}

// The block's triangles (bits) a ray of direction (dx, dy, dz) surely misses.
[[gnu::always_inline]] inline uint32_t block_reject(const BlockEdges& e, double dx, double dy, double dz) {
  constexpr int K = PacketLayout::kBlock;
  uint32_t reject = 0;
  for (int k = 0; k < K; ++k) {
    const double e0 = dx * e.n[0][k] + dy * e.n[1][k] + dz * e.n[2][k];
    const double e1 = dx * e.n[3][k] + dy * e.n[4][k] + dz * e.n[5][k];
    const double e2 = dx * e.n[6][k] + dy * e.n[7][k] + dz * e.n[8][k];
    const double m = e.margin[k];
    const bool pos = (e0 > m) | (e1 > m) | (e2 > m);
    const bool neg = (e0 < -m) | (e1 < -m) | (e2 < -m);
    reject |= uint32_t(pos & neg) << k;
  }
  return reject;
}

// The traversal (packet.h), compiled per instruction set.
__attribute__((target_clones("avx512f", "avx2", "default"))) void trace_lanes(
    const Scene& scene, const KdTree& tree, const PacketLayout* layout, CellMarks* marks, CellGate* gate,
    double slack_scale, std::vector<PacketStackEntry>& stack, const Soa& s, const RayPacket& packet, PacketResult& out,
    Counters& counters) {
  const std::vector<KdTree::Node>& nodes = tree.nodes();
  Lanes near, far;
  Mask mask = 0;
  for (int l = 0; l < N; ++l) {
    out.hit[l] = {};
    near.v[l] = kInfinity;
    far.v[l] = -kInfinity;
    double t0, t1;
    if (l < packet.count && ray_box_interval(packet.rays[l], tree.bounds(), t0, t1)) {
      near.v[l] = std::max(t0, packet.tmin[l]);
      far.v[l] = t1;
      if (near.v[l] <= far.v[l]) mask |= Mask{1} << l;
    }
  }
  out.parked = 0;
  Mask alive = s.lanes;  // lanes without a hit and not parked
  stack.clear();
  int32_t node = 0;
  while (mask != 0) {
    const KdTree::Node* nd = &nodes[size_t(node)];
    while (!nd->is_leaf()) {
      if (nd->is_link()) {
        node = int32_t(nd->child);
        nd = &nodes[size_t(node)];
        continue;
      }
      const int axis = int(nd->axis_or_leaf);
      const double diff = nd->split - s.origin[axis];
      const Lanes& d = s.d[axis];
      const Lanes& inv = s.inv[axis];
      Lanes ts;
      Mask need_near = 0, need_far = 0;
      for (int l = 0; l < N; ++l) {
        // A ray parallel to the plane stays on its side: the lower one (the near one: zero
        // counts as positive) when it starts below, else the upper (ties: upper, as descend).
        const double t = d.v[l] == 0.0 ? (diff > 0.0 ? kInfinity : -kInfinity) : diff * inv.v[l];
        ts.v[l] = t;
        need_near |= Mask(near.v[l] <= t) << l;
        need_far |= Mask(t <= far.v[l]) << l;
      }
      need_near &= mask;
      need_far &= mask;
      const auto lower = node + 1, upper = int32_t(nd->child);
      const int32_t near_child = s.negative[axis] ? upper : lower;
      const int32_t far_child = s.negative[axis] ? lower : upper;
      if (need_far == 0) {
        for (int l = 0; l < N; ++l) far.v[l] = std::min(far.v[l], ts.v[l]);
        mask = need_near;
        node = near_child;
      } else if (need_near == 0) {
        for (int l = 0; l < N; ++l) near.v[l] = std::max(near.v[l], ts.v[l]);
        mask = need_far;
        node = far_child;
      } else {
        PacketStackEntry& e = stack.emplace_back();
        e.node = far_child;
        e.mask = need_far;
        e.far = far;
        for (int l = 0; l < N; ++l) {
          e.near.v[l] = std::max(near.v[l], ts.v[l]);
          far.v[l] = std::min(far.v[l], ts.v[l]);
        }
        mask = need_near;
        node = near_child;
      }
      nd = &nodes[size_t(node)];
    }
    // A leaf: the lanes in `mask` cross it over [near, far], nearest first.
    const auto cell = int32_t(nd->child);
    mask &= alive;
    if (mask != 0) {
      counters.cell_visits += uint64_t(std::popcount(mask));
      ++counters.packet_leaves;
      if (marks != nullptr && marks->mark(cell)) ++counters.cells_touched;
      if (gate != nullptr && gate->missing(cell)) {
        gate->want(cell);
        out.parked |= mask;
        alive &= ~mask;
      } else if (layout != nullptr) {
        const PacketLayout::Leaf& leaf = layout->leaf(cell);
        if (leaf.tris + leaf.others > 0) {
          Lanes tmax;
          for (int l = 0; l < N; ++l) tmax.v[l] = far.v[l] + cell_slack(far.v[l], slack_scale);
          const uint64_t lanes = uint64_t(std::popcount(mask));
          counters.primitives_tested += uint64_t(leaf.tris + leaf.others) * lanes;
          counters.packet_filter_tests += uint64_t(leaf.tris) * lanes;
          const Vec3 origin_local = s.origin - Vec3(leaf.base[0], leaf.base[1], leaf.base[2]);
          const PacketLayout::Block* blocks = layout->blocks() + leaf.first_block;
          for (uint32_t first = 0; first < leaf.tris; first += PacketLayout::kBlock) {
            const PacketLayout::Block& b = blocks[first / PacketLayout::kBlock];
            const uint32_t in_block = std::min<uint32_t>(leaf.tris - first, PacketLayout::kBlock);
            const uint32_t used = (1u << in_block) - 1;
            BlockEdges edges;
            block_edges(b, origin_local, s.dmax, edges);
            for (Mask m = mask; m != 0; m &= m - 1) {
              const int l = std::countr_zero(m);
              uint32_t test = used & ~block_reject(edges, s.d[0].v[l], s.d[1].v[l], s.d[2].v[l]);
              RayHit& best = out.hit[l];
              for (; test != 0; test &= test - 1) {
                const int k = std::countr_zero(test);
                double th = 0.0;
                const bool hit = intersect_triangle(scene.triangles[b.index[k]], packet.rays[l], packet.tmin[l],
                                                    std::min(tmax.v[l], best.t), th);
                record_test(hit, b.prim[k], th, best, counters);
              }
            }
          }
          const uint32_t* others = layout->others() + leaf.first_other;
          for (uint32_t k = 0; k < leaf.others; ++k) {
            for (Mask m = mask; m != 0; m &= m - 1) {
              const int l = std::countr_zero(m);
              RayHit& best = out.hit[l];
              double th = 0.0;
              const bool hit =
                  scene.intersect(others[k], packet.rays[l], packet.tmin[l], std::min(tmax.v[l], best.t), th);
              record_test(hit, others[k], th, best, counters);
            }
          }
          for (Mask m = mask; m != 0; m &= m - 1) {
            const int l = std::countr_zero(m);
            if (out.hit[l].hit()) alive &= ~(Mask{1} << l);
          }
        }
      } else if (const KdTree::Cell& c = tree.cell(cell); c.count > 0) {
        Lanes tmax;
        for (int l = 0; l < N; ++l) tmax.v[l] = far.v[l] + cell_slack(far.v[l], slack_scale);
        counters.primitives_tested += uint64_t(c.count) * uint64_t(std::popcount(mask));
        for (uint32_t r = c.first; r < c.first + c.count; ++r) {
          const uint32_t prim = tree.ref(r);
          const PrimRef& p = scene.prims[prim];
          Mask test = mask;
          if (p.kind == PrimKind::Triangle) {
            counters.packet_filter_tests += uint64_t(std::popcount(mask));
            test &= ~edge_reject(s, scene.triangles[p.index]);
          }
          for (Mask m = test; m != 0; m &= m - 1) {
            const int l = std::countr_zero(m);
            RayHit& best = out.hit[l];
            double t = 0.0;
            const bool hit = scene.intersect(prim, packet.rays[l], packet.tmin[l], std::min(tmax.v[l], best.t), t);
            record_test(hit, prim, t, best, counters);
          }
        }
        for (Mask m = mask; m != 0; m &= m - 1) {
          const int l = std::countr_zero(m);
          if (out.hit[l].hit()) alive &= ~(Mask{1} << l);
        }
      }
    }
    // The next node some live lane still needs.
    mask = 0;
    while (mask == 0 && !stack.empty()) {
      const PacketStackEntry& e = stack.back();
      mask = e.mask & alive;
      if (mask != 0) {
        node = e.node;
        near = e.near;
        far = e.far;
      }
      stack.pop_back();
    }
  }
}

}  // namespace

bool PacketTracer::trace(const RayPacket& packet, PacketResult& out, Counters& counters) {
  if (packet.count <= 0) return false;
  Soa s;
  if (!make_soa(packet, s)) return false;
  trace_lanes(scene_, tree_, layout_, marks_, gate_, slack_scale_, stack_, s, packet, out, counters);
  counters.packet_rays += uint64_t(packet.count);
  return true;
}

}  // namespace frontier
