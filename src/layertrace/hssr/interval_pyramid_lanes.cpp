// The interval pyramid's level merge in vector lanes (one cell per lane), written once with
// Google Highway and compiled for every target it builds (this file is included once per target
// through hwy/foreach_target.h).
#include "layertrace/hssr/interval_pyramid_lanes.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <limits>
#include <utility>

#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/util/error.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "layertrace/hssr/interval_pyramid_lanes.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <hwy/highway.h>

#include "layertrace/util/lanes-inl.h"

HWY_BEFORE_NAMESPACE();
namespace lt::HWY_NAMESPACE {
namespace {

using namespace lanes;

/// The comparators of Batcher's odd–even merge sort for 16 keys without its first two rounds:
/// those sort runs of four, and a cell's 16 children intervals are four runs sorted already (each
/// child pixel's k = 4 intervals, sorted by front). What is left merges 4 + 4 twice (9
/// comparators each) and then 8 + 8 (25): 43 compare-exchanges, the same for every lane.
struct Comparator {
  int a, b;
};
constexpr auto kMerge = [] {
  std::array<Comparator, 43> c{};
  int n = 0;
  for (int p = 4; p < 16; p *= 2)
    for (int k = p; k >= 1; k /= 2)
      for (int j = k % p; j + k < 16; j += 2 * k)
        for (int i = 0; i < k && i + j + k < 16; ++i)
          if ((i + j) / (2 * p) == (i + j + k) / (2 * p)) c[size_t(n++)] = {i + j, i + j + k};
  if (n != 43) throw "the merge network has 43 comparators";  // (a compile-time check)
  return c;
}();

/// Orders positions a < b by front in every lane; the back travels with its front. (Equal fronts
/// may leave their backs in either order: the sweep joins equal fronts into one interval and
/// takes the larger back, so the order does not change the result — mergeChildren's argument.)
inline void exchange(VF f[16], VF b[16], int i, int j) {
  const M swap = gt(f[i], f[j]);
  const VF fi = f[i], bi = b[i];
  f[i] = sel(swap, f[j], fi), f[j] = sel(swap, fi, f[j]);
  b[i] = sel(swap, b[j], bi), b[j] = sel(swap, bi, b[j]);
}
template <size_t... C>
inline void mergeRuns(VF f[16], VF b[16], std::index_sequence<C...>) {
  (exchange(f, b, kMerge[C].a, kMerge[C].b), ...);
}

/// One pixel row dy of cells x0 … x0 + n − 1 (n = the lanes) into the runs f/b: child
/// 2·dy + dx's slot s goes to position 4·child + s. `children(j, dx)` is the 8-float record of
/// cell x0 + j's child dx in that row (its k = 4 intervals, sentinels past its count).
template <class Children>
inline void childrenIntoRuns(int dy, Children&& children, VF f[16], VF b[16]) {
  for (int dx = 0; dx < 2; ++dx) {
    const float* rows[kMaxLanes] = {};
    for (size_t j = 0; j < laneCount(); ++j) rows[j] = children(j, dx);
    VF field[8];
    transposeRecords(rows, field);
    const int child = 2 * dy + dx;
    for (int s = 0; s < 4; ++s) f[4 * child + s] = field[2 * s], b[4 * child + s] = field[2 * s + 1];
  }
}

/// The four runs of f/b merged (the network), then mergeChildren's sweep in every lane; appends
/// the lanes' cells in order and writes their counts.
void mergeRunsAndSweep(VF f[16], VF b[16], float tauPerDepth, std::vector<Interval>& out, uint32_t* counts) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  mergeRuns(f, b, std::make_index_sequence<kMerge.size()>{});

  // Sentinels ({+∞, +∞}: slots past a pixel's or a cell's count) sort last and take no part.
  // The interval step i closes is stored at index i − 1 (the last one at 15) with the lane's bit
  // i − 1 set; the set bits are read out lane by lane, in cell order.
  const VF tau = splat(tauPerDepth), infinity = splat(inf);
  HWY_ALIGN float closedF[16][kMaxLanes], closedB[16][kMaxLanes];
  HWY_ALIGN int32_t closed[kMaxLanes];
  VF curF = f[0], curB = b[0], limit = hn::Add(curF, hn::Mul(tau, curF));
  VI bitsSet = splat(int32_t(0));
  for (int i = 1; i < 16; ++i) {
    const M valid = lt(f[i], infinity);
    const M join = valid & (le(f[i], limit) | le(f[i], curB));
    const M close = valid & ~join;
    store(closedF[i - 1], curF), store(closedB[i - 1], curB);
    bitsSet = sel(close, hn::Or(bitsSet, splat(int32_t(1) << (i - 1))), bitsSet);
    curB = sel(join, vmax(curB, b[i]), curB);
    curF = sel(close, f[i], curF), curB = sel(close, b[i], curB);
    limit = sel(close, hn::Add(f[i], hn::Mul(tau, f[i])), limit);
  }
  store(closedF[15], curF), store(closedB[15], curB);
  bitsSet = sel(lt(f[0], infinity), hn::Or(bitsSet, splat(int32_t(1) << 15)), bitsSet);
  store(closed, bitsSet);

  const size_t n = laneCount();
  size_t at = out.size(), total = 0;
  for (size_t j = 0; j < n; ++j) total += size_t(std::popcount(uint32_t(closed[j])));
  out.resize(at + total);
  for (size_t j = 0; j < n; ++j) {
    uint32_t m = uint32_t(closed[j]);
    counts[j] = uint32_t(std::popcount(m));
    for (; m != 0; m &= m - 1) {
      const int i = std::countr_zero(m);
      out[at++] = {closedF[i][j], closedB[i][j]};
    }
  }
}

}  // namespace

/// Sixteen cells x0 … x0 + 15, the lanes' count at a time (mergeCellsLanes' contract).
bool mergeSixteenLanes(const IntervalPyramid& p, int L, int x0, int y, float tauPerDepth, std::vector<Interval>& out,
                       uint32_t* counts) {
  const size_t n = laneCount();
  if (L >= 2) {
    // Levels ≥ 2: each child cell's CSR intervals (sorted by front, disjoint); nothing is
    // written when one of the 32 children holds more than four.
    const PyramidLevel& child = p.levels[size_t(L - 1)];
    for (int dy = 0; dy < 2; ++dy) {
      const uint32_t* offset = &child.offset[child.cellIndex(2 * x0, 2 * y + dy)];
      for (int i = 0; i < 32; ++i)
        if (offset[i + 1] - offset[i] > 4) return false;
    }
  }
  constexpr float inf = std::numeric_limits<float>::infinity();
  for (size_t g = 0; g < 16; g += n) {
    const int xg = x0 + int(g);
    VF f[16], b[16];
    for (int dy = 0; dy < 2; ++dy) {
      if (L == 1) {
        // Level 1: a cell's two children in one pixel row are 2 × 4 intervals = 16 floats in a
        // row (sentinels included).
        const float* row = &p.base->pixel(2 * xg, 2 * y + dy)->front;
        childrenIntoRuns(dy, [&](size_t j, int dx) { return row + 16 * j + 8 * dx; }, f, b);
      } else {
        // A child's n ≤ 4 intervals copied into a record filled with the {+∞, +∞} sentinel.
        const PyramidLevel& child = p.levels[size_t(L - 1)];
        const uint32_t* offset = &child.offset[child.cellIndex(2 * xg, 2 * y + dy)];
        HWY_ALIGN float records[2 * kMaxLanes][8];
        for (size_t c = 0; c < 2 * n; ++c) {
          const uint32_t first = offset[c], count = offset[c + 1] - first;
          std::fill(records[c], records[c] + 8, inf);
          if (count) std::memcpy(records[c], &child.intervals[first], sizeof(Interval) * count);
        }
        childrenIntoRuns(dy, [&](size_t j, int dx) { return records[2 * j + size_t(dx)]; }, f, b);
      }
    }
    mergeRunsAndSweep(f, b, tauPerDepth, out, counts + g);
  }
  return true;
}

}  // namespace lt::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lt {

HWY_EXPORT(mergeSixteenLanes);

bool mergeLanesAvailable(const IntervalPyramid& p, int L) { return L >= 2 || (L == 1 && p.base->k == 4); }

bool mergeCellsLanes(const IntervalPyramid& p, int L, int x0, int y, float tauPerDepth, std::vector<Interval>& out, uint32_t counts[16]) {
  LT_CHECK(L >= 1 && size_t(L) < p.levels.size() && x0 >= 0 && y >= 0, L, x0, y);
  const PyramidLevel& child = p.levels[size_t(L - 1)];
  LT_CHECK(2 * x0 + 32 <= child.width && 2 * y + 2 <= child.height, x0, y, child.width, child.height);
  if (L == 1) LT_CHECK(p.base->k == 4 && p.base->width == child.width && p.base->height == child.height, p.base->k);
  return HWY_DYNAMIC_DISPATCH(mergeSixteenLanes)(p, L, x0, y, tauPerDepth, out, counts);
}

}  // namespace lt
#endif
