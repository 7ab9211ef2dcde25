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

void makeIntervalLayers(const LayerArrays& layers, int maxLayers, IntervalLayers& out) {
  out.width = layers.width;
  out.height = layers.height;
  out.k = std::clamp(maxLayers, 1, layers.k);
  const size_t pixels = size_t(layers.width) * size_t(layers.height);
  if (out.slots.size() != pixels * size_t(out.k)) checkAllocation("the interval layers", pixels * (size_t(out.k) * sizeof(Interval) + 1));
  out.slots.resize(pixels * size_t(out.k));
  out.count.resize(pixels);
  parallelFor(tbb::blocked_range<size_t>(0, pixels, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t p = r.begin(); p != r.end(); ++p) {
      const int n = std::min<int>(layers.count[p], out.k);
      out.count[p] = uint8_t(n);
      const FragmentNode* f = &layers.slots[p * size_t(layers.k)];
      Interval* s = &out.slots[p * size_t(out.k)];
      for (int i = 0; i < out.k; ++i) s[i] = i < n ? Interval{f[i].depth, f[i].back()} : Interval{kInf, kInf};
    }
  });
}

}  // namespace lt
