// PrimAccel (prim_accel.h): Embree's BVH over user geometry, frontier's exact test in the
// callback.
#include "src/engine/prim_accel.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <utility>

namespace frontier {

namespace {

void report_error(void*, RTCError code, const char* message) {
  std::fprintf(stderr, "frontier: Embree error %d: %s\n", int(code), message != nullptr ? message : "");
}

// One device for the process; its builds run on Embree's TBB threads (as many as the machine's).
RTCDevice device() {
  static RTCDevice d = [] {
    RTCDevice created = rtcNewDevice(nullptr);
    if (created == nullptr) {
      std::fprintf(stderr, "frontier: rtcNewDevice failed (%d)\n", int(rtcGetDeviceError(nullptr)));
      std::abort();
    }
    rtcSetDeviceErrorFunction(created, report_error, nullptr);
    return created;
  }();
  return d;
}

float round_down(double x) {
  const auto f = float(x);
  return double(f) <= x ? f : std::nextafter(f, -std::numeric_limits<float>::infinity());
}
float round_up(double x) {
  const auto f = float(x);
  return double(f) >= x ? f : std::nextafter(f, std::numeric_limits<float>::infinity());
}

// What the bounds callback reads while the BVH is built.
struct BuildInput {
  const Scene* scene;
  Vec3 centre;
  double margin;
};

void bounds(const RTCBoundsFunctionArguments* args) {
  const auto* in = static_cast<const BuildInput*>(args->geometryUserPtr);
  Aabb b = in->scene->prim_bounds(args->primID);
  b.lo -= in->centre;
  b.hi -= in->centre;
  RTCBounds* o = args->bounds_o;
  o->lower_x = round_down(b.lo.x - in->margin);
  o->lower_y = round_down(b.lo.y - in->margin);
  o->lower_z = round_down(b.lo.z - in->margin);
  o->upper_x = round_up(b.hi.x + in->margin);
  o->upper_y = round_up(b.hi.y + in->margin);
  o->upper_z = round_up(b.hi.z + in->margin);
}

// What the intersect callback reads: the one ray being traced (rtcIntersect1).
struct TraceContext {
  RTCIntersectContext context;  // first: Embree hands the callback a pointer to it
  const Scene* scene;
  const Ray* ray;
  double tmin, tmax;
  RayHit* best;
  Counters* counters;
};

void intersect(const RTCIntersectFunctionNArguments* args) {
  if (args->valid[0] != -1) return;
  const auto* c = reinterpret_cast<const TraceContext*>(args->context);
  const uint32_t prim = args->primID;
  RayHit& best = *c->best;
  double t = 0.0;
  const bool hit = c->scene->intersect(prim, *c->ray, c->tmin, std::min(c->tmax, best.t), t);
  const RayHit before = best;
  record_test(hit, prim, t, best, *c->counters);
  if (best.prim != before.prim || best.t != before.t) {
    RTCRayN* ray = RTCRayHitN_RayN(args->rayhit, args->N);
    RTCHitN* h = RTCRayHitN_HitN(args->rayhit, args->N);
    RTCRayN_tfar(ray, args->N, 0) = round_up(best.t);
    RTCHitN_geomID(h, args->N, 0) = args->geomID;
    RTCHitN_primID(h, args->N, 0) = args->primID;
  }
}

void occluded(const RTCOccludedFunctionNArguments*) {}

}  // namespace

bool KernelChoice::prefers_accel() const {
  const uint64_t ar = accel_.rays.load(std::memory_order_relaxed), kr = kd_.rays.load(std::memory_order_relaxed);
  if (ar == 0 || kr == 0) return true;
  // ns_a / ar < ns_k / kr, without division.
  return double(accel_.ns.load(std::memory_order_relaxed)) * double(kr) <
         double(kd_.ns.load(std::memory_order_relaxed)) * double(ar);
}

bool KernelChoice::use_accel(uint64_t packet, bool& timed) const {
  const bool measuring = accel_.rays.load(std::memory_order_relaxed) < kMeasureRays ||
                         kd_.rays.load(std::memory_order_relaxed) < kMeasureRays;
  if (measuring) {
    timed = true;
    return packet % 2 == 0;
  }
  // The other kernel once in kExplore packets, the chosen one timed as often.
  const bool explore = packet % kExplore == 0;
  timed = explore || packet % kExplore == kExplore / 2;
  return prefers_accel() != explore;
}

void KernelChoice::record(bool accel, uint64_t ns, uint64_t rays) {
  Sum& s = accel ? accel_ : kd_;
  s.ns.fetch_add(ns, std::memory_order_relaxed);
  const uint64_t total = s.rays.fetch_add(rays, std::memory_order_relaxed) + rays;
  if (total > kForgetRays) {
    // Halved by whichever thread crosses the mark (a lost update only delays the next halving).
    for (Sum* h : {&accel_, &kd_}) {
      h->ns.store(h->ns.load(std::memory_order_relaxed) / 2, std::memory_order_relaxed);
      h->rays.store(h->rays.load(std::memory_order_relaxed) / 2, std::memory_order_relaxed);
    }
  }
}

PrimAccel PrimAccel::build(const Scene& scene) {
  PrimAccel out;
  const size_t n = scene.size();
  if (n == 0) return out;
  RTCDevice dev = device();
  const Aabb box = scene.bounds();
  // 2^-16 of the diagonal, and never below what the centre's own rounding could move a box.
  BuildInput input{&scene, box.center(), 0x1p-16 * glm::length(box.extent()) + 0x1p-40 * box.magnitude()};
  RTCScene rtc = rtcNewScene(dev);
  rtcSetSceneFlags(rtc, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(rtc, RTC_BUILD_QUALITY_MEDIUM);
  RTCGeometry geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_USER);
  rtcSetGeometryUserPrimitiveCount(geom, unsigned(n));
  rtcSetGeometryUserData(geom, &input);
  rtcSetGeometryBoundsFunction(geom, bounds, nullptr);
  rtcSetGeometryIntersectFunction(geom, intersect);
  rtcSetGeometryOccludedFunction(geom, occluded);
  rtcCommitGeometry(geom);
  rtcAttachGeometry(rtc, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(rtc);
  // The bounds callback is done with `input`: only the intersect callback runs from now on.
  rtcSetGeometryUserData(rtcGetGeometry(rtc, 0), nullptr);
  out.handle_ = rtc;
  out.margin_ = input.margin;
  out.centre_ = input.centre;
  return out;
}

PrimAccel::PrimAccel(PrimAccel&& other) noexcept
    : handle_(std::exchange(other.handle_, nullptr)),
      margin_(other.margin_),
      centre_(other.centre_) {}

PrimAccel& PrimAccel::operator=(PrimAccel&& other) noexcept {
  if (this != &other) {
    if (handle_ != nullptr) rtcReleaseScene(static_cast<RTCScene>(handle_));
    handle_ = std::exchange(other.handle_, nullptr);
    margin_ = other.margin_;
    centre_ = other.centre_;
  }
  return *this;
}

PrimAccel::~PrimAccel() {
  if (handle_ != nullptr) rtcReleaseScene(static_cast<RTCScene>(handle_));
}

bool PrimAccel::usable(const Vec3& origin, double dmax, double tmax) const {
  // How far Embree's float ray may lie from the double one at t <= tmax, relative to the
  // centre: the origin's and the direction's rounding (2^-24 each), times four for Embree's own
  // arithmetic.
  const Vec3 o = origin - centre_;
  const double m = std::max({std::abs(o.x), std::abs(o.y), std::abs(o.z)});
  return 0x1p-22 * (m + 3.0 * tmax * dmax) < margin_;
}

void PrimAccel::trace(const Scene& scene, const Ray& ray, double tmin, double tmax, RayHit& best,
                      Counters& counters) const {
  TraceContext c;
  rtcInitIntersectContext(&c.context);
  c.scene = &scene;
  c.ray = &ray;
  c.tmin = tmin;
  c.tmax = tmax;
  c.best = &best;
  c.counters = &counters;
  RTCRayHit rh;
  const Vec3 o = ray.origin - centre_;
  rh.ray.org_x = float(o.x);
  rh.ray.org_y = float(o.y);
  rh.ray.org_z = float(o.z);
  rh.ray.dir_x = float(ray.dir.x);
  rh.ray.dir_y = float(ray.dir.y);
  rh.ray.dir_z = float(ray.dir.z);
  rh.ray.tnear = std::max(0.0f, round_down(tmin));
  rh.ray.tfar = round_up(std::min(tmax, best.t));
  rh.ray.time = 0.0f;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.id = 0;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(static_cast<RTCScene>(handle_), &c.context, &rh);
  ++counters.accel_rays;
}

}  // namespace frontier
