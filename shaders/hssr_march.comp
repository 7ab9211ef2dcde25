#version 450
// The march of Hofmann et al. 2017, §5, over an interval pyramid: the GLSL twin of
// src/layertrace/hssr/hssr_march.h hssrMarch, line for line (the same cells, the same floats, the
// same hit). With one level it is the exhaustive image-space oracle; over a min/max pyramid with
// n_up = 1 it is the Hi-Z march (src/layertrace/hiz/hiz_pyramid.h). One invocation per ray.
// The subgroup operations of §5.3's in-warp reloading (main below), through either extension.
#ifdef LT_SUBGROUP_ARB
#extension GL_ARB_shader_ballot : require
#extension GL_ARB_shader_group_vote : require
#extension GL_ARB_gpu_shader_int64 : require
uvec4 ltBallot(bool b) { return uvec4(unpackUint2x32(ballotARB(b)), 0u, 0u); }
uvec4 ltLowerLanes() {
  const uint lane = gl_SubGroupInvocationARB % gl_SubGroupSizeARB;
  return lane < 32u ? uvec4((1u << lane) - 1u, 0u, 0u, 0u) : uvec4(~0u, (1u << (lane - 32u)) - 1u, 0u, 0u);
}
bool ltAny(bool b) { return anyInvocationARB(b); }
bool ltLeader() { return gl_SubGroupInvocationARB == readFirstInvocationARB(gl_SubGroupInvocationARB); }
uint ltFirstValue(uint v) { return readFirstInvocationARB(v); }
uint ltSize() { return gl_SubGroupSizeARB; }
#endif
#ifdef LT_SUBGROUP_KHR
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_vote : require
uvec4 ltBallot(bool b) { return subgroupBallot(b); }
uvec4 ltLowerLanes() { return gl_SubgroupLtMask; }
bool ltAny(bool b) { return subgroupAny(b); }
bool ltLeader() { return subgroupElect(); }
uint ltFirstValue(uint v) { return subgroupBroadcastFirst(v); }
uint ltSize() { return gl_SubgroupSize; }
#endif
uint ltCount(uvec4 m) { return uint(bitCount(m.x) + bitCount(m.y) + bitCount(m.z) + bitCount(m.w)); }
layout(local_size_x = 64) in;

#include "ray_io.glsl"
#include "screen_segment.glsl"
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

// The march's state: one ray's progress through the pyramid. The march runs as marchBegin, then
// marchStep until it answers, so the in-warp reloading below can interleave another ray's start
// with its neighbours' steps; the plain march (march) runs the same two functions back to back.
const ivec3 kNone = ivec3(-1, -1, -1);
Segment mSeg;
bool mIncreasing;
float mK0, mDk, mInvDk, mInvAbsDk, mPixelBackoff, mKScale;
vec4 mSp;
float mSStart, mS, mCornerLeft, mSLast, mZLast;
int mCx, mCy, mOx, mOy, mL, mMisses, mGuard, mSafety;
ivec3 mHit;  // the level-0 hit (x, y, interval), or interval -1, once the march has answered
float mHitS;  // the screen parameter at which the segment entered the hit pixel (MarchHit::s)
#ifdef LT_HIT_PARAM
// Per ray the hit's MarchHit::s (0 for a miss): the hybrid's known-space march (gpu_hybrid.h)
// reads where knowledge ends.
layout(std430, binding = 6) writeonly buffer HitParams { float hitParams[]; };
#endif

// Begins the march of a segment (hssr_detail::MarchStart); true when it answers at once.
bool marchBegin(Segment seg) {
  const int W = uWidth, H = uHeight;
  mSeg = seg;
  mHit = kNone;
  mHitS = 0.0;
  gP0 = seg.p0;
  gD = seg.p1 - seg.p0;
  gInvDx = gD.x != 0.0 ? 1.0 / gD.x : kInf;
  gInvDy = gD.y != 0.0 ? 1.0 / gD.y : kInf;
  gStepX = gD.x > 0.0 ? 1 : gD.x < 0.0 ? -1 : 0;
  gStepY = gD.y > 0.0 ? 1 : gD.y < 0.0 ? -1 : 0;
  const int px = clamp(int(floor(seg.p0.x)), 0, W - 1), py = clamp(int(floor(seg.p0.y)), 0, H - 1);
  mIncreasing = seg.k1 <= seg.k0;
  if (gStepX == 0 && gStepY == 0) {
    if (!seg.clippedStart) return true;
    countIteration(0);
    ++cPixels;
    const float za = depthAt(seg, 0.0), zb = depthAt(seg, 1.0);
    const int i = firstMet(pixelBase(px, py), uK, min(za, zb), max(za, zb), mIncreasing);
    if (i >= 0) mHit = ivec3(px, py, i);
    return true;
  }
  precise float k0 = seg.k0, dk = seg.k1 - seg.k0;
  precise float invDk = 1.0 / dk;
  precise float invAbsDk = abs(invDk);
  precise float pixelBackoff = 1.0 / (64.0 * max(abs(gD.x), abs(gD.y)));
  precise float kScale = max(seg.k0, seg.k1) * invAbsDk;
  mK0 = k0, mDk = dk, mInvDk = invDk, mInvAbsDk = invAbsDk, mPixelBackoff = pixelBackoff, mKScale = kScale;
  mSp = span(px, py, 1);
  if (!(spanIn(mSp) <= spanOut(mSp))) return true;
  mSStart = seg.clippedStart ? 0.0 : spanOut(mSp);
  mCx = px, mCy = py, mOx = px, mOy = py;
  if (seg.clippedStart) {
    mOx = -(1 << 29);
    mOy = -(1 << 29);
  } else {
    stepCell(mSp, mCx, mCy, 1);
  }
  mS = mSStart;
  mL = 0, mMisses = 0;
  mCornerLeft = -1.0;
  mSLast = -1.0, mZLast = 0.0;
  mSafety = 8 * (W + H) * uLevels + 64;
  mGuard = 0;
  return false;
}

// Counts one cell of the march's safety bound; true (a give-up, no hit) when it is spent.
bool marchNext() {
  if (++mGuard < mSafety) return false;
  ++cGiveUps;
  return true;
}

// One cell of the march (one pass of hssrMarch's loop); true when the march has answered
// (mHit), or has given up.
bool marchStep() {
  const int W = uWidth, H = uHeight;
  const int lw = mL == 0 ? W : uLevelWidth[mL], lh = mL == 0 ? H : uLevelHeight[mL];
  bool done = mCx < 0 || mCy < 0 || mCx >= lw || mCy >= lh;
  const float sIn = spanIn(mSp), sOut = spanOut(mSp);
  const float s0 = mL == 0 ? max(sIn, mSStart) : max(sIn, mS);
  const float s1 = min(sOut, 1.0);
  if (!done && s0 > 1.0) done = true;
  bool descended = false;
  if (!done) {
    countIteration(mL);
    if (mL == 0) {
      ++cPixels;
      const float za = s0 == mSLast ? mZLast : depthAt(mSeg, s0), zb = depthAt(mSeg, s1);
      mSLast = s1;
      mZLast = zb;
      const int i = firstMet(pixelBase(mCx, mCy), uK, min(za, zb), max(za, zb), mIncreasing);
      if (i >= 0) {
        mHit = ivec3(mCx, mCy, i);
        mHitS = s0;
        done = true;
      }
    } else {
      precise float ka = mK0 + s0 * mDk, kb = mK0 + s1 * mDk;
      precise float kmin = min(ka, kb) * (1.0 - 4e-7), kmax = max(ka, kb) * (1.0 + 4e-7);
      const uint cell = uint(uLevelOffset[mL]) + uint(mCy) * uint(lw) + uint(mCx);
      const vec4 kFront = cells[2u * cell], kBack = cells[2u * cell + 1u];
      float sHit = kInf;
      for (int i = 0; i < 4; ++i) {
        ++cIntervals;
        if (kFront[i] < kmin) break;
        if (kBack[i] > kmax) continue;
        const float kz = mIncreasing ? kFront[i] : kBack[i];
        precise float p = (kz - mK0) * mInvDk;
        precise float backoff = max(mPixelBackoff, 8.0 * (1.0 / 16777216.0) * (max(mKScale, kz * mInvAbsDk) + abs(p)));
        precise float e = p - backoff;
        sHit = min(sHit, clampStd(!isinf(e) && !isnan(e) ? e : s0, s0, s1));
      }
      if (sHit != kInf) {
        descended = true;
        mS = max(mS, sHit);
        --mL;
        const int half_ = 1 << mL;
        const float xMid = float((2 * mCx + 1) * half_), yMid = float((2 * mCy + 1) * half_);
        const float mx = crossX(xMid), my = crossY(yMid);
        int best = -1;
        float bestOut = 0.0;
        vec4 bestSpan = vec4(0.0);
        for (int q = 0; q < 4; ++q) {
          const vec4 ch = vec4(childSlab(mSp.x, mSp.y, mx, xMid, gP0.x, gStepX, q & 1), childSlab(mSp.z, mSp.w, my, yMid, gP0.y, gStepY, q >> 1));
          const float a = spanIn(ch), b = spanOut(ch);
          const bool holds = (a <= mS && mS <= b) && !(b == mS && a < b) && !(a == b && (exitX(ch) || a == mCornerLeft));
          if (holds && (best < 0 || b < bestOut)) {
            best = q;
            bestOut = b;
            bestSpan = ch;
          }
        }
        if (best < 0) {
          const vec2 pt = pointAt(mSeg, mS);
          best = (pt.x >= xMid ? 1 : 0) + (pt.y >= yMid ? 2 : 0);
          bestSpan = span(2 * mCx + (best & 1), 2 * mCy + (best >> 1), half_);
        }
        mCx = 2 * mCx + (best & 1);
        mCy = 2 * mCy + (best >> 1);
        mSp = bestSpan;
        mMisses = 0;
      }
    }
  }
  if (!done && !descended) {
    if (sIn == sOut) mCornerLeft = sOut;
    mS = max(mS, s1);
    done = sOut >= 1.0;
    if (!done) {
      const int size = 1 << mL;
      const int parentX = mCx >> 1, parentY = mCy >> 1;
      stepCell(mSp, mCx, mCy, size);
      // Hofmann et al. 2017, §5.2: ascend after n_up cells without an overlap, or on entering
      // another parent cell (the CPU march's choice, hssr_march.h), unless the coarser cell
      // holds the origin pixel.
      const bool newParent = uParentAscent && ((mCx >> 1) != parentX || (mCy >> 1) != parentY);
      if ((++mMisses >= uNUp || newParent) && mL + 1 < uLevels) {
        const int qx = mCx >> 1, qy = mCy >> 1;
        if ((mOx >> (mL + 1)) != qx || (mOy >> (mL + 1)) != qy) {
          if (qx < uLevelWidth[mL + 1] && qy < uLevelHeight[mL + 1] && mCx >= 0 && mCy >= 0) {
            ++mL;
            mCx = qx;
            mCy = qy;
            mMisses = 0;
            mSp = span(mCx, mCy, 2 * size);
          }
        }
      }
    }
  }
  return done || marchNext();
}

// The level-0 hit of a segment: (x, y, interval), or interval -1.
ivec3 march(Segment seg) {
  if (!marchBegin(seg)) {
    while (!marchStep()) {
    }
  }
  return mHit;
}

// Hofmann et al. 2017, §5.3: with persistent threads (uPersistent) a fixed set of work groups
// pulls rays from one atomic counter until none is left ("ray reloading"), so a lane whose ray
// ended early takes the next one instead of waiting for the longest ray of the frame's last
// groups.
uniform bool uPersistent;
layout(std430, binding = 5) buffer Queue { uint nextRay; };

void beginRay(uint id) {
  cIterations = 0u, cIntervals = 0u, cPixels = 0u, cGiveUps = 0u, cFragments = 0u;
  for (int l = 0; l < 8; ++l) cLevel[l] = 0u;
}

void traceRay(uint id) {
  beginRay(id);
  const Segment seg = makeSegment(rays[id]);
  ivec3 h = kNone;
  if (seg.valid) h = march(seg);
  writeHit(id, h.x, h.y, h.z);
#ifdef LT_HIT_PARAM
  hitParams[id] = h.z >= 0 ? mHitS : 0.0;
#endif
}

#if defined(LT_SUBGROUP_ARB) || defined(LT_SUBGROUP_KHR)
// §5.3 as published: warp-level early termination and in-warp ray reloading. Every lane holds
// one ray and the subgroup steps all of them one cell at a time; after each step the lanes whose
// ray has answered take the next rays of the queue together (one atomic per subgroup, the
// indices handed out in lane order by a ballot), and the subgroup leaves as soon as the queue is
// empty and none of its lanes has a ray. No work-group barrier: subgroups run independently.
// Choice: the atomic is executed by every lane of the subgroup, the leader adding the count and
// the others 0, so that it never runs in divergent control flow.
void main() {
  if (!uPersistent) {
    const uint id = gl_GlobalInvocationID.x + uint(uFirst);
    if (id < uint(uRayCount)) traceRay(id);
    return;
  }
  const uint count = uint(uRayCount);
  const uvec4 lower = ltLowerLanes();
  // Each subgroup takes at most twice its even share of the rays: enough for the queue to
  // balance the load, and a bound on one subgroup's loop iterations, which a driver may cap
  // (llvmpipe stops a shader's loops after 65535 iterations in all).
  const uint subgroups = gl_NumWorkGroups.x * ((gl_WorkGroupSize.x + ltSize() - 1u) / ltSize());
  const uint quota = 2u * ((count + subgroups - 1u) / subgroups);
  uint taken = 0u;
  bool holding = false, drained = false;
  uint id = 0u;
  do {
    if (!drained) {
      const uvec4 need = ltBallot(!holding);
      const uint wanted = ltCount(need);
      if (wanted != 0u) {
        const uint base = ltFirstValue(atomicAdd(nextRay, ltLeader() ? wanted : 0u));
        taken += wanted;
        if (base + wanted >= count || taken >= quota) drained = true;
        if (!holding) {
          id = base + ltCount(need & lower);
          if (id < count) {
            beginRay(id);
            const Segment seg = makeSegment(rays[id]);
            mHit = kNone;
            bool answered = true;
            if (seg.valid) answered = marchBegin(seg);
            if (answered) {
              writeHit(id, mHit.x, mHit.y, mHit.z);
            } else {
              holding = true;
            }
          }
        }
      }
    }
    if (holding && marchStep()) {
      writeHit(id, mHit.x, mHit.y, mHit.z);
      holding = false;
    }
  } while (!drained || ltAny(holding));
}
#else
// Without subgroup operations a work group fetches a batch of 64 rays at a time (as Aila and
// Laine's persistent warps fetch 32), behind a barrier: one atomic per batch. A group takes at
// most twice its even share of the batches, as the subgroups above do.
shared uint batchStart;

void main() {
  if (!uPersistent) {
    const uint id = gl_GlobalInvocationID.x + uint(uFirst);
    if (id < uint(uRayCount)) traceRay(id);
    return;
  }
  const uint batches = (uint(uRayCount) + 63u) / 64u;
  const uint quota = 2u * ((batches + gl_NumWorkGroups.x - 1u) / gl_NumWorkGroups.x);
  for (uint b = 0u; b < quota; ++b) {
    if (gl_LocalInvocationIndex == 0u) batchStart = atomicAdd(nextRay, 64u);
    barrier();
    const uint start = batchStart;
    barrier();
    if (start >= uint(uRayCount)) return;
    const uint id = start + gl_LocalInvocationIndex;
    if (id < uint(uRayCount)) traceRay(id);
  }
}
#endif
