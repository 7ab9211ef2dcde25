#include "layertrace/ssr/ssr_tracer.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "layertrace/screen/fragment_hit.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/ssr/ssr_march_lanes.h"
#include "layertrace/util/error.h"

namespace lt {

SsrTracer::SsrTracer(const Camera& camera, const LayerArrays& layers, const SsrConfig& config)
    : camera_(camera), layers_(layers), depth_(makeIntervalLayers(layers, config.allLayers ? layers.k : 1)), config_(config) {
  if (!(config_.stride >= 1.0f)) inputError("--stride ", config_.stride, ": must be >= 1");
  if (!(config_.jitter >= 0.0f && config_.jitter <= 1.0f)) inputError("--jitter ", config_.jitter, ": must be in [0, 1]");
  if (config_.maxSteps < 0) inputError("--max-steps ", config_.maxSteps, ": must be >= 0");
  config_.maxSteps = ssrMaxSteps(config_, camera.width(), camera.height());
}

template <class C>
TraceHit SsrTracer::traceImpl(const Ray& ray, C& c) const {
  const ScreenSegment seg = makeScreenSegment(camera_, ray);
  if (!seg.valid) return {};
  const SsrStart m(seg, config_.stride, config_.jitter);
  const SsrSample h = ssrMarch(depth_, m, config_.maxSteps, camera_.width(), camera_.height(), c);
  return h.hit() ? finish(m, h.s, h.x, h.y, h.layer, c) : TraceHit{};
}

template <class C>
TraceHit SsrTracer::finish(const SsrStart& m, float s, int x, int y, int layer, C& c) const {
  const int W = camera_.width(), H = camera_.height();
  const ScreenSegment& seg = m.seg;
  auto pixelAt = [&](float t, int& px, int& py) {
    glm::vec2 p = m.P0 + (m.P1 - m.P0) * t;
    if (m.permute) std::swap(p.x, p.y);
    px = int(std::floor(p.x)), py = int(std::floor(p.y));
    return px >= 0 && py >= 0 && px < W && py < H;
  };
  // Depth range of the ray over one step centred at t (McGuire and Mara 2014: from the previous
  // half-step estimate to the next one).
  auto rangeAt = [&](float t, float halfStep, float& zmin, float& zmax) {
    const float a = seg.depthAt(std::clamp(t - halfStep, 0.0f, 1.0f)), b = seg.depthAt(std::clamp(t + halfStep, 0.0f, 1.0f));
    zmin = std::min(a, b), zmax = std::max(a, b);
  };
  if (config_.refine && config_.stride > 1.0f) {
    // Binary search between the previous (missed) sample and this one for the first hit.
    float lo = s - m.dsStep, hi = s;
    while ((hi - lo) > m.ds) {
      const float mid = 0.5f * (lo + hi);
      int mx, my;
      c.iteration();
      if (!pixelAt(mid, mx, my)) {
        lo = mid;
        continue;
      }
      float a, b;
      rangeAt(mid, 0.25f * (hi - lo), a, b);
      const int ml = firstMet(depth_.pixel(mx, my), depth_.countAt(mx, my), a, b, m.increasing, c);
      if (ml >= 0) hi = mid, x = mx, y = my, layer = ml;
      else lo = mid;
    }
  }
  return fragmentHit(camera_, layers_, x, y, layer);
}

void SsrTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  if ((kCountersCompiled && !counters.empty()) || !ssrLanesAvailable(depth_)) return TracerImpl::traceBatch(rays, hits, counters);
  // Uncounted: the batch's starts through the lane march, then each hit refined and shaded.
  thread_local std::vector<SsrStart> starts;
  thread_local std::vector<SsrSample> samples;
  starts.resize(rays.size());
  samples.resize(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) starts[i] = SsrStart(makeScreenSegment(camera_, rays[i]), config_.stride, config_.jitter);
  ssrMarchBatch(depth_, starts, config_.maxSteps, camera_.width(), camera_.height(), samples);
  NoCounters none;
  for (size_t i = 0; i < rays.size(); ++i) {
    const SsrSample& h = samples[i];
    hits[i] = h.hit() ? finish(starts[i], h.s, h.x, h.y, h.layer, none) : TraceHit{};
  }
}

template TraceHit SsrTracer::traceImpl(const Ray&, RayCounters&) const;
template TraceHit SsrTracer::traceImpl(const Ray&, NoCounters&) const;

}  // namespace lt
