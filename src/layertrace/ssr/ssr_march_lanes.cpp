#include "layertrace/ssr/ssr_march_lanes.h"

#include <algorithm>
#include <cstdint>
#include <cstring>

#include "layertrace/screen/interval_lanes.h"
#include "layertrace/util/simd512.h"

namespace lt {

namespace {
void marchEach(const IntervalLayers& depth, std::span<const SsrStart> starts, int maxSteps, int W, int H, std::span<SsrSample> out) {
  NoCounters none;
  for (size_t i = 0; i < starts.size(); ++i) out[i] = ssrMarch(depth, starts[i], maxSteps, W, H, none);
}
}  // namespace

#if LT_SIMD512
// Compiled for AVX-512 and run only where the CPU has it (ssrLanesAvailable); the portable path
// is marchEach.
#pragma GCC push_options
#pragma GCC target("avx512f,avx512vl,avx512bw,avx512dq")
namespace {

using namespace simd512;

/// One ray's march state per lane (ssrMarch's locals and its start's constants), kept in memory
/// between steps so that a finished lane can be refilled with scalar writes.
struct alignas(64) Lanes {
  float px[kLanes], py[kLanes], dpx[kLanes], dpy[kLanes];
  float s[kLanes], dsStep[kLanes], kHalf[kLanes], dk[kLanes], kLo[kLanes], kHi[kLanes], prevDepth[kLanes];
  int32_t step[kLanes];
  int32_t ray[kLanes];  ///< the start's index in the batch; −1 for an empty lane
  // The pixel of each lane's next sample (nextPixel): its coordinates, and its index where it
  // lies in the view (0 elsewhere: not read). A finished lane's hit is at x, y.
  int32_t x[kLanes], y[kLanes], pixel[kLanes];
  __mmask16 permute, increasing;
  // Written by a step for the lanes it finished:
  __mmask16 hitMask;
  int32_t layer[kLanes];
  float hitS[kLanes];
};

struct Tables {
  const char* slots = nullptr;  ///< the pixels' intervals
  int k = 1, W = 0, H = 0, width = 0, maxSteps = 0;
};

/// int(std::floor(v)) per lane (the masked form of roundscale: the plain one reads an undefined
/// register, which GCC 12 warns about).
inline I floorToInt(F v) {
  const __m512 f = _mm512_mask_roundscale_ps((__m512)v, __mmask16(0xffff), (__m512)v, _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC);
  return __builtin_convertvector((F)f, I);
}

/// Stores the pixel each lane's next sample reads (ssrMarch's floor and un-permute of P) in
/// Lanes::x, y and pixel, for the next step's bounds check, record loads and prefetch.
inline void nextPixel(Lanes& ln, const Tables& tb) {
  const M permute{ln.permute};
  const I px = floorToInt(load<F>(ln.px)), py = floorToInt(load<F>(ln.py));
  const I x = sel(permute, py, px), y = sel(permute, px, py), zero = I{};
  const M out = outside(x, zero + tb.W) | outside(y, zero + tb.H);
  // Lanes outside the view read pixel 0 (their x, y are clamped first: y * width of a lane far
  // outside would overflow).
  store(ln.x, x), store(ln.y, y), store(ln.pixel, sel(out, zero, y) * tb.width + sel(out, zero, x));
}

void start(Lanes& ln, int j, const SsrStart& m, int i) {
  ln.px[j] = m.P.x, ln.py[j] = m.P.y, ln.dpx[j] = m.dP.x, ln.dpy[j] = m.dP.y;
  ln.s[j] = m.s, ln.dsStep[j] = m.dsStep, ln.kHalf[j] = m.kHalf, ln.dk[j] = m.dk, ln.kLo[j] = m.kLo, ln.kHi[j] = m.kHi;
  ln.prevDepth[j] = m.prevDepth;
  ln.step[j] = 0;
  ln.ray[j] = i;
  const __mmask16 bit = __mmask16(1u << j);
  ln.permute = __mmask16((ln.permute & ~bit) | (m.permute ? bit : 0));
  ln.increasing = __mmask16((ln.increasing & ~bit) | (m.increasing ? bit : 0));
}

/// One iteration of ssrMarch's loop in every live lane. Returns the lanes that finished
/// (hitMask: with a hit).
__attribute__((noinline)) uint32_t step(Lanes& ln, const Tables& tb) {
  const I zero = I{}, one = zero + 1;
  const M increasing{ln.increasing};
  F px = load<F>(ln.px), py = load<F>(ln.py), s = load<F>(ln.s), kHalf = load<F>(ln.kHalf);
  I steps = load<I>(ln.step);
  const M live = ge(load<I>(ln.ray), zero);
  // The loop's condition, then the sample's pixel and the view's bounds.
  M act = le(lt(live, steps, zero + tb.maxSteps), s, F{} + 1.0f);
  const I x = load<I>(ln.x), y = load<I>(ln.y);  // the sample's pixel (nextPixel)
  act = andNot(act, outside(x, zero + tb.W) | outside(y, zero + tb.H));
  // The depth range from half a step back to half a step ahead (clamped to the segment).
  const F prevDepth = load<F>(ln.prevDepth);
  const F nextDepth = 1.0f / vmin(vmax(kHalf, load<F>(ln.kLo)), load<F>(ln.kHi));
  const F zmin = vmin(prevDepth, nextDepth), zmax = vmax(prevDepth, nextDepth);
  // The pixels' records (requested by the previous step's prefetch): 8k ≤ 32 bytes each, read
  // with masked row loads (floats past the record are not read) and transposed.
  F field[8];
  if (tb.k <= 2) {
    // One or two intervals: a gather per float (index in intervals, scale 8: no overflow below
    // 2^31 intervals).
    const I index = load<I>(ln.pixel) * tb.k;
    const __m512 none = _mm512_setzero_ps();
    for (int i = 0; i < tb.k; ++i) {
      field[2 * i] = (F)_mm512_mask_i32gather_ps(none, act.bits, (__m512i)(index + i), tb.slots, 8);
      field[2 * i + 1] = (F)_mm512_mask_i32gather_ps(none, act.bits, (__m512i)(index + i), tb.slots + 4, 8);
    }
  } else {
    const __mmask8 record = __mmask8((1u << (2 * tb.k)) - 1);
    const size_t bytes = sizeof(Interval) * size_t(tb.k);
    auto row = [&](int j) {
      const __mmask8 m = (act.bits >> j & 1) ? record : __mmask8(0);
      return (F8)_mm256_maskz_loadu_ps(m, tb.slots + size_t(ln.pixel[j]) * bytes);
    };
    F r[8];
    for (int j = 0; j < 8; ++j) r[j] = joinRows(row(j), row(j + 8));
    transposeRows8(r, field);
  }
  const I found = firstMetLanes(field, tb.k, zmin, zmax, act, increasing);
  const M hit = act & ge(found, zero);
  // No hit: advance (++step, s += dsStep, P += dP, κ += dκ).
  const M move = andNot(act, hit);
  store(ln.prevDepth, sel(move, nextDepth, prevDepth));
  store(ln.step, sel(move, steps + one, steps));
  store(ln.s, sel(move, s + load<F>(ln.dsStep), s));
  px = sel(move, px + load<F>(ln.dpx), px);
  py = sel(move, py + load<F>(ln.dpy), py);
  store(ln.px, px), store(ln.py, py);
  store(ln.kHalf, sel(move, kHalf + load<F>(ln.dk), kHalf));
  store(ln.layer, found), store(ln.hitS, s);
  ln.hitMask = hit.bits;
  // The next samples' records, requested now so that their loads overlap the other group's step
  // (a lane that hit keeps its sample: x, y stay its hit pixel).
  nextPixel(ln, tb);
  const size_t bytes = sizeof(Interval) * size_t(tb.k);
  for (int j = 0; j < kLanes; ++j) __builtin_prefetch(tb.slots + size_t(ln.pixel[j]) * bytes);
  return (live & ~move).bits;
}

void marchLanes(const IntervalLayers& depth, std::span<const SsrStart> starts, int maxSteps, int W, int H, std::span<SsrSample> out) {
  Tables tb;
  tb.slots = reinterpret_cast<const char*>(depth.slots.data());
  tb.k = depth.k, tb.W = W, tb.H = H, tb.width = depth.width, tb.maxSteps = maxSteps;
  // Two groups of lanes stepped in turn, as in the HSSR lanes (runLaneGroups).
  Lanes lanes[2];
  size_t next = 0;
  auto fill = [&](Lanes& ln, int j) {
    ln.ray[j] = -1;
    while (next < starts.size()) {
      const size_t i = next++;
      if (!starts[i].seg.valid) {
        out[i] = {};
        continue;
      }
      start(ln, j, starts[i], int(i));
      return true;
    }
    return false;
  };
  auto done = [&](const Lanes& ln, int j) {
    out[size_t(ln.ray[j])] = (ln.hitMask >> j & 1) ? SsrSample{ln.x[j], ln.y[j], ln.layer[j], ln.hitS[j]} : SsrSample{};
  };
  // (after a refill: the new lanes' first samples, for the step's record loads)
  runLaneGroups(lanes, fill, [&](Lanes& ln) { return step(ln, tb); }, done, [&](Lanes& ln) { nextPixel(ln, tb); });
}

}  // namespace
#pragma GCC pop_options
#endif

bool ssrLanesAvailable(const IntervalLayers& depth) {
#if LT_SIMD512
  return simd512Available() && depth.k >= 1 && depth.k <= 4;
#else
  (void)depth;
  return false;
#endif
}

void ssrMarchBatch(const IntervalLayers& depth, std::span<const SsrStart> starts, int maxSteps, int W, int H,
                   std::span<SsrSample> out) {
#if LT_SIMD512
  if (ssrLanesAvailable(depth)) return marchLanes(depth, starts, maxSteps, W, H, out);
#endif
  marchEach(depth, starts, maxSteps, W, H, out);
}

}  // namespace lt
