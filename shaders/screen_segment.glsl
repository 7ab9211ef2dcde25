// The camera and the screen segment of McGuire and Mara 2014, shared by the screen-space
// tracers (screen_common.glsl) and the hybrid's passes (hybrid_common.glsl). Each function is the
// GLSL twin of a CPU function (named beside it) and computes the same floats in the same order;
// `precise` keeps the compiler from contracting a product and a sum into one FMA, which the CPU
// build does not do either (-ffp-contract=off).

uniform int uWidth, uHeight;
uniform float uNear, uFocal;
uniform bool uOrtho;

#define kInf uintBitsToFloat(0x7f800000u)

// std::clamp: lo when v < lo, else hi when hi < v, else v (GLSL's clamp differs when lo > hi).
float clampStd(float v, float lo, float hi) {
  return v < lo ? lo : (hi < v ? hi : v);
}

// scene/camera.cpp Camera::project.
vec2 project(vec3 c) {
  precise vec2 p;
  if (uOrtho) {
    p.x = float(uWidth) * 0.5 + uFocal * c.x;
    p.y = float(uHeight) * 0.5 - uFocal * c.y;
  } else {
    precise float depth = -c.z;
    p.x = float(uWidth) * 0.5 + uFocal * c.x / depth;
    p.y = float(uHeight) * 0.5 - uFocal * c.y / depth;
  }
  return p;
}

// screen/screen_segment.h ScreenSegment.
struct Segment {
  vec2 p0, p1;
  float k0, k1;
  bool valid, clippedStart, startOutside, clippedEnd;
};

float depthAt(Segment seg, float s) {
  precise float z = 1.0 / (seg.k0 + s * (seg.k1 - seg.k0));
  return z;
}

vec2 pointAt(Segment seg, float s) {
  precise vec2 p = seg.p0 + s * (seg.p1 - seg.p0);
  return p;
}

// screen/screen_segment.cpp makeScreenSegment.
Segment makeSegment(GpuRay ray) {
  Segment seg;
  seg.p0 = vec2(0.0);
  seg.p1 = vec2(0.0);
  seg.k0 = 1.0;
  seg.k1 = 1.0;
  seg.valid = false;
  seg.clippedEnd = false;
  seg.startOutside = false;
  seg.clippedStart = ray.dirSurface.w == 0.0;
  // A negative length marks a slot without a ray (gpu/gpu_effects.h: a pixel that emits fewer
  // rays than its slots): it answers a miss at once, with zero counters.
  if (ray.originMax.w < 0.0) return seg;
  const float nearZ = -uNear;
  const vec3 dir = ray.dirSurface.xyz;
  precise vec3 origin = ray.originMax.xyz;
  precise float maxDistance = ray.originMax.w;
  if (origin.z > nearZ) {
    if (!(dir.z < 0.0)) return seg;
    precise float t = (nearZ - origin.z) / dir.z;
    if (!(t < maxDistance)) return seg;
    origin += dir * t;
    origin.z = nearZ;
    maxDistance -= t;
    seg.clippedStart = seg.startOutside = true;
  }
  precise float len = (origin.z + dir.z * maxDistance > nearZ) ? (nearZ - origin.z) / dir.z : maxDistance;
  seg.clippedEnd = len < maxDistance;
  precise vec3 end = origin + dir * max(len, 0.0);
  seg.k0 = 1.0 / -origin.z;
  seg.k1 = 1.0 / -end.z;
  seg.p0 = project(origin);
  seg.p1 = project(end);
  const float W = float(uWidth), H = float(uHeight);
  if (!(seg.p0.x >= 0.0 && seg.p0.y >= 0.0 && seg.p0.x <= W && seg.p0.y <= H)) {
    // Liang–Barsky entry into the viewport.
    precise float tA = 0.0, tB = 1.0;
    precise vec2 d = seg.p1 - seg.p0;
    for (int a = 0; a < 2; ++a) {
      const float hi = a == 0 ? W : H;
      if (d[a] == 0.0) {
        if (seg.p0[a] < 0.0 || seg.p0[a] > hi) return seg;
        continue;
      }
      precise float t0 = (0.0 - seg.p0[a]) / d[a], t1 = (hi - seg.p0[a]) / d[a];
      tA = max(tA, min(t0, t1));
      tB = min(tB, max(t0, t1));
    }
    if (!(tA <= tB)) return seg;
    seg.p0 = clamp(seg.p0 + d * tA, vec2(0.0), vec2(W, H));
    seg.k0 = seg.k0 + (seg.k1 - seg.k0) * tA;
    seg.clippedStart = seg.startOutside = true;
  }
  precise float tEnd = 1.0;
  precise vec2 d = seg.p1 - seg.p0;
  for (int a = 0; a < 2; ++a) {
    const float p = seg.p0[a], dp = d[a], hi = a == 0 ? W : H;
    if (dp > 0.0 && p + dp > hi) tEnd = min(tEnd, (hi - p) / dp);
    if (dp < 0.0 && p + dp < 0.0) tEnd = min(tEnd, (0.0 - p) / dp);
  }
  tEnd = max(tEnd, 0.0);
  if (tEnd < 1.0) {
    seg.clippedEnd = true;
    seg.p1 = seg.p0 + d * tEnd;
    seg.k1 = seg.k0 + (seg.k1 - seg.k0) * tEnd;
  }
  seg.valid = !isinf(seg.p1.x) && !isnan(seg.p1.x) && !isinf(seg.p1.y) && !isnan(seg.p1.y) && seg.k1 > 0.0;
  return seg;
}

