#version 450
// Every fragment of every list in the CPU capture's 16-byte node (fragment.h: depth, octahedral
// normal, albedo and specular, next), for `layers --verify`, which compares each fragment with
// Embree. The pool's nodes are thin (capture_lists.frag); this pass, run only when the lists are
// asked for, evaluates each fragment's attributes as the sort does for the kept ones.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)

#include "capture_common.glsl"
#include "capture_surface.glsl"

layout(std430, binding = 0) readonly buffer Nodes { uvec2 nodes[]; };
layout(std430, binding = 1) readonly buffer Heads { uint heads[]; };
layout(std430, binding = 2) readonly buffer NodeTriangle { uint nodeTriangle[]; };
layout(std430, binding = 3) writeonly buffer FullNodes { uvec4 fullNodes[]; };
layout(std430, binding = 6) readonly buffer Setups { TriangleSetup setups[]; };
layout(std430, binding = 7) readonly buffer CamNormals { vec4 camNormals[]; };
#include "capture_attributes.glsl"

const uint kNull = 0xFFFFFFFFu;

void main() {
  const uint p = gl_GlobalInvocationID.x + uint(uFirst);
  if (p >= uint(uWidth * uHeight)) return;
  const int px = int(p % uint(uWidth)), py = int(p / uint(uWidth));
  for (uint i = heads[p]; i != kNull; i = nodes[i].y) {
    const uint t = nodeTriangle[i];
    fullNodes[i] = uvec4(nodes[i].x, fragmentAttributes(setups[t], t, px, py, uintBitsToFloat(nodes[i].x)), nodes[i].y);
  }
}
