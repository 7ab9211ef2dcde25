#include "layertrace/hybrid/known_space.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>

#include "layertrace/hssr/hssr_march.h"
#include "layertrace/hssr/hssr_march_lanes.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

namespace lt {

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();
}

float CaptureCoverage::unknownDepth(size_t p) const {
  const int n = layers.count[p];
  const FragmentNode* f = &layers.slots[p * size_t(layers.k)];
  if (frontFacesOnly) return n > 0 ? f[0].back() : 0.0f;
  const bool truncated = complexity.empty() ? n == layers.k : complexity[p] > uint32_t(n);
  const float u = !truncated ? kInf : n > 0 ? f[n - 1].back() : 0.0f;
  return unsampled.empty() ? u : std::min(u, unsampled[p]);
}

namespace {

void checkCoverage(const CaptureCoverage& c) {
  const size_t pixels = size_t(c.layers.width) * size_t(c.layers.height);
  LT_CHECK(c.complexity.empty() || c.complexity.size() == pixels, "fragment counts of ", c.complexity.size(), " pixels for ", pixels);
  LT_CHECK(c.unsampled.empty() || c.unsampled.size() == pixels, "unsampled depths of ", c.unsampled.size(), " pixels for ", pixels);
  LT_CHECK(c.nearest.empty() || c.nearest.size() == pixels, "nearest depths of ", c.nearest.size(), " pixels for ", pixels);
}

}  // namespace

IntervalLayers solidIntervals(const Camera& camera, const CaptureCoverage& c, float lastThicknessPx) {
  checkCoverage(c);
  const LayerArrays& L = c.layers;
  IntervalLayers out;
  out.width = L.width;
  out.height = L.height;
  out.k = L.k;
  const size_t pixels = size_t(L.width) * size_t(L.height);
  checkAllocation("the hybrid's solid intervals", pixels * (size_t(L.k) * sizeof(Interval) + 1));
  out.slots.resize(pixels * size_t(L.k));
  out.count.resize(pixels);
  parallelFor(size_t(0), pixels, [&](size_t p) {
    const FragmentNode* f = &L.slots[p * size_t(L.k)];
    Interval* iv = &out.slots[p * size_t(L.k)];
    const float u = c.unknownDepth(p);
    int n = L.count[p];
    if (c.frontFacesOnly) n = std::min(n, 1);
    for (int i = 0; i < n; ++i) {
      const float next = i + 1 < n ? f[i + 1].depth : u < kInf ? kInf : f[i].depth + lastThicknessPx * camera.pixelFootprint(f[i].depth);
      iv[i] = {f[i].depth, std::max(f[i].back(), next)};
    }
    // The first interval starts at the nearest depth any surface has inside the
    // pixel's square. The centre sample alone leaves a gap in front of it where a surface is
    // steep in depth across the pixel (grazing, or a neighbour triangle covering part of the
    // pixel): a ray crossing that surface there, in front of every sample, then passes behind
    // it unseen (found on assimp's ClearCoatTest.gltf, the camera inside its thin plate: 1.2 %
    // of AO rays passed through the plate's far face, seen at a grazing angle). From the nearest depth on the
    // pixel is solid, so such a ray meets the interval, and the exact check decides.
    if (n > 0 && !c.nearest.empty()) iv[0].front = std::min(iv[0].front, c.nearest[p]);
    // An unstored surface crossing the pixel (raster/unsampled.h): what lies behind its depth d
    // is unknown — solid from d on, so a ray reaching it meets an interval no stored triangle
    // backs, and the hybrid's exact check hands the ray to geometry. A pixel that stores nothing
    // is unknown from u on (front faces only: from the near plane, anything may be there), even
    // where an unstored surface lies farther (were the pixel solid only from that surface on,
    // AO rays would pass in front of it through a back face the capture culled — 9 of 34 144
    // on assimp's COLLADA.dae seen from behind).
    float d = c.unsampled.empty() ? kInf : c.unsampled[p];
    if (n == 0) d = std::min(d, u);
    if (d < kInf) {
      while (n > 0 && iv[n - 1].front >= d) --n;  // stored behind it: unreachable unseen
      if (n > 0 && (iv[n - 1].back >= d || n == L.k)) iv[n - 1].back = kInf;  // joins (or no slot left: from earlier)
      else iv[n] = {d, kInf}, ++n;
    }
    for (int i = n; i < L.k; ++i) iv[i] = {kInf, kInf};  // the march's sentinel (interval_layers.h)
    out.count[p] = uint8_t(n);
  });
  return out;
}

KnownSpace::KnownSpace(const Camera& camera, const CaptureCoverage& coverage, const Bounds& sceneBounds, bool frustumOnly, int levels)
    : camera_(camera), farLimit_(kInf) {
  const auto start = std::chrono::steady_clock::now();
  checkCoverage(coverage);
  if (!frustumOnly) {
    // Level 0: one interval [u, ∞) on every pixel whose unknown depth is finite (rule 3).
    const LayerArrays& layers = coverage.layers;
    const size_t pixels = size_t(layers.width) * size_t(layers.height);
    IntervalLayers base;
    base.width = layers.width;
    base.height = layers.height;
    base.k = 1;
    checkAllocation("the known-space pyramid", pixels * (sizeof(Interval) + 1) * 2);
    base.slots.resize(pixels);
    base.count.resize(pixels);
    parallelFor(size_t(0), pixels, [&](size_t p) {
      const float u = coverage.unknownDepth(p);
      base.slots[p] = {u, kInf};
      base.count[p] = u < kInf ? 1 : 0;
    });
    // τ = ∞: every coarse cell keeps one interval [min u, ∞).
    pyramid_ = buildIntervalPyramid(std::move(base), camera, PyramidConfig{std::clamp(levels, 1, 16), kInf});
  }
  // Rule 2: the rasterizer clipped everything beyond the far plane.
  if (camera.far() < sceneBounds.farthestFrom(camera.desc().eye)) farLimit_ = camera.far();
  buildMs_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

template <class C>
KnownSpace::Boundary KnownSpace::boundary(const Ray& ray, C& c) const {
  const ScreenSegment seg = makeScreenSegment(camera_, ray);
  if (!seg.valid || seg.startOutside) return {};  // rule 1
  MarchHit m;
  if (pyramid_.levelCount() > 0) m = hssrMarch(pyramid_, pyramid_.levelCount(), 1, seg, camera_.width(), camera_.height(), c);  // rule 3
  return finish(ray, seg, m);
}

void KnownSpace::boundaries(std::span<const Ray> rays, std::span<Boundary> out, std::span<ScreenSegment> segments) const {
  thread_local std::vector<ScreenSegment> own;
  thread_local std::vector<MarchHit> marched;
  thread_local std::vector<uint8_t> valid;
  if (segments.empty()) own.resize(rays.size()), segments = own;
  std::span<ScreenSegment> segs = segments;
  marched.assign(rays.size(), MarchHit{});
  valid.resize(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) {
    segs[i] = makeScreenSegment(camera_, rays[i]);
    valid[i] = segs[i].valid;
    segs[i].valid = segs[i].valid && !segs[i].startOutside;  // rule 1 answers these: not marched
  }
  if (pyramid_.levelCount() > 0) hssrMarchBatch(pyramid_, pyramid_.levelCount(), 1, segs, camera_.width(), camera_.height(), marched);
  for (size_t i = 0; i < rays.size(); ++i) {
    out[i] = segs[i].valid ? finish(rays[i], segs[i], marched[i]) : Boundary{};
    segs[i].valid = valid[i] != 0;  // the caller's segments are makeScreenSegment's
  }
}

KnownSpace::Boundary KnownSpace::finish(const Ray& ray, const ScreenSegment& seg, const MarchHit& m) const {
  float s = 1.0f;
  bool leaves = seg.clippedEnd;  // rule 2: the near plane or the viewport's border
  if (m.hit()) s = m.s, leaves = true;  // rule 3
  if (farLimit_ < kInf) {  // rule 2: beyond the far plane
    const float sFar = seg.paramAtDepth(farLimit_);
    if (std::max(seg.depthAt(0.0f), seg.depthAt(s)) > farLimit_ && sFar >= 0.0f && sFar < s) s = sFar, leaves = true;
  }
  if (!leaves) return {ray.maxDistance, ray.maxDistance};
  const float known = rayParamAt(camera_, ray, seg, s);
  return {known, std::min(known, rayParamAt(camera_, ray, seg, std::max(0.0f, s - seg.pixelParam(1.0f))))};
}

template KnownSpace::Boundary KnownSpace::boundary(const Ray&, RayCounters&) const;
template KnownSpace::Boundary KnownSpace::boundary(const Ray&, NoCounters&) const;

}  // namespace lt
