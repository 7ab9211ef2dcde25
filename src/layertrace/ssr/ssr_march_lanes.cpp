// ssrMarch in vector lanes, written once with Google Highway and compiled for every target it
// builds (this file is included once per target through hwy/foreach_target.h); the batch runs
// on the best target this CPU has.
#include "layertrace/ssr/ssr_march_lanes.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <span>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "layertrace/ssr/ssr_march_lanes.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <hwy/cache_control.h>
#include <hwy/highway.h>

#include "layertrace/screen/interval_lanes-inl.h"

HWY_BEFORE_NAMESPACE();
namespace lt::HWY_NAMESPACE {
namespace {

using namespace lanes;
constexpr size_t kL = kMaxLanes;

/// One ray's march state per lane (ssrMarch's locals and its start's constants), kept in memory
/// between steps so that a finished lane can be refilled with scalar writes.
struct Lanes {
  HWY_ALIGN float px[kL], py[kL], dpx[kL], dpy[kL];
  HWY_ALIGN float s[kL], dsStep[kL], kHalf[kL], dk[kL], kLo[kL], kHi[kL], prevDepth[kL];
  HWY_ALIGN int32_t step[kL];
  HWY_ALIGN int32_t ray[kL];  ///< the start's index in the batch; −1 for an empty lane
  // The pixel of each lane's next sample (nextPixel): its coordinates, and its index where it
  // lies in the view (0 elsewhere: not read). A finished lane's hit is at x, y.
  HWY_ALIGN int32_t x[kL], y[kL], pixel[kL];
  HWY_ALIGN int32_t permute[kL], increasing[kL];  ///< flags (0 / −1)
  // Written by a step for the lanes it finished:
  HWY_ALIGN int32_t hitMask[kL];
  HWY_ALIGN int32_t layer[kL];
  HWY_ALIGN float hitS[kL];
};

struct Tables {
  const char* slots = nullptr;  ///< the pixels' intervals
  int k = 1, W = 0, H = 0, width = 0, maxSteps = 0;
};

/// Stores the pixel each lane's next sample reads (ssrMarch's floor and un-permute of P) in
/// Lanes::x, y and pixel, for the next step's bounds check, record loads and prefetch.
inline void nextPixel(Lanes& ln, const Tables& tb) {
  const M permute = flags(ln.permute);
  const VI px = toInt(vfloor(loadF(ln.px))), py = toInt(vfloor(loadF(ln.py)));
  const VI x = sel(permute, py, px), y = sel(permute, px, py), zero = splat(int32_t(0));
  const M out = outside(x, splat(int32_t(tb.W))) | outside(y, splat(int32_t(tb.H)));
  // Lanes outside the view read pixel 0 (their x, y are clamped first: y * width of a lane far
  // outside would overflow).
  store(ln.x, x), store(ln.y, y);
  store(ln.pixel, hn::Add(hn::Mul(sel(out, zero, y), splat(int32_t(tb.width))), sel(out, zero, x)));
}

void start(Lanes& ln, int j, const SsrStart& m, int i) {
  ln.px[j] = m.P.x, ln.py[j] = m.P.y, ln.dpx[j] = m.dP.x, ln.dpy[j] = m.dP.y;
  ln.s[j] = m.s, ln.dsStep[j] = m.dsStep, ln.kHalf[j] = m.kHalf, ln.dk[j] = m.dk, ln.kLo[j] = m.kLo, ln.kHi[j] = m.kHi;
  ln.prevDepth[j] = m.prevDepth;
  ln.step[j] = 0;
  ln.ray[j] = i;
  ln.permute[j] = m.permute ? -1 : 0;
  ln.increasing[j] = m.increasing ? -1 : 0;
}

/// One iteration of ssrMarch's loop in every live lane. Returns the lanes that finished
/// (hitMask: with a hit).
HWY_NOINLINE uint64_t step(Lanes& ln, const Tables& tb) {
  const VI zero = splat(int32_t(0)), one = splat(int32_t(1));
  const M increasing = flags(ln.increasing);
  VF px = loadF(ln.px), py = loadF(ln.py);
  const VF s = loadF(ln.s), kHalf = loadF(ln.kHalf);
  const VI steps = loadI(ln.step);
  const M live = ge(loadI(ln.ray), zero);
  // The loop's condition, then the sample's pixel and the view's bounds.
  M act = le(lt(live, steps, splat(int32_t(tb.maxSteps))), s, splat(1.0f));
  const VI x = loadI(ln.x), y = loadI(ln.y);  // the sample's pixel (nextPixel)
  act = andNot(act, outside(x, splat(int32_t(tb.W))) | outside(y, splat(int32_t(tb.H))));
  // The depth range from half a step back to half a step ahead (clamped to the segment).
  const VF prevDepth = loadF(ln.prevDepth);
  const VF nextDepth = hn::Div(splat(1.0f), vmin(vmax(kHalf, loadF(ln.kLo)), loadF(ln.kHi)));
  const VF zmin = vmin(prevDepth, nextDepth), zmax = vmax(prevDepth, nextDepth);
  // The pixels' records (requested by the previous step's prefetch), 8k bytes each.
  VF field[8];
  const size_t bytes = sizeof(Interval) * size_t(tb.k);
  if (tb.k == 4) {
    // One 32-byte record per lane, read as rows and transposed.
    const float* rows[kL] = {};
    for (size_t j = 0; j < laneCount(); ++j) rows[j] = reinterpret_cast<const float*>(tb.slots + size_t(ln.pixel[j]) * bytes);
    transposeRecords(rows, field);
  } else {
    // Fewer intervals: a gather per float (index in floats; ssrLanesAvailable bounds it). Every
    // lane's pixel is a valid one (0 outside the view), so no gather reads past the array.
    const VI index = hn::Mul(loadI(ln.pixel), splat(int32_t(2 * tb.k)));
    const float* slots = reinterpret_cast<const float*>(tb.slots);
    for (int i = 0; i < 2 * tb.k; ++i) field[i] = hn::GatherIndex(DF(), slots, hn::Add(index, splat(int32_t(i))));
  }
  const VI found = firstMetLanes(field, tb.k, zmin, zmax, act, increasing);
  const M hit = act & ge(found, zero);
  // No hit: advance (++step, s += dsStep, P += dP, κ += dκ).
  const M move = andNot(act, hit);
  store(ln.prevDepth, sel(move, nextDepth, prevDepth));
  store(ln.step, sel(move, hn::Add(steps, one), steps));
  store(ln.s, sel(move, hn::Add(s, loadF(ln.dsStep)), s));
  px = sel(move, hn::Add(px, loadF(ln.dpx)), px);
  py = sel(move, hn::Add(py, loadF(ln.dpy)), py);
  store(ln.px, px), store(ln.py, py);
  store(ln.kHalf, sel(move, hn::Add(kHalf, loadF(ln.dk)), kHalf));
  store(ln.layer, found), store(ln.hitS, s);
  storeFlags(ln.hitMask, hit);
  // The next samples' records, requested now so that their loads overlap the other group's step
  // (a lane that hit keeps its sample: x, y stay its hit pixel).
  nextPixel(ln, tb);
  for (size_t j = 0; j < laneCount(); ++j) hwy::Prefetch(tb.slots + size_t(ln.pixel[j]) * bytes);
  return bits(andNot(live, move));
}

}  // namespace

void ssrMarchLanes(const IntervalLayers& depth, std::span<const SsrStart> starts, int maxSteps, int W, int H, std::span<SsrSample> out) {
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
    out[size_t(ln.ray[j])] = ln.hitMask[j] ? SsrSample{ln.x[j], ln.y[j], ln.layer[j], ln.hitS[j]} : SsrSample{};
  };
  // (after a refill: the new lanes' first samples, for the step's record loads)
  runLaneGroups(lanes, fill, [&](Lanes& ln) { return step(ln, tb); }, done, [&](Lanes& ln) { nextPixel(ln, tb); });
}

}  // namespace lt::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lt {

HWY_EXPORT(ssrMarchLanes);

bool ssrLanesAvailable(const IntervalLayers& depth) {
  // (the gathers index floats in int32: 2k floats per pixel)
  return depth.k >= 1 && depth.k <= 4 && uint64_t(depth.width) * uint64_t(depth.height) * uint64_t(2 * depth.k) < (uint64_t(1) << 31);
}

namespace {
/// The fallback: ssrMarch one start after the other.
void ssrMarchEach(const IntervalLayers& depth, std::span<const SsrStart> starts, int maxSteps, int W, int H, std::span<SsrSample> out) {
  NoCounters none;
  for (size_t i = 0; i < starts.size(); ++i) out[i] = ssrMarch(depth, starts[i], maxSteps, W, H, none);
}
}  // namespace

void ssrMarchBatch(const IntervalLayers& depth, std::span<const SsrStart> starts, int maxSteps, int W, int H,
                   std::span<SsrSample> out) {
  if (ssrLanesAvailable(depth)) return HWY_DYNAMIC_DISPATCH(ssrMarchLanes)(depth, starts, maxSteps, W, H, out);
  ssrMarchEach(depth, starts, maxSteps, W, H, out);
}

}  // namespace lt
#endif
