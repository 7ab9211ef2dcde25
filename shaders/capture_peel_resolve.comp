#version 450
// Depth peeling's last step: the k layers' winners (pixel, triangle) become fragment nodes —
// depth, normal and material evaluated as the list capture evaluates them — with their
// z-thickness, in the k-layer arrays' layout.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)

#include "capture_common.glsl"
#include "capture_surface.glsl"

layout(std430, binding = 0) readonly buffer Setups { TriangleSetup setups[]; };
layout(std430, binding = 1) readonly buffer CamNormals { vec4 camNormals[]; };
layout(std430, binding = 2) readonly buffer PeelTriangle { uint peelTriangle[]; };
layout(std430, binding = 3) writeonly buffer Slots { uvec4 slots[]; };
layout(std430, binding = 4) writeonly buffer Counts { uint counts[]; };
layout(std430, binding = 5) writeonly buffer SlotTriangle { uint slotTriangle[]; };
#include "capture_attributes.glsl"
uniform int uK;
uniform float uThickness, uThicknessPerDepth;

void main() {
  const uint p = gl_GlobalInvocationID.x + uint(uFirst);
  if (p >= uint(uWidth * uHeight)) return;
  const int px = int(p % uint(uWidth)), py = int(p / uint(uWidth));
  vec3 origin, dir;
  pixelRay(px, py, origin, dir);
  uint n = 0u;
  for (int j = 0; j < uK; ++j) {
    const uint slot = p * uint(uK) + uint(j);
    const uint tri = peelTriangle[slot];
    if (tri == 0u) {
      slots[slot] = uvec4(0u);
      slotTriangle[slot] = 0xFFFFFFFFu;
      continue;
    }
    const TriangleSetup ts = setups[tri - 1u];
    const float depth = fragmentDepth(ts, origin, dir);
    precise float thickness = uThickness + uThicknessPerDepth * depth;
    const uvec2 attributes = fragmentAttributes(ts, tri - 1u, px, py, depth);  // a winner passed the alpha test
    slots[slot] = uvec4(floatBitsToUint(depth), attributes, floatBitsToUint(thickness));
    slotTriangle[slot] = tri - 1u;
    ++n;
  }
  counts[p] = n;
}
