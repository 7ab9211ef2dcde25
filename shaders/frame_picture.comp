#version 450
// The picture of a resident frame packed for the read-back, in rows (row 0 first): from the
// effect passes' output (per pixel slot in 8×8 tiles, effect_common.glsl slotPixel: the picture
// and the traced colour, two RGBA floats) to what the command writes.
//   uFormat 0: RGBA8, sRGB-encoded as the PNG writer encodes (util/image.cpp encode8): a
//              channel's code is the number of the 255 thresholds at or below its value, the
//              thresholds computed on the CPU from that very encoding (srgb8Thresholds), so the
//              codes are the CPU's to the bit (GLSL's pow is not libm's, and is not used);
//   uFormat 1: RGBA32F, the linear values (for .exr, which stores 32-bit floats).
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uWidth, uHeight, uFormat;
uniform float uThresholds[255];
layout(std430, binding = 0) readonly buffer Out { vec4 outPixels[]; };
layout(std430, binding = 1) writeonly buffer Packed8 { uint packed8[]; };
layout(std430, binding = 2) writeonly buffer Packed32 { vec4 packed32[]; };

uint code(float v) {
  // upper_bound over the sorted thresholds: 8 halvings of 256
  uint lo = 0u, n = 255u;
  while (n > 0u) {
    const uint half_n = n / 2u;
    if (uThresholds[lo + half_n] <= v) {
      lo += half_n + 1u;
      n -= half_n + 1u;
    } else {
      n = half_n;
    }
  }
  return lo;
}

void main() {
  const uint p = gl_GlobalInvocationID.x + uint(uFirst);
  if (p >= uint(uWidth * uHeight)) return;
  const uint x = p % uint(uWidth), y = p / uint(uWidth);
  const uint tilesX = (uint(uWidth) + 7u) / 8u;
  const uint slot = ((y / 8u) * tilesX + x / 8u) * 64u + (y % 8u) * 8u + x % 8u;
  const vec4 c = outPixels[2u * slot];
  if (uFormat == 0) packed8[p] = code(c.r) | code(c.g) << 8 | code(c.b) << 16 | 0xFF000000u;
  else packed32[p] = vec4(c.rgb, 1.0);
}
