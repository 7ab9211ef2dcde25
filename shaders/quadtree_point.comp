#version 450
// The quad-tree's hit as the effect passes take it (gpu_quadtree.h GpuQuadtreeTracer::answerWave):
// the hit fragment at the exact ray–plane point, which QuadtreeTracer computes from the hit's
// parameter s on the ray's screen segment and the depth scale (the same floats in the same order);
// and the sums of the march's node counters over the run.
layout(local_size_x = 64) in;

#include "ray_io.glsl"
#include "glm_float.glsl"
#include "screen_segment.glsl"
#include "screen_camera.glsl"

struct QuadtreeExtra {  // gpu_quadtree.h GpuQuadtreeExtra
  float s;
  uint planes, boxes, occlusions;
};
layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
layout(std430, binding = 1) readonly buffer Hits { GpuHit hits[]; };
layout(std430, binding = 2) readonly buffer Extras { QuadtreeExtra extra[]; };
layout(std430, binding = 3) readonly buffer Scale { float depthScale; };
layout(std430, binding = 4) writeonly buffer Records { SurfaceRecord records[]; };
// The run's plane, box and occlusion counts, each as a low and a high word.
layout(std430, binding = 5) buffer NodeSums { uint nodeSums[6]; };

uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uRayCount;

void main() {
  const uint i = gl_GlobalInvocationID.x + uint(uFirst);
  if (i >= uint(uRayCount)) return;
  // Every slot adds its counts: a slot without a ray (or done in an earlier round) has none.
  const uint counts[3] = uint[3](extra[i].planes, extra[i].boxes, extra[i].occlusions);
  for (int c = 0; c < 3; ++c)
    if (counts[c] != 0u && atomicAdd(nodeSums[2 * c], counts[c]) + counts[c] < counts[c]) atomicAdd(nodeSums[2 * c + 1], 1u);
  if (hits[i].layer < 0) return;
  const Segment seg = makeSegment(rays[i]);
  const float s = extra[i].s, scale = depthScale;
  precise vec2 at = seg.p0 + s * (seg.p1 - seg.p0);
  precise float w = scale * seg.k0 + s * (scale * (seg.k1 - seg.k0));
  precise vec3 p = rayThrough(at) * (scale / w);
  records[i].point = vec4(p, 0.0);
}
