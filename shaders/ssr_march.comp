#version 450
// The screen-space march of McGuire and Mara 2014 (JCGT, §3) with the binary refinement of a
// strided hit: the GLSL twin of src/layertrace/ssr/ssr_march.h (SsrStart, ssrMarch) and
// SsrTracer::finish (src/layertrace/ssr/ssr_tracer.cpp). Level 0 holds the front interval of
// each pixel (ssr) or all k (ssr-layers). One invocation per ray.
layout(local_size_x = 64) in;

#include "ray_io.glsl"
#include "screen_segment.glsl"
#include "screen_common.glsl"

uniform float uStride, uJitter;
uniform int uMaxSteps;
uniform bool uRefine;
uniform int uMaxIntervals;  // of a pixel's intervals, the first this many (SSR over a resident frame's k: 1)

// SsrStart.
Segment gSeg;
vec2 gP0, gP1;
bool gPermute, gIncreasing;
float gDs, gDsStep, gDk, gKLo, gKHi;
vec2 gDP;

bool pixelAt(float t, out int px, out int py) {
  precise vec2 p = gP0 + (gP1 - gP0) * t;
  if (gPermute) p = p.yx;
  px = int(floor(p.x));
  py = int(floor(p.y));
  return px >= 0 && py >= 0 && px < uWidth && py < uHeight;
}

int pixelMet(int x, int y, float zmin, float zmax) {
  return firstMet(pixelBase(x, y), min(int(counts[uint(y) * uint(uWidth) + uint(x)]), uMaxIntervals), zmin, zmax, gIncreasing);
}

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uRayCount)) return;
  gSeg = makeSegment(rays[id]);
  if (!gSeg.valid) {
    writeHit(id, -1, -1, -1);
    return;
  }
  gP0 = gSeg.p0;
  gP1 = gSeg.p1;
  precise vec2 delta0 = gP1 - gP0;
  if (dot(delta0, delta0) < 1e-4) gP1 += vec2(0.01);
  precise vec2 delta = gP1 - gP0;
  gPermute = abs(delta.x) < abs(delta.y);
  if (gPermute) {
    delta = delta.yx;
    gP0 = gP0.yx;
    gP1 = gP1.yx;
  }
  const float stepDir = delta.x >= 0.0 ? 1.0 : -1.0;
  precise float ds = stepDir / delta.x;
  gDs = ds;
  gIncreasing = gSeg.k1 <= gSeg.k0;
  precise float dsStep = ds * uStride;
  precise float dk = (gSeg.k1 - gSeg.k0) * dsStep;
  precise vec2 dP = (gP1 - gP0) * dsStep;
  gDsStep = dsStep;
  gKLo = min(gSeg.k0, gSeg.k1);
  gKHi = max(gSeg.k0, gSeg.k1);
  precise float s = dsStep * ((gSeg.clippedStart ? 1e-3 : 1.0) + uJitter);
  precise vec2 P = gP0 + (gP1 - gP0) * s;
  precise float kHalf = gSeg.k0 + (gSeg.k1 - gSeg.k0) * max(s - 0.5 * dsStep, 0.0);
  precise float prevDepth = 1.0 / kHalf;
  kHalf += dk;

  // ssrMarch.
  int x = -1, y = -1, layer = -1;
  int stp = 0;
  for (; stp < uMaxSteps && s <= 1.0; ++stp, s += dsStep, P += dP, kHalf += dk) {
    countIteration(0);
    const int qx = int(floor(P.x)), qy = int(floor(P.y));
    const int px = gPermute ? qy : qx, py = gPermute ? qx : qy;
    if (px < 0 || py < 0 || px >= uWidth || py >= uHeight) break;
    ++cPixels;
    precise float nextDepth = 1.0 / clamp(kHalf, gKLo, gKHi);
    const float zmin = min(prevDepth, nextDepth), zmax = max(prevDepth, nextDepth);
    prevDepth = nextDepth;
    const int l = pixelMet(px, py, zmin, zmax);
    if (l >= 0) {
      x = px;
      y = py;
      layer = l;
      break;
    }
  }
  if (layer < 0) {
    if (stp == uMaxSteps && s <= 1.0) ++cGiveUps;
    writeHit(id, -1, -1, -1);
    return;
  }
  // SsrTracer::finish: binary search between the missed sample and this one.
  if (uRefine && uStride > 1.0) {
    precise float lo = s - dsStep, hi = s;
    while ((hi - lo) > gDs) {
      precise float mid = 0.5 * (lo + hi);
      int mx, my;
      countIteration(0);
      if (!pixelAt(mid, mx, my)) {
        lo = mid;
        continue;
      }
      precise float halfStep = 0.25 * (hi - lo);
      const float a = depthAt(gSeg, clamp(mid - halfStep, 0.0, 1.0)), b = depthAt(gSeg, clamp(mid + halfStep, 0.0, 1.0));
      const int ml = pixelMet(mx, my, min(a, b), max(a, b));
      if (ml >= 0) {
        hi = mid;
        x = mx;
        y = my;
        layer = ml;
      } else {
        lo = mid;
      }
    }
  }
  writeHit(id, x, y, layer);
}
