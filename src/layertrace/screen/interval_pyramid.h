// The interval resolution pyramid of seed 000 §4.3 (Figure 3 right, Figure 4).
//
// Level 0 is the k-layer arrays as compact intervals [depth, depth + thickness] (IntervalLayers).
// Level L ≥ 1 has ceil(W / 2^L) × ceil(H / 2^L) cells; each holds the intervals of its 2×2
// children merged front to back while they stay within τ, as two floats per interval.
// Invariant (checked by tests on every level of real scenes): every child interval lies inside
// one interval of its parent cell — the hierarchy never hides geometry (hssr-pitfalls §3).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/screen/interval_layers.h"

namespace lt {

struct PyramidConfig {
  int levels = 5;        ///< levels including level 0 (seed 000 Figure 9: "5 levels")
  /// τ as a multiple of the projected pixel footprint at the interval's start depth, for a
  /// level-L cell 2^L pixels wide (seed 000 §4.3: "25 times the projected pixel-footprint").
  float tau = 25.0f;
};

/// A coarse cell in the form the march reads (hssr_march.h): its intervals as inverse depths
/// κ = 1/z, at most kSlots of them in one half cache line, sorted front to back (κFront
/// descending), unused slots κFront = −∞ (a sentinel the march's early exit stops at, so no
/// count is read). With the ray's κ linear in the screen parameter (screen_segment.h) the march
/// tests a cell and finds where it enters an interval without a division. A cell whose CSR list
/// holds more than kSlots intervals merges the two separated by the smallest depth gap until
/// kSlots remain (choice: a fixed size removes the dependent offset load; merging only widens
/// intervals, so the cell still covers its children — hssr-pitfalls §3 — and answers cannot
/// change; on the real views at 1280×720, τ = 25: 0.01–0.32 % of level-1 cells, ≤ 0.13 % above).
struct alignas(32) CoarseCell {
  static constexpr int kSlots = 4;
  float kFront[kSlots];  ///< 1 / front depth (the larger κ)
  float kBack[kSlots];   ///< 1 / back depth (0 for an interval that reaches ∞)
};

struct PyramidLevel {
  int width = 0, height = 0;
  std::vector<uint32_t> offset;  ///< per cell: first interval; offset[cells] = total
  std::vector<Interval> intervals;
  PoolVector<CoarseCell> cells;  ///< the same intervals as fixed-slot κ cells (levels ≥ 1)
  size_t cellIndex(int x, int y) const { return size_t(y) * size_t(width) + size_t(x); }
};

struct IntervalPyramid {
  /// level 0: k intervals per pixel; slots past a pixel's count hold {+∞, +∞}, a sentinel that
  /// ends firstMet's scan, so the march reads no count. Shared: the capture writes level 0 while
  /// each tile is in cache (pipeline/frame.h), and every pyramid built for that frame uses it.
  std::shared_ptr<IntervalLayers> base;
  std::vector<PyramidLevel> levels;  ///< levels[0] only records the size: level 0 is `base`
  int levelCount() const { return int(levels.size()); }
  size_t memoryBytes() const;
  double buildMs = 0.0;
  /// Build scratch (merged intervals and counts per row of cells), kept so that a rebuild of
  /// the same size writes into memory it already has.
  std::vector<std::vector<Interval>> scratchRows;
  std::vector<std::vector<uint32_t>> scratchCounts;
};

/// Builds levels 1..levels-1 (parallel over rows of cells).
IntervalPyramid buildIntervalPyramid(const LayerArrays& layers, const Camera& camera, const PyramidConfig& config);
/// The same into `out`, reusing its memory: the next frame's pyramid of the same size allocates
/// nothing and pays no first-touch page faults (issue 13 §4; they were half of a cold build).
/// Level 0 is rewritten in place unless another owner shares it (then a new one is made).
void buildIntervalPyramid(const LayerArrays& layers, const Camera& camera, const PyramidConfig& config, IntervalPyramid& out);
/// Levels 1..levels-1 over a level 0 that already exists — with the {+∞, +∞} sentinels, as
/// makeIntervalLayers and the capture write it — shared, not copied; into `out`'s memory.
void buildIntervalPyramid(std::shared_ptr<IntervalLayers> level0, const Camera& camera, const PyramidConfig& config,
                          IntervalPyramid& out);
/// The same over level-0 intervals that need not come from fragments (known_space.h).
IntervalPyramid buildIntervalPyramid(IntervalLayers base, const Camera& camera, const PyramidConfig& config);

}  // namespace lt
