// Sphere-and-cylinder NFF scenes (see header). Everything is streamed: recursive families
// are walked depth-first and recomputed (from per-node seeded streams) instead of stored.
#include "data_gen/spheres.h"

#include "src/core/progress.h"
#include "data_gen/rng.h"
#include "src/io/nff_writer.h"

#include <fmt/format.h>

#include <array>
#include <cmath>
#include <functional>
#include <numbers>

namespace frontier::gen {
namespace {

constexpr double kPi = std::numbers::pi;

uint64_t saturating_pow(uint64_t b, int e) {
  uint64_t r = 1;
  for (int i = 0; i < e; ++i) r = r > UINT64_MAX / b ? UINT64_MAX : r * b;
  return r;
}

// Orthonormal u, v with u x v = w.
void frame_of(const Vec3& w, Vec3& u, Vec3& v) {
  const Vec3 helper = std::abs(w.z) < 0.9 ? Vec3(0, 0, 1) : Vec3(1, 0, 0);
  u = glm::normalize(glm::cross(helper, w));
  v = glm::cross(w, u);
}

Material shiny(Vec3 color) {
  Material m;
  m.color = color;
  m.kd = 0.7;
  m.ks = 0.3;
  m.shine = 20.0;
  return m;
}

// The NffWriter the families write through: shapes go to the writer, and every 4096 of them
// (and the rest at flush) to the progress report.
class ProgressWriter {
 public:
  ProgressWriter(NffWriter& w, Progress& progress) : w_(w), progress_(progress) {}
  void sphere(const Vec3& c, double r) {
    w_.sphere(c, r);
    tick();
  }
  void cone(const Vec3& a, double ra, const Vec3& b, double rb) {
    w_.cone(a, ra, b, rb);
    tick();
  }
  NffWriter& writer() { return w_; }
  void flush() {
    progress_.advance(pending_);
    pending_ = 0;
  }

 private:
  void tick() {
    if (++pending_ == 4096) {
      progress_.advance(pending_);
      pending_ = 0;
    }
  }
  NffWriter& w_;
  Progress& progress_;
  uint64_t pending_ = 0;
};

// --- rings -------------------------------------------------------------------------------
constexpr int kRingSpheres = 12;
constexpr double kRingRadius = 0.55, kRingSphere = 0.09, kRingRod = 0.035;

void rings(ProgressWriter& s, int k, const SpheresParams& p) {
  static const Vec3 kColors[3] = {{0.85, 0.25, 0.2}, {0.25, 0.7, 0.3}, {0.25, 0.4, 0.9}};
  for (int orientation = 0; orientation < 3; ++orientation) {
    s.writer().material(shiny(kColors[orientation]));
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j)
        for (int l = 0; l < k; ++l) {
          if ((i + j + l) % 3 != orientation) continue;
          Rng rng(p.seed, Stream::Spheres, 1, i, j, l);
          const Vec3 c(i, j, l);
          Vec3 u, v;
          frame_of(Vec3(orientation == 0, orientation == 1, orientation == 2), u, v);
          const double phase = rng.uniform(0.0, 2 * kPi / kRingSpheres);
          std::array<Vec3, kRingSpheres> pts;
          for (int n = 0; n < kRingSpheres; ++n) {
            const double a = phase + 2 * kPi * n / kRingSpheres;
            pts[n] = c + kRingRadius * (std::cos(a) * u + std::sin(a) * v);
          }
          for (int n = 0; n < kRingSpheres; ++n) {
            s.sphere(pts[n], kRingSphere);
            s.cone(pts[n], kRingRod, pts[(n + 1) % kRingSpheres], kRingRod);
          }
        }
  }
}

// --- tree --------------------------------------------------------------------------------
struct Branch {
  Vec3 start, dir;
  double length, radius;
};

// Visits branch `id` (heap numbering: children 2id+1, 2id+2) and its subtree.
void walk_tree(const SpheresParams& p, int depth, uint64_t id, const Branch& b,
               const std::function<void(const Branch&, bool leaf)>& visit) {
  const bool leaf = depth == p.size;
  visit(b, leaf);
  if (leaf) return;
  Rng rng(p.seed, Stream::Spheres, 2, id);
  Vec3 u, v;
  frame_of(b.dir, u, v);
  const double azimuth = rng.uniform(0.0, 2 * kPi);
  const Vec3 end = b.start + b.dir * b.length;
  for (int c = 0; c < 2; ++c) {
    const double tilt = rng.uniform(22.0, 40.0) * kPi / 180.0;
    const double az = azimuth + c * kPi + rng.uniform(-0.3, 0.3);
    const Vec3 side = std::cos(az) * u + std::sin(az) * v;
    Branch child{end, glm::normalize(std::cos(tilt) * b.dir + std::sin(tilt) * side),
                 b.length * rng.uniform(0.72, 0.82), b.radius * 0.7};
    walk_tree(p, depth + 1, 2 * id + 1 + c, child, visit);
  }
}

void tree(ProgressWriter& s, const SpheresParams& p) {
  const Branch trunk{Vec3(0.0), Vec3(0, 0, 1), 1.0, 0.08};
  s.writer().material(shiny({0.55, 0.35, 0.2}));
  walk_tree(p, 0, 0, trunk, [&](const Branch& b, bool leaf) {
    const Vec3 end = b.start + b.dir * b.length;
    s.cone(b.start, b.radius, end, b.radius * 0.7);
    if (!leaf) s.sphere(end, b.radius * 0.7);
  });
  s.writer().material(shiny({0.2, 0.65, 0.25}));
  walk_tree(p, 0, 0, trunk, [&](const Branch& b, bool leaf) {
    if (leaf) s.sphere(b.start + b.dir * b.length, std::max(b.radius * 2.5, 0.02 * b.length + b.radius));
  });
}

// --- flake -------------------------------------------------------------------------------
constexpr int kFlakeChildren = 9;

void flake_node(ProgressWriter& s, const SpheresParams& p, int depth, uint64_t id, const Vec3& c, double r,
                const Vec3& axis) {
  s.sphere(c, r);
  if (depth == p.size) return;
  Rng rng(p.seed, Stream::Spheres, 3, id);
  Vec3 u, v;
  frame_of(axis, u, v);
  const double twist = rng.uniform(0.0, 2 * kPi);
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < kFlakeChildren; ++k) {
    // Fibonacci points on the outer hemisphere, from near the pole to near the equator.
    const double z = 1.0 - (k + 0.5) / kFlakeChildren;
    const double rho = std::sqrt(1.0 - z * z), phi = twist + k * golden;
    const Vec3 dir = z * axis + rho * (std::cos(phi) * u + std::sin(phi) * v);
    flake_node(s, p, depth + 1, id * kFlakeChildren + 1 + k, c + dir * (r * 4.0 / 3.0), r / 3.0, dir);
  }
}

// --- shells ------------------------------------------------------------------------------
void shells(ProgressWriter& s, const SpheresParams& p) {
  const uint64_t n = 200ull * p.size * p.size;
  const double turns = 4.0 + p.size, theta_max = turns * 2 * kPi;
  const double shrink = std::log(60.0) / theta_max;  // apex spheres are 1/60 of the mouth's
  Rng rng(p.seed, Stream::Spheres, 4);
  const double twist = rng.uniform(0.0, 2 * kPi);
  s.writer().material(shiny({0.9, 0.75, 0.6}));
  for (uint64_t i = 0; i < n; ++i) {
    const double theta = theta_max * static_cast<double>(i) / static_cast<double>(n - 1);
    const double scale = std::exp(-shrink * (theta_max - theta));  // 1 at the mouth
    const double a = theta + twist;
    const Vec3 c(scale * std::cos(a), scale * std::sin(a), 2.2 * (1.0 - scale));
    s.sphere(c, 0.45 * scale);
  }
}

Aabb scene_bounds(const SpheresParams& p) {
  switch (p.family) {
    case SphereFamily::Rings: {
      const double m = kRingRadius + kRingSphere;
      return Aabb(Vec3(-m), Vec3(p.size - 1 + m));
    }
    case SphereFamily::Tree: {
      Aabb b;
      walk_tree(p, 0, 0, Branch{Vec3(0.0), Vec3(0, 0, 1), 1.0, 0.08}, [&](const Branch& br, bool) {
        const Vec3 e = br.start + br.dir * br.length;
        b.extend(br.start - Vec3(br.radius));
        b.extend(e + Vec3(3 * br.radius + 0.02 * br.length));
        b.extend(e - Vec3(3 * br.radius + 0.02 * br.length));
      });
      return b;
    }
    case SphereFamily::Flake: return Aabb(Vec3(-2.0), Vec3(2.0));
    case SphereFamily::Shells: return Aabb(Vec3(-1.5, -1.5, -0.5), Vec3(1.5, 1.5, 2.7));
  }
  return {};
}

}  // namespace

uint64_t spheres_primitive_count(const SpheresParams& p) {
  const uint64_t k = static_cast<uint64_t>(std::max(0, p.size));
  switch (p.family) {
    case SphereFamily::Rings: return saturating_pow(k, 3) > UINT64_MAX / 24 ? UINT64_MAX : 24 * k * k * k + 1;
    case SphereFamily::Tree: {
      const uint64_t b = saturating_pow(2, p.size + 1);
      return b > UINT64_MAX / 3 ? UINT64_MAX : 2 * (b - 1) + 1;
    }
    case SphereFamily::Flake: {
      const uint64_t b = saturating_pow(9, p.size + 1);
      return b == UINT64_MAX ? b : (b - 1) / 8 + 1;
    }
    case SphereFamily::Shells: return 200 * k * k + 1;
  }
  return 0;
}

Status validate(const SpheresParams& p) {
  if (p.size < 1) return Status::invalid_argument(fmt::format("--size {} must be at least 1", p.size));
  if (p.size > 100000)
    return Status::invalid_argument(fmt::format("--size {} is too large", p.size));
  const uint64_t n = spheres_primitive_count(p);
  if (n > kMaxQuadrics)
    return Status::invalid_argument(fmt::format(
        "--size {}: {} primitives exceed the limit of {}", p.size, n, kMaxQuadrics));
  return Status::ok();
}

Status write_spheres(const SpheresParams& p, const std::string& path, bool quiet) {
  Status st = validate(p);
  if (!st) return st;
  auto writer = NffWriter::create(path);
  if (!writer) return writer.status();
  NffWriter& w = **writer;
  static const char* kNames[] = {"rings", "tree", "flake", "shells"};
  w.comment(fmt::format("frontier-gen spheres --family {} --size {} --seed {}",
                        kNames[static_cast<int>(p.family)], p.size, p.seed));
  w.comment(fmt::format("{} primitives; z up", spheres_primitive_count(p)));

  const Aabb b = scene_bounds(p);
  const Vec3 center = b.center();
  const double radius = 0.5 * glm::length(b.extent());
  Camera cam;
  cam.vfov_deg = 45.0;
  cam.look_at = center;
  cam.eye = center + glm::normalize(Vec3(1.1, -1.7, 0.9)) * (radius / std::sin(0.5 * cam.vfov_deg * kPi / 180.0));
  cam.up = Vec3(0, 0, 1);
  w.background(Vec3(0.078, 0.361, 0.753));
  w.view(cam, 0.01 * radius, 512, 512);
  w.light(center + Vec3(-2.0, -3.0, 4.0) * radius, Vec3(1.0));
  w.light(center + Vec3(3.0, -1.0, 2.0) * radius, Vec3(0.6));
  w.material(shiny({0.6, 0.6, 0.55}));
  const double gz = b.lo.z - 0.02 * radius, g = 3.0 * radius;
  const Vec3 ground[4] = {{center.x - g, center.y - g, gz}, {center.x + g, center.y - g, gz},
                          {center.x + g, center.y + g, gz}, {center.x - g, center.y + g, gz}};
  w.polygon(ground);

  Progress progress("spheres", "primitives", spheres_primitive_count(p), quiet);
  progress.advance(1);  // the ground polygon
  ProgressWriter s(w, progress);
  switch (p.family) {
    case SphereFamily::Rings: rings(s, p.size, p); break;
    case SphereFamily::Tree: tree(s, p); break;
    case SphereFamily::Flake:
      w.material(shiny({0.85, 0.85, 0.9}));
      flake_node(s, p, 0, 0, Vec3(0.0), 1.0, Vec3(0, 0, 1));
      break;
    case SphereFamily::Shells: shells(s, p); break;
  }
  s.flush();
  st = w.finish();
  if (!st) return st;
  progress.finish();
  return Status::ok();
}

}  // namespace frontier::gen
