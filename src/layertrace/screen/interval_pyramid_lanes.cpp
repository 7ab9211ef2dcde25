#include "layertrace/screen/interval_pyramid_lanes.h"

#include <array>
#include <bit>
#include <limits>
#include <utility>

#include "layertrace/util/error.h"
#include "layertrace/util/simd512.h"

namespace lt {

#if LT_SIMD512
// Compiled for AVX-512 (util/simd512.h) and run only where level1LanesAvailable says so; the
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

void mergeLanes(const IntervalLayers& base, int x0, int y, float tauPerDepth, std::vector<Interval>& out, uint32_t counts[16]) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  // Lane j = cell x0 + j. A cell's two children in one pixel row are 2 × 4 intervals = 16 floats
  // in a row: sixteen row loads and a transpose put float i of every cell's row in r[i], i.e.
  // child pixel i / 8, slot (i % 8) / 2, front or back by i's parity.
  F f[16], b[16];
  for (int dy = 0; dy < 2; ++dy) {
    const float* row = &base.pixel(2 * x0, 2 * y + dy)->front;
    F r[16];
    for (int j = 0; j < 16; ++j) r[j] = load<F>(row + 16 * j);
    transpose16(r);
    for (int dx = 0; dx < 2; ++dx)
      for (int s = 0; s < 4; ++s) {
        const int child = 2 * dy + dx;  // four sorted runs of four: positions 4·child + slot
        f[4 * child + s] = r[8 * dx + 2 * s];
        b[4 * child + s] = r[8 * dx + 2 * s + 1];
      }
  }
  mergeRuns(f, b, std::make_index_sequence<kMerge.size()>{});

  // mergeChildren's sweep in every lane; sentinels ({+∞, +∞}: slots past a pixel's count) sort
  // last and take no part. The interval a step closes is stored at the step's index, and the
  // lane's bit for that index says it was closed there.
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

}  // namespace
#pragma GCC pop_options

bool level1LanesAvailable(int k) { return k == 4 && simd512Available(); }

void mergeLevel1Lanes(const IntervalLayers& base, int x0, int y, float tauPerDepth, std::vector<Interval>& out, uint32_t counts[16]) {
  LT_CHECK(base.k == 4 && x0 >= 0 && 2 * x0 + 32 <= base.width && y >= 0 && 2 * y + 2 <= base.height, base.k, x0, y);
  mergeLanes(base, x0, y, tauPerDepth, out, counts);
}

#else

bool level1LanesAvailable(int) { return false; }
void mergeLevel1Lanes(const IntervalLayers&, int, int, float, std::vector<Interval>&, uint32_t[16]) {
  LT_CHECK(false && "mergeLevel1Lanes needs LT_SIMD512");
}

#endif

}  // namespace lt
