#include "layertrace/screen/ssr_tracer.h"

#include <algorithm>
#include <cmath>

#include "layertrace/screen/fragment_hit.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/util/error.h"

namespace lt {

SsrTracer::SsrTracer(const Camera& camera, const LayerArrays& layers, const SsrConfig& config)
    : camera_(camera), layers_(layers), config_(config) {
  if (!(config_.stride >= 1.0f)) inputError("--stride ", config_.stride, ": must be >= 1");
  if (!(config_.jitter >= 0.0f && config_.jitter <= 1.0f)) inputError("--jitter ", config_.jitter, ": must be in [0, 1]");
  if (config_.maxSteps < 0) inputError("--max-steps ", config_.maxSteps, ": must be >= 0");
  if (config_.maxSteps == 0) config_.maxSteps = int(float(std::max(camera.width(), camera.height())) / config_.stride) + 2;
}

int SsrTracer::overlap(int x, int y, float zmin, float zmax, RayCounters& c) const {
  const int n = config_.allLayers ? layers_.countAt(x, y) : std::min(1, layers_.countAt(x, y));
  const FragmentNode* f = layers_.pixel(x, y);
  for (int i = 0; i < n; ++i) {
    ++c.intervals;
    if (f[i].depth > zmax) break;  // sorted by front: nothing further can overlap
    if (f[i].back() >= zmin) return i;
  }
  return -1;
}

TraceHit SsrTracer::trace(const ScreenRay& ray, RayCounters& c) const {
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

  // Skip the origin's own pixel (as HSSR does, seed 000 §5.1), then march with stride and jitter.
  const float sEnd = 1.0f;
  float s = ds * stride * (1.0f + config_.jitter);
  for (int step = 0; step < config_.maxSteps && s <= sEnd; ++step, s += ds * stride) {
    ++c.iterations;
    int x, y;
    if (!pixelAt(s, x, y)) break;
    ++c.pixels;
    float zmin, zmax;
    rangeAt(s, 0.5f * ds * stride, zmin, zmax);
    int layer = overlap(x, y, zmin, zmax, c);
    if (layer < 0) continue;
    if (config_.refine && stride > 1.0f) {
      // Binary search between the previous (missed) sample and this one for the first hit.
      float lo = s - ds * stride, hi = s;
      int hx = x, hy = y, hl = layer;
      while ((hi - lo) > ds * 1.0f) {
        const float mid = 0.5f * (lo + hi);
        int mx, my;
        ++c.iterations;
        if (!pixelAt(mid, mx, my)) { lo = mid; continue; }
        float a, b;
        rangeAt(mid, 0.25f * (hi - lo), a, b);
        const int ml = overlap(mx, my, a, b, c);
        if (ml >= 0) hi = mid, hx = mx, hy = my, hl = ml;
        else lo = mid;
      }
      x = hx, y = hy, layer = hl;
    }
    return fragmentHit(camera_, layers_, x, y, layer);
  }
  return {};
}

}  // namespace lt
