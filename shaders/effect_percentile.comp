#version 450
// The 99th percentile of the iterations per ray (stats key rays.iterations_p99), on the device:
// the smallest iteration count whose cumulative number of rays reaches 0.99 × the rays, over the
// histogram effect_step.comp kept — render/effects.cpp percentile99, with the same
// double-precision test. One work group: each invocation sums a chunk of 257 bins, then the first
// finds the chunk and the bin (no invocation loops over all 65537 bins).
layout(local_size_x = 256) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
layout(std430, binding = 1) readonly buffer Tally { uint tally[]; };
layout(std430, binding = 6) buffer Sums { uint sums[34]; };  // [0, 32): the 64-bit sums; [32]: the percentile

const uint kHistogramFirst = 16u, kBins = 65537u;  // effect_step.comp
const uint kChunk = (kBins + 255u) / 256u;
shared double chunkRays[256];

void main() {
  const uint lane = gl_LocalInvocationID.x;
  double s = 0.0;
  const uint first = lane * kChunk, last = min(kBins, first + kChunk);
  for (uint b = first; b < last; ++b) s += double(tally[kHistogramFirst + b]);
  chunkRays[lane] = s;
  barrier();
  if (lane != 0u) return;
  const double rays = double(sums[1]) * 4294967296.0 + double(sums[0]);
  const double threshold = 0.99 * rays;
  uint answer = 0u;
  double seen = 0.0;
  if (rays > 0.0) {
    uint c = 0u;
    while (c < 255u && seen + chunkRays[c] < threshold) seen += chunkRays[c++];
    for (uint b = c * kChunk; b < min(kBins, (c + 1u) * kChunk); ++b) {
      seen += double(tally[kHistogramFirst + b]);
      if (seen >= threshold) {
        answer = b;
        break;
      }
    }
  }
  sums[32] = answer;
}
