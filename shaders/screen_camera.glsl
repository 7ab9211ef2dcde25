// The frame camera's pixel rays and pixels (scene/camera.h), the GLSL twins in the CPU's float
// order (a pixel ray's negated y keeps the CPU's sign of zero: negStd). Include after
// glm_float.glsl and screen_segment.glsl.

uniform float uPixelScale;  // Camera::pixelFootprint(1)

// Camera::rayThrough.
vec3 rayThrough(vec2 pixel) {
  if (uOrtho) return vec3(0.0, 0.0, -1.0);
  precise float x = (pixel.x - float(uWidth) * 0.5) * uPixelScale, y = (pixel.y - float(uHeight) * 0.5) * uPixelScale;
  return vec3(x, negStd(y), -1.0);
}

// Camera::pixelOf.
bool pixelOf(vec3 c, out int x, out int y) {
  x = 0;
  y = 0;
  if (negStd(c.z) < uNear) return false;
  const vec2 s = project(c);
  if (!(s.x >= 0.0 && s.y >= 0.0 && s.x < float(uWidth) && s.y < float(uHeight))) return false;
  x = int(s.x);
  y = int(s.y);
  return true;
}
