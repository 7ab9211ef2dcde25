// Traversal of the plane/box quad-tree (Widmer et al. 2015, supplement, Algorithms 3 and 4), one
// layer at a time, continued into the next layer from the first occlusion hit.
#include <algorithm>
#include <bit>
#include <cmath>

#include "layertrace/screen/fragment_hit.h"
#include "layertrace/quadtree/quadtree.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/util/error.h"

namespace lt {

namespace {
/// Relative slack of the depth comparisons: a ray that meets a plane exactly at a node
/// boundary must register as a hit in one of the two nodes (not as an occlusion in the second),
/// whatever the rounding of the two plane evaluations. 1e-5 of w is 1e-5 of the depth.
constexpr float kTolerance = 1e-5f;
}  // namespace

/// The ray in (pixel x, pixel y, w) space: a straight line in the screen parameter s ∈ [0, 1]
/// (w is linear in s because 1/depth is, screen_segment.h).
struct QuadtreeTracer::Line {
  glm::vec2 p0, d;
  float w0, dw;
  glm::vec2 p(float s) const { return p0 + s * d; }
  float w(float s) const { return w0 + s * dw; }
  /// Where the ray leaves the axis-aligned cell [x0, x0 + size) × [y0, y0 + size): the
  /// parameters of the exit lines in x and in y (infinite along an axis it does not move on).
  void exits(float x0, float y0, float size, float& sx, float& sy) const {
    sx = d.x != 0.0f ? ((d.x > 0.0f ? x0 + size : x0) - p0.x) / d.x : INFINITY;
    sy = d.y != 0.0f ? ((d.y > 0.0f ? y0 + size : y0) - p0.y) / d.y : INFINITY;
  }
};

struct QuadtreeTracer::LayerResult {
  bool hit = false;
  float s = 0.0f;           ///< hit parameter
  int x = -1, y = -1;       ///< hit pixel
  float occluded = INFINITY;  ///< parameter of the first occlusion hit (the ray went behind a surface)
};

QuadtreeTracer::QuadtreeTracer(const Camera& camera, const LayerArrays& layers, const Quadtree& tree)
    : camera_(camera), layers_(layers), tree_(tree) {
  LT_CHECK(tree.width == layers.width && tree.height == layers.height && tree.k == layers.k, "quadtree built for other layers");
}

// Algorithm 3 for one layer over [sStart, sEnd]: start at the first pixel (below); a box the ray's w range
// overlaps is entered at the child holding the ray's current point; a plane is intersected
// within the node's part of the ray; after a node, Algorithm 4 gives the next node at the same
// level and the walk climbs by the most significant bit that changed in its coordinates.
template <class C>
QuadtreeTracer::LayerResult QuadtreeTracer::traceLayer(int layer, const Line& line, float sStart, float sEnd, C& c) const {
  LayerResult res;
  const int top = tree_.levelCount() - 1;
  const int stepX = line.d.x > 0.0f ? 1 : -1, stepY = line.d.y > 0.0f ? 1 : -1;
  // A bound the walk cannot reach (each level-0 pixel of the line is visited once, with a climb
  // and descent per step): it only guards against a rounding bug looping forever.
  const int budget = 64 + 4 * (tree_.width + tree_.height) * (top + 1);
  // Algorithm 3 line 1 starts at the root and descends; every box above the ray's first pixel
  // holds the surface the ray starts on, so that descent is ~log2(size) visits that decide
  // nothing, per layer. We start at the first pixel instead (the pixel the ray is entering at
  // sStart, ties on a pixel edge going the ray's way) and let the climb of lines 43–46 lift the
  // walk as in the paper after its first descent. (26 % fewer visits on FZK-Haus; the answers
  // differ only where a proxy plane and its level-0 planes disagree, within γ_dist.)
  const glm::vec2 p0 = line.p(sStart);
  auto firstCell = [](float p, float d, int size) {
    int cell = int(std::floor(p));
    if (d < 0.0f && float(cell) == p) --cell;
    return std::clamp(cell, 0, size - 1);
  };
  int level = 0, qx = firstCell(p0.x, line.d.x, tree_.width), qy = firstCell(p0.y, line.d.y, tree_.height);
  if (tree_.config.rootStart) level = top, qx = 0, qy = 0;  // Algorithm 3 as published
  float s = sStart;
  // Which side of this layer's surface the ray was on where the previous node ended (+1 in
  // front, −1 behind, 0 unknown), at which parameter, and whether that node was flagged.
  int side = 0;
  float sideAt = -1.0f;
  bool sideFlagged = true;
  auto hitAt = [&](float sh, int cell) {
    res.hit = true;
    res.s = sh;
    const glm::vec2 p = line.p(sh);
    res.x = std::clamp(int(std::floor(p.x)), qx * cell, std::min((qx + 1) * cell, tree_.width) - 1);
    res.y = std::clamp(int(std::floor(p.y)), qy * cell, std::min((qy + 1) * cell, tree_.height) - 1);
  };
  for (int it = 0;; ++it) {
    if (it > budget) {
      c.giveUp();
      break;
    }
    c.iteration(level);
    const float size = float(1 << level), x0 = float(qx) * size, y0 = float(qy) * size;
    float sx, sy;
    line.exits(x0, y0, size, sx, sy);
    const float sExit = std::min(sx, sy), sOut = std::max(s, std::min(sExit, sEnd));
    const QuadNode& n = tree_.node(layer, level, qx, qy);
    const bool adjacent = side != 0 && sideAt == s && !sideFlagged;
    int newSide = 0;
    if (n.kind() == QuadNode::Plane) {
      c.planeNode();
      if (level == 0) c.pixel();
      // The ray's height above the plane, linear in s: + in front, − behind (w grows toward
      // the camera). Evaluated at the node's own ends so rounding stays local.
      const float cx = x0 + 0.5f * size, cy = y0 + 0.5f * size;
      auto above = [&](float t) {
        const glm::vec2 p = line.p(t);
        return line.w(t) - (n.a + n.b * (p.x - cx) + n.c * (p.y - cy));
      };
      const float fin = above(s), fout = above(sOut), tol = kTolerance * std::abs(line.w(s));
      const bool behind = fin < -tol;
      // Two planes fitted to neighbouring pixels of one curved surface need not meet at their
      // common edge; a ray through that crack is in front of one and behind the next without
      // crossing either. Where neither node carries the discontinuity hint of Algorithm 1 the
      // surface is continuous there, and changing sides across the edge is a hit on it.
      // (A change from behind to in front crosses the surface from behind: with backfaceHits off,
      // no hit, as below.)
      if (adjacent && !n.discontinuity() && (side > 0 ? behind : fin > tol && tree_.config.backfaceHits)) {
        hitAt(s, 1 << level);
        return res;
      }
      // Behind the plane where the ray enters the node: it passed behind this layer's surface
      // (lines 15 and 22: a front-facing plane met before the node, a back-facing one within
      // or after it). The next layer is traced from here.
      if (behind && res.occluded == INFINITY) res.occluded = s, c.occlusion();
      // Lines 16–19: the plane is crossed inside the node's part of the ray. Unlike the
      // single-layer pseudo-code we also accept a crossing from behind (a back-facing plane):
      // with several layers the ray gets behind layer i legitimately (it was occluded, and
      // layer i + 1 is traced from there), and crossing a stored surface's plane within its
      // footprint from either side is a surface hit — the back face of an object seen from
      // behind, say, which Embree hits too. The nearest hit over the layers is kept.
      // (backfaceHits off: the pseudo-code's rule, a crossing from behind is no hit.)
      if (behind ? fout >= 0.0f && tree_.config.backfaceHits : fout < 0.0f) {
        hitAt(!behind && fin <= 0.0f ? s : std::clamp(s + (sOut - s) * (fin / (fin - fout)), s, sOut), 1 << level);
        return res;
      }
      newSide = behind ? -1 : 1;
    } else if (n.kind() == QuadNode::Box) {
      c.boxNode();
      const float wa = line.w(s), wb = line.w(sOut);
      const float lo = std::min(wa, wb), hi = std::max(wa, wb), slack = kTolerance * std::max(std::abs(hi), std::abs(n.b));
      if (hi < n.a - slack) {
        // Line 37: behind everything in the box — the occlusion volume.
        if (res.occluded == INFINITY) res.occluded = s, c.occlusion();
        newSide = -1;
      } else if (lo <= n.b + slack) {
        // Lines 31–35: overlap — descend to the child holding the ray's current point.
        const glm::vec2 p = line.p(s);
        const QuadtreeLevel& child = tree_.levels[size_t(level - 1)];
        qx = std::min(2 * qx + (p.x >= x0 + 0.5f * size ? 1 : 0), child.width - 1);
        qy = std::min(2 * qy + (p.y >= y0 + 0.5f * size ? 1 : 0), child.height - 1);
        --level;
        continue;
      } else {
        newSide = 1;
      }
    }
    side = newSide, sideAt = sOut, sideFlagged = n.discontinuity();
    if (sExit >= sEnd) break;
    // Algorithm 4: the neighbour across the nearer exit line (both on a corner).
    const int nx = qx + (sx <= sy ? stepX : 0), ny = qy + (sy <= sx ? stepY : 0);
    s = std::max(s, sExit);
    const QuadtreeLevel& lv = tree_.levels[size_t(level)];
    if (nx < 0 || ny < 0 || nx >= lv.width || ny >= lv.height) break;  // left the image
    // Algorithm 3 lines 43–46: climb to the coarsest node that holds the new one but not the old.
    const int shift = std::bit_width(unsigned((qx ^ nx) | (qy ^ ny))) - 1;
    const int up = std::min(level + shift, top);
    qx = nx >> (up - level), qy = ny >> (up - level), level = up;
  }
  return res;
}

// Widmer et al. 2015: "quickly trace even multiple depth layers". Layer i + 1 only holds surfaces
// behind layer i, so the ray can meet one only after passing behind layer i: trace it from layer
// i's first occlusion hit, up to the nearest hit found so far, and keep the nearest hit.
template <class C>
TraceHit QuadtreeTracer::traceImpl(const Ray& ray, C& c) const {
  const ScreenSegment seg = makeScreenSegment(camera_, ray);
  if (!seg.valid) return {};
  const float scale = tree_.depthScale;
  const Line line{seg.p0, seg.p1 - seg.p0, scale * seg.k0, scale * (seg.k1 - seg.k0)};
  float sStart = 0.0f, sEnd = 1.0f;
  if (!seg.clippedStart) {
    // Skip the origin's own pixel, as every screen tracer here (Hofmann et al. 2017, §5.1).
    float sx, sy;
    line.exits(std::floor(seg.p0.x), std::floor(seg.p0.y), 1.0f, sx, sy);
    sStart = std::min(sx, sy);
  }
  LayerResult best;
  int bestLayer = -1;
  for (int layer = 0; layer < tree_.k && sStart < sEnd; ++layer) {
    const LayerResult r = traceLayer(layer, line, sStart, sEnd, c);
    if (r.hit) best = r, bestLayer = layer, sEnd = r.s;
    if (!(r.occluded < sEnd)) break;
    sStart = r.occluded;
  }
  if (bestLayer < 0) return {};
  LT_CHECK(layers_.countAt(best.x, best.y) > bestLayer, "quadtree plane over an empty pixel ", best.x, ",", best.y);
  TraceHit h = fragmentHit(camera_, layers_, best.x, best.y, bestLayer);
  // The exact ray–plane point, not the pixel centre's sample: hits on flat surfaces are exact.
  h.point = camera_.rayThrough(line.p(best.s)) * (scale / line.w(best.s));
  return h;
}

template TraceHit QuadtreeTracer::traceImpl(const Ray&, RayCounters&) const;
template TraceHit QuadtreeTracer::traceImpl(const Ray&, NoCounters&) const;

}  // namespace lt
