#version 450
// The quad-tree's traversal (Widmer et al. 2015, supplement, Algorithms 3 and 4): the GLSL twin
// of src/layertrace/quadtree/quadtree_tracer.cpp, one invocation per ray. Each layer's walk
// starts at the ray's first pixel (or the root: uRootStart), descends into boxes the ray
// overlaps, intersects planes, and climbs by the most significant changed bit of the node
// coordinate; the next layer is traced from the first occlusion hit. The answer is the hit
// fragment (pixel, layer) with the counters, and in `extra` the hit's parameter on the screen
// segment (the exact ray–plane point) and the quad-tree's own counters.
layout(local_size_x = 64) in;
#include "ray_io.glsl"
#include "screen_segment.glsl"
#include "screen_common.glsl"
#include "glm_float.glsl"
#include "quadtree_common.glsl"
layout(std430, binding = 4) readonly buffer Nodes { QuadNode nodes[]; };
layout(std430, binding = 5) readonly buffer Scale { float depthScale; };
// Per ray: the hit parameter's bits, plane nodes, box nodes and occlusion hits visited.
layout(std430, binding = 6) writeonly buffer Extra { uvec4 extra[]; };
uniform bool uRootStart, uBackfaceHits;

// Relative slack of the depth comparisons (quadtree_tracer.cpp kTolerance).
const float kTolerance = 1e-5;

uint cPlanes = 0u, cBoxes = 0u, cOcclusions = 0u;

// QuadtreeTracer::Line: the ray in (pixel x, pixel y, w).
vec2 lineP0, lineD;
float lineW0, lineDw;
vec2 lineP(float s) {
  precise vec2 p = lineP0 + s * lineD;
  return p;
}
float lineW(float s) {
  precise float w = lineW0 + s * lineDw;
  return w;
}
void exits(float x0, float y0, float size, out float sx, out float sy) {
  precise float ex = lineD.x > 0.0 ? x0 + size : x0, ey = lineD.y > 0.0 ? y0 + size : y0;
  precise float tx = (ex - lineP0.x) / lineD.x, ty = (ey - lineP0.y) / lineD.y;
  sx = lineD.x != 0.0 ? tx : kInf;
  sy = lineD.y != 0.0 ? ty : kInf;
}

struct LayerResult {
  bool hit;
  float s;
  int x, y;
  float occluded;
};

int firstCell(float p, float d, int size) {
  int cell = int(floor(p));
  if (d < 0.0 && float(cell) == p) --cell;
  return clamp(cell, 0, size - 1);
}

// QuadtreeTracer::traceLayer.
LayerResult traceLayer(int layer, float sStart, float sEnd) {
  LayerResult res = LayerResult(false, 0.0, -1, -1, kInf);
  const int top = uLevelCount - 1;
  const int W = uLevelWidth[0], H = uLevelHeight[0];
  const int stepX = lineD.x > 0.0 ? 1 : -1, stepY = lineD.y > 0.0 ? 1 : -1;
  const int budget = 64 + 4 * (W + H) * (top + 1);
  const vec2 p0 = lineP(sStart);
  int level = 0, qx = firstCell(p0.x, lineD.x, W), qy = firstCell(p0.y, lineD.y, H);
  if (uRootStart) level = top, qx = 0, qy = 0;
  float s = sStart;
  int side = 0;
  float sideAt = -1.0;
  bool sideFlagged = true;
  for (int it = 0;; ++it) {
    if (it > budget) {
      ++cGiveUps;
      break;
    }
    countIteration(level);
    const float size = float(1 << level);
    precise float x0 = float(qx) * size, y0 = float(qy) * size;
    float sx, sy;
    exits(x0, y0, size, sx, sy);
    const float sExit = minStd(sx, sy), sOut = maxStd(s, minStd(sExit, sEnd));
    const QuadNode n = nodes[nodeIndex(layer, level, qx, qy)];
    const uint kind = n.flags & kQuadKindMask;
    const bool flagged = (n.flags & kQuadDiscontinuity) != 0u;
    const bool adjacent = side != 0 && sideAt == s && !sideFlagged;
    int newSide = 0;
    bool hitNow = false;
    float hitS = s;
    if (kind == kQuadPlane) {
      ++cPlanes;
      if (level == 0) ++cPixels;
      precise float cx = x0 + 0.5 * size, cy = y0 + 0.5 * size;
      const vec2 pin = lineP(s), pout = lineP(sOut);
      precise float fin = lineW(s) - (n.a + n.b * (pin.x - cx) + n.c * (pin.y - cy));
      precise float fout = lineW(sOut) - (n.a + n.b * (pout.x - cx) + n.c * (pout.y - cy));
      precise float tol = kTolerance * abs(lineW(s));
      const bool behind = fin < -tol;
      if (adjacent && !flagged && (side > 0 ? behind : fin > tol && uBackfaceHits)) {
        hitNow = true;
      } else {
        if (behind && res.occluded == kInf) {
          res.occluded = s;
          ++cOcclusions;
        }
        if (behind ? fout >= 0.0 && uBackfaceHits : fout < 0.0) {
          precise float crossing = s + (sOut - s) * (fin / (fin - fout));
          hitNow = true;
          hitS = !behind && fin <= 0.0 ? s : clampStd(crossing, s, sOut);
        }
      }
      if (hitNow) {
        const int cell = 1 << level;
        const vec2 p = lineP(hitS);
        res.hit = true;
        res.s = hitS;
        res.x = clamp(int(floor(p.x)), qx * cell, min((qx + 1) * cell, W) - 1);
        res.y = clamp(int(floor(p.y)), qy * cell, min((qy + 1) * cell, H) - 1);
        return res;
      }
      newSide = behind ? -1 : 1;
    } else if (kind == kQuadBox) {
      ++cBoxes;
      const float wa = lineW(s), wb = lineW(sOut);
      const float lo = minStd(wa, wb), hi = maxStd(wa, wb);
      precise float slack = kTolerance * maxStd(abs(hi), abs(n.b));
      precise float below = n.a - slack, above = n.b + slack;
      if (hi < below) {
        if (res.occluded == kInf) {
          res.occluded = s;
          ++cOcclusions;
        }
        newSide = -1;
      } else if (lo <= above) {
        const vec2 p = lineP(s);
        precise float mx = x0 + 0.5 * size, my = y0 + 0.5 * size;
        qx = min(2 * qx + (p.x >= mx ? 1 : 0), uLevelWidth[level - 1] - 1);
        qy = min(2 * qy + (p.y >= my ? 1 : 0), uLevelHeight[level - 1] - 1);
        --level;
        continue;
      } else {
        newSide = 1;
      }
    }
    side = newSide;
    sideAt = sOut;
    sideFlagged = flagged;
    if (sExit >= sEnd) break;
    const int nx = qx + (sx <= sy ? stepX : 0), ny = qy + (sy <= sx ? stepY : 0);
    s = maxStd(s, sExit);
    if (nx < 0 || ny < 0 || nx >= uLevelWidth[level] || ny >= uLevelHeight[level]) break;
    const int shift = findMSB(uint((qx ^ nx) | (qy ^ ny)));
    const int up = min(level + shift, top);
    qx = nx >> (up - level);
    qy = ny >> (up - level);
    level = up;
  }
  return res;
}

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uRayCount)) return;
  const Segment seg = makeSegment(rays[id]);
  LayerResult best = LayerResult(false, 0.0, -1, -1, kInf);
  int bestLayer = -1;
  if (seg.valid) {
    const float scale = depthScale;
    lineP0 = seg.p0;
    precise vec2 d = seg.p1 - seg.p0;
    precise float w0 = scale * seg.k0, dw = scale * (seg.k1 - seg.k0);
    lineD = d;
    lineW0 = w0;
    lineDw = dw;
    float sStart = 0.0, sEnd = 1.0;
    if (!seg.clippedStart) {
      // The origin's own pixel is skipped (Hofmann et al. 2017, §5.1).
      float sx, sy;
      exits(floor(seg.p0.x), floor(seg.p0.y), 1.0, sx, sy);
      sStart = minStd(sx, sy);
    }
    for (int layer = 0; layer < uK && sStart < sEnd; ++layer) {
      const LayerResult r = traceLayer(layer, sStart, sEnd);
      if (r.hit) {
        best = r;
        bestLayer = layer;
        sEnd = r.s;
      }
      if (!(r.occluded < sEnd)) break;
      sStart = r.occluded;
    }
  }
  writeHit(id, best.x, best.y, bestLayer);
#ifdef LT_NO_COUNTERS
  extra[id] = uvec4(floatBitsToUint(best.s), 0u, 0u, 0u);
#else
  extra[id] = uvec4(floatBitsToUint(best.s), cPlanes, cBoxes, cOcclusions);
#endif
}
