#version 450
// An exclusive prefix sum over n counts, in place, with the total written at [n]: one work
// group, each invocation summing a contiguous run, then a scan of the runs' sums in shared
// memory. It turns the interval counts of a pyramid level's cells into the CSR offsets.
layout(local_size_x = 1024) in;
layout(std430, binding = 4) buffer Offset { uint offsets[]; };
// A resident build (gpu_pyramid.h buildPyramidResident) also keeps the total in status[slot],
// for the frame's end to read with its other counters.
layout(std430, binding = 7) writeonly buffer Status { uint status[]; };
uniform int uCount;
uniform int uStatusSlot;  // −1: none
shared uint sums[1024];

void main() {
  const uint t = gl_LocalInvocationID.x, n = uint(uCount);
  const uint run = (n + 1023u) / 1024u, begin = min(t * run, n), end = min(begin + run, n);
  uint sum = 0u;
  for (uint i = begin; i < end; ++i) sum += offsets[i];
  sums[t] = sum;
  barrier();
  // Hillis–Steele inclusive scan of the 1024 run sums.
  for (uint d = 1u; d < 1024u; d <<= 1u) {
    const uint add = t >= d ? sums[t - d] : 0u;
    barrier();
    sums[t] += add;
    barrier();
  }
  uint at = t == 0u ? 0u : sums[t - 1u];
  for (uint i = begin; i < end; ++i) {
    const uint c = offsets[i];
    offsets[i] = at;
    at += c;
  }
  if (t == 1023u) {
    offsets[n] = sums[1023];
    if (uStatusSlot >= 0) status[uStatusSlot] = sums[1023];
  }
}
