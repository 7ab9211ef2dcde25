#version 450
// The irregular grid's build, step 1 on the GPU (gpu/gpu_grid_build.h): the references of the
// top-level cells, one invocation per triangle, every top cell its bounding box overlaps tested
// exactly (irregular_grid_build.cpp initialGrid). The counting run adds 1 per overlap to the
// cell's count; the emitting run, after the counts' prefix sum, writes each reference and its
// cell at a slot taken from the cell's cursor (the order within a cell is the atomics').
layout(local_size_x = 64) in;
#include "glm_float.glsl"
#include "grid_build_common.glsl"
layout(std430, binding = 2) buffer Counts { uint counts[]; };  // counting: the counts; emitting: the cursors
layout(std430, binding = 3) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = 4) writeonly buffer Refs { uint refs[]; };
layout(std430, binding = 5) writeonly buffer RefCells { uint refCells[]; };

uniform int uFirst, uTriangles;
uniform vec3 uTopSize;
uniform ivec3 uTop;
uniform float uEps;  // 1e-5 · |topSize|
uniform bool uEmit;

void main() {
  const uint t = gl_GlobalInvocationID.x + uint(uFirst);
  if (t >= uint(uTriangles)) return;
  vec3 a, b, c;
  triangleAt(t, a, b, c);
  const vec3 mn = minStd(a, minStd(b, c)), mx = maxStd(a, maxStd(b, c));
  ivec3 lo, hi;
  for (int i = 0; i < 3; ++i) {
    precise float l = (mn[i] - uLo[i]) / uTopSize[i], h = (mx[i] - uLo[i]) / uTopSize[i];
    lo[i] = clamp(int(l), 0, uTop[i] - 1);
    hi[i] = clamp(int(h), 0, uTop[i] - 1);
  }
  for (int z = lo.z; z <= hi.z; ++z)
    for (int y = lo.y; y <= hi.y; ++y)
      for (int x = lo.x; x <= hi.x; ++x) {
        precise vec3 bl = uLo + vec3(x, y, z) * uTopSize;
        precise vec3 bh = bl + uTopSize;
        if (!triangleBoxOverlap(a, b, c, bl, bh, uEps)) continue;
        const uint cell = (uint(z) * uint(uTop.y) + uint(y)) * uint(uTop.x) + uint(x);
        if (!uEmit) {
          atomicAdd(counts[cell], 1u);
        } else {
          const uint slot = offsets[cell] + atomicAdd(counts[cell], 1u);
          refs[slot] = t;
          refCells[slot] = cell;
        }
      }
}
