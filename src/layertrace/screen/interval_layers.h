// Compact per-pixel depth intervals: what a screen-space tracer reads while it marches.
//
// The 16-byte fragments carry shading attributes a tracer only needs at the hit; marching reads
// depth intervals only. Like the camera-space depth texture of seed 001 (one float per pixel) or
// the two-float hierarchy levels of seed 000 (Figure 3, right), this keeps each visited pixel to
// 8·k bytes instead of 16·k, so SSR, SSR-layers and HSSR level 0 all stream the same data.
#pragma once

#include <cstdint>
#include <vector>

#include "layertrace/raster/layer_arrays.h"

namespace lt {

struct Interval {
  float front, back;
};

struct IntervalLayers {
  int width = 0, height = 0, k = 0;
  std::vector<Interval> slots;  ///< pixel-major, k per pixel, sorted by front
  std::vector<uint8_t> count;
  size_t pixelIndex(int x, int y) const { return size_t(y) * size_t(width) + size_t(x); }
  const Interval* pixel(int x, int y) const { return &slots[pixelIndex(x, y) * size_t(k)]; }
  int countAt(int x, int y) const { return count[pixelIndex(x, y)]; }
  size_t memoryBytes() const { return slots.size() * sizeof(Interval) + count.size(); }
};

/// The first `maxLayers` intervals of every pixel (all k when maxLayers >= k).
IntervalLayers makeIntervalLayers(const LayerArrays& layers, int maxLayers);

}  // namespace lt
