// The ray and answer layouts every march reads and writes (screen_common.glsl's tracers, and the
// effect passes around them: effect_common.glsl), std430 twins of gpu/gpu_screen_tracer.cpp's
// RayRecord and HitRecord, and the surface record the effect passes keep a hit as.

// One ray: camera-space origin and maximum distance, direction and 1 when it starts on a
// stored surface (trace/tracer.h Ray).
struct GpuRay {
  vec4 originMax;
  vec4 dirSurface;
};
// One answer: the hit fragment (x, y, layer; layer -1 for a miss) and the per-ray counters of
// trace/tracer.h RayCounters (fragments: the stored fragments tested at visited level-0 pixels).
struct GpuHit {
  int x, y, layer;
  uint iterations, intervals, pixels, giveUps, fragments;
  uint levelIterations[8];
};
// A surface by value, as a tracer answers with it (trace/tracer.h TraceHit): the camera-space
// point, the shading normal as given (not yet turned to the viewer), the triangle and the packed
// albedo and specular. A fragment's is effect_common.glsl fragmentRecord; the tracers that answer with surfaces
// write their own (gpu_effects.h GpuEffectTracer::Surfaces).
struct SurfaceRecord {
  vec4 point;   // xyz
  vec4 normal;  // xyz
  uint triangle, albedoSpec, pad0, pad1;
};
