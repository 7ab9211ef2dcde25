// firstMet (interval_layers.h) in vector lanes: what a lane march asks of a pixel's stored
// intervals (ssr_march_lanes.cpp, hssr_march_lanes.cpp). Included per Highway target, like
// util/lanes-inl.h.
#if defined(LAYERTRACE_SCREEN_INTERVAL_LANES_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef LAYERTRACE_SCREEN_INTERVAL_LANES_INL_H_
#undef LAYERTRACE_SCREEN_INTERVAL_LANES_INL_H_
#else
#define LAYERTRACE_SCREEN_INTERVAL_LANES_INL_H_
#endif

#include <limits>

#include "layertrace/util/lanes-inl.h"

HWY_BEFORE_NAMESPACE();
namespace lt::HWY_NAMESPACE::lanes {

/// Per lane of `scan`, firstMet (screen/interval_layers.h) over the lane's k ≤ 4 intervals
/// (field[2i] = fronts of interval i, field[2i + 1] = backs; slots past a pixel's count are the
/// {+∞, +∞} sentinel) while the ray's depth covers [zmin, zmax]: the interval index, or −1. The
/// scalar rule's selects, so every lane answers bit for bit like firstMet: when depth grows the
/// first overlap in front order; when it shrinks the largest entry depth min(back, zmax), ties to
/// the later interval.
inline VI firstMetLanes(const VF field[8], int k, VF zmin, VF zmax, M scan, M increasing) {
  const VI none = splat(int32_t(-1)), zero = splat(int32_t(0));
  zmax = vmin(zmax, splat(std::numeric_limits<float>::max()));  // firstMet's finite far depth
  VI found = none;
  VF bestEntry = splat(0.0f);
  for (int i = 0; i < k; ++i) {
    const VF front = field[2 * i], back = field[2 * i + 1];
    scan = notGt(scan, front, zmax);  // sorted by front: nothing further can overlap (nor the sentinel)
    if (!any(scan)) break;            // no lane can still overlap
    const M overlap = notLt(scan, back, zmin);
    const M first = overlap & increasing;  // depth grows: the first overlap in front order
    found = sel(first, splat(int32_t(i)), found);
    scan = andNot(scan, first);
    const VF entry = vmin(zmax, back);  // depth shrinks: the largest entry depth (back < zmax ? back : zmax)
    const M later = andNot(overlap, increasing) & (lt(found, zero) | ge(entry, bestEntry));
    found = sel(later, splat(int32_t(i)), found);
    bestEntry = sel(later, entry, bestEntry);
  }
  return found;
}

}  // namespace lt::HWY_NAMESPACE::lanes
HWY_AFTER_NAMESPACE();

#endif  // per-target include guard
