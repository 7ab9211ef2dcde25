#version 450
// The march of Hofmann et al. 2017, §5, over an interval pyramid: the GLSL twin of
// src/layertrace/hssr/hssr_march.h hssrMarch, line for line (the same cells, the same floats, the
// same hit). With one level it is the exhaustive image-space oracle; over a min/max pyramid with
// n_up = 1 it is the Hi-Z march (src/layertrace/hiz/hiz_pyramid.h). One invocation per ray.
layout(local_size_x = 64) in;

#include "ray_io.glsl"
#include "screen_common.glsl"

// Coarse cells of levels 1.. (hssr/interval_pyramid.h CoarseCell): two vec4 per cell, κ of the
// four fronts then of the four backs; unused slots have κFront = −∞.
layout(std430, binding = 4) readonly buffer Cells { vec4 cells[]; };

uniform int uLevels, uNUp;
uniform bool uParentAscent;  // also ascend on entering another parent cell (false: the paper's pure n_up)
uniform int uLevelWidth[16], uLevelHeight[16], uLevelOffset[16];

// hssr_detail::Line: P(s) = p0 + s d.
vec2 gP0, gD;
float gInvDx, gInvDy;
int gStepX, gStepY;

float crossX(float x) {
  precise float s = (x - gP0.x) * gInvDx;
  return gStepX != 0 ? s : kInf;
}
float crossY(float y) {
  precise float s = (y - gP0.y) * gInvDy;
  return gStepY != 0 ? s : kInf;
}
// A span (xIn, xOut, yIn, yOut).
float spanIn(vec4 sp) { return max(sp.x, sp.z); }
float spanOut(vec4 sp) { return min(sp.y, sp.w); }
bool exitX(vec4 sp) { return sp.y <= sp.w; }

vec2 slabX(float x0, float x1) {
  vec2 r = vec2(gStepX > 0 ? crossX(x0) : gStepX < 0 ? crossX(x1) : -kInf, gStepX > 0 ? crossX(x1) : crossX(x0));
  if (gStepX == 0 && !(gP0.x >= x0 && gP0.x < x1)) r = vec2(kInf, -kInf);
  return r;
}
vec2 slabY(float y0, float y1) {
  vec2 r = vec2(gStepY > 0 ? crossY(y0) : gStepY < 0 ? crossY(y1) : -kInf, gStepY > 0 ? crossY(y1) : crossY(y0));
  if (gStepY == 0 && !(gP0.y >= y0 && gP0.y < y1)) r = vec2(kInf, -kInf);
  return r;
}
vec4 span(int cx, int cy, int size) {
  return vec4(slabX(float(cx * size), float((cx + 1) * size)), slabY(float(cy * size), float((cy + 1) * size)));
}
void stepCell(inout vec4 sp, inout int cx, inout int cy, int size) {
  if (exitX(sp)) {
    cx += gStepX;
    sp.x = sp.y;
    sp.y = crossX(float((gStepX > 0 ? cx + 1 : cx) * size));
  } else {
    cy += gStepY;
    sp.z = sp.w;
    sp.w = crossY(float((gStepY > 0 ? cy + 1 : cy) * size));
  }
}
vec2 childSlab(float parentIn, float parentOut, float mid, float middle, float pos, int stp, int b) {
  if (stp == 0) {
    const bool inside = (pos >= middle) == (b == 1);
    return inside ? vec2(-kInf, kInf) : vec2(kInf, -kInf);
  }
  if ((stp > 0) == (b == 0)) return vec2(parentIn, mid);
  return vec2(mid, parentOut);
}

// The level-0 hit: (x, y, interval), or interval -1.
ivec3 march(Segment seg) {
  const int W = uWidth, H = uHeight;
  gP0 = seg.p0;
  gD = seg.p1 - seg.p0;
  gInvDx = gD.x != 0.0 ? 1.0 / gD.x : kInf;
  gInvDy = gD.y != 0.0 ? 1.0 / gD.y : kInf;
  gStepX = gD.x > 0.0 ? 1 : gD.x < 0.0 ? -1 : 0;
  gStepY = gD.y > 0.0 ? 1 : gD.y < 0.0 ? -1 : 0;
  // hssr_detail::MarchStart.
  const int px = clamp(int(floor(seg.p0.x)), 0, W - 1), py = clamp(int(floor(seg.p0.y)), 0, H - 1);
  const bool increasing = seg.k1 <= seg.k0;
  const ivec3 none = ivec3(-1, -1, -1);
  if (gStepX == 0 && gStepY == 0) {
    if (!seg.clippedStart) return none;
    countIteration(0);
    ++cPixels;
    const float za = depthAt(seg, 0.0), zb = depthAt(seg, 1.0);
    const int i = firstMet(pixelBase(px, py), uK, min(za, zb), max(za, zb), increasing);
    return i >= 0 ? ivec3(px, py, i) : none;
  }
  precise float k0 = seg.k0, dk = seg.k1 - seg.k0;
  precise float invDk = 1.0 / dk;
  precise float invAbsDk = abs(invDk);
  precise float pixelBackoff = 1.0 / (64.0 * max(abs(gD.x), abs(gD.y)));
  precise float kScale = max(seg.k0, seg.k1) * invAbsDk;
  vec4 sp = span(px, py, 1);
  if (!(spanIn(sp) <= spanOut(sp))) return none;
  const float sStart = seg.clippedStart ? 0.0 : spanOut(sp);
  int cx = px, cy = py, ox = px, oy = py;
  if (seg.clippedStart) {
    ox = -(1 << 29);
    oy = -(1 << 29);
  } else {
    stepCell(sp, cx, cy, 1);
  }
  float s = sStart;
  int L = 0, misses = 0;
  float cornerLeft = -1.0;
  float sLast = -1.0, zLast = 0.0;
  const int safety = 8 * (W + H) * uLevels + 64;
  for (int guard = 0; guard < safety; ++guard) {
    const int lw = L == 0 ? W : uLevelWidth[L], lh = L == 0 ? H : uLevelHeight[L];
    if (cx < 0 || cy < 0 || cx >= lw || cy >= lh) return none;
    const float sIn = spanIn(sp), sOut = spanOut(sp);
    const float s0 = L == 0 ? max(sIn, sStart) : max(sIn, s);
    const float s1 = min(sOut, 1.0);
    if (s0 > 1.0) return none;
    countIteration(L);
    if (L == 0) {
      ++cPixels;
      const float za = s0 == sLast ? zLast : depthAt(seg, s0), zb = depthAt(seg, s1);
      sLast = s1;
      zLast = zb;
      const int i = firstMet(pixelBase(cx, cy), uK, min(za, zb), max(za, zb), increasing);
      if (i >= 0) return ivec3(cx, cy, i);
    } else {
      precise float ka = k0 + s0 * dk, kb = k0 + s1 * dk;
      precise float kmin = min(ka, kb) * (1.0 - 4e-7), kmax = max(ka, kb) * (1.0 + 4e-7);
      const uint cell = uint(uLevelOffset[L]) + uint(cy) * uint(lw) + uint(cx);
      const vec4 kFront = cells[2u * cell], kBack = cells[2u * cell + 1u];
      float sHit = kInf;
      for (int i = 0; i < 4; ++i) {
        ++cIntervals;
        if (kFront[i] < kmin) break;
        if (kBack[i] > kmax) continue;
        const float kz = increasing ? kFront[i] : kBack[i];
        precise float p = (kz - k0) * invDk;
        precise float backoff = max(pixelBackoff, 8.0 * (1.0 / 16777216.0) * (max(kScale, kz * invAbsDk) + abs(p)));
        precise float e = p - backoff;
        sHit = min(sHit, clampStd(!isinf(e) && !isnan(e) ? e : s0, s0, s1));
      }
      if (sHit != kInf) {
        s = max(s, sHit);
        --L;
        const int half_ = 1 << L;
        const float xMid = float((2 * cx + 1) * half_), yMid = float((2 * cy + 1) * half_);
        const float mx = crossX(xMid), my = crossY(yMid);
        int best = -1;
        float bestOut = 0.0;
        vec4 bestSpan = vec4(0.0);
        for (int q = 0; q < 4; ++q) {
          const vec4 ch = vec4(childSlab(sp.x, sp.y, mx, xMid, gP0.x, gStepX, q & 1), childSlab(sp.z, sp.w, my, yMid, gP0.y, gStepY, q >> 1));
          const float a = spanIn(ch), b = spanOut(ch);
          if (!(a <= s && s <= b) || (b == s && a < b)) continue;
          if (a == b && (exitX(ch) || a == cornerLeft)) continue;
          if (best < 0 || b < bestOut) {
            best = q;
            bestOut = b;
            bestSpan = ch;
          }
        }
        if (best < 0) {
          const vec2 pt = pointAt(seg, s);
          best = (pt.x >= xMid ? 1 : 0) + (pt.y >= yMid ? 2 : 0);
          bestSpan = span(2 * cx + (best & 1), 2 * cy + (best >> 1), half_);
        }
        cx = 2 * cx + (best & 1);
        cy = 2 * cy + (best >> 1);
        sp = bestSpan;
        misses = 0;
        continue;
      }
    }
    if (sIn == sOut) cornerLeft = sOut;
    s = max(s, s1);
    if (sOut >= 1.0) return none;
    const int size = 1 << L;
    const int parentX = cx >> 1, parentY = cy >> 1;
    stepCell(sp, cx, cy, size);
    // Hofmann et al. 2017, §5.2: ascend after n_up cells without an overlap, or on entering
    // another parent cell (the CPU march's choice, hssr_march.h), unless the coarser cell holds
    // the origin pixel.
    const bool newParent = uParentAscent && ((cx >> 1) != parentX || (cy >> 1) != parentY);
    if ((++misses >= uNUp || newParent) && L + 1 < uLevels) {
      const int qx = cx >> 1, qy = cy >> 1;
      if ((ox >> (L + 1)) != qx || (oy >> (L + 1)) != qy) {
        if (qx < uLevelWidth[L + 1] && qy < uLevelHeight[L + 1] && cx >= 0 && cy >= 0) {
          ++L;
          cx = qx;
          cy = qy;
          misses = 0;
          sp = span(cx, cy, 2 * size);
        }
      }
    }
  }
  ++cGiveUps;
  return none;
}

// Hofmann et al. 2017, §5.3: with persistent threads (uPersistent) a fixed set of work groups
// pulls batches of rays from one atomic counter until none is left ("ray reloading"), so a
// group whose rays ended early takes the next batch instead of waiting for the longest ray of
// the frame's last groups. Choice: a group fetches a whole batch of 64 (as Aila and Laine's
// persistent warps fetch 32): one atomic per batch, and every invocation keeps its lane's
// alignment, which per-invocation fetching broke on llvmpipe (a few rays answered differently).
uniform bool uPersistent;
layout(std430, binding = 5) buffer Queue { uint nextRay; };
shared uint batchStart;

void traceRay(uint id) {
  cIterations = 0u, cIntervals = 0u, cPixels = 0u, cGiveUps = 0u;
  for (int l = 0; l < 8; ++l) cLevel[l] = 0u;
  const Segment seg = makeSegment(rays[id]);
  ivec3 h = ivec3(-1, -1, -1);
  if (seg.valid) h = march(seg);
  writeHit(id, h.x, h.y, h.z);
}

void main() {
  if (!uPersistent) {
    const uint id = gl_GlobalInvocationID.x + uint(uFirst);
    if (id < uint(uRayCount)) traceRay(id);
    return;
  }
  for (;;) {
    if (gl_LocalInvocationIndex == 0u) batchStart = atomicAdd(nextRay, 64u);
    barrier();
    const uint start = batchStart;
    barrier();
    if (start >= uint(uRayCount)) return;
    const uint id = start + gl_LocalInvocationIndex;
    if (id < uint(uRayCount)) traceRay(id);
  }
}
