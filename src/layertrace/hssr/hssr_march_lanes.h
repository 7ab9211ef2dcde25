// The HSSR march (hssr_march.h) for a batch of segments, one ray per vector lane (SIMD over the
// rays of a batch: 16 lanes with AVX-512, 8 with AVX2, 4 with SSE4 or NEON; Google Highway,
// util/lanes-inl.h, on the best target of the CPU). One ray's march is a chain of
// data-dependent loads and branches that a CPU runs one cell at a time; the lanes' cells
// are independent, so their loads overlap and the branches become lane masks. A lane whose ray
// ends takes the next ray of the batch (lane refill), so the lanes stay busy however unequal
// the rays' lengths. Measured on this project's real views: the march 1.3–1.4× faster than one
// ray at a time (bench_trace BM_HssrLanes; docs/results.md has the steps).
//
// Same answers bit for bit as hssrMarch on every segment (tested on the default scene and the
// real scenes for 1, 3, 5 and 8 levels): every lane runs hssrMarch's own operations — the same
// float expressions in the same order, std::min/max/clamp's select rules, no FMA (the project
// compiles with -ffp-contract=off), axis-parallel lines through a substitution that gives the
// flat axis's crossings the values of hssrMarch's flat-axis branches (start()) — and
// the rare cases the lanes leave out run hssrMarch itself: single-pixel lines, and a descent
// whose rounding left s outside every child.
#pragma once

#include <cstdint>
#include <span>

#include "layertrace/hssr/hssr_march.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// hssrMarch's counters reduced to the cells it tests (c.iteration() calls): what
/// hssrMarchBatch's `cells` reports per ray.
struct MarchCellCount : NoCounters {
  uint32_t cells = 0;
  void iteration(int = 0) { ++cells; }
};

/// Whether hssrMarchBatch runs in lanes for this pyramid: k ≤ 4 (a pixel's intervals are one
/// 32-byte record, like a coarse cell), at most 8 levels, a view narrower and lower than 2^22
/// pixels (for the axis-parallel lines' substitution; views are at most 32768) and fewer than
/// 2^29 pixels (record offsets in int32 lanes). Otherwise the batch runs hssrMarchEach.
bool hssrLanesAvailable(const IntervalPyramid& pyramid, int levels);

/// out[i] = hssrMarch(pyramid, levels, rule, segs[i], W, H) for every valid segment, {} for an
/// invalid one; no counters (uncounted batches only). With `cells` (as long as `segs`), also
/// cells[i] = the cells the march that answered segs[i] tested: hssrMarch's c.iteration() count
/// where it runs the ray (one ray at a time, or a case the lanes hand over, above), else the
/// lane's steps — the same number when the lanes follow hssrMarch's traversal. Answers do not depend on the traversal, so only this lets the tests hold the lanes to
/// hssrMarch's traversal (its ascent and descent rules) and not only to its hits.
void hssrMarchBatch(const IntervalPyramid& pyramid, int levels, AscentRule rule, std::span<const ScreenSegment> segs, int W, int H,
                    std::span<MarchHit> out, std::span<uint32_t> cells = {});

/// The same, one segment after the other (compiled for each vector target and dispatched like
/// the lanes): the fallback, and the reference bench_trace measures the lanes against.
void hssrMarchEach(const IntervalPyramid& pyramid, int levels, AscentRule rule, std::span<const ScreenSegment> segs, int W, int H,
                   std::span<MarchHit> out, std::span<uint32_t> cells = {});

}  // namespace lt
