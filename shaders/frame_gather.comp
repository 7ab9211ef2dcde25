#version 450
// The stored fragment each marched ray hit, from a resident frame's fragment records
// (gpu/gpu_frame.h GpuFrame::march): depth bits, octahedral normal, albedo and specular, scene
// triangle; an empty record for a miss. One word-quad per ray, so that only the answers' own
// fragments cross the bus, not the frame's layers.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uCount, uWidth, uK;
#include "ray_io.glsl"
layout(std430, binding = 0) readonly buffer Hits { GpuHit hits[]; };
layout(std430, binding = 1) readonly buffer Fragments { uvec4 fragments[]; };
layout(std430, binding = 2) writeonly buffer Gathered { uvec4 gathered[]; };

void main() {
  const uint i = gl_GlobalInvocationID.x + uint(uFirst);
  if (i >= uint(uCount)) return;
  const GpuHit h = hits[i];
  gathered[i] = h.layer < 0 ? uvec4(0xFFFFFFFFu, 0u, 0u, 0xFFFFFFFFu)
                            : fragments[(uint(h.y) * uint(uWidth) + uint(h.x)) * uint(uK) + uint(h.layer)];
}
