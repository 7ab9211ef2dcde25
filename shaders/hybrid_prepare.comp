#version 450
// The hybrid tracer's first pass on the GPU (gpu/gpu_hybrid.h): per ray, where the layers'
// knowledge ends (known_space.h rules 1–2, and rule 3 from the known space's march run before
// this pass, unless the screen march over the solid intervals meets rule 3 itself), the
// geometric window over the origin's pixel (rule 6) and the segment the screen march traces, as
// HybridTracer::run computes them before its march.
layout(local_size_x = 64) in;
#include "ray_io.glsl"
#include "glm_float.glsl"
#include "screen_segment.glsl"
#include "screen_camera.glsl"
#include "geometric_ray.glsl"
#include "hybrid_common.glsl"

layout(std430, binding = 0) readonly buffer Rays { GpuRay rays[]; };
layout(std430, binding = 1) writeonly buffer ScreenRays { GpuRay screenRays[]; };
layout(std430, binding = 2) writeonly buffer States { HybridState states[]; };
// Rule 3's march over [u, ∞) (uKnownMarch): its GpuHit records (16 words a ray) and the screen
// parameter of each hit (KnownSpace::finish's m.s).
layout(std430, binding = 3) readonly buffer KnownHits { uint knownWords[]; };
layout(std430, binding = 4) readonly buffer KnownParams { float knownParams[]; };

uniform int uRayCount, uFirst;
uniform mat4 uViewInverse;  // camera space → world (Camera::viewInverse)
uniform float uOffsetUnit;  // GeometricHits::offsetUnit of the scene
uniform float uFarLimit;    // depth beyond which nothing was captured (+∞: the far plane covers the scene)
uniform bool uKnownMarch;   // rule 3 comes from the known space's march (KnownHits)

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uRayCount)) return;
  const GpuRay r = rays[id];
  const vec3 o = r.originMax.xyz, d = r.dirSurface.xyz;
  const float maxDistance = r.originMax.w;
  const bool onSurface = r.dirSurface.w != 0.0;
  HybridState st;
  st.origin = vec4(transformPoint(uViewInverse, o), 0.0);
  st.dir = vec4(transformDirection(uViewInverse, d), 0.0);
  st.origin.w = originOffset(o, uOffsetUnit);
  // KnownSpace::boundaries and finish, without the rule-3 march (a world-space screen half
  // knows all space: no boundary).
  const bool world = uWorldMargin > 0.0;
  const Segment seg = makeSegment(r);
  float knownUntil = 0.0, geoFrom = 0.0;
  uint flags = 0u;
  if (!world && seg.valid && !seg.startOutside) {
    float s = 1.0;
    bool leaves = seg.clippedEnd;
    if (uKnownMarch) {
      flags |= kFlagKnownMarch;
      if (int(knownWords[16u * id + 2u]) >= 0) s = knownParams[id], leaves = true;
    }
    if (uFarLimit < kInf) {
      const float sFar = paramAtDepth(seg, uFarLimit);
      if (maxStd(depthAt(seg, 0.0), depthAt(seg, s)) > uFarLimit && sFar >= 0.0 && sFar < s) s = sFar, leaves = true;
    }
    if (!leaves) {
      knownUntil = geoFrom = maxDistance;
    } else {
      knownUntil = rayParamAt(o, d, maxDistance, seg, s);
      precise float before = s - pixelParam(seg, 1.0);
      geoFrom = minStd(knownUntil, rayParamAt(o, d, maxDistance, seg, maxStd(0.0, before)));
    }
  }
  // Rule 6: the origin's pixel, up to two pixels past it, is the origin window's (a world
  // tracer's: at least the margin, past the texel it skips).
  float windowEnd = -1.0;
  int x, y;
  if (onSurface && pixelOf(o, x, y))
    windowEnd = maxStd(seg.valid ? paramAfter(o, d, maxDistance, seg, pixelParams(seg, x, y).y, pixelParam(seg, kPixelMargin)) : maxDistance,
                       uWorldMargin);
  else if (world && onSurface)
    windowEnd = uWorldMargin;
  const float end = minStd(maxDistance, knownUntil);
  GpuRay sr = r;
  if (world) {
    // the whole ray
  } else if (windowEnd <= 0.0) {
    sr.originMax.w = end;
  } else {  // HybridTracer::segment(ray, min(windowEnd, end), end)
    const float from = minStd(windowEnd, end);
    precise vec3 start = o + d * from;
    precise float length = end - from;
    sr.originMax = vec4(start, maxStd(length, 0.0));
    sr.dirSurface.w = onSurface && from == 0.0 ? 1.0 : 0.0;
  }
  screenRays[id] = sr;
  st.dir.w = world || knownUntil >= maxDistance ? kInf : geoFrom;
  st.best = vec4(0.0);
  st.span = windowEnd;
  st.bestTriangle = kMiss;
  st.flags = flags;
  st.geoIterations = 0u;
  states[id] = st;
}
