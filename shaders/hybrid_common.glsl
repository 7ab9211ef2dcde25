// Shared by the hybrid tracer's passes on the GPU (hybrid_prepare, hybrid_check, hybrid_combine,
// hybrid_resolve; gpu/gpu_hybrid.h), after ray_io.glsl, glm_float.glsl, screen_segment.glsl and
// screen_camera.glsl: one ray's state between the passes and the twins of the CPU functions the
// hybrid's decisions use (hybrid/hybrid_tracer.cpp, hybrid/known_space.cpp,
// screen/screen_segment.cpp), each computing the CPU's floats in the CPU's order.

// One ray's state (gpu/gpu_hybrid.cpp StateRecord), std430.
struct HybridState {
  vec4 origin;  // the ray in world space (Camera::toWorld); w: the origin offset of the geometric tracers
  vec4 dir;     // its world-space direction (Camera::dirToWorld); w: where geometry takes over (+∞: answered)
  vec4 best;    // the nearest window hit: the geometric normal, w its t
  float span;   // before the check: where the origin's window ends (≤ 0: none); from the combine on: where the ray's answer ends
  uint bestTriangle;  // the window hit's triangle (kMiss: none)
  uint flags;         // kFlag* below; bits 8–15: the geometric queries a step cap ended
  uint geoIterations; // cells the geometric queries visited (each at least 1, as GpuGridTracer counts)
};

const uint kMiss = 0xFFFFFFFFu;
const uint kFlagScreenHit = 1u;     // the screen march hit a solid interval
const uint kFlagOriginWindow = 2u;  // a window over the origin's pixel was asked
const uint kFlagHitWindow = 4u;     // a window around the screen hit was asked
const uint kFlagRemainder = 8u;     // the geometric tracer continues the ray
const uint kFlagUndecided = 16u;    // a query met an alpha-tested candidate: the CPU decides the ray
const uint kFlagRejected = 32u;     // a screen hit without a crossing, or whose window found nothing
const uint kFlagWindowHit = 64u;    // a window found the ray's answer
const uint kFlagKnownMarch = 128u;  // rule 3's march ran (its counters count)

// hybrid_tracer.cpp kPixelMargin.
#define kPixelMargin 2.0
// The hit window's stretch past its crossing, float(1 + 1e-5).
#define kWindowStretch uintBitsToFloat(0x3F800054u)

// > 0: the screen half answers in world space (the layered depth cube: HybridTracer's
// worldMargin): it knows all space, its hits are certified by windows this far either side.
uniform float uWorldMargin;
// The screen half's "nothing here" is not certain (HybridTracer's uncertainEmptySpace): a ray
// without a certified hit goes to geometry from its origin, and a hit's window starts there.
uniform bool uUncertain;

// ScreenSegment::pixelParam.
float pixelParam(Segment seg, float pixels) {  // (1e-6: float bits 0x358637BD)
  precise vec2 d = seg.p1 - seg.p0;
  precise float p = pixels / maxStd(maxStd(abs(d.x), abs(d.y)), uintBitsToFloat(0x358637BDu));
  return p;
}

// ScreenSegment::paramAtDepth.
float paramAtDepth(Segment seg, float depth) {
  precise float s = (1.0 / depth - seg.k0) / (seg.k1 - seg.k0);
  return seg.k1 != seg.k0 ? s : 0.0;
}

// screen_segment.cpp rayParamAt: `ray` is the camera-space ray (its origin, direction, length).
float rayParamAt(vec3 o, vec3 d, float maxDistance, Segment seg, float s) {
  precise vec3 p = rayThrough(pointAt(seg, s)) * depthAt(seg, s);
  precise vec3 v = p - o;
  return clampStd(dotStd(v, d), 0.0, maxDistance);
}

// screen_segment.cpp pixelParams: where the 2D segment enters and leaves pixel (x, y).
vec2 pixelParams(Segment seg, int x, int y) {
  precise vec2 d = seg.p1 - seg.p0;
  float sIn = 0.0, sOut = 1.0;
  for (int a = 0; a < 2; ++a) {
    const float lo = float(a == 0 ? x : y), hi = lo + 1.0;
    if (d[a] == 0.0) continue;
    precise float s0 = (lo - seg.p0[a]) / d[a], s1 = (hi - seg.p0[a]) / d[a];
    sIn = maxStd(sIn, minStd(s0, s1));
    sOut = minStd(sOut, maxStd(s0, s1));
  }
  return vec2(sIn, sOut);
}

// screen_segment.cpp paramAfter.
float paramAfter(vec3 o, vec3 d, float maxDistance, Segment seg, float sOut, float m) {
  precise float s = sOut + m;
  return !seg.clippedEnd && s >= 1.0 ? maxDistance : rayParamAt(o, d, maxDistance, seg, clampStd(s, 0.0, 1.0));
}

// screen_segment.cpp rayParamsAroundPixel (x: before, y: after).
vec2 rayParamsAroundPixel(vec3 o, vec3 d, float maxDistance, Segment seg, int x, int y, float margin) {
  if (!seg.valid) return vec2(0.0, maxDistance);
  const vec2 s = pixelParams(seg, x, y);
  const float m = pixelParam(seg, margin);
  precise float before = s.x - m;
  return vec2(rayParamAt(o, d, maxDistance, seg, clampStd(before, 0.0, 1.0)), paramAfter(o, d, maxDistance, seg, s.y, m));
}
