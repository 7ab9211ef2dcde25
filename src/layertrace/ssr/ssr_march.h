// The march of McGuire and Mara 2014 (JCGT, §3: the 2D DDA along the projected ray with
// perspective-correct depth) as a reusable piece: SsrStart sets a segment up, ssrMarch walks it
// one sample per stride and reports the first stored interval it meets. SsrTracer refines and
// shades the hit; the lane march (ssr_march_lanes.h) runs a vector's count of these at once and must
// answer bit for bit like ssrMarch.
#pragma once

#include <algorithm>
#include <cmath>

#include "layertrace/screen/interval_layers.h"
#include "layertrace/screen/screen_segment.h"

namespace lt {

/// Everything the march sets up before its first sample. The segment is permuted so that x is
/// its major axis; the march then advances incrementally (P += dP, κ += dκ), one division per
/// sample.
struct SsrStart {
  ScreenSegment seg;  ///< invalid: nothing to march
  glm::vec2 P0{0.0f}, P1{0.0f};  ///< the segment's ends, permuted
  bool permute = false;  ///< x and y swapped (|dy| > |dx|)
  bool increasing = false;  ///< depth grows along the ray
  float ds = 0.0f;  ///< segment parameter per pixel of the major axis
  float dsStep = 0.0f, dk = 0.0f;  ///< per sample: the parameter and κ advance
  glm::vec2 dP{0.0f};  ///< per sample: the screen advance (permuted)
  float kLo = 0.0f, kHi = 0.0f;  ///< κ's range over the segment
  // The first sample: parameter, point, κ half a sample ahead, and the depth half a sample back.
  float s = 0.0f, kHalf = 0.0f, prevDepth = 0.0f;
  glm::vec2 P{0.0f};

  SsrStart() = default;
  /// `stride` pixels per sample (>= 1), the start offset by `jitter` of a stride.
  SsrStart(const ScreenSegment& segment, float stride, float jitter) : seg(segment) {
    if (!seg.valid) return;
    P0 = seg.p0, P1 = seg.p1;
    // McGuire and Mara 2014: a degenerate line covers at least one pixel.
    if (glm::dot(P1 - P0, P1 - P0) < 1e-4f) P1 += glm::vec2(0.01f);
    glm::vec2 delta = P1 - P0;
    permute = std::abs(delta.x) < std::abs(delta.y);
    if (permute) std::swap(delta.x, delta.y), std::swap(P0.x, P0.y), std::swap(P1.x, P1.y);
    const float stepDir = delta.x >= 0.0f ? 1.0f : -1.0f;
    ds = stepDir / delta.x;
    increasing = seg.k1 <= seg.k0;
    // As in McGuire and Mara 2014 the state advances incrementally and each step costs one
    // division: the depth estimate half a step ahead, reused as the next step's start.
    dsStep = ds * stride;
    dk = (seg.k1 - seg.k0) * dsStep;
    dP = (P1 - P0) * dsStep;
    kLo = std::min(seg.k0, seg.k1), kHi = std::max(seg.k0, seg.k1);
    // Skip the origin's own pixel (as HSSR does, Hofmann et al. 2017, §5.1). A ray entering from
    // outside the view (clippedStart) starts no surface: sample its first pixel too (a hair inside,
    // so the viewport edge it enters through is not the sample).
    s = dsStep * ((seg.clippedStart ? 1e-3f : 1.0f) + jitter);
    P = P0 + (P1 - P0) * s;
    kHalf = seg.k0 + (seg.k1 - seg.k0) * std::max(s - 0.5f * dsStep, 0.0f);
    prevDepth = 1.0f / kHalf;
    kHalf += dk;
  }
};

/// The first sample whose depth range meets a stored interval: pixel, interval, parameter s.
struct SsrSample {
  int x = -1, y = -1, layer = -1;
  float s = 0.0f;
  bool hit() const { return layer >= 0; }
};

/// The march of McGuire and Mara 2014 over `depth` for at most `maxSteps` samples of a W×H view.
template <class C>
SsrSample ssrMarch(const IntervalLayers& depth, const SsrStart& m, int maxSteps, int W, int H, C& c) {
  if (!m.seg.valid) return {};
  float s = m.s, kHalf = m.kHalf, prevDepth = m.prevDepth;
  glm::vec2 P = m.P;
  int step = 0;
  for (; step < maxSteps && s <= 1.0f; ++step, s += m.dsStep, P += m.dP, kHalf += m.dk) {
    c.iteration();
    const int px = int(std::floor(P.x)), py = int(std::floor(P.y));
    const int x = m.permute ? py : px, y = m.permute ? px : py;
    if (x < 0 || y < 0 || x >= W || y >= H) break;
    c.pixel();
    // Half a step ahead, but not beyond the segment's end.
    const float nextDepth = 1.0f / std::clamp(kHalf, m.kLo, m.kHi);
    const float zmin = std::min(prevDepth, nextDepth), zmax = std::max(prevDepth, nextDepth);
    prevDepth = nextDepth;
    const int layer = firstMet(depth.pixel(x, y), depth.countAt(x, y), zmin, zmax, m.increasing, c);
    if (layer >= 0) return {x, y, layer, s};
  }
  if (step == maxSteps && s <= 1.0f) c.giveUp();  // --max-steps ended the march early
  return {};
}

}  // namespace lt
