#version 450
// A resident frame's layer arrays in the two forms its passes read (gpu/gpu_frame.h), from the
// capture's sorted slots on the device: the march's level 0 (hssr/interval_pyramid.h: per slot
// [depth, depth + thickness], {+∞, +∞} past the pixel's count; screen/interval_layers.cpp
// writePixel) and the effect passes' fragments (effect_common.glsl: depth bits, normal, albedo
// and specular, scene triangle; kEmptySlot past the count), as the host builds them elsewhere.
// It also reduces the depth complexity's maximum (stats key fragments.depth_complexity_max) and
// the number of kept fragments (level 0's intervals, hssr.intervals_per_level), so that no
// per-pixel buffer needs to leave the device: a work group's in shared memory, then one atomic
// each per group.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uPixels, uK;
layout(std430, binding = 0) readonly buffer Slots { uvec4 slots[]; };
layout(std430, binding = 1) readonly buffer Counts { uint counts[]; };
layout(std430, binding = 2) readonly buffer SlotTriangle { uint slotTriangle[]; };
layout(std430, binding = 3) writeonly buffer Level0 { vec2 level0[]; };
layout(std430, binding = 4) writeonly buffer Fragments { uvec4 fragments[]; };
layout(std430, binding = 5) readonly buffer Complexity { uint complexity[]; };
layout(std430, binding = 6) buffer Reduced { uint maxComplexity, keptFragments; };
shared uint groupMax[64], groupKept[64];

#define kInf uintBitsToFloat(0x7f800000u)

void main() {
  const uint p = gl_GlobalInvocationID.x + uint(uFirst), lane = gl_LocalInvocationID.x;
  groupMax[lane] = p < uint(uPixels) ? complexity[p] : 0u;
  groupKept[lane] = p < uint(uPixels) ? min(counts[p], uint(uK)) : 0u;
  barrier();
  for (uint stride = 32u; stride > 0u; stride >>= 1) {
    if (lane < stride) {
      groupMax[lane] = max(groupMax[lane], groupMax[lane + stride]);
      groupKept[lane] += groupKept[lane + stride];
    }
    barrier();
  }
  if (lane == 0u && groupMax[0] > 0u) atomicMax(maxComplexity, groupMax[0]);
  if (lane == 0u && groupKept[0] > 0u) atomicAdd(keptFragments, groupKept[0]);
  if (p >= uint(uPixels)) return;
  const uint n = min(counts[p], uint(uK));
  for (uint l = 0u; l < uint(uK); ++l) {
    const uint s = p * uint(uK) + l;
    if (l < n) {
      const uvec4 f = slots[s];
      const float depth = uintBitsToFloat(f.x);
      precise float back = depth + uintBitsToFloat(f.w);
      level0[s] = vec2(depth, back);
      fragments[s] = uvec4(f.x, f.y, f.z, slotTriangle[s]);
    } else {
      level0[s] = vec2(kInf, kInf);
      fragments[s] = uvec4(0xFFFFFFFFu, 0u, 0u, 0xFFFFFFFFu);
    }
  }
}
