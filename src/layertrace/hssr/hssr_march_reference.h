// The traversal of Hofmann et al. 2017, §5, as first written: the simple reference the fast march
// (hssr_march.h) replaced. It recomputes every crossing of every visited cell, compares depths
// (two divisions per cell) and reads the pyramid's CSR levels. Kept unchanged so that the fast
// march stays tested hit for hit against it (tests/hssr_test.cpp); nothing else calls it.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "layertrace/hssr/hssr_march.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/screen/screen_segment.h"

namespace lt {

namespace hssr_reference_detail {
/// The 2D line P(s) = p0 + s d and the parameters where it crosses a cell's box
/// (Hofmann et al. 2017, §5.1: "a simple 2D ray/AABB test"). Every level computes a boundary's
/// parameter with the same expression, so a level-0 pixel gets bit-identical entry/exit whichever
/// level the ray came down from.
struct Line {
  glm::vec2 p0, d;
  float invDx, invDy;
  int stepX, stepY;
  explicit Line(const ScreenSegment& seg) : p0(seg.p0), d(seg.p1 - seg.p0) {
    constexpr float inf = std::numeric_limits<float>::infinity();
    invDx = d.x != 0.0f ? 1.0f / d.x : inf;
    invDy = d.y != 0.0f ? 1.0f / d.y : inf;
    stepX = d.x > 0.0f ? 1 : d.x < 0.0f ? -1 : 0;
    stepY = d.y > 0.0f ? 1 : d.y < 0.0f ? -1 : 0;
  }
  float crossX(float x) const { return stepX ? (x - p0.x) * invDx : std::numeric_limits<float>::infinity(); }
  float crossY(float y) const { return stepY ? (y - p0.y) * invDy : std::numeric_limits<float>::infinity(); }
  /// Entry and exit parameters of cell (cx, cy) of size `size` pixels; also which axis exits first.
  void cellParams(int cx, int cy, int size, float& sIn, float& sOut, bool& exitX) const {
    const float x0 = float(cx * size), x1 = float((cx + 1) * size), y0 = float(cy * size), y1 = float((cy + 1) * size);
    const float txIn = stepX > 0 ? crossX(x0) : stepX < 0 ? crossX(x1) : -std::numeric_limits<float>::infinity();
    const float txOut = stepX > 0 ? crossX(x1) : crossX(x0);
    const float tyIn = stepY > 0 ? crossY(y0) : stepY < 0 ? crossY(y1) : -std::numeric_limits<float>::infinity();
    const float tyOut = stepY > 0 ? crossY(y1) : crossY(y0);
    sIn = std::max(txIn, tyIn);
    sOut = std::min(txOut, tyOut);
    // An axis-parallel line only passes the cells of its own row or column.
    if ((stepX == 0 && !(p0.x >= x0 && p0.x < x1)) || (stepY == 0 && !(p0.y >= y0 && p0.y < y1)))
      sIn = std::numeric_limits<float>::infinity(), sOut = -std::numeric_limits<float>::infinity();
    exitX = txOut <= tyOut;  // ties step in x first (deterministic)
  }
};

}  // namespace hssr_reference_detail

/// The march of Hofmann et al. 2017, §5, over `pyramid` (its first `levels` levels) for a valid
/// segment of a W×H view. Hits are reported at level 0 only; `nUp` cells without an overlap before
/// ascending.
template <class C>
MarchHit hssrMarchReference(const IntervalPyramid& pyramid, int levels, int nUp, const ScreenSegment& seg, int W, int H, C& c) {
  using hssr_reference_detail::Line;
  const Line line(seg);
  int ox = std::clamp(int(std::floor(seg.p0.x)), 0, W - 1), oy = std::clamp(int(std::floor(seg.p0.y)), 0, H - 1);
  const bool increasing = seg.k1 <= seg.k0;  // depth grows along the ray
  if (line.stepX == 0 && line.stepY == 0) {
    // The ray runs along one pixel's line of sight: only a ray entering from outside the view
    // can meet something there (a ray from a surface skips its own pixel).
    if (!seg.clippedStart) return {};
    c.iteration(0);
    c.pixel();
    const float za = seg.depthAt(0.0f), zb = seg.depthAt(1.0f);
    const int i = firstMet(pyramid.base->pixel(ox, oy), pyramid.base->countAt(ox, oy), std::min(za, zb), std::max(za, zb), increasing, c);
    return i >= 0 ? MarchHit{ox, oy, i, 0.0f} : MarchHit{};
  }
  // Back-off for the coarse entry: paramAtDepth divides by k1 − k0, so its rounding error
  // grows as the ray turns parallel to the image plane (|k1 − k0| ≪ k0). Step back at least
  // 1/64 pixel, and at least 4× the error bound of the division (in units of s):
  //   |Δs| ≤ 4 u (max(k0, k1, 1/z) / |k1 − k0| + |s|),  u = 2^-24,
  // so rounding can never carry the entry past the pixel the level-0 scan would hit.
  const float pixelBackoff = 1.0f / (64.0f * std::max(std::abs(line.d.x), std::abs(line.d.y)));
  const float kScale = std::max(seg.k0, seg.k1) / std::abs(seg.k1 - seg.k0);
  auto backoff = [&](float e, float z) {
    constexpr float u = 1.0f / 16777216.0f;
    return std::max(pixelBackoff, 4.0f * u * (std::max(kScale, 1.0f / (z * std::abs(seg.k1 - seg.k0))) + std::abs(e)));
  };

  // Hofmann et al. 2017, §5.1: skip the first pixel (no self-intersection with the origin's
  // surface). A ray entering from outside the view starts no surface: its first pixel is tested,
  // and no pixel is the origin pixel of the ascend rule.
  float sIn, sOut;
  bool exitX;
  line.cellParams(ox, oy, 1, sIn, sOut, exitX);
  const float sStart = seg.clippedStart ? 0.0f : sOut;
  float s = sStart;
  int L = 0, cx = ox + (exitX ? line.stepX : 0), cy = oy + (exitX ? 0 : line.stepY);
  if (seg.clippedStart) cx = ox, cy = oy, ox = oy = -(1 << 29);
  int misses = 0;
  // Parameter of the last zero-length (corner) cell the DDA stepped out of: a descent at that
  // same parameter must not go back into it (the oracle visits it once).
  float cornerLeft = -1.0f;
  float sLast = -1.0f, zLast = 0.0f;  // the last depthAt(s) computed, for reuse
  const int safety = 8 * (W + H) * levels + 64;
  for (int guard = 0; guard < safety; ++guard) {
    const PyramidLevel& lvl = pyramid.levels[size_t(L)];
    if (cx < 0 || cy < 0 || cx >= lvl.width || cy >= lvl.height) return {};
    const int size = 1 << L;
    line.cellParams(cx, cy, size, sIn, sOut, exitX);
    const float s0 = L == 0 ? std::max(sIn, sStart) : std::max(sIn, s);
    const float s1 = std::min(sOut, 1.0f);
    if (s0 > 1.0f) return {};  // the segment ended before this cell
    c.iteration(L);
    // The exit of one cell is usually the entry of the next: reuse its depth (the same
    // division of the same s, so bit-identical) instead of dividing again.
    const float za = s0 == sLast ? zLast : seg.depthAt(s0), zb = seg.depthAt(s1);
    sLast = s1, zLast = zb;
    float zmin = std::min(za, zb), zmax = std::max(za, zb);
    if (L == 0) {
      c.pixel();
      const int i = firstMet(pyramid.base->pixel(cx, cy), pyramid.base->countAt(cx, cy), zmin, zmax, increasing, c);
      if (i >= 0) return MarchHit{cx, cy, i, s0};
    } else {
      // Coarse levels only accelerate: widen the range by a few ulps so rounding can never
      // make them skip what level 0 would find.
      zmin *= 1.0f - 4e-7f, zmax *= 1.0f + 4e-7f;
      const size_t cell = lvl.cellIndex(cx, cy);
      float sHit = std::numeric_limits<float>::infinity();
      for (uint32_t i = lvl.offset[cell]; i < lvl.offset[cell + 1]; ++i) {
        c.interval();
        const Interval& iv = lvl.intervals[i];
        if (iv.front > zmax) break;
        if (iv.back < zmin) continue;
        // Enter at the front when depth grows, at the back when it shrinks; never move back.
        // Step back from the computed entry by its error bound (backoff above): an entry that
        // lands just past a pixel boundary would skip the pixel the oracle hits. Re-testing a
        // little more is always safe; s0 keeps it from reaching behind the current position.
        const float z = increasing ? iv.front : iv.back;
        const float p = seg.paramAtDepth(z);
        const float e = p - backoff(p, z);
        sHit = std::min(sHit, std::clamp(std::isfinite(e) ? e : s0, s0, s1));
      }
      if (sHit != std::numeric_limits<float>::infinity()) {
        // Hofmann et al. 2017, §5.2: advance to the entry, re-project, descend one level.
        s = std::max(s, sHit);
        --L;
        const int half = size >> 1;
        // The child holding s, chosen as the oracle's DDA reaches it.
        // The child being left (exit == s) is done. Where the line passes exactly through a
        // corner, the DDA steps in x first and visits that zero-length cell (entry == exit == s)
        // before the diagonal one: prefer it (smallest exit), so level-0 visits match the
        // oracle's, ties included.
        int best = -1;
        float bestOut = 0.0f;
        for (int k = 0; k < 4; ++k) {
          const int nx = 2 * cx + (k & 1), ny = 2 * cy + (k >> 1);
          float a, b;
          bool ex;
          line.cellParams(nx, ny, half, a, b, ex);
          if (!(a <= s && s <= b) || (b == s && a < b)) continue;
          // A zero-length cell is one the x-first DDA steps into at a corner and leaves through
          // y; the other corner cell (left through x) it never visits. Once left, not again.
          if (a == b && (ex || a == cornerLeft)) continue;
          if (best < 0 || b < bestOut) best = k, bestOut = b;
        }
        if (best < 0) {  // rounding left s just outside every child: take the one under P(s)
          const glm::vec2 p = seg.pointAt(s);
          best = (p.x >= float((2 * cx + 1) * half) ? 1 : 0) + (p.y >= float((2 * cy + 1) * half) ? 2 : 0);
        }
        cx = 2 * cx + (best & 1);
        cy = 2 * cy + (best >> 1);
        misses = 0;
        continue;
      }
    }
    // No overlap: step to the next cell of this level.
    if (sIn == sOut) cornerLeft = sOut;
    s = std::max(s, s1);
    if (sOut >= 1.0f) return {};
    if (exitX) cx += line.stepX;
    else cy += line.stepY;
    if (++misses >= nUp && L + 1 < levels) {
      const int px = cx >> 1, py = cy >> 1;
      // Hofmann et al. 2017, §5.2: only ascend when the coarser cell does not overlap the origin
      // pixel.
      if ((ox >> (L + 1)) != px || (oy >> (L + 1)) != py) {
        if (px < pyramid.levels[size_t(L + 1)].width && py < pyramid.levels[size_t(L + 1)].height && cx >= 0 && cy >= 0) {
          ++L, cx = px, cy = py, misses = 0;
        }
      }
    }
  }
  c.giveUp();  // the step cap: never reached by a conservative DDA (tested), counted if it is
  return {};
}

}  // namespace lt
