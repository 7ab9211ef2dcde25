#version 450
// The layered depth cube's answers as the effect passes take them (gpu_ldc.h
// GpuLdcTracer::answerWave): per ray the march's counters as a GpuHit (layer 0 for a hit, −1 for
// a miss), and for a hit the surface LdcTracer gives: the point at the hit's distance along the
// ray, the sample's shading normal turned from its LDI's camera into the frame's, the sample's
// albedo and specular, and its triangle.
layout(local_size_x = 64) in;

#include "ray_io.glsl"
#include "glm_float.glsl"

layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
// ldc_march.comp's answers: (t's bits, sample or −1, view, iterations), (intervals, pixels, level-0 and level-1 visits).
layout(std430, binding = 1) readonly buffer Answers { uvec4 answers[]; };
layout(std430, binding = 2) readonly buffer Samples { uvec4 samples[]; };  // ldc_march.comp's
layout(std430, binding = 3) readonly buffer SampleTriangles { uint sampleTriangles[]; };
layout(std430, binding = 4) writeonly buffer Hits { GpuHit hits[]; };
layout(std430, binding = 5) writeonly buffer Records { SurfaceRecord records[]; };

uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uRayCount;
uniform mat4 uCameraView;    // the frame's camera: world → camera space
uniform mat4 uViewInverse[3];  // each LDI's camera: its camera space → world

void main() {
  const uint i = gl_GlobalInvocationID.x + uint(uFirst);
  if (i >= uint(uRayCount)) return;
  const uvec4 a = answers[2u * i], b = answers[2u * i + 1u];
  const bool hit = a.y != 0xFFFFFFFFu;
  hits[i].x = -1;
  hits[i].y = -1;
  hits[i].layer = hit ? 0 : -1;
  hits[i].iterations = a.w;
  hits[i].intervals = b.x;
  hits[i].pixels = b.y;
  hits[i].giveUps = 0u;
  hits[i].fragments = 0u;
  hits[i].levelIterations[0] = b.z;
  hits[i].levelIterations[1] = b.w;
  for (int l = 2; l < 8; ++l) hits[i].levelIterations[l] = 0u;
  if (!hit) return;
  const GpuRay ray = rays[i];
  const uvec4 s = samples[a.y];
  precise vec3 p = ray.originMax.xyz + ray.dirSurface.xyz * uintBitsToFloat(a.x);
  SurfaceRecord r;
  r.point = vec4(p, 0.0);
  r.normal = vec4(transformDirection(uCameraView, transformDirection(uViewInverse[a.z], decodeOctahedral(s.y))), 0.0);
  r.triangle = sampleTriangles[a.y];
  r.albedoSpec = s.z;
  r.pad0 = r.pad1 = 0u;
  records[i] = r;
}
