#version 450
// The quad-tree's depth scale (src/layertrace/quadtree/quadtree_build.cpp defaultDepthScale):
// the median front-layer depth of every stride-th pixel, found by a radix select over the
// depths' bits in one work group (four passes of 8 bits; non-negative floats order as their
// bits), then the scale at which λ_h = 10⁻³ is the w slope of a surface seen at 85°. The
// median is the element std::nth_element puts at n / 2: the same value.
layout(local_size_x = 256) in;
// Each slot's depth, k per pixel: the CPU's layers uploaded, or (LT_LEVEL0) a resident frame's
// level 0, whose intervals begin at the depth (gpu/gpu_frame.h).
#ifdef LT_LEVEL0
layout(std430, binding = 0) readonly buffer Level0 { vec2 level0[]; };
float depthOf(uint slot) { return level0[slot].x; }
#else
layout(std430, binding = 0) readonly buffer Depths { float depths[]; };
float depthOf(uint slot) { return depths[slot]; }
#endif
layout(std430, binding = 1) readonly buffer Counts { uint counts[]; };
layout(std430, binding = 3) writeonly buffer Scale { float depthScale; };
uniform int uPixels, uStride, uK;
uniform float uFocal, uGrazing;
uniform float uFixedScale;  // > 0: the configured scale, taken as it is
shared uint sHistogram[256];
shared uint sCount, sRank, sPrefix;

// A float's bits as a uint that orders as the float (negative values below the positive).
uint orderedBits(float f) {
  const uint b = floatBitsToUint(f);
  return (b & 0x80000000u) != 0u ? ~b : b | 0x80000000u;
}
float fromOrderedBits(uint u) {
  return uintBitsToFloat((u & 0x80000000u) != 0u ? u & 0x7fffffffu : ~u);
}

void main() {
  const uint t = gl_LocalInvocationID.x;
  if (uFixedScale > 0.0) {
    if (t == 0u) depthScale = uFixedScale;
    return;
  }
  const uint samples = (uint(uPixels) + uint(uStride) - 1u) / uint(uStride);
  if (t == 0u) sCount = 0u, sPrefix = 0u;
  barrier();
  uint mine = 0u;
  for (uint i = t; i < samples; i += 256u) mine += counts[i * uint(uStride)] > 0u ? 1u : 0u;
  atomicAdd(sCount, mine);
  barrier();
  if (sCount == 0u) {  // no pixel holds a surface (the same value in every invocation)
    if (t == 0u) depthScale = 1.0;
    return;
  }
  if (t == 0u) sRank = sCount / 2u;
  for (int pass = 0; pass < 4; ++pass) {
    const int shift = 24 - 8 * pass;
    const uint high = pass == 0 ? 0u : ~0u << uint(shift + 8);  // the bits already chosen
    sHistogram[t] = 0u;
    barrier();
    for (uint i = t; i < samples; i += 256u) {
      const uint p = i * uint(uStride);
      if (counts[p] == 0u) continue;
      const uint bits = orderedBits(depthOf(p * uint(uK)));
      if ((bits & high) == sPrefix) atomicAdd(sHistogram[(bits >> uint(shift)) & 255u], 1u);
    }
    barrier();
    if (t == 0u) {
      uint below = 0u, bin = 0u;
      while (bin < 255u && below + sHistogram[bin] <= sRank) below += sHistogram[bin++];
      sRank -= below;
      sPrefix |= bin << uint(shift);
    }
    barrier();
  }
  if (t != 0u) return;
  const float mid = fromOrderedBits(sPrefix);
  precise float s = 1e-3 * mid * uFocal / uGrazing;
  depthScale = mid > 0.0 ? s : 1.0;
}
