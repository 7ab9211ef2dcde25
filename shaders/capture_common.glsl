// Shared by the capture shaders: the per-triangle setup and the per-fragment arithmetic of the
// CPU rasterizer (src/layertrace/raster/raster_setup.h), so that a fragment's depth, normal and
// material are the CPU's. Depth and attributes are evaluated where the pixel-centre ray meets the
// triangle's plane (perspective-correct), not interpolated by the GL pipeline.

// raster_setup.h TriangleSetup, with the triangle's vertices and packed material.
struct TriangleSetup {
  vec4 v0;          // xyz; w = 1 when the triangle is culled (front faces only)
  vec4 e1, e2;      // xyz; e1.w: the triangle's material index (its bits)
  vec4 plane;       // normal xyz, offset w
  vec4 dots;        // d00, d01, d11, invDen
  uvec4 info;       // vertex indices xyz, albedoSpec w
};

uniform int uWidth, uHeight;
uniform float uNear, uFar, uPixelScale;
uniform bool uOrtho;

// scene/camera.h rayThrough and rayOrigin of the pixel centre (px + 0.5, py + 0.5).
void pixelRay(int px, int py, out vec3 origin, out vec3 dir) {
  precise float x = (float(px) + 0.5 - float(uWidth) * 0.5) * uPixelScale;
  precise float y = -((float(py) + 0.5 - float(uHeight) * 0.5) * uPixelScale);
  origin = uOrtho ? vec3(x, y, 0.0) : vec3(0.0);
  dir = uOrtho ? vec3(0.0, 0.0, -1.0) : vec3(x, y, -1.0);
}

float dot3(vec3 a, vec3 b) {
  precise float d = (a.x * b.x + a.y * b.y) + a.z * b.z;
  return d;
}

// raster_setup.h fragmentDepth.
float fragmentDepth(TriangleSetup ts, vec3 origin, vec3 dir) {
  precise float offset = uOrtho ? ts.plane.w - dot3(ts.plane.xyz, origin) : ts.plane.w;
  precise float denom = dot3(ts.plane.xyz, dir);
  precise float depth = denom != 0.0 ? offset / denom : uFar;
  if (!(depth >= uNear)) depth = uNear;
  if (!(depth <= uFar)) depth = uFar;
  return depth;
}

// fragment.h roundHalfAway and encodeOctahedral.
float roundHalfAway(float v) {
  precise float t = trunc(v);
  precise float r = v - t;
  return t + (r >= 0.5 ? 1.0 : 0.0) - (r <= -0.5 ? 1.0 : 0.0);
}
uint snorm16(float v) {
  precise float s = clamp(v, -1.0, 1.0) * 32767.0;
  return uint(int(roundHalfAway(s))) & 0xFFFFu;
}
uint encodeOctahedral(vec3 n) {
  precise float l1 = (abs(n.x) + abs(n.y)) + abs(n.z);
  if (!(l1 > 0.0)) return 0u;
  precise float px = n.x / l1, py = n.y / l1;
  if (n.z < 0.0) {
    precise float ox = (1.0 - abs(py)) * (px >= 0.0 ? 1.0 : -1.0);
    precise float oy = (1.0 - abs(px)) * (py >= 0.0 ? 1.0 : -1.0);
    px = ox;
    py = oy;
  }
  return snorm16(px) | (snorm16(py) << 16);
}

// raster_setup.h fragmentBarycentrics: the weights of the second and third vertex where the
// pixel-centre ray meets the triangle's plane, clamped to the triangle.
vec2 fragmentBarycentrics(TriangleSetup ts, vec3 origin, vec3 dir, float depth) {
  precise vec3 vp = (uOrtho ? origin + dir * depth : dir * depth) - ts.v0.xyz;
  precise float d20 = dot3(vp, ts.e1.xyz), d21 = dot3(vp, ts.e2.xyz);
  precise float b1 = clamp((ts.dots.z * d20 - ts.dots.y * d21) * ts.dots.w, 0.0, 1.0);
  precise float b2 = clamp((ts.dots.x * d21 - ts.dots.y * d20) * ts.dots.w, 0.0, 1.0);
  if (b1 + b2 > 1.0) {
    precise float sum = b1 + b2;
    b1 /= sum;
    b2 /= sum;
  }
  return vec2(b1, b2);
}

// raster_setup.h fragmentNormal: the interpolated normal at the fragment's point.
uint fragmentNormal(TriangleSetup ts, vec3 n0, vec3 n1, vec3 n2, vec3 origin, vec3 dir, float depth) {
  const vec2 b = fragmentBarycentrics(ts, origin, dir, depth);
  precise vec3 n = (n0 * (1.0 - b.x - b.y) + n1 * b.x) + n2 * b.y;
  return encodeOctahedral(n);
}
