// The march of McGuire and Mara 2014 (ssr_march.h) for a batch of segments, sixteen at a time
// in the lanes of AVX-512 registers (SIMD over the rays of a batch), as the HSSR march is
// (hssr_march_lanes.h). A lane whose ray ends takes the next ray of the batch.
//
// Same samples bit for bit as ssrMarch (tested): every lane runs ssrMarch's operations — the
// incremental P += dP and κ += dκ, the same division, std::min/max/clamp's select rules, no FMA
// (the project compiles with -ffp-contract=off).
#pragma once

#include <span>

#include "layertrace/ssr/ssr_march.h"

namespace lt {

/// Whether ssrMarchBatch runs in lanes over `depth` on this CPU: x86-64 with AVX-512
/// F/VL/BW/DQ, a GCC build, and k ≤ 4 (a pixel's intervals fit one 32-byte record). Otherwise
/// the batch runs ssrMarch one start after the other.
bool ssrLanesAvailable(const IntervalLayers& depth);

/// out[i] = ssrMarch(depth, starts[i], maxSteps, W, H) for every start; no counters.
void ssrMarchBatch(const IntervalLayers& depth, std::span<const SsrStart> starts, int maxSteps, int W, int H,
                   std::span<SsrSample> out);

}  // namespace lt
