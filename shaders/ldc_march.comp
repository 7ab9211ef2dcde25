#version 450
// The layered depth cube's traversal (Bürger et al. 2007, §1.4): the GLSL twin of
// src/layertrace/ldc/ldc_tracer.cpp, one invocation per ray. Per LDI (the ray's dominant axis
// first), a DDA over the coarse blocks tests the ray's depth range against each block's
// intervals, and a DDA over an overlapping block's texels tests their samples; a hit shortens
// the ray for the LDIs after it, and the nearest hit wins. The answer is the hit's sample (its
// index in the samples of all three LDIs), its view and parameter, and the counters.
layout(local_size_x = 64) in;
#include "ray_io.glsl"
#include "glm_float.glsl"
layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
// Per ray two words of four: (t's bits, sample or −1 for a miss, view, iterations) and
// (samples tested, texels visited, texel visits, block visits).
layout(std430, binding = 1) writeonly buffer Answers { uvec4 answers[]; };
// Per view, its texels' first sample (width · height + 1 entries, the view's own numbering).
layout(std430, binding = 2) readonly buffer Offsets { uint offsets[]; };
// Per sample: depth's bits, shading normal, albedoSpec, geometric normal (ldc.h FragmentNode).
layout(std430, binding = 3) readonly buffer Samples { uvec4 samples[]; };
// Per block, uSlots [front, back] intervals, sorted; unused slots have front > back.
layout(std430, binding = 4) readonly buffer Blocks { vec2 blockIntervals[]; };

uniform int uRayCount, uFirst;
uniform mat4 uCameraInverse;  // the frame's camera: camera space → world
uniform mat4 uView[3];        // each LDI's orthographic camera: world → its camera space
uniform ivec2 uSize[3], uBlocks[3];
uniform float uFar[3];
uniform int uOffsetBase[3], uSampleBase[3], uBlockBase[3];
uniform float uTexel, uEpsilon, uHitDistance;
uniform int uBlock, uSlots;
uniform bool uAnyHit;

#define kInf uintBitsToFloat(0x7f800000u)

uint cIterations = 0u, cIntervals = 0u, cPixels = 0u, cLevel0 = 0u, cLevel1 = 0u;

// ViewRay: x(t) = px + dx t, y(t) = py + dy t (texels), depth(t) = pz + dz t; ix, iy = 1/dx, 1/dy.
struct ViewRay {
  float px, py, dx, dy, pz, dz, ix, iy;
};
float rayX(ViewRay r, float t) { precise float v = r.px + r.dx * t; return v; }
float rayY(ViewRay r, float t) { precise float v = r.py + r.dy * t; return v; }
float rayDepth(ViewRay r, float t) { precise float v = r.pz + r.dz * t; return v; }

// clipSlab: narrows [t0, t1] to where p + d t lies in [lo, hi].
bool clipSlab(float p, float d, float inv, float lo, float hi, inout float t0, inout float t1) {
  if (d == 0.0) return p >= lo && p <= hi;
  precise float a = (lo - p) * inv, b = (hi - p) * inv;
  if (a > b) {
    const float s = a;
    a = b;
    b = s;
  }
  t0 = maxStd(t0, a);
  t1 = minStd(t1, b);
  return t0 <= t1;
}

// depthRangeOver: the ray's depth range where it lies above [x0, x1] × [y0, y1] within [t0, t1].
bool depthRangeOver(ViewRay r, float x0, float x1, float y0, float y1, float t0, float t1, out float zLo, out float zHi) {
  zLo = 0.0;
  zHi = 0.0;
  if (!clipSlab(r.px, r.dx, r.ix, x0, x1, t0, t1) || !clipSlab(r.py, r.dy, r.iy, y0, y1, t0, t1)) return false;
  const float za = rayDepth(r, t0), zb = rayDepth(r, t1);
  zLo = minStd(za, zb);
  zHi = maxStd(za, zb);
  return true;
}

// Dda: the cells of `size` texels the ray crosses, exits from the cell index each time.
struct Dda {
  int ix, iy, stepX, stepY;
  float nextX, nextY, size;
};
float exitX(Dda g, ViewRay r) {
  precise float e = (float(g.ix + (g.stepX > 0 ? 1 : 0)) * g.size - r.px) * r.ix;
  return g.stepX == 0 ? kInf : e;
}
float exitY(Dda g, ViewRay r) {
  precise float e = (float(g.iy + (g.stepY > 0 ? 1 : 0)) * g.size - r.py) * r.iy;
  return g.stepY == 0 ? kInf : e;
}
Dda ddaStart(ViewRay r, float cellSize, float t, int cx0, int cx1, int cy0, int cy1) {
  Dda g;
  g.size = cellSize;
  precise float fx = rayX(r, t) / cellSize, fy = rayY(r, t) / cellSize;
  g.ix = clamp(int(floor(fx)), cx0, cx1);
  g.iy = clamp(int(floor(fy)), cy0, cy1);
  g.stepX = r.dx > 0.0 ? 1 : r.dx < 0.0 ? -1 : 0;
  g.stepY = r.dy > 0.0 ? 1 : r.dy < 0.0 ? -1 : 0;
  g.nextX = exitX(g, r);
  g.nextY = exitY(g, r);
  return g;
}
float ddaExit(Dda g) { return minStd(g.nextX, g.nextY); }
void ddaStep(inout Dda g, ViewRay r) {
  if (g.nextX < g.nextY) {
    g.ix += g.stepX;
    g.nextX = exitX(g, r);
  } else {
    g.iy += g.stepY;
    g.nextY = exitY(g, r);
  }
}

float bestT = kInf;
int bestView = -1;
uint bestSample = 0u;

// LdcTracer::traceView for LDI a.
bool traceView(int a, vec3 wo, vec3 wd, float tMin, inout float tMax, bool found) {
  const int W = uSize[a].x, H = uSize[a].y, bx = uBlocks[a].x, by = uBlocks[a].y;
  const float texel = uTexel, eps = uEpsilon;
  precise float inv = 1.0 / texel;
  const vec3 o = transformPoint(uView[a], wo), d = transformDirection(uView[a], wd);
  ViewRay r;
  precise float px = float(W) * 0.5 + o.x * inv, py = float(H) * 0.5 - o.y * inv, dx = d.x * inv, dy = negStd(d.y) * inv;
  r.px = px;
  r.py = py;
  r.dx = dx;
  r.dy = dy;
  r.pz = negStd(o.z);
  r.dz = negStd(d.z);
  precise float ix = 1.0 / r.dx, iy = 1.0 / r.dy, iz = 1.0 / r.dz;
  r.ix = ix;
  r.iy = iy;
  float t0 = tMin, t1 = tMax;
  precise float zBoxHi = uFar[a] - texel;
  if (!clipSlab(r.px, r.dx, r.ix, 0.0, float(W), t0, t1) || !clipSlab(r.py, r.dy, r.iy, 0.0, float(H), t0, t1) ||
      !clipSlab(r.pz, r.dz, iz, texel, zBoxHi, t0, t1))
    return false;
  precise float half_ = (0.5 + eps) * texel;
  precise float margin = 2.0 * half_ * 1.001;
  const int B = uBlock;
  Dda blocks = ddaStart(r, float(B), t0, 0, bx - 1, 0, by - 1);
  float blockEntry = t0;
  for (;;) {
    const float blockExit = minStd(ddaExit(blocks), t1);
    ++cIterations;
    ++cLevel1;
    const uint spans = uint(uBlockBase[a]) + (uint(blocks.iy) * uint(bx) + uint(blocks.ix)) * uint(uSlots);
    float zLo, zHi;
    const float bx0 = float(blocks.ix * B), by0 = float(blocks.iy * B);
    precise float bxLo = bx0 - eps, bxHi = bx0 + float(B) + eps, byLo = by0 - eps, byHi = by0 + float(B) + eps;
    bool overlap = false;
    const vec2 first = blockIntervals[spans];
    if (first.x <= first.y && depthRangeOver(r, bxLo, bxHi, byLo, byHi, tMin, tMax, zLo, zHi)) {
      for (int k = 0; k < uSlots && !overlap; ++k) {
        const vec2 span = blockIntervals[spans + uint(k)];
        if (!(span.x <= span.y)) break;
        precise float hiM = zHi + margin, loM = zLo - margin;
        overlap = hiM >= span.x && loM <= span.y;
      }
    }
    if (overlap) {
      const int x0 = blocks.ix * B, y0 = blocks.iy * B;
      const int x1 = min(x0 + B, W) - 1, y1 = min(y0 + B, H) - 1;
      Dda cells = ddaStart(r, 1.0, blockEntry, x0, x1, y0, y1);
      for (int guard = 0; guard < 2 * B + 2; ++guard) {
        const float cellExit = minStd(ddaExit(cells), blockExit);
        ++cIterations;
        ++cLevel0;
        ++cPixels;
        const float cx = float(cells.ix), cy = float(cells.iy);
        const uint p = uint(uOffsetBase[a]) + uint(cells.iy) * uint(W) + uint(cells.ix);
        const uint begin = offsets[p], end = offsets[p + 1u];
        precise float cxLo = cx - eps, cxHi = cx + 1.0 + eps, cyLo = cy - eps, cyHi = cy + 1.0 + eps;
        if (begin < end && depthRangeOver(r, cxLo, cxHi, cyLo, cyHi, tMin, tMax, zLo, zHi)) {
          precise float centreX = (cx + 0.5 - float(W) * 0.5) * texel;
          precise float centreY = negStd(cy + 0.5 - float(H) * 0.5) * texel;
          precise float below = zLo - margin, beyond = zHi + margin;
          for (uint i = begin; i < end; ++i) {
            const uvec4 s = samples[uint(uSampleBase[a]) + i];
            const float depth = uintBitsToFloat(s.x);
            if (depth < below) continue;
            if (depth > beyond) break;
            ++cIntervals;
            const vec3 P = vec3(centreX, centreY, negStd(depth));
            float t;
            precise vec3 toP = P - o;
            if (uHitDistance > 0.0) {
              precise float tt = dotStd(toP, d) / dotStd(d, d);
              t = tt;
              if (!(t >= tMin && (found ? t < tMax : t <= tMax))) continue;
              precise vec3 miss = o + d * t - P;
              precise float dist = sqrt(dotStd(miss, miss));
              if (dist >= uHitDistance) continue;
            } else {
              const vec3 n = decodeOctahedral(s.w);
              const float denom = dotStd(d, n);
              if (denom == 0.0) continue;
              precise float tt = dotStd(toP, n) / denom;
              t = tt;
              if (!(t >= tMin && (found ? t < tMax : t <= tMax))) continue;
              precise vec3 X = o + d * t;
              precise float ex = abs(X.x - P.x), ey = abs(X.y - P.y);
              if (ex > half_ || ey > half_) continue;
            }
            tMax = t;
            bestT = t;
            bestView = a;
            bestSample = uint(uSampleBase[a]) + i;
            found = true;
            if (uAnyHit) return true;
          }
        }
        if (cellExit >= blockExit || cellExit > tMax) break;
        ddaStep(cells, r);
        if (cells.ix < x0 || cells.ix > x1 || cells.iy < y0 || cells.iy > y1) break;
      }
    }
    if (blockExit >= t1 || blockExit > tMax) break;
    blockEntry = blockExit;
    ddaStep(blocks, r);
    if (blocks.ix < 0 || blocks.ix >= bx || blocks.iy < 0 || blocks.iy >= by) break;
  }
  return found;
}

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uRayCount)) return;
  const GpuRay ray = rays[id];
  bool found = false;
  if (ray.originMax.w >= 0.0) {  // (a negative length: a slot without a ray)
    const vec3 wo = transformPoint(uCameraInverse, ray.originMax.xyz), wd = transformDirection(uCameraInverse, ray.dirSurface.xyz);
    const float tMin = ray.dirSurface.w != 0.0 ? uTexel : 0.0;
    float tMax = ray.originMax.w;
    // The LDI of the ray's dominant axis first (a stable sort of the axes by |wd|, descending).
    const vec3 m = abs(wd);
    int order[3] = int[3](0, 1, 2);
    for (int i = 1; i < 3; ++i)
      for (int j = i; j > 0 && m[order[j]] > m[order[j - 1]]; --j) {
        const int s = order[j];
        order[j] = order[j - 1];
        order[j - 1] = s;
      }
    for (int i = 0; i < 3; ++i) {
      found = traceView(order[i], wo, wd, tMin, tMax, found);
      if (uAnyHit && found) break;
    }
  }
  answers[2u * id] = uvec4(floatBitsToUint(bestT), found ? bestSample : 0xFFFFFFFFu, uint(max(bestView, 0)), cIterations);
  answers[2u * id + 1u] = uvec4(cIntervals, cPixels, cLevel0, cLevel1);
}
