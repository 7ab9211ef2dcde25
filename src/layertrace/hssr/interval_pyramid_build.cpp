#include <algorithm>
#include <bit>
#include <chrono>
#include <limits>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/util/parallel.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/hssr/interval_pyramid_lanes.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"

namespace lt {

size_t IntervalPyramid::memoryBytes() const {
  size_t bytes = base ? base->memoryBytes() : 0;
  for (const PyramidLevel& l : levels)
    bytes += l.offset.size() * sizeof(uint32_t) + l.intervals.size() * sizeof(Interval) + l.cells.size() * sizeof(CoarseCell);
  for (const auto& row : scratchRows) bytes += row.capacity() * sizeof(Interval);  // kept for the next build
  for (const auto& row : scratchCounts) bytes += row.capacity() * sizeof(uint32_t);
  return bytes;
}

namespace {

/// The merge of Hofmann et al. 2017, §4.3, of the 2×2 children's intervals (sorted by front). A
/// parent interval starts at the front-most remaining child d_min and takes every child starting
/// within [d_min, d_min + τ(d_min)]; a child that is longer than τ or overlaps the running interval
/// extends it instead of being dropped or split (the merge must cover).
/// The result depends on the order of fronts only: children with equal fronts always end in the
/// same parent interval (the second is within τ of the first), so any sort gives the same bits.
void mergeChildren(Interval* children, size_t n, float tauPerDepth, std::vector<Interval>& out) {
  auto byFront = [](const Interval& a, const Interval& b) { return a.front < b.front; };
  if (n <= 32) {  // a level-1 cell has at most 4k children: insertion sort wins
    for (size_t i = 1; i < n; ++i) {
      const Interval c = children[i];
      size_t j = i;
      for (; j > 0 && c.front < children[j - 1].front; --j) children[j] = children[j - 1];
      children[j] = c;
    }
  } else {
    std::sort(children, children + n, byFront);
  }
  size_t i = 0;
  while (i < n) {
    Interval cur = children[i++];
    const float limit = cur.front + tauPerDepth * cur.front;
    while (i < n && (children[i].front <= limit || children[i].front <= cur.back)) {
      cur.back = std::max(cur.back, children[i].back);
      ++i;
    }
    out.push_back(cur);
  }
}

/// One cell's CSR intervals (sorted by front, disjoint) as a fixed-slot κ cell (CoarseCell).
CoarseCell toCoarseCell(const Interval* first, const Interval* last, std::vector<Interval>& scratch) {
  size_t n = size_t(last - first);
  if (n > size_t(CoarseCell::kSlots)) {  // rare (≤ 0.32 % of level-1 cells at τ = 25): merge in a copy
    scratch.assign(first, last);
    while (scratch.size() > size_t(CoarseCell::kSlots)) {
      // Merge the neighbours separated by the smallest gap: the union still covers both.
      size_t best = 0;
      for (size_t i = 1; i + 1 < scratch.size(); ++i)
        if (scratch[i + 1].front - scratch[i].back < scratch[best + 1].front - scratch[best].back) best = i;
      scratch[best].back = std::max(scratch[best].back, scratch[best + 1].back);
      scratch.erase(scratch.begin() + std::ptrdiff_t(best) + 1);
    }
    first = scratch.data(), n = scratch.size();
  }
  CoarseCell c;
  for (size_t i = 0; i < size_t(CoarseCell::kSlots); ++i) {
    // The same division the reference march made (paramAtDepth), so κ is bit-identical to it.
    c.kFront[i] = i < n ? 1.0f / first[i].front : -std::numeric_limits<float>::infinity();
    c.kBack[i] = i < n ? 1.0f / first[i].back : std::numeric_limits<float>::infinity();
  }
  return c;
}

void validate(const PyramidConfig& config) {
  if (config.levels < 1 || config.levels > 16) inputError("--levels ", config.levels, ": must be between 1 and 16");
  if (!(config.tau > 0.0f)) inputError("--tau ", config.tau, ": must be positive");
}

/// τ per unit depth for level L: the factor × the footprint of a 2^L-pixel cell
/// (Hofmann et al. 2017, §4.3).
float tauPerDepth(const Camera& camera, const PyramidConfig& config, int L) {
  return config.tau * camera.pixelFootprint(1.0f) * float(1 << L);
}

/// Sizes p.levels for config over p.base (levels[0] records level 0's size).
void sizeLevels(IntervalPyramid& p, const PyramidConfig& config) {
  LT_CHECK(p.base->k >= 1 && p.base->k <= 16, p.base->k);  // level 1 gathers ≤ 4 × 16 children on the stack
  p.levels.resize(size_t(config.levels));
  p.levels[0].width = p.base->width;
  p.levels[0].height = p.base->height;
  for (int L = 1; L < config.levels; ++L) {
    p.levels[size_t(L)].width = (p.levels[size_t(L - 1)].width + 1) / 2;
    p.levels[size_t(L)].height = (p.levels[size_t(L - 1)].height + 1) / 2;
  }
}

/// Gathers the intervals of cell (x, y)'s 2×2 children at level L into `small` (level 1: at
/// most 4k ≤ 64 from level 0, short copies, no library calls) or `children` (above: the child
/// level's CSR ranges, read through `childRange(cx, cy)` → [first, last)), then merges them.
///
/// Each child's intervals are sorted; they are gathered interleaved — every child's first, then
/// every child's second, … — not child after child. Neighbouring pixels mostly see the same
/// surfaces in the same order, so the interleaved sequence is nearly sorted and the insertion
/// sort's inner loop exits at its first compare, predictably (child after child, each child's
/// second interval had to move back past the others' first: a mispredicted exit per interval).
/// The merge does not depend on the order it receives (mergeChildren), so the bits are the same.
template <class ChildRange>
void mergeCell(const IntervalPyramid& p, int L, int x, int y, float tau, ChildRange&& childRange, std::vector<Interval>& children,
               std::vector<Interval>& out) {
  const PyramidLevel& child = p.levels[size_t(L - 1)];
  const Interval* first[4];
  size_t count[4], kids = 0, longest = 0;
  for (int cy = 2 * y; cy < std::min(2 * y + 2, child.height); ++cy)
    for (int cx = 2 * x; cx < std::min(2 * x + 2, child.width); ++cx) {
      if (L == 1) {
        first[kids] = p.base->pixel(cx, cy);
        count[kids] = size_t(p.base->countAt(cx, cy));
      } else {
        const auto [f, l] = childRange(cx, cy);
        first[kids] = f == l ? nullptr : &*f;
        count[kids] = size_t(l - f);
      }
      longest = std::max(longest, count[kids++]);
    }
  Interval small[4 * 16];
  Interval* gathered = small;
  if (L > 1) {
    size_t n = 0;
    for (size_t c = 0; c < kids; ++c) n += count[c];
    children.resize(n);
    gathered = children.data();
  }
  size_t n = 0;
  for (size_t i = 0; i < longest; ++i)
    for (size_t c = 0; c < kids; ++c)
      if (i < count[c]) gathered[n++] = first[c][i];
  mergeChildren(gathered, n, tau, out);
}

/// Checks the memory a level of `intervals` intervals needs before it grows.
void checkLevelMemory(const PyramidLevel& lvl, int L, size_t intervals) {
  if (intervals > 0xFFFFFFFFull) inputError("interval pyramid level ", L, ": ", intervals, " intervals exceed the 32-bit offsets");
  if (intervals > lvl.intervals.capacity() || size_t(lvl.width) * size_t(lvl.height) > lvl.cells.capacity())
    checkAllocation(cat("interval pyramid level ", L),
                    intervals * sizeof(Interval) + (size_t(lvl.width) * size_t(lvl.height) + 1) * (sizeof(uint32_t) + sizeof(CoarseCell)));
}

/// Level L ≥ 1 of p (sized by sizeLevels) from level L − 1, parallel over rows of cells.
void buildLevel(IntervalPyramid& p, const Camera& camera, const PyramidConfig& config, int L) {
  const PyramidLevel& child = p.levels[size_t(L - 1)];
  PyramidLevel& lvl = p.levels[size_t(L)];
  const float tau = tauPerDepth(camera, config, L);
  std::vector<std::vector<Interval>>& rows = p.scratchRows;
  std::vector<std::vector<uint32_t>>& rowCounts = p.scratchCounts;
  rows.resize(size_t(lvl.height));
  rowCounts.resize(size_t(lvl.height));
  auto childRange = [&](int cx, int cy) {
    const size_t c = child.cellIndex(cx, cy);
    return std::pair{child.intervals.begin() + child.offset[c], child.intervals.begin() + child.offset[c + 1]};
  };
  // Sixteen cells at a time in vector lanes where all their children exist and hold ≤ 4
  // intervals (interval_pyramid_lanes.h, the same bits); the other cells one at a time.
  const int laneCells = mergeLanesAvailable(p, L) ? child.width / 2 / 16 * 16 : 0;
  parallelFor(tbb::blocked_range<int>(0, lvl.height, 4), [&](const tbb::blocked_range<int>& r) {
    std::vector<Interval> children;
    for (int y = r.begin(); y != r.end(); ++y) {
      std::vector<Interval>& row = rows[size_t(y)];
      row.clear();
      row.reserve(size_t(lvl.width) * 2);
      rowCounts[size_t(y)].resize(size_t(lvl.width));
      const int lanes = 2 * y + 2 <= child.height ? laneCells : 0;
      for (int x0 = 0; x0 < lvl.width; x0 += 16) {
        if (x0 < lanes && mergeCellsLanes(p, L, x0, y, tau, row, &rowCounts[size_t(y)][size_t(x0)])) continue;
        for (int x = x0; x < std::min(x0 + 16, lvl.width); ++x) {
          const size_t before = row.size();
          mergeCell(p, L, x, y, tau, childRange, children, row);
          rowCounts[size_t(y)][size_t(x)] = uint32_t(row.size() - before);
        }
      }
    }
  });
  // Rows in order: a short serial scan over the rows' sizes, then each row — its intervals, its
  // cells' offsets and fixed-slot κ cells — in parallel (no serial pass over the cells).
  std::vector<size_t> rowStart(size_t(lvl.height) + 1, 0);
  for (int y = 0; y < lvl.height; ++y) rowStart[size_t(y) + 1] = rowStart[size_t(y)] + rows[size_t(y)].size();
  const size_t intervals = rowStart.back();
  checkLevelMemory(lvl, L, intervals);
  lvl.offset.resize(size_t(lvl.width) * size_t(lvl.height) + 1);
  lvl.offset.back() = uint32_t(intervals);
  lvl.intervals.resize(intervals);
  lvl.cells.resize(size_t(lvl.width) * size_t(lvl.height));
  parallelFor(0, lvl.height, [&](int y) {
    std::vector<Interval> scratch;  // toCoarseCell's, for the rare cell of more than kSlots intervals
    size_t at = rowStart[size_t(y)];
    std::copy(rows[size_t(y)].begin(), rows[size_t(y)].end(), lvl.intervals.begin() + std::ptrdiff_t(at));
    for (int x = 0; x < lvl.width; ++x) {
      const size_t c = lvl.cellIndex(x, y), n = rowCounts[size_t(y)][size_t(x)];
      lvl.offset[c] = uint32_t(at);
      lvl.cells[c] = toCoarseCell(lvl.intervals.data() + at, lvl.intervals.data() + at + n, scratch);
      at += n;
    }
  });
}

/// Levels 1..levels-1 over p.base (Hofmann et al. 2017, §4.3), into p's existing memory where it
/// fits.
void buildLevels(IntervalPyramid& p, const Camera& camera, const PyramidConfig& config) {
  sizeLevels(p, config);
  for (int L = 1; L < config.levels; ++L) buildLevel(p, camera, config, L);
}

}  // namespace

IntervalPyramid buildIntervalPyramid(const LayerArrays& layers, const Camera& camera, const PyramidConfig& config) {
  IntervalPyramid p;
  buildIntervalPyramid(layers, camera, config, p);
  return p;
}

void buildIntervalPyramid(const LayerArrays& layers, const Camera& camera, const PyramidConfig& config, IntervalPyramid& out) {
  validate(config);
  const auto start = std::chrono::steady_clock::now();
  if (!out.base || out.base.use_count() > 1) out.base = std::make_shared<IntervalLayers>();
  makeIntervalLayers(layers, layers.k, *out.base);  // with the sentinels
  buildLevels(out, camera, config);
  out.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void buildIntervalPyramid(std::shared_ptr<IntervalLayers> level0, const Camera& camera, const PyramidConfig& config,
                          IntervalPyramid& out) {
  validate(config);
  LT_CHECK(level0 != nullptr);
  const auto start = std::chrono::steady_clock::now();
  out.base = std::move(level0);
  buildLevels(out, camera, config);
  out.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void PyramidTileBuilder::begin(std::shared_ptr<IntervalLayers> level0, const Camera& camera, const PyramidConfig& config, int tileSize,
                               IntervalPyramid& out) {
  validate(config);
  LT_CHECK(level0 != nullptr && tileSize >= 1, tileSize);
  out_ = &out, camera_ = &camera, config_ = config, tileSize_ = tileSize;
  out.base = std::move(level0);
  sizeLevels(out, config);
  tileLevels_ = std::min(config.levels - 1, std::countr_zero(unsigned(tileSize)));
  tilesX_ = (out.base->width + tileSize - 1) / tileSize;
  tilesY_ = (out.base->height + tileSize - 1) / tileSize;
  const size_t tiles = size_t(tilesX_) * size_t(tilesY_);
  tileIntervals_.resize(tiles * size_t(tileLevels_));
  tileMs_.assign(tiles, 0.0);
  for (int L = 1; L <= tileLevels_; ++L) {
    PyramidLevel& lvl = out.levels[size_t(L)];
    const size_t cells = size_t(lvl.width) * size_t(lvl.height);
    checkLevelMemory(lvl, L, lvl.intervals.size());
    lvl.offset.resize(cells + 1);  // per-cell counts until finish() turns them into offsets
    lvl.cells.resize(cells);
  }
}

void PyramidTileBuilder::tile(int x0, int y0, int x1, int y1) {
  LT_CHECK(x0 % tileSize_ == 0 && y0 % tileSize_ == 0, x0, y0);
  const auto start = std::chrono::steady_clock::now();
  const IntervalPyramid& p = *out_;
  const size_t t = size_t(y0 / tileSize_) * size_t(tilesX_) + size_t(x0 / tileSize_);
  // Per level, the offset of each of the tile's cells in its tile storage (cell order within the
  // tile), so that the level above finds its children's intervals.
  thread_local std::vector<uint32_t> local[2];
  thread_local std::vector<Interval> children, scratch;
  static const std::vector<Interval> none;
  int childX0 = x0, childX1 = x1, childY0 = y0;
  for (int L = 1; L <= tileLevels_; ++L) {
    PyramidLevel& lvl = out_->levels[size_t(L)];
    const int cx0 = x0 >> L, cx1 = x1 >> L, cy0 = y0 >> L, cy1 = y1 >> L;
    const int childW = childX1 - childX0 + 1;
    const std::vector<Interval>& below = L > 1 ? tileIntervals_[t * size_t(tileLevels_) + size_t(L - 2)] : none;
    const std::vector<uint32_t>& belowOffset = local[(L + 1) & 1];
    std::vector<uint32_t>& offset = local[L & 1];
    std::vector<Interval>& mine = tileIntervals_[t * size_t(tileLevels_) + size_t(L - 1)];
    mine.clear();
    offset.clear();
    auto childRange = [&](int cx, int cy) {
      const size_t c = size_t(cy - childY0) * size_t(childW) + size_t(cx - childX0);
      return std::pair{below.begin() + belowOffset[c], below.begin() + belowOffset[c + 1]};
    };
    const float tau = tauPerDepth(*camera_, config_, L);
    for (int y = cy0; y <= cy1; ++y)
      for (int x = cx0; x <= cx1; ++x) {
        const size_t before = mine.size();
        offset.push_back(uint32_t(before));
        mergeCell(p, L, x, y, tau, childRange, children, mine);
        lvl.offset[lvl.cellIndex(x, y)] = uint32_t(mine.size() - before);
        lvl.cells[lvl.cellIndex(x, y)] = toCoarseCell(mine.data() + before, mine.data() + mine.size(), scratch);
      }
    offset.push_back(uint32_t(mine.size()));
    childX0 = cx0, childX1 = cx1, childY0 = cy0;
  }
  tileMs_[t] = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void PyramidTileBuilder::finish(int threads) {
  const auto start = std::chrono::steady_clock::now();
  IntervalPyramid& p = *out_;
  for (int L = 1; L <= tileLevels_; ++L) {
    PyramidLevel& lvl = p.levels[size_t(L)];
    // Counts → offsets in cell order (the CSR of the global build), in place.
    const size_t total = parallelExclusiveScan(lvl.offset.data(), lvl.offset.data(), lvl.offset.size() - 1, 0xFFFFFFFFull);
    checkLevelMemory(lvl, L, total);
    lvl.offset.back() = uint32_t(total);
    lvl.intervals.resize(total);
    // Each tile's intervals, already in cell order within the tile, to their cells' places.
    parallelFor(size_t(0), size_t(tilesX_) * size_t(tilesY_), [&](size_t t) {
      const int x0 = int(t % size_t(tilesX_)) * tileSize_, y0 = int(t / size_t(tilesX_)) * tileSize_;
      const int cx0 = x0 >> L, cy0 = y0 >> L;
      const int cx1 = (std::min(x0 + tileSize_, p.base->width) - 1) >> L, cy1 = (std::min(y0 + tileSize_, p.base->height) - 1) >> L;
      const Interval* from = tileIntervals_[t * size_t(tileLevels_) + size_t(L - 1)].data();
      for (int y = cy0; y <= cy1; ++y) {
        const size_t first = lvl.offset[lvl.cellIndex(cx0, y)], last = lvl.offset[lvl.cellIndex(cx1, y) + 1];
        std::copy(from, from + (last - first), lvl.intervals.begin() + std::ptrdiff_t(first));
        from += last - first;
      }
    });
  }
  for (int L = tileLevels_ + 1; L < config_.levels; ++L) buildLevel(p, *camera_, config_, L);
  double tilesMs = 0.0;
  for (double ms : tileMs_) tilesMs += ms;
  finishMs_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  p.buildMs = finishMs_ + tilesMs / std::max(1, threads);
  out_ = nullptr, camera_ = nullptr;  // the frame may move; begin() points them again
}

size_t PyramidTileBuilder::scratchBytes() const {
  size_t bytes = tileMs_.capacity() * sizeof(double);
  for (const auto& v : tileIntervals_) bytes += v.capacity() * sizeof(Interval);
  return bytes;
}

IntervalPyramid buildIntervalPyramid(IntervalLayers base, const Camera& camera, const PyramidConfig& config) {
  validate(config);
  const auto start = std::chrono::steady_clock::now();
  IntervalPyramid p;
  p.base = std::make_shared<IntervalLayers>(std::move(base));
  IntervalLayers& b = *p.base;
  // The march's sentinel: slots past a pixel's count hold {+∞, +∞} (interval_pyramid.h).
  parallelFor(tbb::blocked_range<size_t>(0, b.count.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    constexpr float inf = std::numeric_limits<float>::infinity();
    for (size_t px = r.begin(); px != r.end(); ++px)
      for (size_t i = b.count[px]; i < size_t(b.k); ++i) b.slots[px * size_t(b.k) + i] = {inf, inf};
  });
  buildLevels(p, camera, config);
  p.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return p;
}

}  // namespace lt
