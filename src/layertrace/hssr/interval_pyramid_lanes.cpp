#include "layertrace/hssr/interval_pyramid_lanes.h"

#include <array>
#include <bit>
#include <limits>
#include <utility>

#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/util/error.h"
#include "layertrace/util/simd512.h"

namespace lt {

#if LT_SIMD512
// Compiled for AVX-512 (util/simd512.h) and run only where mergeLanesAvailable says so; the
// one-cell merge of interval_pyramid_build.cpp is the portable path and the reference.
#pragma GCC push_options
#pragma GCC target("avx512f,avx512vl,avx512bw,avx512dq")
namespace {

using namespace simd512;

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
inline void exchange(F f[16], F b[16], int i, int j) {
  const M swap = gt(f[i], f[j]);
  const F fi = f[i], bi = b[i];
  f[i] = sel(swap, f[j], fi), f[j] = sel(swap, fi, f[j]);
  b[i] = sel(swap, b[j], bi), b[j] = sel(swap, bi, b[j]);
}
template <size_t... C>
inline void mergeRuns(F f[16], F b[16], std::index_sequence<C...>) {
  (exchange(f, b, kMerge[C].a, kMerge[C].b), ...);
}

/// Cell x0 + j's children of pixel row dy, as loaded into r[j] (two children of four intervals,
/// 16 floats), transposed into runs: float i of every cell's row is child i / 8, slot (i % 8) / 2,
/// front or back by i's parity; child 2·dy + dx's slots go to positions 4·child + slot.
inline void childrenIntoRuns(F r[16], int dy, F f[16], F b[16]) {
  transpose16(r);
  for (int dx = 0; dx < 2; ++dx)
    for (int s = 0; s < 4; ++s) {
      const int child = 2 * dy + dx;
      f[4 * child + s] = r[8 * dx + 2 * s];
      b[4 * child + s] = r[8 * dx + 2 * s + 1];
    }
}

/// Level 1: a cell's two children in one pixel row are 2 × 4 intervals = 16 floats in a row
/// (sentinels included): one row load per cell and row.
inline void loadPixels(const IntervalLayers& base, int x0, int y, F f[16], F b[16]) {
  for (int dy = 0; dy < 2; ++dy) {
    const float* row = &base.pixel(2 * x0, 2 * y + dy)->front;
    F r[16];
    for (int j = 0; j < 16; ++j) r[j] = load<F>(row + 16 * j);
    childrenIntoRuns(r, dy, f, b);
  }
}

/// Levels ≥ 2: each child cell's CSR intervals (sorted by front, disjoint) by a masked load of
/// its first n ≤ 4 intervals, the rest filled with the {+∞, +∞} sentinel. False (nothing
/// loaded) when a child holds more than four.
inline bool loadCells(const PyramidLevel& child, int x0, int y, F f[16], F b[16]) {
  const F8 sentinel = F8{} + std::numeric_limits<float>::infinity();
  // (as an address, not a member access: a level whose cells are all empty has no intervals,
  // and then every load below is fully masked and reads nothing)
  const float* intervals = reinterpret_cast<const float*>(child.intervals.data());
  for (int dy = 0; dy < 2; ++dy) {
    const uint32_t* offset = &child.offset[child.cellIndex(2 * x0, 2 * y + dy)];
    for (int i = 0; i < 32; ++i)
      if (offset[i + 1] - offset[i] > 4) return false;
    F r[16];
    for (int j = 0; j < 16; ++j) {
      F8 half[2];
      for (int dx = 0; dx < 2; ++dx) {
        const uint32_t first = offset[2 * j + dx], n = offset[2 * j + dx + 1] - first;
        half[dx] = (F8)_mm256_mask_loadu_ps((__m256)sentinel, __mmask8((1u << (2 * n)) - 1), intervals + 2 * size_t(first));
      }
      r[j] = __builtin_shufflevector(half[0], half[1], 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    }
    childrenIntoRuns(r, dy, f, b);
  }
  return true;
}

/// The four runs of f/b merged (the network), then mergeChildren's sweep in every lane.
void mergeRunsAndSweep(F f[16], F b[16], float tauPerDepth, std::vector<Interval>& out, uint32_t counts[16]) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  mergeRuns(f, b, std::make_index_sequence<kMerge.size()>{});

  // Sentinels ({+∞, +∞}: slots past a pixel's or a cell's count) sort last and take no part.
  // The interval step i closes is stored at index i − 1 (the last one at 15) with the lane's bit
  // i − 1 set; the set bits are read out lane by lane, in cell order.
  const F tau = F{} + tauPerDepth, infinity = F{} + inf;
  alignas(64) float closedF[16][16], closedB[16][16];
  alignas(64) int32_t closed[16];
  F curF = f[0], curB = b[0], limit = curF + tau * curF;
  I bits = I{};
  for (int i = 1; i < 16; ++i) {
    const M valid = lt(f[i], infinity);
    const M join = valid & (le(f[i], limit) | le(f[i], curB));
    const M close = valid & ~join;
    store(closedF[i - 1], curF), store(closedB[i - 1], curB);
    bits = sel(close, bits | (1 << (i - 1)), bits);
    curB = sel(join, vmax(curB, b[i]), curB);
    curF = sel(close, f[i], curF), curB = sel(close, b[i], curB);
    limit = sel(close, f[i] + tau * f[i], limit);
  }
  store(closedF[15], curF), store(closedB[15], curB);
  bits = sel(lt(f[0], infinity), bits | (1 << 15), bits);
  store(closed, bits);

  size_t at = out.size(), total = 0;
  for (int j = 0; j < 16; ++j) total += size_t(std::popcount(uint32_t(closed[j])));
  out.resize(at + total);
  for (int j = 0; j < 16; ++j) {
    uint32_t m = uint32_t(closed[j]);
    counts[j] = uint32_t(std::popcount(m));
    for (; m != 0; m &= m - 1) {
      const int i = std::countr_zero(m);
      out[at++] = {closedF[i][j], closedB[i][j]};
    }
  }
}

bool mergeSixteen(const IntervalPyramid& p, int L, int x0, int y, float tauPerDepth, std::vector<Interval>& out, uint32_t counts[16]) {
  F f[16], b[16];
  if (L == 1) loadPixels(*p.base, x0, y, f, b);
  else if (!loadCells(p.levels[size_t(L - 1)], x0, y, f, b)) return false;
  mergeRunsAndSweep(f, b, tauPerDepth, out, counts);
  return true;
}

}  // namespace
#pragma GCC pop_options

bool mergeLanesAvailable(const IntervalPyramid& p, int L) { return simd512Available() && (L >= 2 || (L == 1 && p.base->k == 4)); }

bool mergeCellsLanes(const IntervalPyramid& p, int L, int x0, int y, float tauPerDepth, std::vector<Interval>& out, uint32_t counts[16]) {
  LT_CHECK(L >= 1 && size_t(L) < p.levels.size() && x0 >= 0 && y >= 0, L, x0, y);
  const PyramidLevel& child = p.levels[size_t(L - 1)];
  LT_CHECK(2 * x0 + 32 <= child.width && 2 * y + 2 <= child.height, x0, y, child.width, child.height);
  if (L == 1) LT_CHECK(p.base->k == 4 && p.base->width == child.width && p.base->height == child.height, p.base->k);
  return mergeSixteen(p, L, x0, y, tauPerDepth, out, counts);
}

#else

bool mergeLanesAvailable(const IntervalPyramid&, int) { return false; }
bool mergeCellsLanes(const IntervalPyramid&, int, int, int, float, std::vector<Interval>&, uint32_t[16]) {
  LT_CHECK(false && "mergeCellsLanes needs LT_SIMD512");
  return false;
}

#endif

}  // namespace lt
