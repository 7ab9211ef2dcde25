// Compact per-pixel depth intervals: what a screen-space tracer reads while it marches.
//
// The 16-byte fragments carry shading attributes a tracer only needs at the hit; marching reads
// depth intervals only. Like the camera-space depth texture of McGuire and Mara 2014 (one float per
// pixel) or the two-float hierarchy levels of Hofmann et al. 2017 (Figure 3, right), this keeps
// each visited pixel to 8·k bytes instead of 16·k, so SSR, SSR-layers and HSSR level 0 all stream
// the same data.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <vector>

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/util/default_init.h"

namespace lt {

struct Interval {
  float front, back;
};

struct IntervalLayers {
  int width = 0, height = 0, k = 0;
  PoolVector<Interval> slots;  ///< pixel-major, k per pixel, sorted by front
  std::vector<uint8_t> count;
  size_t pixelIndex(int x, int y) const { return size_t(y) * size_t(width) + size_t(x); }
  const Interval* pixel(int x, int y) const { return &slots[pixelIndex(x, y) * size_t(k)]; }
  int countAt(int x, int y) const { return count[pixelIndex(x, y)]; }
  size_t memoryBytes() const { return slots.size() * sizeof(Interval) + count.size(); }
};

/// The stored interval a ray meets first while its depth covers [zmin, zmax] in one pixel, or
/// -1 (`f` sorted by front, `n` intervals). When depth grows the ray enters at its smallest
/// depth, so the first overlapping interval in front order is met first (ties: the front-most
/// layer); when depth shrinks it enters at zmax, and meets first the interval with the largest
/// entry depth min(back, zmax) (ties: the back-most layer). The independent oracle
/// (eval/image_oracle.h) states the same rule in 3D.
/// zmax is taken as at most the largest finite float: a very long ray's far depth can round to
/// +∞ (1/k with k − k₀ cancelling to 0), and must still stop at the empty slots' {+∞, +∞}
/// sentinel, as a scan over the pixel's count alone does.
template <class C>
int firstMet(const Interval* f, int n, float zmin, float zmax, bool increasing, C& counters) {
  zmax = std::min(zmax, std::numeric_limits<float>::max());
  int best = -1;
  float bestEntry = 0.0f;
  for (int i = 0; i < n; ++i) {
    counters.interval();
    counters.fragment();
    if (f[i].front > zmax) break;  // sorted by front: nothing further can overlap
    if (f[i].back < zmin) continue;
    if (increasing) return i;
    const float entry = f[i].back < zmax ? f[i].back : zmax;
    if (best < 0 || entry >= bestEntry) best = i, bestEntry = entry;
  }
  return best;
}

/// The first `maxLayers` intervals of every pixel (all k when maxLayers >= k); slots past a
/// pixel's count hold {+∞, +∞} (the sentinel the HSSR march stops at, interval_pyramid.h).
IntervalLayers makeIntervalLayers(const LayerArrays& layers, int maxLayers);
/// The same into `out`, reusing its memory (no allocation when the size is unchanged).
void makeIntervalLayers(const LayerArrays& layers, int maxLayers, IntervalLayers& out);
/// Sizes `out` for width × height pixels of k intervals (checking the memory first when it
/// grows); reuses its memory when the size is unchanged. Contents are left to writeIntervals.
void sizeIntervalLayers(int width, int height, int k, IntervalLayers& out);
/// The pixels [x0, x1] × [y0, y1] (inclusive) of an `out` already sized for all k layers: the
/// capture writes level 0 so, tile by tile, while the tile's layers are in cache.
void writeIntervals(const LayerArrays& layers, int x0, int y0, int x1, int y1, IntervalLayers& out);

}  // namespace lt
