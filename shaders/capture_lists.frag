#version 450
// Hofmann et al. 2017, §4.1: every fragment of every triangle (no depth test, no culling unless
// asked) appended to its pixel's list — one atomic counter hands out pool nodes, an atomic
// exchange on the pixel's head links them. The node is thin: what the sort needs, its depth and
// next pointer (8 bytes) and its triangle (4 bytes, a separate array); the sort evaluates the
// normal and material of the k fragments it keeps. Only the alpha test is evaluated here, since
// it decides whether the fragment exists. A full pool keeps counting, so the exact number of
// fragments is known and the capture runs again with a pool that fits.

#include "capture_common.glsl"
#include "capture_surface.glsl"

layout(std430, binding = 0) readonly buffer Setups { TriangleSetup setups[]; };
layout(std430, binding = 2) writeonly buffer Nodes { uvec2 nodes[]; };
layout(std430, binding = 3) buffer Heads { uint heads[]; };
layout(std430, binding = 4) writeonly buffer NodeTriangle { uint nodeTriangle[]; };
layout(std430, binding = 5) buffer Complexity { uint complexity[]; };
layout(std430, binding = 6) buffer Counter { uint generated; };
uniform uint uCapacity;

void main() {
  const int px = int(gl_FragCoord.x), py = int(gl_FragCoord.y);
  const uint t = uint(gl_PrimitiveID);
  const TriangleSetup ts = setups[t];
  if (ts.v0.w != 0.0) return;  // culled: a back face with --front-faces-only
  vec3 origin, dir;
  pixelRay(px, py, origin, dir);
  const float depth = fragmentDepth(ts, origin, dir);
  uint albedoSpec;
  if (!fragmentSurface(ts, t, origin, dir, depth, false, albedoSpec)) return;  // cut away by the alpha test: no fragment
  const uint pixel = uint(py) * uint(uWidth) + uint(px);
  atomicAdd(complexity[pixel], 1u);
  const uint node = atomicAdd(generated, 1u);
  if (node >= uCapacity) return;  // pool exhausted: counted, not stored
  nodeTriangle[node] = t;
  const uint next = atomicExchange(heads[pixel], node);
  nodes[node] = uvec2(floatBitsToUint(depth), next);
}
