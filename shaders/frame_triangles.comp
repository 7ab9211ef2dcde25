#version 450
// A resident frame's per-triangle records for the effect passes (effect_common.glsl Triangles),
// made on the device for each view: the camera-space geometric normal (0 for a degenerate
// triangle) and the material's mirror weight, shininess, transmission and ior — the floats of
// render/effects.cpp surfaceOf: glm's cross product, the view's mat4 · vec4(g, 0) in glm's order,
// and glm::normalize as v · (1 / sqrt(dot(v, v))), dot summed left to right.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)
uniform int uTriangleCount;
uniform mat4 uView;
layout(std430, binding = 0) readonly buffer Positions { float positions[]; };
layout(std430, binding = 1) readonly buffer Indices { uint indices[]; };
layout(std430, binding = 2) readonly buffer TriMaterial { uint triMaterial[]; };
layout(std430, binding = 3) readonly buffer Materials { vec4 materials[]; };  // mirror, shininess, transmission, ior
struct TriangleInfo {
  vec4 normalMirror;
  vec4 material;
};
layout(std430, binding = 4) writeonly buffer Triangles { TriangleInfo triangles[]; };

vec3 position(uint v) { return vec3(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]); }

float dotLeftToRight(vec3 a, vec3 b) {
  precise vec3 m = a * b;
  precise float d = (m.x + m.y) + m.z;
  return d;
}

void main() {
  const uint t = gl_GlobalInvocationID.x + uint(uFirst);
  if (t > uint(uTriangleCount)) return;  // record uTriangleCount: a triangle the scene lacks
  vec3 n = vec3(0.0);
  // (the record of a triangle the scene lacks takes triangle 0's material, as the host's does)
  uint material = uTriangleCount > 0 ? triMaterial[0] : 0u;
  if (t < uint(uTriangleCount)) {
    const vec3 a = position(indices[3u * t]);
    precise vec3 e1 = position(indices[3u * t + 1u]) - a;
    precise vec3 e2 = position(indices[3u * t + 2u]) - a;
    precise vec3 g = vec3(e1.y * e2.z - e2.y * e1.z, e1.z * e2.x - e2.z * e1.x, e1.x * e2.y - e2.x * e1.y);
    if (dotLeftToRight(g, g) > 0.0) {
      precise vec4 c = (uView[0] * g.x + uView[1] * g.y) + (uView[2] * g.z + uView[3] * 0.0);
      const float len2 = dotLeftToRight(c.xyz, c.xyz);
      precise float inv = 1.0 / sqrt(len2);
      precise vec3 unit = c.xyz * inv;
      n = unit;
    }
    material = triMaterial[t];
  }
  const vec4 m = materials[material];
  triangles[t].normalMirror = vec4(n, m.x);
  triangles[t].material = vec4(m.y, m.z, m.w, 0.0);
}
