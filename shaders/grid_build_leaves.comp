#version 450
// The irregular grid's build, step 2 on the GPU (gpu/gpu_grid_build.h): each top cell fully
// subdivided to its octree depths, and the references of its leaves, one invocation per top-cell
// reference: the leaves its triangle's bounding box (grown by a leaf) overlaps, each tested
// exactly (irregular_grid_build.cpp initialGrid). A top cell of depth 0 is its own leaf and keeps
// its references untested. Counting, then emitting at the prefix sum, as grid_build_top.comp.
layout(local_size_x = 64) in;
#include "glm_float.glsl"
#include "grid_build_common.glsl"
layout(std430, binding = 2) readonly buffer TopRefs { uint topRefs[]; };
layout(std430, binding = 3) readonly buffer TopRefCells { uint topRefCells[]; };
layout(std430, binding = 4) readonly buffer TopInfo { uvec2 topInfo[]; };  // first leaf; depths x | y << 8 | z << 16
layout(std430, binding = 5) buffer Counts { uint counts[]; };               // per leaf: counting: counts; emitting: cursors
layout(std430, binding = 6) readonly buffer Offsets { uint offsets[]; };
layout(std430, binding = 7) writeonly buffer Refs { uint refs[]; };

uniform int uFirst, uTopRefCount;
uniform vec3 uVoxel;
uniform ivec3 uTop;
uniform int uDepth;  // D: the virtual grid is top · 2^D
uniform bool uEmit;

#define k1e5 uintBitsToFloat(0x3727C5ACu)  // 1e-5f

void add(uint leaf, uint t) {
  if (!uEmit) atomicAdd(counts[leaf], 1u);
  else refs[offsets[leaf] + atomicAdd(counts[leaf], 1u)] = t;
}

void main() {
  const uint r = gl_GlobalInvocationID.x + uint(uFirst);
  if (r >= uint(uTopRefCount)) return;
  const uint t = topRefs[r], c = topRefCells[r];
  const uvec2 info = topInfo[c];
  const ivec3 d = ivec3(info.y & 255u, (info.y >> 8) & 255u, (info.y >> 16) & 255u);
  if (d.x + d.y + d.z == 0) {
    add(info.x, t);
    return;
  }
  const ivec3 tc = ivec3(int(c % uint(uTop.x)), int(c / uint(uTop.x) % uint(uTop.y)), int(c / (uint(uTop.x) * uint(uTop.y))));
  const ivec3 n = ivec3(1) << d, span = ivec3(1) << (ivec3(uDepth) - d);
  const ivec3 base = tc << uDepth;
  vec3 a, b, cc;
  triangleAt(t, a, b, cc);
  precise vec3 leafSize = uVoxel * vec3(span);
  precise vec3 cellLo = uLo + vec3(base) * uVoxel;
  precise vec3 mn = (minStd(a, minStd(b, cc)) - cellLo) / leafSize, mx = (maxStd(a, maxStd(b, cc)) - cellLo) / leafSize;
  ivec3 lo, hi;
  for (int i = 0; i < 3; ++i) {
    lo[i] = clamp(int(floor(mn[i])) - 1, 0, n[i] - 1);
    hi[i] = clamp(int(floor(mx[i])) + 1, 0, n[i] - 1);
  }
  for (int z = lo.z; z <= hi.z; ++z)
    for (int y = lo.y; y <= hi.y; ++y)
      for (int x = lo.x; x <= hi.x; ++x) {
        const ivec3 vlo = base + ivec3(x, y, z) * span, vhi = vlo + span;
        precise vec3 bl = uLo + vec3(vlo) * uVoxel, bh = uLo + vec3(vhi) * uVoxel;
        precise vec3 size = bh - bl;
        precise float eps = k1e5 * sqrt(dotStd(size, size));
        if (triangleBoxOverlap(a, b, cc, bl, bh, eps)) add(info.x + uint((z * n.y + y) * n.x + x), t);
      }
}
