#include "layertrace/raster/layer_arrays.h"

#include <algorithm>
#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

namespace lt {


namespace {

struct Entry {
  float depth;
  uint32_t node;
};

/// Hofmann et al. 2017, §4.2: insertion sort into k cells; fragments beyond the k-th are shifted
/// out.
int insertionSortK(const FragmentLists& lists, uint32_t head, int k, Entry* out) {
  int n = 0;
  for (uint32_t i = head; i != kNullIndex; i = lists.nodes[i].next) {
    const float d = lists.nodes[i].depth;
    if (n == k && !(d < out[k - 1].depth)) continue;
    int j = std::min(n, k - 1);
    while (j > 0 && d < out[j - 1].depth) {  // strict: equal depths keep list order
      out[j] = out[j - 1];
      --j;
    }
    out[j] = {d, i};
    n = std::min(n + 1, k);
  }
  return n;
}

/// The pixel's whole list sorted front to back (ties keep list order).
void collectSorted(const FragmentLists& lists, uint32_t head, std::vector<Entry>& all) {
  all.clear();
  for (uint32_t i = head; i != kNullIndex; i = lists.nodes[i].next) all.push_back({lists.nodes[i].depth, i});
  std::stable_sort(all.begin(), all.end(), [](const Entry& a, const Entry& b) { return a.depth < b.depth; });
}

/// Minimum separation: sort the whole list, then keep a fragment only if it lies at least
/// `sep` behind the previously kept one (McGuire & Mara; Hofmann et al. 2017, §4.2, note the risk).
int separatedK(const FragmentLists& lists, uint32_t head, int k, float sep, std::vector<Entry>& all, Entry* out) {
  collectSorted(lists, head, all);
  int n = 0;
  for (const Entry& e : all) {
    if (n == k) break;
    if (n > 0 && e.depth < out[n - 1].depth + sep) continue;
    out[n++] = e;
  }
  return n;
}

/// Adaptive thickness (Hofmann et al. 2017, §4.2): sort the whole list; a fragment whose front lies
/// within the previous kept interval extends that interval; otherwise it opens the next layer.
int adaptiveK(const FragmentLists& lists, uint32_t head, int k, const LayerConfig& config, std::vector<Entry>& all, Entry* out,
              float* backs) {
  collectSorted(lists, head, all);
  int n = 0;
  for (const Entry& e : all) {
    if (n > 0 && e.depth <= backs[n - 1]) {
      backs[n - 1] = std::max(backs[n - 1], e.depth + config.thicknessAt(e.depth));
      continue;
    }
    if (n == k) break;
    out[n] = e;
    backs[n++] = e.depth + config.thicknessAt(e.depth);
  }
  return n;
}

}  // namespace

void validateLayerConfig(const LayerConfig& config) {
  if (config.k < 1 || config.k > 16) inputError("--layers ", config.k, ": must be between 1 and 16");
  if (!(config.thickness >= 0.0f) || !std::isfinite(config.thickness))
    inputError("--thickness ", config.thickness, ": must be a positive number");
  if (!(config.thicknessPerDepth >= 0.0f) || !std::isfinite(config.thicknessPerDepth))
    inputError("--thickness-px: the thickness per unit depth ", config.thicknessPerDepth, " must be >= 0");
  if (!(config.thickness > 0.0f || config.thicknessPerDepth > 0.0f)) inputError("--thickness ", config.thickness, ": must be positive");
  if (!(config.minSeparation >= 0.0f)) inputError("--min-separation ", config.minSeparation, ": must be >= 0");
}

LayerArrays sortAndTruncate(const FragmentLists& lists, const LayerConfig& config) {
  validateLayerConfig(config);
  LayerArrays out;
  out.width = lists.width;
  out.height = lists.height;
  out.k = config.k;
  const size_t pixels = size_t(lists.width) * size_t(lists.height);
  LT_CHECK(lists.head.size() == pixels, lists.head.size(), pixels);  // lists of a tile-local capture hold no nodes
  checkAllocation(cat("the k-layer arrays (k = ", config.k, ")"), pixels * (size_t(config.k) * (sizeof(FragmentNode) + sizeof(uint32_t)) + 1));
  out.slots.resize(pixels * size_t(config.k));
  out.count.assign(pixels, 0);
  out.triangle.assign(pixels * size_t(config.k), kNullIndex);
  tbb::enumerable_thread_specific<std::vector<Entry>> scratch;
  parallelFor(tbb::blocked_range<size_t>(0, pixels, 1024), [&](const tbb::blocked_range<size_t>& r) {
    Entry kept[16];
    float backs[16];
    std::vector<Entry>& all = scratch.local();
    for (size_t p = r.begin(); p != r.end(); ++p) {
      const int n = config.adaptiveThickness   ? adaptiveK(lists, lists.head[p], config.k, config, all, kept, backs)
                    : config.minSeparation > 0 ? separatedK(lists, lists.head[p], config.k, config.minSeparation, all, kept)
                                               : insertionSortK(lists, lists.head[p], config.k, kept);
      out.count[p] = uint8_t(n);
      FragmentNode* slot = &out.slots[p * size_t(config.k)];
      for (int i = 0; i < n; ++i) {
        slot[i] = lists.nodes[kept[i].node];
        slot[i].setThickness(config.adaptiveThickness ? backs[i] - kept[i].depth : config.thicknessAt(kept[i].depth));
        out.triangle[p * size_t(config.k) + size_t(i)] = lists.triangle[kept[i].node];
      }
      for (int i = n; i < config.k; ++i) slot[i] = FragmentNode{0.0f, 0u, 0u, 0u};
    }
  });
  return out;
}

}  // namespace lt
