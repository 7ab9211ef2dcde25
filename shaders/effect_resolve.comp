#version 450
// The origin rule of trace/tracer.h Tracer::query on the device, one invocation per ray slot
// after each march: an answer on the ray's own triangle is replaced by what the rest of the ray
// meets (continuePastOrigin), up to kOriginSkips times, then by a miss. Round 0 takes the first
// march's answers; each later round adds the continuation's counters. A ray still pending is
// written back as its continuation and counted, so the host knows whether to march again. A ray
// answered for good keeps the surface it met beside it (EffectRay::hit): the hit fragment's, or
// the record the tracer wrote (a geometric tracer's answers name no fragment).
layout(local_size_x = 64) in;

#include "ray_io.glsl"
#include "glm_float.glsl"
#include "effect_common.glsl"

layout(std430, binding = 0) buffer Rays { GpuRay rays[]; };
layout(std430, binding = 1) readonly buffer Hits { GpuHit hits[]; };
layout(std430, binding = 3) readonly buffer Surfaces { SurfaceRecord surfaces[]; };
layout(std430, binding = 4) buffer EffectRays { EffectRay effectRays[]; };
layout(std430, binding = 5) buffer Answers { GpuHit answers[]; };
layout(std430, binding = 6) buffer Pending { uint pendingRays; };

const int kOriginSkips = 4;  // trace/tracer.h
uniform int uRound;
// How the tracer's answers name the surface they met (gpu_effects.h GpuEffectTracer::Surfaces):
// 0 the hit fragment, 1 the record at binding 3, 2 the hit fragment at the record's point.
uniform int uSurfaces;

void main() {
  const uint r = gl_GlobalInvocationID.x + uint(uFirst);
  if (r >= uint(uItems) || effectRays[r].pending == 0u) return;
  const GpuHit h = hits[r];
  if (uRound == 0) {
    answers[r] = h;
  } else {
    answers[r].x = h.x;
    answers[r].y = h.y;
    answers[r].layer = h.layer;
    answers[r].iterations += h.iterations;
    answers[r].intervals += h.intervals;
    answers[r].pixels += h.pixels;
    answers[r].giveUps += h.giveUps;
    for (int l = 0; l < 8; ++l) answers[r].levelIterations[l] += h.levelIterations[l];
  }
  const EffectRay ray = effectRays[r];
  bool again = false;
  SurfaceRecord met;
  if (h.layer >= 0) {
    met = uSurfaces == 1 ? surfaces[r] : fragmentRecord(h.x, h.y, fragmentAt(h.x, h.y, h.layer));
    if (uSurfaces == 2) met.point = surfaces[r].point;
  }
  if (h.layer >= 0 && ray.originTriangle != kNoTriangle) {
    if (met.triangle == ray.originTriangle) {
      // On its own triangle: continue from the hit's distance along the ray, on a surface.
      answers[r].layer = -1;  // a miss unless the continuation finds something
      if (uRound < kOriginSkips) {
        const vec3 origin = ray.originMax.xyz, dir = ray.dirSurface.xyz;
        precise float t = max(dotStd(met.point.xyz - origin, dir), 0.0);
        precise vec3 next = origin + dir * t;
        precise float left = ray.originMax.w - t;
        if (left > 0.0) {
          rays[r].originMax = vec4(next, left);
          rays[r].dirSurface = vec4(dir, 1.0);
          again = true;
        }
      }
    }
  }
  if (again) {
    atomicAdd(pendingRays, 1u);
  } else {
    if (answers[r].layer >= 0) effectRays[r].hit = met;
    effectRays[r].pending = 0u;
    rays[r].originMax.w = -1.0;  // the next round's march skips it
  }
}
