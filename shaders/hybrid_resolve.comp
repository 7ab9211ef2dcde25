#version 450
// The hybrid tracer's answers on the GPU (gpu/gpu_hybrid.h): the window's hit, or the geometric
// tracer's answer to the ray's remainder, with what the ray's geometric queries did.
layout(local_size_x = 64) in;
#include "ray_io.glsl"
#include "glm_float.glsl"
#include "screen_segment.glsl"
#include "screen_camera.glsl"
#include "hybrid_common.glsl"

layout(std430, binding = 0) readonly buffer States { HybridState states[]; };
layout(std430, binding = 1) readonly buffer RemainderAnswers { uvec4 remainderAnswers[]; };  // grid_march.comp's
// Per ray (gpu/gpu_hybrid.cpp AnswerRecord): (t, triangle, flags, geometric iterations), (the
// geometric normal, unused), (from, end of the remainder, unused, unused).
layout(std430, binding = 2) writeonly buffer Answers { uvec4 answers[]; };

uniform int uRayCount, uFirst;
uniform bool uAnyHit;

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uRayCount)) return;
  HybridState st = states[id];
  vec4 best = st.best;
  uint triangle = st.bestTriangle;
  if ((st.flags & kFlagRemainder) != 0u) {
    const uvec4 a = remainderAnswers[2u * id], b = remainderAnswers[2u * id + 1u];
    st.geoIterations += max(a.z, 1u);
    st.flags += (b.w & 1u) << 8;
    if ((b.w & 2u) != 0u) st.flags |= kFlagUndecided;
    if (a.y != kMiss) {
      if (uAnyHit) best.w = 0.0, triangle = 0u;
      else best = vec4(uintBitsToFloat(b.xyz), uintBitsToFloat(a.x)), triangle = a.y;
    }
  }
  answers[3u * id] = uvec4(floatBitsToUint(best.w), triangle, st.flags, st.geoIterations);
  answers[3u * id + 1u] = uvec4(floatBitsToUint(best.xyz), 0u);
  answers[3u * id + 2u] = uvec4(floatBitsToUint(st.dir.w), floatBitsToUint(st.span), 0u, 0u);
}
