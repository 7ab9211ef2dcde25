// The march of McGuire and Mara 2014 (ssr_march.h) for a batch of segments, one ray per vector
// lane (SIMD over the rays of a batch: 16 with AVX-512, 8 with AVX2, 4 with SSE4 or NEON), as the
// HSSR march is (hssr_march_lanes.h). A lane whose ray ends takes the next ray of the batch.
//
// Same samples bit for bit as ssrMarch (tested): every lane runs ssrMarch's operations — the
// incremental P += dP and κ += dκ, the same division, std::min/max/clamp's select rules, no FMA
// (the project compiles with -ffp-contract=off).
#pragma once

#include <span>

#include "layertrace/ssr/ssr_march.h"

namespace lt {

/// Whether ssrMarchBatch runs in lanes over `depth`: k ≤ 4 (a pixel's intervals fit one 32-byte
/// record) and fewer than 2^31 floats of intervals. Otherwise the batch runs ssrMarch one start
/// after the other. The lanes run on the best vector target of this CPU (util/simd_targets.h).
bool ssrLanesAvailable(const IntervalLayers& depth);

/// out[i] = ssrMarch(depth, starts[i], maxSteps, W, H) for every start; no counters.
void ssrMarchBatch(const IntervalLayers& depth, std::span<const SsrStart> starts, int maxSteps, int W, int H,
                   std::span<SsrSample> out);

}  // namespace lt
