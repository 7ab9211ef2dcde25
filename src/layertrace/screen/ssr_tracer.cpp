#include "layertrace/screen/ssr_tracer.h"

#include <algorithm>
#include <cmath>

#include "layertrace/screen/fragment_hit.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/util/error.h"

namespace lt {

SsrTracer::SsrTracer(const Camera& camera, const LayerArrays& layers, const SsrConfig& config)
    : camera_(camera), layers_(layers), depth_(makeIntervalLayers(layers, config.allLayers ? layers.k : 1)), config_(config) {
  if (!(config_.stride >= 1.0f)) inputError("--stride ", config_.stride, ": must be >= 1");
  if (!(config_.jitter >= 0.0f && config_.jitter <= 1.0f)) inputError("--jitter ", config_.jitter, ": must be in [0, 1]");
  if (config_.maxSteps < 0) inputError("--max-steps ", config_.maxSteps, ": must be >= 0");
  if (config_.maxSteps == 0) config_.maxSteps = int(float(std::max(camera.width(), camera.height())) / config_.stride) + 2;
}

template <class C>
TraceHit SsrTracer::traceImpl(const Ray& ray, C& c) const {
  const ScreenSegment seg = makeScreenSegment(camera_, ray);
  if (!seg.valid) return {};
  glm::vec2 P0 = seg.p0, P1 = seg.p1;
  // seed 001: a degenerate line covers at least one pixel.
  if (glm::dot(P1 - P0, P1 - P0) < 1e-4f) P1 += glm::vec2(0.01f);
  glm::vec2 delta = P1 - P0;
  const bool permute = std::abs(delta.x) < std::abs(delta.y);
  if (permute) std::swap(delta.x, delta.y), std::swap(P0.x, P0.y), std::swap(P1.x, P1.y);
  const float stepDir = delta.x >= 0.0f ? 1.0f : -1.0f;
  const float invdx = stepDir / delta.x;
  // Derivatives per unit step along the major axis, in the segment parameter s.
  const float ds = invdx;  // ds per pixel of x
  const float stride = config_.stride;
  const bool increasing = seg.k1 <= seg.k0;  // depth grows along the ray
  const int W = camera_.width(), H = camera_.height();

  auto pixelAt = [&](float s, int& x, int& y) {
    glm::vec2 p = P0 + (P1 - P0) * s;
    if (permute) std::swap(p.x, p.y);
    x = int(std::floor(p.x)), y = int(std::floor(p.y));
    return x >= 0 && y >= 0 && x < W && y < H;
  };
  // Depth range of the ray over one step centred at s (seed 001: from the previous half-step
  // estimate to the next one).
  auto rangeAt = [&](float s, float halfStep, float& zmin, float& zmax) {
    const float a = seg.depthAt(std::clamp(s - halfStep, 0.0f, 1.0f)), b = seg.depthAt(std::clamp(s + halfStep, 0.0f, 1.0f));
    zmin = std::min(a, b), zmax = std::max(a, b);
  };

  // Skip the origin's own pixel (as HSSR does, seed 000 §5.1), then march with stride and
  // jitter. As in seed 001 the state advances incrementally (P += dP, k += dk) and each step
  // costs one division: the depth estimate half a step ahead, reused as the next step's start.
  const float dsStep = ds * stride;
  const float dk = (seg.k1 - seg.k0) * dsStep;
  const glm::vec2 dP = (P1 - P0) * dsStep;
  const float kLo = std::min(seg.k0, seg.k1), kHi = std::max(seg.k0, seg.k1);
  // A ray entering from outside the view (clippedStart) starts no surface: sample its first
  // pixel too (a hair inside, so the viewport edge it enters through is not the sample).
  float s = dsStep * ((seg.clippedStart ? 1e-3f : 1.0f) + config_.jitter);
  glm::vec2 P = P0 + (P1 - P0) * s;
  float kHalf = seg.k0 + (seg.k1 - seg.k0) * std::max(s - 0.5f * dsStep, 0.0f);
  float prevDepth = 1.0f / kHalf;
  kHalf += dk;
  int step = 0;
  for (; step < config_.maxSteps && s <= 1.0f; ++step, s += dsStep, P += dP, kHalf += dk) {
    c.iteration();
    const int px = int(std::floor(P.x)), py = int(std::floor(P.y));
    const int x = permute ? py : px, y = permute ? px : py;
    if (x < 0 || y < 0 || x >= W || y >= H) break;
    c.pixel();
    // Half a step ahead, but not beyond the segment's end.
    const float nextDepth = 1.0f / std::clamp(kHalf, kLo, kHi);
    const float zmin = std::min(prevDepth, nextDepth), zmax = std::max(prevDepth, nextDepth);
    prevDepth = nextDepth;
    int layer = firstMet(depth_.pixel(x, y), depth_.countAt(x, y), zmin, zmax, increasing, c);
    if (layer < 0) continue;
    int hx = x, hy = y;
    if (config_.refine && stride > 1.0f) {
      // Binary search between the previous (missed) sample and this one for the first hit.
      float lo = s - dsStep, hi = s;
      while ((hi - lo) > ds) {
        const float mid = 0.5f * (lo + hi);
        int mx, my;
        c.iteration();
        if (!pixelAt(mid, mx, my)) {
          lo = mid;
          continue;
        }
        float a, b;
        rangeAt(mid, 0.25f * (hi - lo), a, b);
        const int ml = firstMet(depth_.pixel(mx, my), depth_.countAt(mx, my), a, b, increasing, c);
        if (ml >= 0) hi = mid, hx = mx, hy = my, layer = ml;
        else lo = mid;
      }
    }
    return fragmentHit(camera_, layers_, hx, hy, layer);
  }
  if (step == config_.maxSteps && s <= 1.0f) c.giveUp();  // --max-steps ended the march early
  return {};
}

template TraceHit SsrTracer::traceImpl(const Ray&, RayCounters&) const;
template TraceHit SsrTracer::traceImpl(const Ray&, NoCounters&) const;

}  // namespace lt
