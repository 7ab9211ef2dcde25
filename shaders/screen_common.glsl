// Shared by the screen-space tracers' compute shaders (after ray_io.glsl): the camera,
// the screen segment of McGuire and Mara 2014 and the first-met interval rule. Each function is
// the GLSL twin of a CPU function (named beside it) and computes the same floats in the same
// order; `precise` keeps the compiler from contracting a product and a sum into one FMA, which
// the CPU build does not do either (-ffp-contract=off).

layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
layout(std430, binding = 1) writeonly buffer Hits { GpuHit hits[]; };
// Level 0: k intervals (front, back depth) per pixel, pixel-major (screen/interval_layers.h).
layout(std430, binding = 2) readonly buffer Level0 { vec2 level0[]; };
// The number of stored intervals of each pixel.
layout(std430, binding = 3) readonly buffer Counts { uint counts[]; };

uniform int uRayCount;  // rays in the batch
uniform int uFirst;     // the first ray of this dispatch (GpuContext::dispatch)
uniform int uWidth, uHeight, uK;
uniform float uNear, uFocal;
uniform bool uOrtho;

#define kInf uintBitsToFloat(0x7f800000u)

// The counters of the ray this invocation traces.
uint cIterations = 0u, cIntervals = 0u, cPixels = 0u, cGiveUps = 0u, cFragments = 0u;
uint cLevel[8] = uint[8](0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u);
void countIteration(int level) {
  ++cIterations;
  ++cLevel[min(level, 7)];
}

// std::clamp: lo when v < lo, else hi when hi < v, else v (GLSL's clamp differs when lo > hi).
float clampStd(float v, float lo, float hi) {
  return v < lo ? lo : (hi < v ? hi : v);
}

// scene/camera.cpp Camera::project.
vec2 project(vec3 c) {
  precise vec2 p;
  if (uOrtho) {
    p.x = float(uWidth) * 0.5 + uFocal * c.x;
    p.y = float(uHeight) * 0.5 - uFocal * c.y;
  } else {
    precise float depth = -c.z;
    p.x = float(uWidth) * 0.5 + uFocal * c.x / depth;
    p.y = float(uHeight) * 0.5 - uFocal * c.y / depth;
  }
  return p;
}

// screen/screen_segment.h ScreenSegment.
struct Segment {
  vec2 p0, p1;
  float k0, k1;
  bool valid, clippedStart, clippedEnd;
};

float depthAt(Segment seg, float s) {
  precise float z = 1.0 / (seg.k0 + s * (seg.k1 - seg.k0));
  return z;
}

vec2 pointAt(Segment seg, float s) {
  precise vec2 p = seg.p0 + s * (seg.p1 - seg.p0);
  return p;
}

// screen/screen_segment.cpp makeScreenSegment.
Segment makeSegment(GpuRay ray) {
  Segment seg;
  seg.p0 = vec2(0.0);
  seg.p1 = vec2(0.0);
  seg.k0 = 1.0;
  seg.k1 = 1.0;
  seg.valid = false;
  seg.clippedEnd = false;
  seg.clippedStart = ray.dirSurface.w == 0.0;
  // A negative length marks a slot without a ray (gpu/gpu_effects.h: a pixel that emits fewer
  // rays than its slots): it answers a miss at once, with zero counters.
  if (ray.originMax.w < 0.0) return seg;
  const float nearZ = -uNear;
  const vec3 dir = ray.dirSurface.xyz;
  precise vec3 origin = ray.originMax.xyz;
  precise float maxDistance = ray.originMax.w;
  if (origin.z > nearZ) {
    if (!(dir.z < 0.0)) return seg;
    precise float t = (nearZ - origin.z) / dir.z;
    if (!(t < maxDistance)) return seg;
    origin += dir * t;
    origin.z = nearZ;
    maxDistance -= t;
    seg.clippedStart = true;
  }
  precise float len = (origin.z + dir.z * maxDistance > nearZ) ? (nearZ - origin.z) / dir.z : maxDistance;
  seg.clippedEnd = len < maxDistance;
  precise vec3 end = origin + dir * max(len, 0.0);
  seg.k0 = 1.0 / -origin.z;
  seg.k1 = 1.0 / -end.z;
  seg.p0 = project(origin);
  seg.p1 = project(end);
  const float W = float(uWidth), H = float(uHeight);
  if (!(seg.p0.x >= 0.0 && seg.p0.y >= 0.0 && seg.p0.x <= W && seg.p0.y <= H)) {
    // Liang–Barsky entry into the viewport.
    precise float tA = 0.0, tB = 1.0;
    precise vec2 d = seg.p1 - seg.p0;
    for (int a = 0; a < 2; ++a) {
      const float hi = a == 0 ? W : H;
      if (d[a] == 0.0) {
        if (seg.p0[a] < 0.0 || seg.p0[a] > hi) return seg;
        continue;
      }
      precise float t0 = (0.0 - seg.p0[a]) / d[a], t1 = (hi - seg.p0[a]) / d[a];
      tA = max(tA, min(t0, t1));
      tB = min(tB, max(t0, t1));
    }
    if (!(tA <= tB)) return seg;
    seg.p0 = clamp(seg.p0 + d * tA, vec2(0.0), vec2(W, H));
    seg.k0 = seg.k0 + (seg.k1 - seg.k0) * tA;
    seg.clippedStart = true;
  }
  precise float tEnd = 1.0;
  precise vec2 d = seg.p1 - seg.p0;
  for (int a = 0; a < 2; ++a) {
    const float p = seg.p0[a], dp = d[a], hi = a == 0 ? W : H;
    if (dp > 0.0 && p + dp > hi) tEnd = min(tEnd, (hi - p) / dp);
    if (dp < 0.0 && p + dp < 0.0) tEnd = min(tEnd, (0.0 - p) / dp);
  }
  tEnd = max(tEnd, 0.0);
  if (tEnd < 1.0) {
    seg.clippedEnd = true;
    seg.p1 = seg.p0 + d * tEnd;
    seg.k1 = seg.k0 + (seg.k1 - seg.k0) * tEnd;
  }
  seg.valid = !isinf(seg.p1.x) && !isnan(seg.p1.x) && !isinf(seg.p1.y) && !isnan(seg.p1.y) && seg.k1 > 0.0;
  return seg;
}

// screen/interval_layers.h firstMet over the `n` intervals of level 0 from `base`.
int firstMet(uint base, int n, float zmin, float zmax, bool increasing) {
  zmax = min(zmax, uintBitsToFloat(0x7f7fffffu));  // the largest finite float, as the CPU's
  int best = -1;
  float bestEntry = 0.0;
  for (int i = 0; i < n; ++i) {
    ++cIntervals;
    ++cFragments;
    const vec2 f = level0[base + uint(i)];
    if (f.x > zmax) break;
    if (f.y < zmin) continue;
    if (increasing) return i;
    const float entry = f.y < zmax ? f.y : zmax;
    if (best < 0 || entry >= bestEntry) {
      best = i;
      bestEntry = entry;
    }
  }
  return best;
}

uint pixelBase(int x, int y) {
  return (uint(y) * uint(uWidth) + uint(x)) * uint(uK);
}

// The counters go with the answer, except in the timed variant (LT_NO_COUNTERS, compiled by
// GpuScreenTracer for runs that read no counter): there they are written as zeros, so the
// compiler drops their increments from the march.
void writeHit(uint id, int x, int y, int layer) {
  hits[id].x = x;
  hits[id].y = y;
  hits[id].layer = layer;
#ifdef LT_NO_COUNTERS
  hits[id].iterations = 0u;
  hits[id].intervals = 0u;
  hits[id].pixels = 0u;
  hits[id].giveUps = 0u;
  hits[id].fragments = 0u;
  for (int l = 0; l < 8; ++l) hits[id].levelIterations[l] = 0u;
#else
  hits[id].iterations = cIterations;
  hits[id].intervals = cIntervals;
  hits[id].pixels = cPixels;
  hits[id].giveUps = cGiveUps;
  hits[id].fragments = cFragments;
  for (int l = 0; l < 8; ++l) hits[id].levelIterations[l] = cLevel[l];
#endif
}
