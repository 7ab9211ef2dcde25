#version 450
// The hybrid tracer's decisions after the windows on the GPU (gpu/gpu_hybrid.h): a window's hit
// answers the ray (the nearest of its two windows); a certain miss and an any hit are answered;
// every other ray goes on to the geometric tracer from where the layers' knowledge ended (a
// closest-hit miss in known space from its origin), written as its query — as HybridTracer::run
// decides.
layout(local_size_x = 64) in;
#include "ray_io.glsl"
#include "glm_float.glsl"
#include "screen_segment.glsl"
#include "screen_camera.glsl"
#include "geometric_ray.glsl"
#include "hybrid_common.glsl"

layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
layout(std430, binding = 1) buffer States { HybridState states[]; };
layout(std430, binding = 2) readonly buffer WindowAnswers { uvec4 windowAnswers[]; };  // grid_march.comp's, two per query
layout(std430, binding = 3) writeonly buffer Remainders { vec4 remainders[]; };      // one query per ray

uniform int uRayCount, uFirst;
uniform bool uAnyHit;

// Adds what the walk of query `q` did to the ray's counts; true when it hit.
bool walked(uint q, inout HybridState st, out float t, out uint triangle, out vec3 ng) {
  const uvec4 a = windowAnswers[2u * q], b = windowAnswers[2u * q + 1u];
  st.geoIterations += max(a.z, 1u);
  st.flags += (b.w & 1u) << 8;
  if ((b.w & 2u) != 0u) st.flags |= kFlagUndecided;
  t = uintBitsToFloat(a.x);
  triangle = a.y;
  ng = uintBitsToFloat(b.xyz);
  return triangle != kMiss;
}

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uRayCount)) return;
  HybridState st = states[id];
  const float maxDistance = rays[id].originMax.w;
  for (uint w = 0u; w < 2u; ++w) {
    if ((st.flags & (w == 0u ? kFlagOriginWindow : kFlagHitWindow)) == 0u) continue;
    float t;
    uint triangle;
    vec3 ng;
    if (!walked(2u * id + w, st, t, triangle, ng)) continue;
    st.dir.w = kInf;
    if (uAnyHit) st.best.w = 0.0, st.bestTriangle = 0u;  // occluded: any-hit answers name no blocker
    else if (st.bestTriangle == kMiss || t <= st.best.w) st.best = vec4(ng, t), st.bestTriangle = triangle;
  }
  const bool hit = st.bestTriangle != kMiss;
  if (hit) st.flags |= kFlagWindowHit;
  float from = st.dir.w;
  if ((st.flags & kFlagScreenHit) != 0u && from == 0.0) st.flags |= kFlagRejected;
  const float end = hit ? st.best.w : maxDistance;
  // A closest-hit miss in known space is certified by geometry from the origin.
  if (!uAnyHit && !hit && !(from < end)) from = 0.0;
  if (uUncertain && !hit) from = 0.0;  // no part of the ray is known to be empty
  st.dir.w = from;
  st.span = end;
  remainders[2u * id] = vec4(st.origin.xyz, kInf);
  remainders[2u * id + 1u] = vec4(st.dir.xyz, 0.0);
  if (!((uAnyHit && hit) || !(from < end))) {
    remainders[2u * id].w = segmentStart(from, st.origin.w, st.origin.xyz);
    remainders[2u * id + 1u].w = end;
    st.flags |= kFlagRemainder;
  }
  states[id] = st;
}
