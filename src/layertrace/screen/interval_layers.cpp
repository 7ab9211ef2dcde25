#include "layertrace/screen/interval_layers.h"

#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

#include <algorithm>
#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace lt {

namespace {
constexpr float kInf = std::numeric_limits<float>::infinity();
}

IntervalLayers makeIntervalLayers(const LayerArrays& layers, int maxLayers) {
  IntervalLayers out;
  makeIntervalLayers(layers, maxLayers, out);
  return out;
}

namespace {

/// Pixel p: its first out.k intervals, then the {+∞, +∞} sentinel.
inline void writePixel(const LayerArrays& layers, size_t p, IntervalLayers& out) {
  const int n = std::min<int>(layers.count[p], out.k);
  out.count[p] = uint8_t(n);
  const FragmentNode* f = &layers.slots[p * size_t(layers.k)];
  Interval* s = &out.slots[p * size_t(out.k)];
  for (int i = 0; i < out.k; ++i) s[i] = i < n ? Interval{f[i].depth, f[i].back()} : Interval{kInf, kInf};
}

}  // namespace

void sizeIntervalLayers(int width, int height, int k, IntervalLayers& out) {
  out.width = width;
  out.height = height;
  out.k = k;
  const size_t pixels = size_t(width) * size_t(height);
  if (out.slots.size() != pixels * size_t(k)) checkAllocation("the interval layers", pixels * (size_t(k) * sizeof(Interval) + 1));
  out.slots.resize(pixels * size_t(k));
  out.count.resize(pixels);
}

void makeIntervalLayers(const LayerArrays& layers, int maxLayers, IntervalLayers& out) {
  sizeIntervalLayers(layers.width, layers.height, std::clamp(maxLayers, 1, layers.k), out);
  parallelFor(tbb::blocked_range<size_t>(0, out.count.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t p = r.begin(); p != r.end(); ++p) writePixel(layers, p, out);
  });
}

void writeIntervals(const LayerArrays& layers, int x0, int y0, int x1, int y1, IntervalLayers& out) {
  for (int y = y0; y <= y1; ++y)
    for (size_t p = layers.pixelIndex(x0, y), end = layers.pixelIndex(x1, y); p <= end; ++p) writePixel(layers, p, out);
}

}  // namespace lt
