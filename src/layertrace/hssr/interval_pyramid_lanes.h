// The interval pyramid's merge (Hofmann et al. 2017, §4.3) for sixteen cells per call, one cell per
// vector lane (Google Highway, util/lanes-inl.h, on the best target of the CPU): what most of a
// pyramid build's time went to (perf: level 1's gather, insertion sort and merge, 60 % of the
// build) done without a branch per interval.
#pragma once
#include <cstdint>
#include <vector>

#include "layertrace/screen/interval_layers.h"

namespace lt {

struct IntervalPyramid;

/// Whether mergeCellsLanes runs for level L of p: level 1 when level 0 holds k = 4 intervals per
/// pixel (the default; other k take the one-cell merge), any level above.
bool mergeLanesAvailable(const IntervalPyramid& p, int L);

/// Cells x0 … x0 + 15 of row y of level L ≥ 1 of p (level L − 1 built), each with all four
/// children inside level L − 1 (2·x0 + 32 ≤ its width, 2·y + 2 ≤ its height): appends the cells'
/// merged intervals to `out` in cell order, writes how many each cell has to counts[0 … 15] and
/// returns true — or returns false, having done nothing, when a child cell (L ≥ 2) holds more
/// than four intervals. The same intervals, bit for bit, as merging each cell alone
/// (interval_pyramid_build.cpp: sort the children by front, then sweep with τ·d, a child that
/// overlaps the running interval extending it). Level 0's pixels must be sorted by front with
/// {+∞, +∞} past their count, as every IntervalLayers the pyramid is built over is.
bool mergeCellsLanes(const IntervalPyramid& p, int L, int x0, int y, float tauPerDepth, std::vector<Interval>& out, uint32_t counts[16]);

}  // namespace lt
