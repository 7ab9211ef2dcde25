#version 450
// The capture's second pass: each triangle's plane and barycentric setup in camera space
// (raster_setup.cpp prepareRaster), its material (packed colour and index), and whether
// front-face culling drops it.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)

#include "capture_common.glsl"

layout(std430, binding = 0) readonly buffer Indices { uint indices[]; };
layout(std430, binding = 1) readonly buffer CamPos { vec4 camPos[]; };
layout(std430, binding = 2) writeonly buffer Setups { TriangleSetup setups[]; };
layout(std430, binding = 3) readonly buffer Materials { uint materials[]; };
layout(std430, binding = 4) readonly buffer TriMaterial { uint triMaterial[]; };
uniform int uTriangleCount;
uniform bool uFrontFacesOnly;

vec3 cross3(vec3 a, vec3 b) {
  precise vec3 c = vec3(a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y);
  return c;
}

void main() {
  const uint t = gl_GlobalInvocationID.x + uint(uFirst);
  if (t >= uint(uTriangleCount)) return;
  const uvec3 i = uvec3(indices[3u * t], indices[3u * t + 1u], indices[3u * t + 2u]);
  const vec3 a = camPos[i.x].xyz, b = camPos[i.y].xyz, c = camPos[i.z].xyz;
  TriangleSetup s;
  bool culled = false;
  if (uFrontFacesOnly) {
    // Counter-clockwise seen from the eye is the front: the winding's normal points back toward
    // the eye at the origin (orthographic: toward +z).
    const vec3 n = cross3(b - a, c - a);
    culled = !(dot3(n, uOrtho ? vec3(0.0, 0.0, -1.0) : a) < 0.0);
  }
  precise vec3 e1 = b - a, e2 = c - a;
  s.v0 = vec4(a, culled ? 1.0 : 0.0);
  s.e1 = vec4(e1, uintBitsToFloat(triMaterial[t]));  // the material, for the fragments' surface (capture_surface.glsl)
  s.e2 = vec4(e2, 0.0);
  const vec3 pn = cross3(e1, e2);
  s.plane = vec4(pn, dot3(pn, a));
  precise float d00 = dot3(e1, e1), d01 = dot3(e1, e2), d11 = dot3(e2, e2);
  precise float den = d00 * d11 - d01 * d01;
  s.dots = vec4(d00, d01, d11, den != 0.0 ? 1.0 / den : 0.0);
  s.info = uvec4(i, materials[triMaterial[t]]);
  setups[t] = s;
}
