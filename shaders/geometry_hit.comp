#version 450
// The irregular grid's answers as the effect passes take them (gpu_grid.h
// GpuGridTracer::answerWave): per ray the walk's counters as a GpuHit (layer 0 for a hit, −1 for
// a miss; GpuGridTracer::queryRays' counters), and for a closest hit the surface
// GeometricHits::makeHit gives, the same floats in the same order: the point at the hit's
// distance along the ray, the vertex normals interpolated there, and the material's albedo and
// specular, textured at the frame camera's footprint as the capture samples a fragment. An
// any-hit answer names no surface (GeometricHits::occludedHit).
layout(local_size_x = 64) in;

#include "ray_io.glsl"
#include "glm_float.glsl"
#include "capture_common.glsl"
#include "capture_surface.glsl"

layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
// grid_march.comp's answers: (t's bits, triangle or 0xFFFFFFFF, cells visited, triangles tested),
// (the geometric normal's bits, flags: 1 where a step cap ended the walk).
layout(std430, binding = 1) readonly buffer Answers { uvec4 answers[]; };
layout(std430, binding = 2) writeonly buffer Hits { GpuHit hits[]; };
layout(std430, binding = 3) writeonly buffer Records { SurfaceRecord records[]; };
layout(std430, binding = 4) readonly buffer Positions { float positions[]; };  // world space, three a vertex
layout(std430, binding = 5) readonly buffer Normals { float normals[]; };      // world space, three a vertex
layout(std430, binding = 6) readonly buffer Indices { uint indices[]; };       // three a triangle
// Per triangle its material, then from uMaterialTable per material its packed albedo and
// specular (raster/fragment.h packAlbedoSpec). Bindings 8 and 9: capture_surface.glsl's tables.
layout(std430, binding = 7) readonly buffer Materials { uint materialWords[]; };
uniform uint uMaterialTable;

uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uRayCount;
uniform mat4 uView, uViewInverse;  // the frame's camera
uniform bool uAnyHit;

const uint kMiss = 0xFFFFFFFFu;

vec3 vertexOf(uint v) { return vec3(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]); }
vec3 normalOf(uint v) { return vec3(normals[3u * v], normals[3u * v + 1u], normals[3u * v + 2u]); }
// std::clamp(v, 0, 1).
float clampUnit(float v) { return v < 0.0 ? 0.0 : (1.0 < v ? 1.0 : v); }

void main() {
  const uint i = gl_GlobalInvocationID.x + uint(uFirst);
  if (i >= uint(uRayCount)) return;
  const uvec4 a = answers[2u * i], w = answers[2u * i + 1u];
  const bool hit = a.y != kMiss;
  const uint steps = max(a.z, 1u);
  hits[i].x = -1;
  hits[i].y = -1;
  hits[i].layer = hit ? 0 : -1;
  hits[i].iterations = steps;
  hits[i].intervals = 0u;
  hits[i].pixels = 0u;
  hits[i].giveUps = w.w & 1u;
  hits[i].fragments = 0u;
  hits[i].levelIterations[0] = steps;
  for (int l = 1; l < 8; ++l) hits[i].levelIterations[l] = 0u;
  if (!hit) return;
  SurfaceRecord r;
  r.point = vec4(0.0);
  r.normal = vec4(0.0);
  r.triangle = kMiss;
  r.albedoSpec = 0u;
  r.pad0 = r.pad1 = 0u;
  if (!uAnyHit) {
    // GeometricHits::makeHit.
    const GpuRay ray = rays[i];
    const uint tri = a.y;
    precise vec3 p = ray.originMax.xyz + ray.dirSurface.xyz * uintBitsToFloat(a.x);
    const uvec3 t = uvec3(indices[3u * tri], indices[3u * tri + 1u], indices[3u * tri + 2u]);
    const vec3 pw = transformPoint(uViewInverse, p);
    const vec3 va = vertexOf(t.x), vb = vertexOf(t.y), vc = vertexOf(t.z);
    precise vec3 e1 = vb - va, e2 = vc - va;
    const vec3 n = crossStd(e1, e2);
    const float area = dotStd(n, n);
    vec3 normal = normalizeStd(n);
    precise float u = 1.0, v = 0.0;  // the weights of the first and second vertex
    if (area > 0.0) {
      precise vec3 cb = vc - vb, pb = pw - vb, ac = va - vc, pc = pw - vc;
      u = dotStd(crossStd(cb, pb), n) / area;
      v = dotStd(crossStd(ac, pc), n) / area;
    }
    precise float third = 1.0 - u - v;  // the third vertex's
    if (area > 0.0) {
      precise vec3 s = normalOf(t.x) * u + normalOf(t.y) * v + normalOf(t.z) * third;
      if (sqrt(dotStd(s, s)) > 0.0) normal = normalizeStd(s);
    }
    r.point = vec4(p, 0.0);
    r.normal = vec4(normalizeStd(transformDirection(uView, normal)), 0.0);
    r.triangle = tri;
    const uint material = materialWords[tri];
    r.albedoSpec = materialWords[uMaterialTable + material];
    if ((materialFlags(material) & kSampled) != 0u) {
      // The texture's level of detail as the capture chooses it for a fragment at this point.
      const float depth = maxStd(-p.z, uNear);
      const vec3 view = uOrtho ? vec3(0.0, 0.0, -1.0) : p;
      const vec3 nc = transformDirection(uView, n);
      const float nl = sqrt(dotStd(nc, nc)), vl = sqrt(dotStd(view, view));
      precise float cosine = nl > 0.0 && vl > 0.0 ? dotStd(nc, view) / (nl * vl) : 1.0;
      precise float footprint = (uOrtho ? uPixelScale : depth * uPixelScale) / maxStd(abs(cosine), 1.0 / 64.0);
      r.albedoSpec = surfaceAlbedoSpec(material, tri, t, vec2(clampUnit(v), clampUnit(third)), footprint);
    }
  }
  records[i] = r;
}
