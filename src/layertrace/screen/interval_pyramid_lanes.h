// The interval pyramid's level-1 merge (seed 000 §4.3) for sixteen cells at once, in the lanes
// of AVX-512 registers: what most of a pyramid build's time went to (perf: level 1's gather,
// insertion sort and merge, 60 % of the build) done without a branch per interval.
#pragma once
#include <cstdint>
#include <vector>

#include "layertrace/screen/interval_layers.h"

namespace lt {

/// Whether mergeLevel1Lanes runs here: a GCC build on a CPU with AVX-512 F/VL/BW/DQ, and level 0
/// of k = 4 intervals per pixel (the default; other k take the one-cell merge).
bool level1LanesAvailable(int k);

/// Level-1 cells x0 … x0 + 15 of row y, each with all four children inside `base`
/// (2·x0 + 32 ≤ base.width, 2·y + 2 ≤ base.height, base.k = 4, every pixel's intervals sorted
/// by front with {+∞, +∞} past its count): appends the cells' merged intervals to `out` in cell
/// order and writes how many each cell has to counts[0 … 15]. The same intervals, bit for bit,
/// as merging each cell alone (interval_pyramid_build.cpp: sort the children by front, then
/// sweep with τ·d, a child that overlaps the running interval extending it).
void mergeLevel1Lanes(const IntervalLayers& base, int x0, int y, float tauPerDepth, std::vector<Interval>& out, uint32_t counts[16]);

}  // namespace lt
