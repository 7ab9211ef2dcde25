#version 450
// The hybrid tracer's exact checks on the GPU (gpu/gpu_hybrid.h), after the screen march: a
// screen hit is a candidate only where the ray crosses a triangle of the hit pixel's layers (up
// to the hit one) before two pixels past the pixel; the windows the geometric tracer then
// certifies are written as its queries, two per ray (the origin's, the hit's), as
// HybridTracer::run asks them.
layout(local_size_x = 64) in;
#include "ray_io.glsl"
#include "glm_float.glsl"
#include "screen_segment.glsl"
#include "screen_camera.glsl"
#include "geometric_ray.glsl"
#include "hybrid_common.glsl"

layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
// The screen march's answers: GpuHit records (16 words a ray), or with a world-space screen half
// shaders/ldc_march.comp's (8 words: the hit's distance, its sample or kMiss, …).
layout(std430, binding = 1) readonly buffer ScreenHits { uint screenWords[]; };
layout(std430, binding = 2) buffer States { HybridState states[]; };
// Per ray two queries of grid_march.comp, two vec4 each: (origin, tnear), (direction, tfar).
layout(std430, binding = 3) writeonly buffer Windows { vec4 windows[]; };
layout(std430, binding = 4) readonly buffer LayerTriangles { uint layerTriangles[]; };  // k per pixel
layout(std430, binding = 5) readonly buffer LayerCounts { uint layerCounts[]; };
layout(std430, binding = 6) readonly buffer Positions { float positions[]; };  // world space, 3 per vertex
layout(std430, binding = 7) readonly buffer Triangles { uint triangles[]; };   // 3 vertex indices each

uniform int uRayCount, uFirst, uK;
uniform uint uTriangleCount;

vec3 vertex(uint v) { return vec3(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]); }

// geometry/ray_triangle.h hitTriangle (Möller–Trumbore, edges widened by 1e-6, t in (tmin, tmax]).
bool hitTriangle(vec3 o, vec3 d, vec3 v0, vec3 e1, vec3 e2, float tmin, float tmax, out float t) {
  t = 0.0;
  const float eps = uintBitsToFloat(0x358637BDu), onePlusEps = uintBitsToFloat(0x3F800008u);  // 1e-6, 1 + 1e-6
  const vec3 p = crossStd(d, e2);
  const float det = dotStd(e1, p);
  if (det == 0.0) return false;
  precise float inv = 1.0 / det;
  precise vec3 s = o - v0;
  precise float u = dotStd(s, p) * inv;
  if (u < negStd(eps) || u > onePlusEps) return false;
  const vec3 q = crossStd(s, e1);
  precise float v = dotStd(d, q) * inv;
  precise float uv = u + v;
  if (v < negStd(eps) || uv > onePlusEps) return false;
  precise float tt = dotStd(e2, q) * inv;
  t = tt;
  return t > tmin && t <= tmax;
}

// HybridTracer::pixelHit: the nearest crossing of the first `layers` layers of pixel (x, y),
// t in (tmin, tmax]; its t in x, kMiss's bits in y when none.
vec2 pixelHit(vec3 o, vec3 d, int x, int y, int layers, float tmin, float tmax) {
  const uint p = uint(y) * uint(uWidth) + uint(x);
  const int n = min(layers, int(layerCounts[p]));
  float bestT = 0.0;
  uint best = kMiss;
  for (int i = 0; i < n; ++i) {
    const uint tri = layerTriangles[p * uint(uK) + uint(i)];
    if (tri >= uTriangleCount) continue;
    const uvec3 v = uvec3(triangles[3u * tri], triangles[3u * tri + 1u], triangles[3u * tri + 2u]);
    const vec3 a = vertex(v.x);
    precise vec3 e1 = vertex(v.y) - a, e2 = vertex(v.z) - a;
    float t;
    if (hitTriangle(o, d, a, e1, e2, tmin, best != kMiss ? bestT : tmax, t)) bestT = t, best = tri;
  }
  return vec2(bestT, uintBitsToFloat(best));
}

void ask(uint query, HybridState st, float from, float to) {
  windows[2u * query] = vec4(st.origin.xyz, segmentStart(from, st.origin.w, st.origin.xyz));
  windows[2u * query + 1u] = vec4(st.dir.xyz, to);
}

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uRayCount)) return;
  const GpuRay r = rays[id];
  HybridState st = states[id];
  const vec3 o = r.originMax.xyz, d = r.dirSurface.xyz;
  const bool world = uWorldMargin > 0.0;
  const bool screenHit = world ? screenWords[8u * id + 1u] != kMiss : int(screenWords[16u * id + 2u]) >= 0;
  const float maxDistance = r.originMax.w;
  // Neither window asked: an empty query (tnear +∞ past tfar 0) the walk leaves at once.
  windows[4u * id] = windows[4u * id + 2u] = vec4(st.origin.xyz, kInf);
  windows[4u * id + 1u] = windows[4u * id + 3u] = vec4(st.dir.xyz, 0.0);
  const bool originWindow = st.span > 0.0;
  if (!screenHit || world) {
    if (originWindow) ask(2u * id, st, 0.0, st.span), st.flags |= kFlagOriginWindow;
    if (!screenHit) {
      states[id] = st;
      return;
    }
  }
  st.flags |= kFlagScreenHit;
  st.dir.w = 0.0;  // no crossing (or no certified hit): geometry answers the ray from its origin
  if (world) {
    // The hit's point on its sample's plane (GpuLdcTracer: origin + t · direction), certified by
    // geometry over the margin either side of it.
    precise vec3 p = o + d * uintBitsToFloat(screenWords[8u * id]);
    precise vec3 v = p - o;
    const float tScreen = dotStd(v, d);
    precise float before = tScreen - uWorldMargin, past = tScreen + uWorldMargin;
    ask(2u * id + 1u, st, uUncertain ? 0.0 : maxStd(0.0, before), minStd(past, maxDistance));
    st.flags |= kFlagHitWindow;
    states[id] = st;
    return;
  }
  // Rule 3's check: the ray against the triangles of the hit pixel's layers up to the hit one.
  const int hx = int(screenWords[16u * id]), hy = int(screenWords[16u * id + 1u]), layer = int(screenWords[16u * id + 2u]);
  const Segment seg = makeSegment(r);
  const vec2 span = rayParamsAroundPixel(o, d, maxDistance, seg, hx, hy, kPixelMargin);
  const vec2 v = pixelHit(st.origin.xyz, st.dir.xyz, hx, hy, layer + 1, st.origin.w, span.y);
  if (floatBitsToUint(v.y) != kMiss) {
    if (originWindow) ask(2u * id, st, 0.0, st.span), st.flags |= kFlagOriginWindow;
    precise float past = v.x * kWindowStretch;
    ask(2u * id + 1u, st, uUncertain ? 0.0 : minStd(v.x, span.x), minStd(maxStd(span.y, past), maxDistance));
    st.flags |= kFlagHitWindow;
  }
  states[id] = st;
}
