// Where a geometric tracer's query along a ray begins (geometry/geometric_tracer.h), the GLSL
// twins in the CPU's float order. Include after glm_float.glsl.

// GeometricHits::originOffset for a ray from camera-space `o`: 1e-4 of the scene's unit or of
// the origin's distance from the eye.
float originOffset(vec3 o, float unit) {
  precise float offset = uintBitsToFloat(0x38D1B717u) * maxStd(unit, sqrt(dotStd(o, o)));
  return offset;
}

// GeoHitQueries::segmentStart for a ray from world-space `origin` with origin offset `offset`:
// 64 float epsilons (2^-17) of the largest coordinate before `from`.
float segmentStart(float from, float offset, vec3 origin) {
  const vec3 a = abs(origin);
  precise float slack = uintBitsToFloat(0x37000000u) * (maxStd(maxStd(a.x, a.y), a.z) + from);
  precise float start = from - slack;
  return from > 0.0 ? maxStd(offset, start) : offset;
}
