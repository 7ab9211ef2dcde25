// hssrMarch in vector lanes, written once with Google Highway and compiled for every target it
// builds (this file is included once per target through hwy/foreach_target.h); the batch runs on
// the best target this CPU has.
#include "layertrace/hssr/hssr_march_lanes.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "layertrace/hssr/hssr_march_lanes.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <hwy/cache_control.h>
#include <hwy/highway.h>

#include "layertrace/screen/interval_lanes-inl.h"

HWY_BEFORE_NAMESPACE();
namespace lt::HWY_NAMESPACE {
namespace {

using namespace lanes;
constexpr size_t kL = kMaxLanes;

/// One ray's march state per lane (the locals of hssrMarch's loop), kept in memory between
/// steps so that a finished lane can be refilled with scalar writes.
struct Lanes {
  HWY_ALIGN float p0x[kL], p0y[kL], invDx[kL], invDy[kL];
  HWY_ALIGN int32_t stepX[kL], stepY[kL];
  HWY_ALIGN float xIn[kL], xOut[kL], yIn[kL], yOut[kL];
  HWY_ALIGN float k0[kL], dk[kL], invDk[kL], invAbsDk[kL], pixelBackoff[kL], kScale[kL];
  HWY_ALIGN float s[kL], sStart[kL], cornerLeft[kL];
  HWY_ALIGN int32_t L[kL], cx[kL], cy[kL], ox[kL], oy[kL], misses[kL];
  HWY_ALIGN int32_t guard[kL];       ///< cells tested so far (hssrMarch's loop counter and c.iteration count)
  HWY_ALIGN int32_t increasing[kL];  ///< flags (0 / −1): the lane's depth grows along the ray
  HWY_ALIGN int32_t ray[kL];         ///< the segment's index in the batch; −1 for an empty lane
  HWY_ALIGN int64_t offset[kL];      ///< byte offset of the lane's current record from Tables::origin
  // Written by a step for the lanes it finished: a hit / left to hssrMarch (others: a miss).
  HWY_ALIGN int32_t hitMask[kL], bailMask[kL];
  HWY_ALIGN int32_t interval[kL];
  HWY_ALIGN float hitS[kL];
};

/// The batch's constants: per level the width/height the march bounds-checks against, the row
/// width of its records, their byte offset from level 0's slots and their size in 8-byte units
/// (tables of 16 entries: a lookup loads as many as a vector holds).
struct Tables {
  HWY_ALIGN int32_t width[16] = {}, height[16] = {}, rowWidth[16] = {}, recordUnits[16] = {};
  HWY_ALIGN int64_t base[16] = {};
  const char* origin = nullptr;
  int levels = 1, nUp = 1, k = 4, safety = 0;
  bool newParent = true;
};

inline VI lookup(const int32_t* table, VI level) { return lookup8(DI(), table, level); }

/// offset[j] = base[level_j] + 8 · units_j for every lane: the record addresses, in 64 bits (the
/// levels are separate arrays anywhere in memory).
inline void storeOffsets(int64_t* offset, VI level, VI units, const int64_t* base) {
#if HWY_TARGET == HWY_SCALAR || HWY_HAVE_SCALABLE
  HWY_ALIGN int32_t l[kL], u[kL];
  store(l, level), store(u, units);
  for (size_t j = 0; j < laneCount(); ++j) offset[j] = base[l[j]] + int64_t(u[j]) * 8;
#else
  using D64 = hn::Repartition<int64_t, DI>;
  const hn::Half<DI> dh;
  const D64 d64;
  auto part = [&](hn::Vec<hn::Half<DI>> l, hn::Vec<hn::Half<DI>> u) {
    return hn::Add(lookup8(d64, base, hn::PromoteTo(d64, l)), hn::ShiftLeft<3>(hn::PromoteTo(d64, u)));
  };
  hn::StoreU(part(hn::LowerHalf(dh, level), hn::LowerHalf(dh, units)), d64, offset);
  hn::StoreU(part(hn::UpperHalf(dh, level), hn::UpperHalf(dh, units)), d64, offset + hn::Lanes(d64));
#endif
}

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
    out = hssrMarch(pyramid, tb.levels, AscentRule(tb.nUp, tb.newParent), seg, W, H, c);
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
  ln.increasing[j] = st.increasing ? -1 : 0;
  ln.ray[j] = i;
  const bool inside = cx >= 0 && cy >= 0 && cx < tb.width[0] && cy < tb.height[0];  // else any valid record
  ln.offset[j] = inside ? (int64_t(cy) * tb.rowWidth[0] + cx) * tb.recordUnits[0] * 8 : 0;
  return true;
}

/// field[f] = float f of every lane's 32-byte record (at Lanes::offset, always a valid record).
inline void loadRecords(const Lanes& ln, const Tables& tb, VF field[8]) {
  // (offsets may point into another level's array: the address is formed as an integer)
  const uintptr_t origin = reinterpret_cast<uintptr_t>(tb.origin);
  const float* rows[kL] = {};
  // A pixel's record is 8k < 32 bytes when k < 4: those lanes read a copy padded to 32 bytes
  // (the last pixel's record ends where the array does).
  HWY_ALIGN float padded[kL][8];
  for (size_t j = 0; j < laneCount(); ++j) {
    rows[j] = reinterpret_cast<const float*>(origin + uintptr_t(ln.offset[j]));
    if (tb.k < 4 && ln.L[j] == 0) {
      std::memcpy(padded[j], rows[j], sizeof(float) * 2 * size_t(tb.k));
      rows[j] = padded[j];
    }
  }
  transposeRecords(rows, field);
}

/// One iteration of hssrMarch's loop in every live lane (the comments name the scalar code's
/// steps). Returns the lanes that finished; hitMask / bailMask say how.
HWY_NOINLINE uint64_t step(Lanes& ln, const Tables& tb) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  const VF p0x = loadF(ln.p0x), p0y = loadF(ln.p0y), invDx = loadF(ln.invDx), invDy = loadF(ln.invDy);
  const VI stepX = loadI(ln.stepX), stepY = loadI(ln.stepY);
  VF xIn = loadF(ln.xIn), xOut = loadF(ln.xOut), yIn = loadF(ln.yIn), yOut = loadF(ln.yOut);
  // (per-ray constants used by one block only are loaded in it: fewer registers spilled)
  const VF k0 = loadF(ln.k0), dk = loadF(ln.dk);
  VF s = loadF(ln.s), cornerLeft = loadF(ln.cornerLeft);
  VI L = loadI(ln.L), cx = loadI(ln.cx), cy = loadI(ln.cy), misses = loadI(ln.misses);
  const VI guard = loadI(ln.guard);
  const VI zero = splat(int32_t(0)), one = splat(int32_t(1));
  const VF fOne = splat(1.0f), fInf = splat(inf);
  const M live = ge(loadI(ln.ray), zero), increasing = flags(ln.increasing);
  const M posX = gt(stepX, zero), posY = gt(stepY, zero);

  // The step cap (never reached by a conservative DDA), the level's bounds, the segment's end.
  // (A live lane that does not step on — act minus the lanes that hit, bail or leave — is
  // finished: the step returns live & ~(stepped | descended) instead of collecting misses.)
  M act = lt(live, guard, splat(int32_t(tb.safety)));
  act = andNot(act, outside(cx, lookup(tb.width, L)) | outside(cy, lookup(tb.height, L)));
  const VF sIn = vmax(xIn, yIn), sOut = vmin(xOut, yOut);
  const M level0 = eq(L, zero);
  const VF s0 = sel(level0, vmax(sIn, loadF(ln.sStart)), vmax(sIn, s));
  const VF s1 = vmin(sOut, fOne);
  act = notGt(act, s0, fOne);  // (past: the segment ended before this cell)

  // The cell's 32-byte record: k ≤ 4 intervals {front, back} of a pixel, or a coarse cell's
  // four κFront then four κBack (requested at the end of the previous step).
  const M at0 = act & level0, coarse = andNot(act, level0);
  VF field[8];
  loadRecords(ln, tb, field);

  // Level 0: firstMet over the pixel's intervals between the depths of its entry and exit.
  // (hssrMarch reuses the previous pixel's exit depth when s0 is its exit: the same division of
  // the same s, so dividing again gives the same bits, and the lanes divide anyway)
  const VF za = fOne / (k0 + s0 * dk), zb = fOne / (k0 + s1 * dk);
  const VI found = any(at0) ? firstMetLanes(field, tb.k, vmin(za, zb), vmax(za, zb), at0, increasing) : splat(int32_t(-1));
  const M hit = at0 & ge(found, zero);

  // Coarse levels: the earliest entry into an interval the ray's κ range overlaps.
  VF sHit = fInf;
  if (any(coarse)) {
    const VF ka = k0 + s0 * dk, kb = k0 + s1 * dk;
    const VF kmin = vmin(ka, kb) * splat(1.0f - 4e-7f), kmax = vmax(ka, kb) * splat(1.0f + 4e-7f);
    constexpr float u = 1.0f / 16777216.0f;
    const VF invDk = loadF(ln.invDk), invAbsDk = loadF(ln.invAbsDk);
    const VF pixelBackoff = loadF(ln.pixelBackoff), kScale = loadF(ln.kScale);
    M scan = coarse;
    for (int i = 0; i < CoarseCell::kSlots; ++i) {
      const VF kFront = field[i], kBack = field[CoarseCell::kSlots + i];
      scan = notLt(scan, kFront, kmin);
      if (!any(scan)) break;
      const M overlap = notGt(scan, kBack, kmax);
      const VF kz = sel(increasing, kFront, kBack);
      const VF p = (kz - k0) * invDk;
      const VF e = p - vmax(pixelBackoff, splat(8.0f * u) * (vmax(kScale, kz * invAbsDk) + vabs(p)));
      const VF entry = vmin(vmax(sel(lt(vabs(e), fInf), e, s0), s0), s1);
      sHit = sel(overlap, vmin(sHit, entry), sHit);
    }
  }
  const M descend = coarse & ne(sHit, fInf);

  // Descent (Hofmann et al. 2017, §5.2): advance to the entry, choose the child holding s.
  M bail = noLanes(), d = noLanes();
  if (any(descend)) {
    const VF sNew = vmax(s, sHit);
    // (L − 1 clamped at 0: lanes at level 0 do not descend, and a negative shift is undefined)
    const VI Ld = L - one, half = one << imax(Ld, zero);
    const VF xMid = toFloat((hn::ShiftLeft<1>(cx) + one) * half), yMid = toFloat((hn::ShiftLeft<1>(cy) + one) * half);
    const VF mx = (xMid - p0x) * invDx, my = (yMid - p0y) * invDy;
    VI best = splat(int32_t(-1));
    VF bestOut = splat(0.0f);
    for (int q = 0; q < 4; ++q) {
      // childSlab: the child entered first along an axis has the cell's entry on that axis.
      const M firstX = (q & 1) ? ~posX : posX, firstY = (q >> 1) ? ~posY : posY;
      const VF cxIn = sel(firstX, xIn, mx), cxOut = sel(firstX, mx, xOut);
      const VF cyIn = sel(firstY, yIn, my), cyOut = sel(firstY, my, yOut);
      const VF a = vmax(cxIn, cyIn), b = vmin(cxOut, cyOut);
      const M in = le(le(descend, a, sNew), sNew, b);
      const M ok = andNot(andNot(in, lt(eq(in, b, sNew), a, b)), eq(in, a, b) & (le(cxOut, cyOut) | eq(a, cornerLeft)));
      const M take = ok & (lt(best, zero) | lt(b, bestOut));
      best = sel(take, splat(int32_t(q)), best);
      bestOut = sel(take, b, bestOut);
    }
    bail = lt(descend, best, zero);  // rounding left s outside every child: hssrMarch's fallback
    d = andNot(descend, bail);
    s = sel(d, sNew, s);
    L = sel(d, Ld, L);
    cx = sel(d, hn::ShiftLeft<1>(cx) + (best & one), cx);
    cy = sel(d, hn::ShiftLeft<1>(cy) + hn::ShiftRight<1>(best), cy);
    // The chosen child's slab (childSlab of quadrant `best`, without carrying four candidates
    // through the loop): along an axis it is entered first, keeping the cell's entry and ending
    // at the midline, or second, from the midline to the cell's exit.
    const M firstX = posX ^ ne(best & one, zero), firstY = posY ^ ne(best & splat(int32_t(2)), zero);
    xIn = sel(andNot(d, firstX), mx, xIn), xOut = sel(d & firstX, mx, xOut);
    yIn = sel(andNot(d, firstY), my, yIn), yOut = sel(d & firstY, my, yOut);
    misses = sel(d, zero, misses);
  }

  // No overlap: step to the next cell of this level, and ascend after n_up of them.
  M move = andNot(andNot(act, hit), descend);
  cornerLeft = sel(eq(move, sIn, sOut), sOut, cornerLeft);
  s = sel(move, vmax(s, s1), s);
  move = notGe(move, sOut, fOne);  // (the others leave the segment: a miss)
  {
    const VI size = one << L;
    const M exitX = le(xOut, yOut);  // ties step in x first
    const M mx = move & exitX, my = andNot(move, exitX);
    const VI parentX = hn::ShiftRight<1>(cx), parentY = hn::ShiftRight<1>(cy);
    cx = sel(mx, cx + stepX, cx);
    cy = sel(my, cy + stepY, cy);
    const VF nextX = (toFloat(sel(posX, cx + one, cx) * size) - p0x) * invDx;
    const VF nextY = (toFloat(sel(posY, cy + one, cy) * size) - p0y) * invDy;
    xIn = sel(mx, xOut, xIn), xOut = sel(mx, nextX, xOut);
    yIn = sel(my, yOut, yIn), yOut = sel(my, nextY, yOut);
    misses = sel(move, misses + one, misses);
    const VI Lu = L + one, px = hn::ShiftRight<1>(cx), py = hn::ShiftRight<1>(cy);
    // (after n_up misses, or on entering another parent cell where the rule has it: hssrMarch's rule)
    const M parentMove = tb.newParent ? move : andNot(move, move);
    M up = lt(ge(move, misses, splat(int32_t(tb.nUp))) | ne(parentMove, px, parentX) | ne(parentMove, py, parentY), Lu,
              splat(int32_t(tb.levels)));
    // Hofmann et al. 2017, §5.2: only ascend when the coarser cell does not overlap the origin
    // pixel.
    up = ne(up, loadI(ln.ox) >> Lu, px) | ne(up, loadI(ln.oy) >> Lu, py);
    // (the table lookups' level capped at 7, the tables' last: lanes with Lu ≥ levels are out of
    // `up` already)
    const VI LuTable = imin(Lu, splat(int32_t(7)));
    up = lt(lt(up, px, lookup(tb.width, LuTable)), py, lookup(tb.height, LuTable)) & ge(cx, zero) & ge(cy, zero);
    if (any(up)) {
      L = sel(up, Lu, L);
      cx = sel(up, px, cx), cy = sel(up, py, cy);
      misses = sel(up, zero, misses);
      const VI sizeUp = hn::ShiftLeft<1>(size);
      const VF x0 = (toFloat(px * sizeUp) - p0x) * invDx, x1 = (toFloat((px + one) * sizeUp) - p0x) * invDx;
      const VF y0 = (toFloat(py * sizeUp) - p0y) * invDy, y1 = (toFloat((py + one) * sizeUp) - p0y) * invDy;
      xIn = sel(up, sel(posX, x0, x1), xIn), xOut = sel(up, sel(posX, x1, x0), xOut);
      yIn = sel(up, sel(posY, y0, y1), yIn), yOut = sel(up, sel(posY, y1, y0), yOut);
    }
  }

  store(ln.xIn, xIn), store(ln.xOut, xOut), store(ln.yIn, yIn), store(ln.yOut, yOut);
  store(ln.s, s), store(ln.cornerLeft, cornerLeft);
  store(ln.L, L), store(ln.cx, cx), store(ln.cy, cy), store(ln.misses, misses), store(ln.guard, sel(act, guard + one, guard));
  store(ln.interval, found);
  store(ln.hitS, s0);
  storeFlags(ln.hitMask, hit), storeFlags(ln.bailMask, bail);
  // The records of the lanes' next cells, requested now so that their loads overlap whatever
  // runs before the next step (the other group's step).
  {
    // A cell outside its level gets record 0 of the level (any valid address: the lane stops
    // before reading it).
    const M out = outside(cx, lookup(tb.width, L)) | outside(cy, lookup(tb.height, L));
    const VI index = sel(out, zero, cy * lookup(tb.rowWidth, L) + cx);
    storeOffsets(ln.offset, L, index * lookup(tb.recordUnits, L), tb.base);
    const uintptr_t origin = reinterpret_cast<uintptr_t>(tb.origin);
    for (size_t j = 0; j < laneCount(); ++j) hwy::Prefetch(reinterpret_cast<const char*>(origin + uintptr_t(ln.offset[j])));
  }
  return bits(andNot(live, move | d));
}

}  // namespace

/// The batch through the lanes: refill every lane that finished with the next segment.
void hssrMarchLanes(const IntervalPyramid& pyramid, int levels, AscentRule rule, std::span<const ScreenSegment> segs, int W, int H,
                    std::span<MarchHit> out, std::span<uint32_t> cells) {
  const IntervalLayers& level0 = *pyramid.base;
  Tables tb;
  tb.levels = levels, tb.nUp = rule.nUp, tb.newParent = rule.newParent, tb.k = level0.k, tb.safety = 8 * (W + H) * levels + 64;
  tb.origin = reinterpret_cast<const char*>(level0.slots.data());
  for (int L = 0; L < levels; ++L) {
    const PyramidLevel& lvl = pyramid.levels[size_t(L)];
    tb.width[L] = lvl.width, tb.height[L] = lvl.height;
    tb.rowWidth[L] = L == 0 ? level0.width : lvl.width;
    const char* data = L == 0 ? tb.origin : reinterpret_cast<const char*>(lvl.cells.data());
    tb.base[L] = int64_t(reinterpret_cast<uintptr_t>(data) - reinterpret_cast<uintptr_t>(tb.origin));
    tb.recordUnits[L] = int32_t((L == 0 ? sizeof(Interval) * size_t(level0.k) : sizeof(CoarseCell)) / 8);
  }
  // Two groups of lanes stepped in turn: each step prefetches its lanes' next records, and the
  // other group's step hides their latency (bench_trace BM_HssrLanes, FZK-Haus, AVX-512: one
  // group 1.16–1.22× the one-ray march, two 1.31–1.37×, three and four no better than two; three
  // were 15–25 % slower in `compare`).
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
    if (ln.hitMask[j]) {
      out[i] = MarchHit{ln.cx[j], ln.cy[j], ln.interval[j], ln.hitS[j]};
    } else if (ln.bailMask[j]) {
      MarchCellCount c;
      out[i] = hssrMarch(pyramid, levels, rule, segs[i], W, H, c);
      tested = c.cells;  // the march that answered (the lane's steps are dropped with its state)
    } else {
      out[i] = {};
    }
    if (!cells.empty()) cells[i] = tested;
  };
  runLaneGroups(lanes, fill, [&](Lanes& ln) { return step(ln, tb); }, done, [](Lanes&) {});
}

/// The portable path (and the reference the lanes are measured against), compiled per target as
/// well (flatten: the march inlined, so compiled for the target too): the compiler's own code for
/// the CPU it runs on.
[[gnu::flatten]] void hssrMarchEachTarget(const IntervalPyramid& pyramid, int levels, AscentRule rule, std::span<const ScreenSegment> segs, int W, int H,
                         std::span<MarchHit> out, std::span<uint32_t> cells) {
  for (size_t i = 0; i < segs.size(); ++i) {
    if (!segs[i].valid) {
      out[i] = {};
      if (!cells.empty()) cells[i] = 0;
    } else if (cells.empty()) {
      NoCounters none;  // (the reference bench_trace times: no counting)
      out[i] = hssrMarch(pyramid, levels, rule, segs[i], W, H, none);
    } else {
      MarchCellCount c;
      out[i] = hssrMarch(pyramid, levels, rule, segs[i], W, H, c);
      cells[i] = c.cells;
    }
  }
}

}  // namespace lt::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lt {

HWY_EXPORT(hssrMarchLanes);
HWY_EXPORT(hssrMarchEachTarget);

void hssrMarchEach(const IntervalPyramid& pyramid, int levels, AscentRule rule, std::span<const ScreenSegment> segs, int W, int H,
                   std::span<MarchHit> out, std::span<uint32_t> cells) {
  HWY_DYNAMIC_DISPATCH(hssrMarchEachTarget)(pyramid, levels, rule, segs, W, H, out, cells);
}

bool hssrLanesAvailable(const IntervalPyramid& pyramid, int levels) {
  constexpr int kExactHalf = 1 << 22;  // floor(p) + 0.5 is exact for 0 ≤ p < 2^22 (start's flat axes)
  if (!pyramid.base || pyramid.base->k < 1 || pyramid.base->k > 4 || levels < 1 || levels > 8) return false;
  const IntervalLayers& base = *pyramid.base;
  // (a record's offset in 8-byte units is an int32 lane: 4 units per pixel at most)
  const bool unitsFit = uint64_t(base.width) * uint64_t(base.height) * 4u < (uint64_t(1) << 31);
  return base.width < kExactHalf && base.height < kExactHalf && unitsFit && levels <= pyramid.levelCount() &&
         pyramid.levels[0].width == base.width && pyramid.levels[0].height == base.height;
}

void hssrMarchBatch(const IntervalPyramid& pyramid, int levels, AscentRule rule, std::span<const ScreenSegment> segs, int W, int H,
                    std::span<MarchHit> out, std::span<uint32_t> cells) {
  if (hssrLanesAvailable(pyramid, levels)) return HWY_DYNAMIC_DISPATCH(hssrMarchLanes)(pyramid, levels, rule, segs, W, H, out, cells);
  hssrMarchEach(pyramid, levels, rule, segs, W, H, out, cells);
}

}  // namespace lt
#endif
