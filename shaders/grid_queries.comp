#version 450
// Camera-space rays to the irregular grid's world-space queries (grid_march.comp), as
// GpuGridTracer::queryRays makes them for whole rays (GeometricTracer::query): the origin and the
// direction in world space, tnear the origin offset (GeometricHits::originOffset: the segment
// start of a whole ray), tfar the ray's length. A slot without a ray (a negative length) has a
// tnear past its tfar and walks nothing.
layout(local_size_x = 64) in;

#include "ray_io.glsl"
#include "glm_float.glsl"
#include "geometric_ray.glsl"

layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
layout(std430, binding = 1) writeonly buffer Queries { vec4 queries[]; };  // (origin, tnear), (direction, tfar)

uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uRayCount;
uniform mat4 uViewInverse;  // camera space → world (Camera::viewInverse)
uniform float uOffsetUnit;  // GeometricHits::offsetUnit of the scene

void main() {
  const uint i = gl_GlobalInvocationID.x + uint(uFirst);
  if (i >= uint(uRayCount)) return;
  const GpuRay r = rays[i];
  const vec3 o = r.originMax.xyz;
  queries[2u * i] = vec4(transformPoint(uViewInverse, o), originOffset(o, uOffsetUnit));
  queries[2u * i + 1u] = vec4(transformDirection(uViewInverse, r.dirSurface.xyz), r.originMax.w);
}
