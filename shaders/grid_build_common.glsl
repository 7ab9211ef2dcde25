// What the irregular grid's build passes share (gpu/gpu_grid_build.h): the scene's triangles and
// the exact triangle/box overlap of grid/irregular_grid_build.cpp, operation for operation, so
// that the GPU keeps the references the CPU keeps. Needs glm_float.glsl before it.

layout(std430, binding = 0) readonly buffer Positions { float positions[]; };  // x, y, z per vertex
layout(std430, binding = 1) readonly buffer Indices { uint indices[]; };       // three per triangle

uniform vec3 uLo;  // the grid box's lower corner

vec3 vertexAt(uint v) { return vec3(positions[3u * v], positions[3u * v + 1u], positions[3u * v + 2u]); }
void triangleAt(uint t, out vec3 a, out vec3 b, out vec3 c) {
  a = vertexAt(indices[3u * t]), b = vertexAt(indices[3u * t + 1u]), c = vertexAt(indices[3u * t + 2u]);
}
vec3 minStd(vec3 a, vec3 b) { return vec3(minStd(a.x, b.x), minStd(a.y, b.y), minStd(a.z, b.z)); }
vec3 maxStd(vec3 a, vec3 b) { return vec3(maxStd(a.x, b.x), maxStd(a.y, b.y), maxStd(a.z, b.z)); }
float min3(float a, float b, float c) { return minStd(minStd(a, b), c); }
float max3(float a, float b, float c) { return maxStd(maxStd(a, b), c); }

#define kGrow uintBitsToFloat(0x3F800054u)  // 1.0f + 1e-5f
#define kTiny uintBitsToFloat(0x0DA24260u)  // 1e-30f

// irregular_grid_build.cpp triangleBoxOverlap (separating axis theorem, the box grown by eps
// and by a few ulps of its coordinates).
bool triangleBoxOverlap(vec3 a, vec3 b, vec3 c, vec3 boxLo, vec3 boxHi, float eps) {
  const vec3 magnitude = maxStd(abs(boxLo), abs(boxHi));
  precise vec3 center = (boxLo + boxHi) * 0.5;
  precise vec3 halfSize = ((boxHi - boxLo) * 0.5 + vec3(eps)) + magnitude * 4.76837158203125e-07;
  precise vec3 v0 = a - center, v1 = b - center, v2 = c - center;
  for (int i = 0; i < 3; ++i)
    if (min3(v0[i], v1[i], v2[i]) > halfSize[i] || max3(v0[i], v1[i], v2[i]) < -halfSize[i]) return false;
  precise vec3 e0 = v1 - v0, e1 = v2 - v1, e2 = v0 - v2;
  const vec3 n = crossStd(e0, e1);
  {
    precise float r = (halfSize.x * abs(n.x) + halfSize.y * abs(n.y)) + halfSize.z * abs(n.z);
    const float s = dotStd(n, v0);
    precise float bound = r * kGrow + kTiny;
    if (abs(s) > bound) return false;
  }
  for (int i = 0; i < 3; ++i) {
    const vec3 e = i == 0 ? e0 : i == 1 ? e1 : e2;
    for (int k = 0; k < 3; ++k) {
      const vec3 axis = vec3(k == 0 ? 1.0 : 0.0, k == 1 ? 1.0 : 0.0, k == 2 ? 1.0 : 0.0);
      const vec3 ax = crossStd(e, axis);
      if (dotStd(ax, ax) < kTiny) continue;
      const float p0 = dotStd(v0, ax), p1 = dotStd(v1, ax), p2 = dotStd(v2, ax);
      precise float r = (halfSize.x * abs(ax.x) + halfSize.y * abs(ax.y)) + halfSize.z * abs(ax.z);
      precise float bound = r * kGrow;
      if (min3(p0, p1, p2) > bound || max3(p0, p1, p2) < -bound) return false;
    }
  }
  return true;
}
