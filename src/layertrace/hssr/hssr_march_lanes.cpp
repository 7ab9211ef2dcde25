#include "layertrace/hssr/hssr_march_lanes.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "layertrace/util/cpu_dispatch.h"
#include "layertrace/screen/interval_lanes.h"
#include "layertrace/util/simd512.h"

#define LT_HSSR_LANES LT_SIMD512

namespace lt {

/// The portable path (and the reference the lanes are measured against).
LT_CPU_DISPATCH void hssrMarchEach(const IntervalPyramid& pyramid, int levels, int nUp, std::span<const ScreenSegment> segs, int W,
                               int H, std::span<MarchHit> out, std::span<uint32_t> cells) {
  auto march = [&](size_t i, auto& counters) {
    return segs[i].valid ? hssrMarch(pyramid, levels, nUp, segs[i], W, H, counters) : MarchHit{};
  };
  for (size_t i = 0; i < segs.size(); ++i) {
    if (cells.empty()) {
      NoCounters none;  // (the reference bench_trace times: no counting)
      out[i] = march(i, none);
    } else {
      MarchCellCount c;
      out[i] = march(i, c);
      cells[i] = c.cells;
    }
  }
}

#if LT_HSSR_LANES
// Everything in this region is compiled for AVX-512 and runs only where the CPU has it
// (hssrLanesAvailable). Arithmetic is written with GCC vector extensions; intrinsics only for
// what they lack (comparisons into k-register lane masks, blends, masked loads); the portable
// fallback is hssrMarchEach.
#pragma GCC push_options
#pragma GCC target("avx512f,avx512vl,avx512bw,avx512dq")
namespace {

using namespace simd512;

inline I lookup(I index, const int32_t* table16) { return __builtin_shuffle(load<I>(table16), index); }
inline Q lookup(Q index, const int64_t* table8) { return __builtin_shuffle(load<Q>(table8), index); }
inline Q lowHalf(I v) { return __builtin_convertvector(__builtin_shufflevector(v, v, 0, 1, 2, 3, 4, 5, 6, 7), Q); }
inline Q highHalf(I v) { return __builtin_convertvector(__builtin_shufflevector(v, v, 8, 9, 10, 11, 12, 13, 14, 15), Q); }

/// One ray's march state per lane (the locals of hssrMarch's loop), kept in memory between
/// steps so that a finished lane can be refilled with scalar writes.
struct alignas(64) Lanes {
  float p0x[kLanes], p0y[kLanes], invDx[kLanes], invDy[kLanes];
  int32_t stepX[kLanes], stepY[kLanes];
  float xIn[kLanes], xOut[kLanes], yIn[kLanes], yOut[kLanes];
  float k0[kLanes], dk[kLanes], invDk[kLanes], invAbsDk[kLanes], pixelBackoff[kLanes], kScale[kLanes];
  float s[kLanes], sStart[kLanes], cornerLeft[kLanes];
  int32_t L[kLanes], cx[kLanes], cy[kLanes], ox[kLanes], oy[kLanes], misses[kLanes];
  int32_t guard[kLanes];  ///< cells tested so far (hssrMarch's loop counter and c.iteration count)
  __mmask16 increasing;  ///< lanes whose depth grows along the ray
  int32_t ray[kLanes];  ///< the segment's index in the batch; −1 for an empty lane
  int64_t offset[kLanes];  ///< byte offset of the lane's current record from Tables::origin
  // Written by a step for the lanes it finished:
  __mmask16 hitMask, bailMask;  ///< finished with a hit / left to hssrMarch (others: a miss)
  int32_t interval[kLanes];
  float hitS[kLanes];
};

/// The batch's constants: per level the width/height the march bounds-checks against, and the
/// byte offset (from level 0's slots) and row width of its records.
struct Tables {
  alignas(64) int32_t width[16] = {}, height[16] = {}, rowWidth[16] = {};
  alignas(64) int64_t base[8] = {}, recordBytes[8] = {};
  const char* origin = nullptr;
  int levels = 1, nUp = 1, k = 4, safety = 0;
};

/// Sets lane j up for segment `i`, as hssrMarch does before its loop. Returns false (and
/// writes out[i]) when the ray is answered without marching or is left to hssrMarch.
/// `cells` (may be null) gets the cells tested for a ray answered here.
bool start(Lanes& ln, int j, const IntervalPyramid& pyramid, const Tables& tb, const ScreenSegment& seg, int i, int W, int H,
           MarchHit& out, uint32_t* cells) {
  using hssr_detail::Line;
  if (cells) *cells = 0;
  if (!seg.valid) {
    out = {};
    return false;
  }
  const hssr_detail::MarchStart st(seg, W, H);
  const Line& line = st.line;
  // An axis-parallel line (6 % of am_thornish's reflection rays: walls parallel to the view
  // axis reflect into rows, a level floor into columns) runs in the lanes too; a single-pixel
  // line runs hssrMarch.
  const bool flatX = line.stepX == 0, flatY = line.stepY == 0;
  if (flatX && flatY) {
    MarchCellCount c;
    out = hssrMarch(pyramid, tb.levels, tb.nUp, seg, W, H, c);
    if (cells) *cells = c.cells;
    return false;
  }
  if (st.meetsNoCell) {
    out = {};
    return false;
  }
  const int cx = st.cx, cy = st.cy;
  ln.p0x[j] = line.p0.x, ln.p0y[j] = line.p0.y, ln.invDx[j] = line.invDx, ln.invDy[j] = line.invDy;
  // Along a flat axis hssrMarch keeps the span (−∞, +∞) of the column (row) holding p0 and never
  // steps across it; a descent keeps the child on p0's side of the midline. The lanes compute
  // every crossing as (boundary − p0) · invD: with p0 moved to the middle of its pixel (no
  // integer boundary changes side, none equals it, so no 0 · ∞; exact, as p0 lies in the view
  // — meetsNoCell above — and views are narrower than 2^22: hssrLanesAvailable) and invD = −∞, a boundary
  // ahead of p0 crosses at −∞ and one behind at +∞ — exactly the spans and child choice of
  // hssrMarch's childSlab (tested bit for bit), with no flat-axis case in the step.
  constexpr float inf = std::numeric_limits<float>::infinity();
  if (flatX) ln.p0x[j] = std::floor(line.p0.x) + 0.5f, ln.invDx[j] = -inf;
  if (flatY) ln.p0y[j] = std::floor(line.p0.y) + 0.5f, ln.invDy[j] = -inf;
  ln.stepX[j] = line.stepX, ln.stepY[j] = line.stepY;
  ln.xIn[j] = st.sp.xIn, ln.xOut[j] = st.sp.xOut, ln.yIn[j] = st.sp.yIn, ln.yOut[j] = st.sp.yOut;
  ln.k0[j] = st.k0, ln.dk[j] = st.dk, ln.invDk[j] = st.invDk, ln.invAbsDk[j] = st.invAbsDk;
  ln.pixelBackoff[j] = st.pixelBackoff, ln.kScale[j] = st.kScale;
  ln.s[j] = st.sStart, ln.sStart[j] = st.sStart, ln.cornerLeft[j] = -1.0f;
  ln.L[j] = 0, ln.cx[j] = cx, ln.cy[j] = cy, ln.ox[j] = st.ox, ln.oy[j] = st.oy, ln.misses[j] = 0, ln.guard[j] = 0;
  ln.increasing = __mmask16((ln.increasing & ~(1u << j)) | (st.increasing ? 1u << j : 0u));
  ln.ray[j] = i;
  const bool inside = cx >= 0 && cy >= 0 && cx < tb.width[0] && cy < tb.height[0];  // else any valid record
  ln.offset[j] = inside ? (int64_t(cy) * tb.rowWidth[0] + cx) * tb.recordBytes[0] : 0;
  return true;
}

/// field[f] = float f of every lane's 32-byte record (at Lanes::offset, always a valid
/// record): sixteen row loads and an 8×8 transpose done on both halves of the registers at once
/// (unpack, shuffle, then 128-bit blocks), cheaper here than sixteen gathers.
inline void loadRecords(const Lanes& ln, const Tables& tb, F field[8]) {
  // (offsets may point into another level's array: the address is formed as an integer)
  const uintptr_t origin = reinterpret_cast<uintptr_t>(tb.origin);
  auto record = [&](int j) { return reinterpret_cast<const void*>(origin + uintptr_t(ln.offset[j])); };
  F r[8];
  if (tb.k == 4) {
    for (int j = 0; j < 8; ++j) {
      F8 lo, hi;
      std::memcpy(&lo, record(j), sizeof lo);
      std::memcpy(&hi, record(j + 8), sizeof hi);
      r[j] = joinRows(lo, hi);
    }
  } else {
    // A pixel's record is 8k < 32 bytes: masked loads read its 2k floats only (the last pixel's
    // record ends where the array does; masked-off floats are not read).
    const __mmask8 pixel = __mmask8((1u << (2 * tb.k)) - 1);
    auto row = [&](int j) { return (F8)_mm256_maskz_loadu_ps(ln.L[j] == 0 ? pixel : __mmask8(0xff), record(j)); };
    for (int j = 0; j < 8; ++j) r[j] = joinRows(row(j), row(j + 8));
  }
  transposeRows8(r, field);
}

/// One iteration of hssrMarch's loop in every live lane (the comments name the scalar code's
/// steps). Returns the lanes that finished; hitMask / bailMask say how.
__attribute__((noinline)) uint32_t step(Lanes& ln, const Tables& tb) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  const F p0x = load<F>(ln.p0x), p0y = load<F>(ln.p0y), invDx = load<F>(ln.invDx), invDy = load<F>(ln.invDy);
  const I stepX = load<I>(ln.stepX), stepY = load<I>(ln.stepY);
  F xIn = load<F>(ln.xIn), xOut = load<F>(ln.xOut), yIn = load<F>(ln.yIn), yOut = load<F>(ln.yOut);
  // (per-ray constants used by one block only are loaded in it: fewer registers spilled)
  const F k0 = load<F>(ln.k0), dk = load<F>(ln.dk);
  F s = load<F>(ln.s), cornerLeft = load<F>(ln.cornerLeft);
  I L = load<I>(ln.L), cx = load<I>(ln.cx), cy = load<I>(ln.cy), misses = load<I>(ln.misses), guard = load<I>(ln.guard);
  const I zero = I{}, one = zero + 1;
  const M live = ge(load<I>(ln.ray), zero), increasing{ln.increasing};
  const M posX = gt(stepX, zero), posY = gt(stepY, zero);

  // The step cap (never reached by a conservative DDA), the level's bounds, the segment's end.
  // (A live lane that does not step on — act minus the lanes that hit, bail or leave — is
  // finished: the step returns live & ~(stepped | descended) instead of collecting misses.)
  M act = lt(live, guard, zero + tb.safety);
  act = andNot(act, outside(cx, lookup(L, tb.width)) | outside(cy, lookup(L, tb.height)));
  const F sIn = vmax(xIn, yIn), sOut = vmin(xOut, yOut);
  const M level0 = eq(L, zero);
  const F s0 = sel(level0, vmax(sIn, load<F>(ln.sStart)), vmax(sIn, s));
  const F s1 = vmin(sOut, F{} + 1.0f);
  act = notGt(act, s0, F{} + 1.0f);  // (past: the segment ended before this cell)

  // The cell's 32-byte record: k ≤ 4 intervals {front, back} of a pixel, or a coarse cell's
  // four κFront then four κBack (requested at the end of the previous step).
  const M at0 = act & level0, coarse = andNot(act, level0);
  F field[8];
  loadRecords(ln, tb, field);

  // Level 0: firstMet over the pixel's intervals between the depths of its entry and exit.
  // (hssrMarch reuses the previous pixel's exit depth when s0 is its exit: the same division of
  // the same s, so dividing again gives the same bits, and the lanes divide anyway)
  const F za = 1.0f / (k0 + s0 * dk), zb = 1.0f / (k0 + s1 * dk);
  // (firstMetLanes is called, not written out here: with one-instruction masks and min/max the
  // call is as fast as an inlined copy — BM_HssrLanes 96 vs 94 ms on FZK-Haus, 126 vs 132 on
  // am_thornish, medians of 5–6 alternating runs.)
  const I found = at0.bits ? firstMetLanes(field, tb.k, vmin(za, zb), vmax(za, zb), at0, increasing) : zero - 1;
  const M hit = at0 & ge(found, zero);

  // Coarse levels: the earliest entry into an interval the ray's κ range overlaps.
  F sHit = F{} + inf;
  if (coarse.bits) {
    const F ka = k0 + s0 * dk, kb = k0 + s1 * dk;
    const F kmin = vmin(ka, kb) * (1.0f - 4e-7f), kmax = vmax(ka, kb) * (1.0f + 4e-7f);
    constexpr float u = 1.0f / 16777216.0f;
    const F invDk = load<F>(ln.invDk), invAbsDk = load<F>(ln.invAbsDk);
    const F pixelBackoff = load<F>(ln.pixelBackoff), kScale = load<F>(ln.kScale);
    M scan = coarse;
    for (int i = 0; i < CoarseCell::kSlots; ++i) {
      const F kFront = field[i], kBack = field[CoarseCell::kSlots + i];
      scan = notLt(scan, kFront, kmin);
      if (!scan.bits) break;
      const M overlap = notGt(scan, kBack, kmax);
      const F kz = sel(increasing, kFront, kBack);
      const F p = (kz - k0) * invDk;
      const F e = p - vmax(pixelBackoff, 8.0f * u * (vmax(kScale, kz * invAbsDk) + vabs(p)));
      const F entry = vmin(vmax(sel(lt(vabs(e), F{} + inf), e, s0), s0), s1);
      sHit = sel(overlap, vmin(sHit, entry), sHit);
    }
  }
  const M descend = coarse & ne(sHit, F{} + inf);

  // Descent (Hofmann et al. 2017, §5.2): advance to the entry, choose the child holding s.
  M bail{0}, d{0};
  if (descend.bits) {
    const F sNew = vmax(s, sHit);
    const I Ld = L - 1, half = one << Ld;
    const F xMid = __builtin_convertvector((2 * cx + 1) * half, F), yMid = __builtin_convertvector((2 * cy + 1) * half, F);
    const F mx = (xMid - p0x) * invDx, my = (yMid - p0y) * invDy;
    I best = zero - 1;
    F bestOut = F{};
    for (int q = 0; q < 4; ++q) {
      // childSlab: the child entered first along an axis has the cell's entry on that axis.
      const M firstX = (q & 1) ? ~posX : posX, firstY = (q >> 1) ? ~posY : posY;
      const F cxIn = sel(firstX, xIn, mx), cxOut = sel(firstX, mx, xOut);
      const F cyIn = sel(firstY, yIn, my), cyOut = sel(firstY, my, yOut);
      const F a = vmax(cxIn, cyIn), b = vmin(cxOut, cyOut);
      const M in = le(le(descend, a, sNew), sNew, b);
      const M ok = andNot(andNot(in, lt(eq(in, b, sNew), a, b)), eq(in, a, b) & (le(cxOut, cyOut) | eq(a, cornerLeft)));
      const M take = ok & (lt(best, zero) | lt(b, bestOut));
      best = sel(take, zero + q, best);
      bestOut = sel(take, b, bestOut);
    }
    bail = lt(descend, best, zero);  // rounding left s outside every child: hssrMarch's fallback
    d = andNot(descend, bail);
    s = sel(d, sNew, s);
    L = sel(d, Ld, L);
    cx = sel(d, 2 * cx + (best & 1), cx);
    cy = sel(d, 2 * cy + (best >> 1), cy);
    // The chosen child's slab (childSlab of quadrant `best`, without carrying four candidates
    // through the loop): along an axis it is entered first, keeping the cell's entry and ending
    // at the midline, or second, from the midline to the cell's exit.
    const M firstX = posX ^ ne(best & 1, zero), firstY = posY ^ ne(best & 2, zero);
    xIn = sel(andNot(d, firstX), mx, xIn), xOut = sel(d & firstX, mx, xOut);
    yIn = sel(andNot(d, firstY), my, yIn), yOut = sel(d & firstY, my, yOut);
    misses = sel(d, zero, misses);
  }

  // No overlap: step to the next cell of this level, and ascend after n_up of them.
  M move = andNot(andNot(act, hit), descend);
  cornerLeft = sel(eq(move, sIn, sOut), sOut, cornerLeft);
  s = sel(move, vmax(s, s1), s);
  move = notGe(move, sOut, F{} + 1.0f);  // (the others leave the segment: a miss)
  {
    const I size = one << L;
    const M exitX = le(xOut, yOut);  // ties step in x first
    const M mx = move & exitX, my = andNot(move, exitX);
    const I parentX = cx >> 1, parentY = cy >> 1;
    cx = sel(mx, cx + stepX, cx);
    cy = sel(my, cy + stepY, cy);
    const F nextX = (__builtin_convertvector(sel(posX, cx + 1, cx) * size, F) - p0x) * invDx;
    const F nextY = (__builtin_convertvector(sel(posY, cy + 1, cy) * size, F) - p0y) * invDy;
    xIn = sel(mx, xOut, xIn), xOut = sel(mx, nextX, xOut);
    yIn = sel(my, yOut, yIn), yOut = sel(my, nextY, yOut);
    misses = sel(move, misses + 1, misses);
    const I Lu = L + 1, px = cx >> 1, py = cy >> 1;
    // (after n_up misses, or on entering another parent cell: hssrMarch's rule)
    M up = lt(ge(move, misses, zero + tb.nUp) | ne(move, px, parentX) | ne(move, py, parentY), Lu, zero + tb.levels);
    // Hofmann et al. 2017, §5.2: only ascend when the coarser cell does not overlap the origin
    // pixel.
    up = ne(up, load<I>(ln.ox) >> Lu, px) | ne(up, load<I>(ln.oy) >> Lu, py);
    up = lt(lt(up, px, lookup(Lu, tb.width)), py, lookup(Lu, tb.height)) & ge(cx, zero) & ge(cy, zero);
    if (up.bits) {
      L = sel(up, Lu, L);
      cx = sel(up, px, cx), cy = sel(up, py, cy);
      misses = sel(up, zero, misses);
      const I sizeUp = 2 * size;
      const F x0 = (__builtin_convertvector(px * sizeUp, F) - p0x) * invDx, x1 = (__builtin_convertvector((px + 1) * sizeUp, F) - p0x) * invDx;
      const F y0 = (__builtin_convertvector(py * sizeUp, F) - p0y) * invDy, y1 = (__builtin_convertvector((py + 1) * sizeUp, F) - p0y) * invDy;
      xIn = sel(up, sel(posX, x0, x1), xIn), xOut = sel(up, sel(posX, x1, x0), xOut);
      yIn = sel(up, sel(posY, y0, y1), yIn), yOut = sel(up, sel(posY, y1, y0), yOut);
    }
  }

  store(ln.xIn, xIn), store(ln.xOut, xOut), store(ln.yIn, yIn), store(ln.yOut, yOut);
  store(ln.s, s), store(ln.cornerLeft, cornerLeft);
  store(ln.L, L), store(ln.cx, cx), store(ln.cy, cy), store(ln.misses, misses), store(ln.guard, sel(act, guard + 1, guard));
  store(ln.interval, found);
  store(ln.hitS, s0);
  ln.hitMask = hit.bits, ln.bailMask = bail.bits;
  // The records of the lanes' next cells, requested now so that their loads overlap whatever
  // runs before the next step (the other group's step).
  {
    // A cell outside its level gets record 0 of the level (any valid address: the lane stops
    // before reading it).
    const M out = outside(cx, lookup(L, tb.width)) | outside(cy, lookup(L, tb.height));
    const I index = sel(out, zero, cy * lookup(L, tb.rowWidth) + cx);
    const Q levelLo = lowHalf(L), levelHi = highHalf(L);
    store(ln.offset, lookup(levelLo, tb.base) + lowHalf(index) * lookup(levelLo, tb.recordBytes));
    store(ln.offset + 8, lookup(levelHi, tb.base) + highHalf(index) * lookup(levelHi, tb.recordBytes));
    const uintptr_t origin = reinterpret_cast<uintptr_t>(tb.origin);
    for (int j = 0; j < kLanes; ++j) __builtin_prefetch(reinterpret_cast<const void*>(origin + uintptr_t(ln.offset[j])));
  }
  return andNot(live, move | d).bits;
}

/// The batch through the lanes: refill every lane that finished with the next segment.
void marchLanes(const IntervalPyramid& pyramid, int levels, int nUp, std::span<const ScreenSegment> segs, int W, int H,
                std::span<MarchHit> out, std::span<uint32_t> cells) {
  const IntervalLayers& level0 = *pyramid.base;
  Tables tb;
  tb.levels = levels, tb.nUp = nUp, tb.k = level0.k, tb.safety = 8 * (W + H) * levels + 64;
  tb.origin = reinterpret_cast<const char*>(level0.slots.data());
  for (int L = 0; L < levels; ++L) {
    const PyramidLevel& lvl = pyramid.levels[size_t(L)];
    tb.width[L] = lvl.width, tb.height[L] = lvl.height;
    tb.rowWidth[L] = L == 0 ? level0.width : lvl.width;
    const char* data = L == 0 ? tb.origin : reinterpret_cast<const char*>(lvl.cells.data());
    tb.base[L] = int64_t(reinterpret_cast<uintptr_t>(data) - reinterpret_cast<uintptr_t>(tb.origin));
    tb.recordBytes[L] = L == 0 ? int64_t(sizeof(Interval)) * level0.k : int64_t(sizeof(CoarseCell));
  }
  // Two groups of lanes stepped in turn: each step prefetches its lanes' next records, and the
  // other group's step hides their latency (bench_trace BM_HssrLanes, FZK-Haus: one group 1.16–
  // 1.22× the one-ray march, two 1.31–1.37×, three and four no better than two). Measured
  // again: three groups were 8 % faster than two in BM_HssrLanes on one core, equal in
  // BM_HssrAgainstEmbree with the renderer's tile order, but 15–25 % slower in `compare`
  // (engine, 5 alternating runs: hssr 1.67 → 1.36×, hiz 0.52 → 0.38× plain Embree) — two stay.
  Lanes lanes[2];
  size_t next = 0;
  auto fill = [&](Lanes& ln, int j) {
    ln.ray[j] = -1;
    ln.offset[j] = 0;
    while (next < segs.size()) {
      const int i = int(next++);
      if (start(ln, j, pyramid, tb, segs[size_t(i)], i, W, H, out[size_t(i)], cells.empty() ? nullptr : &cells[size_t(i)])) return true;
    }
    return false;
  };
  auto done = [&](const Lanes& ln, int j) {
    const size_t i = size_t(ln.ray[j]);
    uint32_t tested = uint32_t(ln.guard[j]);
    if (ln.hitMask >> j & 1) {
      out[i] = MarchHit{ln.cx[j], ln.cy[j], ln.interval[j], ln.hitS[j]};
    } else if (ln.bailMask >> j & 1) {
      MarchCellCount c;
      out[i] = hssrMarch(pyramid, levels, nUp, segs[i], W, H, c);
      tested = c.cells;  // the march that answered (the lane's steps are dropped with its state)
    } else {
      out[i] = {};
    }
    if (!cells.empty()) cells[i] = tested;
  };
  runLaneGroups(lanes, fill, [&](Lanes& ln) { return step(ln, tb); }, done, [](Lanes&) {});
}

}  // namespace
#pragma GCC pop_options
#endif

bool hssrLanesAvailable(const IntervalPyramid& pyramid, int levels) {
#if LT_HSSR_LANES
  constexpr int kExactHalf = 1 << 22;  // floor(p) + 0.5 is exact for 0 ≤ p < 2^22 (start's flat axes)
  return simd512Available() && pyramid.base && pyramid.base->k >= 1 && pyramid.base->k <= 4 && levels >= 1 && levels <= 8 &&
         pyramid.base->width < kExactHalf && pyramid.base->height < kExactHalf &&
         levels <= pyramid.levelCount() && pyramid.levels[0].width == pyramid.base->width &&
         pyramid.levels[0].height == pyramid.base->height;
#else
  (void)pyramid, (void)levels;
  return false;
#endif
}

void hssrMarchBatch(const IntervalPyramid& pyramid, int levels, int nUp, std::span<const ScreenSegment> segs, int W, int H,
                    std::span<MarchHit> out, std::span<uint32_t> cells) {
#if LT_HSSR_LANES
  if (hssrLanesAvailable(pyramid, levels)) return marchLanes(pyramid, levels, nUp, segs, W, H, out, cells);
#endif
  hssrMarchEach(pyramid, levels, nUp, segs, W, H, out, cells);
}

}  // namespace lt
