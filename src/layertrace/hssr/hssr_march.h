// The traversal of Hofmann et al. 2017, §5, as a reusable march: a conservative Amanatides–Woo DDA
// over an interval pyramid that returns the first stored interval a screen segment meets (pixel,
// interval index, entry parameter). HssrTracer turns that into a fragment hit; KnownSpace
// (known_space.h) runs the same march over a pyramid of "unknown" intervals to find where a ray
// leaves the space the layers describe. One traversal, one set of guarantees (exact against the
// level-0 scan, tested through HssrTracer).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/screen/screen_segment.h"

namespace lt {

/// The level-0 interval a march met first: pixel (x, y), interval index in that pixel, and the
/// screen parameter s at which the segment entered the pixel (clamped to the segment's start).
struct MarchHit {
  int x = -1, y = -1, interval = -1;
  float s = 0.0f;
  bool hit() const { return interval >= 0; }
};

namespace hssr_detail {
/// The 2D line P(s) = p0 + s d and the parameters where it crosses cell boundaries
/// (Hofmann et al. 2017, §5.1: "a simple 2D ray/AABB test"). Every level computes a boundary's
/// parameter with the same expression, so a level-0 pixel gets bit-identical entry/exit whichever
/// level the ray came down from — and the same values as the reference march
/// (hssr_march_reference.h), which recomputes all four crossings of every cell.
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

  /// Where the line enters and leaves a cell's column (x) and row (y). An axis-parallel line
  /// passes no cell outside its own row or column: such a cell is `blocked` (in = +∞, out = −∞).
  struct Span {
    float xIn, xOut, yIn, yOut;
    float in() const { return std::max(xIn, yIn); }
    float out() const { return std::min(xOut, yOut); }
    bool exitX() const { return xOut <= yOut; }  // ties step in x first
  };
  /// The column [x0, x1) as entered along the line.
  void slabX(float x0, float x1, float& in, float& out) const {
    constexpr float inf = std::numeric_limits<float>::infinity();
    in = stepX > 0 ? crossX(x0) : stepX < 0 ? crossX(x1) : -inf;
    out = stepX > 0 ? crossX(x1) : crossX(x0);
    if (stepX == 0 && !(p0.x >= x0 && p0.x < x1)) in = inf, out = -inf;
  }
  void slabY(float y0, float y1, float& in, float& out) const {
    constexpr float inf = std::numeric_limits<float>::infinity();
    in = stepY > 0 ? crossY(y0) : stepY < 0 ? crossY(y1) : -inf;
    out = stepY > 0 ? crossY(y1) : crossY(y0);
    if (stepY == 0 && !(p0.y >= y0 && p0.y < y1)) in = inf, out = -inf;
  }
  /// Cell (cx, cy) of size `size` pixels, all four crossings (on entry, ascent, or a rounding
  /// fallback; the march otherwise keeps spans incrementally).
  Span span(int cx, int cy, int size) const {
    Span sp;
    slabX(float(cx * size), float((cx + 1) * size), sp.xIn, sp.xOut);
    slabY(float(cy * size), float((cy + 1) * size), sp.yIn, sp.yOut);
    return sp;
  }
  /// Step from a cell of size `size` to its neighbour across the exit boundary: the exit of one
  /// cell is the entry of the next, so one new crossing per step.
  void step(Span& sp, int& cx, int& cy, int size) const {
    if (sp.exitX()) {
      cx += stepX;
      sp.xIn = sp.xOut;
      sp.xOut = crossX(float((stepX > 0 ? cx + 1 : cx) * size));
    } else {
      cy += stepY;
      sp.yIn = sp.yOut;
      sp.yOut = crossY(float((stepY > 0 ? cy + 1 : cy) * size));
    }
  }
  /// One axis of child `b` (0 low, 1 high) of a cell whose slab on that axis the line crosses
  /// over [parentIn, parentOut] and whose middle `middle` it crosses at `mid`: the child
  /// entered first has the cell's entry. `pos` and `step` are the line's start and direction on
  /// the axis (an axis-parallel line passes only the child holding pos).
  static void childSlab(float parentIn, float parentOut, float mid, float middle, float pos, int step, int b, float& in, float& out) {
    constexpr float inf = std::numeric_limits<float>::infinity();
    if (step == 0) {
      const bool inside = (pos >= middle) == (b == 1);
      in = inside ? -inf : inf, out = inside ? inf : -inf;
    } else if ((step > 0) == (b == 0)) {
      in = parentIn, out = mid;
    } else {
      in = mid, out = parentOut;
    }
  }
  void childX(const Span& parent, float mid, float xMid, int b, float& in, float& out) const {
    childSlab(parent.xIn, parent.xOut, mid, xMid, p0.x, stepX, b, in, out);
  }
  void childY(const Span& parent, float mid, float yMid, int b, float& in, float& out) const {
    childSlab(parent.yIn, parent.yOut, mid, yMid, p0.y, stepY, b, in, out);
  }
};

/// Everything the march computes before its first cell, shared by hssrMarch and the lane march
/// (hssr_march_lanes.cpp) so that both start from the same floats.
struct MarchStart {
  Line line;
  int px, py;  ///< the pixel holding p0 (clamped to the view)
  bool increasing;  ///< depth grows along the ray
  // κ along the segment, κ(s) = k0 + s dκ: the same expression depthAt divides 1 by.
  float k0, dk, invDk, invAbsDk;
  // Back-off for the coarse entry: the entry s = (κ_z − k0) / dκ loses accuracy as the ray turns
  // parallel to the image plane (|dκ| ≪ κ). Step back at least 1/64 pixel (pixelBackoff), and
  // at least 8× the error bound of the product (in units of s; 4× bounded the reference's
  // division, the reciprocal adds 2u|s|):
  //   |Δs| ≤ 8 u (max(k0, k1, κ_z) / |dκ| + |s|),  u = 2^-24,   kScale = max(k0, k1) / |dκ|,
  // so rounding can never carry the entry past the pixel the level-0 scan would hit.
  float pixelBackoff, kScale;
  // Hofmann et al. 2017, §5.1: skip the first pixel (no self-intersection with the origin's
  // surface). A ray entering from outside the view starts no surface: its first pixel is tested,
  // and no pixel is the origin pixel of the ascend rule (ox = oy = −2^29).
  Line::Span sp;  ///< the first cell's span
  int cx, cy, ox, oy;
  float sStart;
  /// An axis-parallel segment starting outside its clamped pixel's row/column (p0 on the far
  /// border) meets no cell: the reference returns at its first cell.
  bool meetsNoCell;

  MarchStart(const ScreenSegment& seg, int W, int H) : line(seg) {
    px = std::clamp(int(std::floor(seg.p0.x)), 0, W - 1), py = std::clamp(int(std::floor(seg.p0.y)), 0, H - 1);
    increasing = seg.k1 <= seg.k0;
    k0 = seg.k0, dk = seg.k1 - seg.k0;
    invDk = 1.0f / dk, invAbsDk = std::abs(invDk);
    pixelBackoff = 1.0f / (64.0f * std::max(std::abs(line.d.x), std::abs(line.d.y)));
    kScale = std::max(seg.k0, seg.k1) * invAbsDk;
    sp = line.span(px, py, 1);
    meetsNoCell = !(sp.in() <= sp.out());
    sStart = seg.clippedStart ? 0.0f : sp.out();
    cx = ox = px, cy = oy = py;
    if (seg.clippedStart) ox = oy = -(1 << 29);
    else line.step(sp, cx, cy, 1);
  }
};

}  // namespace hssr_detail

/// When the march ascends a level (Hofmann et al. 2017, §5.2): after `nUp` cells of a level
/// without an overlap, and with `newParent` also as soon as a step enters another parent cell
/// (below). `newParent = false` is the paper's pure n_up rule (`--preset paper`). An int converts
/// to the default rule with that n_up.
struct AscentRule {
  int nUp = 2;
  bool newParent = true;
  constexpr AscentRule(int n, bool parent = true) : nUp(n), newParent(parent) {}  // NOLINT(google-explicit-constructor)
};

/// The march of Hofmann et al. 2017, §5, over `pyramid` (its first `levels` levels) for a valid
/// segment of a W×H view. Hits are reported at level 0 only; it ascends by `rule`.
///
/// Returns the same hit as hssrMarchReference (tested hit for hit, entry parameter bit for bit);
/// what differs is the cost per cell — spans are kept incrementally (one crossing per step, two
/// per descent instead of sixteen), coarse cells are tested in inverse depth κ = 1/z — linear in
/// s, so no division — against fixed-slot cells (CoarseCell, no offset load), and level 0 stops
/// at the slots' sentinel (no count load) — and when it ascends: also on
/// entering another parent cell (below), so the two visit different cells on the way to the
/// same hit.
template <class C>
MarchHit hssrMarch(const IntervalPyramid& pyramid, int levels, AscentRule rule, const ScreenSegment& seg, int W, int H, C& c) {
  using hssr_detail::Line;
  constexpr float inf = std::numeric_limits<float>::infinity();
  const hssr_detail::MarchStart st(seg, W, H);
  const Line& line = st.line;
  const IntervalLayers& level0 = *pyramid.base;
  const int k = level0.k;
  const bool increasing = st.increasing;
  if (line.stepX == 0 && line.stepY == 0) {
    // The ray runs along one pixel's line of sight: only a ray entering from outside the view
    // can meet something there (a ray from a surface skips its own pixel).
    if (!seg.clippedStart) return {};
    c.iteration(0);
    c.pixel();
    const float za = seg.depthAt(0.0f), zb = seg.depthAt(1.0f);
    const int i = firstMet(level0.pixel(st.px, st.py), k, std::min(za, zb), std::max(za, zb), increasing, c);
    return i >= 0 ? MarchHit{st.px, st.py, i, 0.0f} : MarchHit{};
  }
  const float k0 = st.k0, dk = st.dk, invDk = st.invDk, invAbsDk = st.invAbsDk;
  auto backoff = [&](float e, float kz) {
    constexpr float u = 1.0f / 16777216.0f;
    return std::max(st.pixelBackoff, 8.0f * u * (std::max(st.kScale, kz * invAbsDk) + std::abs(e)));
  };
  if (st.meetsNoCell) return {};
  Line::Span sp = st.sp;
  const float sStart = st.sStart;
  float s = sStart;
  int L = 0, cx = st.cx, cy = st.cy;
  const int ox = st.ox, oy = st.oy;
  int misses = 0;
  // Parameter of the last zero-length (corner) cell the DDA stepped out of: a descent at that
  // same parameter must not go back into it (the oracle visits it once).
  float cornerLeft = -1.0f;
  float sLast = -1.0f, zLast = 0.0f;  // the last level-0 depthAt(s), for reuse
  const int safety = 8 * (W + H) * levels + 64;
  for (int guard = 0; guard < safety; ++guard) {
    const PyramidLevel& lvl = pyramid.levels[size_t(L)];
    if (cx < 0 || cy < 0 || cx >= lvl.width || cy >= lvl.height) return {};
    const float sIn = sp.in(), sOut = sp.out();
    const float s0 = L == 0 ? std::max(sIn, sStart) : std::max(sIn, s);
    const float s1 = std::min(sOut, 1.0f);
    if (s0 > 1.0f) return {};  // the segment ended before this cell
    c.iteration(L);
    if (L == 0) {
      c.pixel();
      // The exit of one pixel is usually the entry of the next: reuse its depth (the same
      // division of the same s, so bit-identical) instead of dividing again.
      const float za = s0 == sLast ? zLast : seg.depthAt(s0), zb = seg.depthAt(s1);
      sLast = s1, zLast = zb;
      const int i = firstMet(level0.pixel(cx, cy), k, std::min(za, zb), std::max(za, zb), increasing, c);
      if (i >= 0) return MarchHit{cx, cy, i, s0};
    } else {
      // Coarse levels only accelerate: widen the κ range by a few ulps so rounding (of κ here,
      // of 1/κ at level 0, of the stored 1/z) can never make them skip what level 0 would find.
      const float ka = k0 + s0 * dk, kb = k0 + s1 * dk;
      const float kmin = std::min(ka, kb) * (1.0f - 4e-7f), kmax = std::max(ka, kb) * (1.0f + 4e-7f);
      const CoarseCell& cell = lvl.cells[lvl.cellIndex(cx, cy)];
      float sHit = inf;
      for (int i = 0; i < CoarseCell::kSlots; ++i) {
        c.interval();
        if (cell.kFront[i] < kmin) break;  // front beyond the ray's depths; the sentinel too
        if (cell.kBack[i] > kmax) continue;
        // Enter at the front when depth grows, at the back when it shrinks; never move back.
        // Step back from the computed entry by its error bound (backoff above): an entry that
        // lands just past a pixel boundary would skip the pixel the oracle hits. Re-testing a
        // little more is always safe; s0 keeps it from reaching behind the current position.
        const float kz = increasing ? cell.kFront[i] : cell.kBack[i];
        const float p = (kz - k0) * invDk;
        const float e = p - backoff(p, kz);
        sHit = std::min(sHit, std::clamp(std::isfinite(e) ? e : s0, s0, s1));
      }
      if (sHit != inf) {
        // Hofmann et al. 2017, §5.2: advance to the entry, re-project, descend one level.
        s = std::max(s, sHit);
        --L;
        const int half = 1 << L;
        const float xMid = float((2 * cx + 1) * half), yMid = float((2 * cy + 1) * half);
        const float mx = line.crossX(xMid), my = line.crossY(yMid);
        // The child holding s, chosen as the oracle's DDA reaches it.
        // The child being left (exit == s) is done. Where the line passes exactly through a
        // corner, the DDA steps in x first and visits that zero-length cell (entry == exit == s)
        // before the diagonal one: prefer it (smallest exit), so level-0 visits match the
        // oracle's, ties included.
        int best = -1;
        float bestOut = 0.0f;
        Line::Span bestSpan{};
        for (int q = 0; q < 4; ++q) {
          Line::Span ch;
          line.childX(sp, mx, xMid, q & 1, ch.xIn, ch.xOut);
          line.childY(sp, my, yMid, q >> 1, ch.yIn, ch.yOut);
          const float a = ch.in(), b = ch.out();
          if (!(a <= s && s <= b) || (b == s && a < b)) continue;
          // A zero-length cell is one the x-first DDA steps into at a corner and leaves through
          // y; the other corner cell (left through x) it never visits. Once left, not again.
          if (a == b && (ch.exitX() || a == cornerLeft)) continue;
          if (best < 0 || b < bestOut) best = q, bestOut = b, bestSpan = ch;
        }
        if (best < 0) {  // rounding left s just outside every child: take the one under P(s)
          const glm::vec2 pt = seg.pointAt(s);
          best = (pt.x >= xMid ? 1 : 0) + (pt.y >= yMid ? 2 : 0);
          bestSpan = line.span(2 * cx + (best & 1), 2 * cy + (best >> 1), half);
        }
        cx = 2 * cx + (best & 1);
        cy = 2 * cy + (best >> 1);
        sp = bestSpan;
        misses = 0;
        continue;
      }
    }
    // No overlap: step to the next cell of this level.
    if (sIn == sOut) cornerLeft = sOut;
    s = std::max(s, s1);
    if (sOut >= 1.0f) return {};
    const int size = 1 << L;
    const int parentX = cx >> 1, parentY = cy >> 1;
    line.step(sp, cx, cy, size);
    // Hofmann et al. 2017, §5.2, ascend after n_up cells without an overlap. Choice: also as soon
    // as the step enters another parent cell — the ray then enters that parent where it enters this
    // cell, so the coarser test covers nothing already passed, and up to three cells of this
    // level are skipped. Answers are the same (the hierarchy only accelerates; tested against
    // the reference march and both oracles); steps per one-bounce reflection ray fall 8–10 %
    // (FZK-Haus 24.6 → 22.6, am_thornish 24.3 → 22.0, engine 20.1 → 18.0 at n_up 2, τ 4), but
    // descents rise 11 % and the lane march gains only 1–3 % in time (BM_HssrLanes, medians of
    // 9 alternating rounds: 68.9 → 68.1 ms FZK-Haus, 70.9 → 68.5 ms am_thornish).
    const bool newParent = rule.newParent && ((cx >> 1) != parentX || (cy >> 1) != parentY);
    if ((++misses >= rule.nUp || newParent) && L + 1 < levels) {
      const int px = cx >> 1, py = cy >> 1;
      // Hofmann et al. 2017, §5.2: only ascend when the coarser cell does not overlap the origin
      // pixel.
      if ((ox >> (L + 1)) != px || (oy >> (L + 1)) != py) {
        if (px < pyramid.levels[size_t(L + 1)].width && py < pyramid.levels[size_t(L + 1)].height && cx >= 0 && cy >= 0) {
          ++L, cx = px, cy = py, misses = 0;
          sp = line.span(cx, cy, 2 * size);
        }
      }
    }
  }
  c.giveUp();  // the step cap: never reached by a conservative DDA (tested), counted if it is
  return {};
}

}  // namespace lt
