// The interval resolution pyramid of Hofmann et al. 2017, §4.3 (Figure 3 right, Figure 4).
//
// Level 0 is the k-layer arrays as compact intervals [depth, depth + thickness] (IntervalLayers).
// Level L ≥ 1 has ceil(W / 2^L) × ceil(H / 2^L) cells; each holds the intervals of its 2×2
// children merged front to back while they stay within τ, as two floats per interval.
// Invariant (checked by tests on every level of real scenes): every child interval lies inside
// one interval of its parent cell — the hierarchy never hides geometry.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/screen/interval_layers.h"

namespace lt {

struct PyramidConfig {
  /// Levels including level 0. Hofmann et al. 2017 use levels 0 to 5 (Figures 9 and 13: six with
  /// the base; hssr_method.cpp gives the reading); answers are the same for
  /// any count (the pyramid only accelerates, §4.3), and on this CPU 7 march faster — top cells
  /// 64 px wide take a long ray across the screen in fewer steps (measured with bench_trace
  /// BM_HssrLanes: 1.11× FZK-Haus, 1.06× am_thornish against 5 levels; 6 and 8 no better than 7).
  int levels = 7;
  /// τ as a multiple of the projected pixel footprint at the interval's start depth, for a
  /// level-L cell 2^L pixels wide. Hofmann et al. 2017, §4.3, use 25 ("25 times the projected
  /// pixel-footprint"); answers are the same for any τ (tested for 1–128). Choice: 4. A smaller τ
  /// leaves fewer gaps filled, so fewer false descents — with the lanes and 7 levels the steps
  /// per one-bounce reflection ray fall from 26.4 to 24.6 on FZK-Haus and 29.4 to 24.3 on
  /// am_thornish (`bench --experiment tau`: within 1 % of τ = 1's count), and HSSR's time
  /// against plain Embree in `compare` (5 runs each) goes 0.97 → 1.07× on FZK-Haus,
  /// 0.98 → 1.10× on am_thornish, 1.66 → 1.67× on engine; below 4 nothing more is gained,
  /// while the cells hold more intervals (FZK-Haus level 1: 514 k at 25, 713 k at 4, 728 k at 1).
  float tau = 4.0f;
  bool operator==(const PyramidConfig&) const = default;
};

/// A coarse cell in the form the march reads (hssr_march.h): its intervals as inverse depths
/// κ = 1/z, at most kSlots of them in one half cache line, sorted front to back (κFront
/// descending), unused slots κFront = −∞ (a sentinel the march's early exit stops at, so no
/// count is read). With the ray's κ linear in the screen parameter (screen_segment.h) the march
/// tests a cell and finds where it enters an interval without a division. A cell whose CSR list
/// holds more than kSlots intervals merges the two separated by the smallest depth gap until
/// kSlots remain (choice: a fixed size removes the dependent offset load; merging only widens
/// intervals, so the cell still covers its children — and answers cannot
/// change; on the real views at 1280×720, τ = 25: 0.01–0.32 % of level-1 cells, ≤ 0.13 % above;
/// more at the default τ = 4, which merges less before the slots run out).
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
/// nothing and pays no first-touch page faults (they were half of a cold build).
/// Level 0 is rewritten in place unless another owner shares it (then a new one is made).
void buildIntervalPyramid(const LayerArrays& layers, const Camera& camera, const PyramidConfig& config, IntervalPyramid& out);
/// Levels 1..levels-1 over a level 0 that already exists — with the {+∞, +∞} sentinels, as
/// makeIntervalLayers and the capture write it — shared, not copied; into `out`'s memory.
void buildIntervalPyramid(std::shared_ptr<IntervalLayers> level0, const Camera& camera, const PyramidConfig& config,
                          IntervalPyramid& out);
/// Levels 1… built tile by tile by the tile-local capture: a capture tile of T pixels, T a
/// multiple of 2^L, holds whole cells of level L, so as soon as a tile's level 0 is written its
/// cells of levels 1..tileLevels() are merged while its pixels are still in cache. Each tile
/// keeps its intervals in its own storage (no shared counter); finish() lays them out in cell
/// order — the CSR `offset`/`intervals` of the global build — and builds any level above
/// tileLevels() the global way. The result is bit-identical to buildIntervalPyramid over the same
/// level 0 (the same children in the same order through the same merge; tested). The object
/// keeps its per-tile storage: the next frame of the same size allocates nothing.
class PyramidTileBuilder {
 public:
  /// Sizes `out` over `level0` (which the tiles will fill) for tiles of `tileSize` pixels whose
  /// origins are multiples of it. `out` must outlive finish().
  void begin(std::shared_ptr<IntervalLayers> level0, const Camera& camera, const PyramidConfig& config, int tileSize,
             IntervalPyramid& out);
  /// Levels built per tile: min(levels − 1, log2 of the largest power of two dividing tileSize).
  int tileLevels() const { return tileLevels_; }
  /// The cells of levels 1..tileLevels() over the pixels [x0, x1] × [y0, y1] (inclusive; one
  /// tile of begin's grid, whose level 0 is final). Concurrent calls for different tiles are safe.
  void tile(int x0, int y0, int x1, int y1);
  /// Lays out the tile-built levels in cell order and builds the levels above; sets buildMs to
  /// the time of this call plus the tiles' merge time divided by `threads`.
  void finish(int threads);
  /// Bytes of per-tile storage kept between frames.
  size_t scratchBytes() const;
  /// The wall time of the last finish() (the rest of buildMs is the tiles' share).
  double finishMs() const { return finishMs_; }

 private:
  IntervalPyramid* out_ = nullptr;
  const Camera* camera_ = nullptr;
  PyramidConfig config_;
  int tileSize_ = 0, tilesX_ = 0, tilesY_ = 0, tileLevels_ = 0;
  std::vector<std::vector<Interval>> tileIntervals_;  ///< [tile × tileLevels + L − 1], cell order within the tile
  std::vector<double> tileMs_;                        ///< per tile: time of its merges
  double finishMs_ = 0.0;
};

/// The same over level-0 intervals that need not come from fragments (known_space.h).
IntervalPyramid buildIntervalPyramid(IntervalLayers base, const Camera& camera, const PyramidConfig& config);

}  // namespace lt
