// Shared by the screen-space tracers' compute shaders (after ray_io.glsl and
// screen_segment.glsl): their buffers, counters and the first-met interval rule, each function
// the GLSL twin of the CPU function named beside it.

layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
layout(std430, binding = 1) writeonly buffer Hits { GpuHit hits[]; };
// Level 0: k intervals (front, back depth) per pixel, pixel-major (screen/interval_layers.h).
layout(std430, binding = 2) readonly buffer Level0 { vec2 level0[]; };
// The number of stored intervals of each pixel.
layout(std430, binding = 3) readonly buffer Counts { uint counts[]; };

uniform int uRayCount;  // rays in the batch
uniform int uFirst;     // the first ray of this dispatch (GpuContext::dispatch)
uniform int uK;

// The counters of the ray this invocation traces.
uint cIterations = 0u, cIntervals = 0u, cPixels = 0u, cGiveUps = 0u, cFragments = 0u;
uint cLevel[8] = uint[8](0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u);
void countIteration(int level) {
  ++cIterations;
  ++cLevel[min(level, 7)];
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
