#version 450
// The frame's counters summed on the device: each pixel slot's 16 tally words (gpu_effects.h
// GpuPixelTally) added over a work group in shared memory, then into 64-bit sums kept as
// (low, high) 32-bit words, the carry added where a low word wraps. The host reads 128 bytes
// instead of the per-pixel tally.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uItems;  // pixel slots
layout(std430, binding = 1) readonly buffer Tally { uint tally[]; };
layout(std430, binding = 6) buffer Sums { uint sums[32]; };

const uint kPixelTally = 16u + 65536u + 1u;  // effect_step.comp
shared uint partial[64][16];

void main() {
  const uint i = gl_GlobalInvocationID.x + uint(uFirst), lane = gl_LocalInvocationID.x;
  for (uint f = 0u; f < 16u; ++f) partial[lane][f] = i < uint(uItems) ? tally[kPixelTally + i * 16u + f] : 0u;
  barrier();
  // A work group's 64 pixel slots: each field summed by one invocation with its carries.
  if (lane < 16u) {
    uint lo = 0u, hi = 0u;
    for (uint j = 0u; j < 64u; ++j) {
      const uint v = partial[j][lane];
      const uint s = lo + v;
      hi += s < lo ? 1u : 0u;
      lo = s;
    }
    const uint old = atomicAdd(sums[2u * lane], lo);
    const uint carry = (old + lo < old ? 1u : 0u) + hi;
    if (carry > 0u) atomicAdd(sums[2u * lane + 1u], carry);
  }
}
