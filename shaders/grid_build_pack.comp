#version 450
// The irregular grid's build on the GPU, last step (gpu/gpu_grid_build.h): the leaves as the
// traversal reads them (IrregularGrid::packForTraversal). The first run sorts each leaf's
// references by triangle (the CPU's order) and gives its size in walk units; after their prefix
// sum, the second writes its 32-byte record (box in virtual voxels, reference count, id) and its
// blocks of four triangles (vertex coordinates lane by lane, then the ids; spare lanes repeat the
// last triangle), and points the voxel map's leaf at it. One invocation per leaf.
layout(local_size_x = 64) in;
#include "glm_float.glsl"
#include "grid_build_common.glsl"
layout(std430, binding = 2) readonly buffer TopInfo { uvec2 topInfo[]; };  // first leaf; depths x | y << 8 | z << 16
layout(std430, binding = 3) readonly buffer Offsets { uint offsets[]; };   // per leaf: its first reference
layout(std430, binding = 4) buffer Refs { uint refs[]; };
layout(std430, binding = 5) buffer Units { uint units[]; };                // first run: sizes; second: first unit
layout(std430, binding = 6) writeonly buffer Walk { uint walk[]; };
layout(std430, binding = 7) writeonly buffer Leaves { uint leaves[]; };

uniform int uFirst, uLeaves, uTopCells;
uniform ivec3 uTop;
uniform int uDepth;
uniform bool uWrite;

void main() {
  const uint l = gl_GlobalInvocationID.x + uint(uFirst);
  if (l >= uint(uLeaves)) return;
  const uint begin = offsets[l], n = offsets[l + 1u] - begin;
  if (!uWrite) {
    for (uint i = 1u; i < n; ++i) {  // insertion sort: a leaf holds a few references
      const uint key = refs[begin + i];
      uint j = i;
      for (; j > 0u && refs[begin + j - 1u] > key; --j) refs[begin + j] = refs[begin + j - 1u];
      refs[begin + j] = key;
    }
    const uint size = 1u + (n + 3u) / 4u * 5u;
    units[l] = size + size % 2u;
    return;
  }
  // The leaf's top cell: the last whose first leaf is at or before l.
  uint lo = 0u, hi = uint(uTopCells);
  while (hi - lo > 1u) {
    const uint mid = (lo + hi) / 2u;
    if (topInfo[mid].x <= l) lo = mid;
    else hi = mid;
  }
  const uint c = lo, k = l - topInfo[c].x;
  const uvec2 info = topInfo[c];
  const ivec3 d = ivec3(info.y & 255u, (info.y >> 8) & 255u, (info.y >> 16) & 255u);
  const ivec3 tc = ivec3(int(c % uint(uTop.x)), int(c / uint(uTop.x) % uint(uTop.y)), int(c / (uint(uTop.x) * uint(uTop.y))));
  const ivec3 n3 = ivec3(1) << d, span = ivec3(1) << (ivec3(uDepth) - d);
  const ivec3 off = ivec3(int(k % uint(n3.x)), int(k / uint(n3.x) % uint(n3.y)), int(k / uint(n3.x * n3.y)));
  const ivec3 vlo = (tc << uDepth) + off * span, vhi = vlo + span;
  const uint unit = units[l], w = unit * 8u;
  walk[w] = uint(vlo.x), walk[w + 1u] = uint(vlo.y), walk[w + 2u] = uint(vlo.z);
  walk[w + 3u] = uint(vhi.x), walk[w + 4u] = uint(vhi.y), walk[w + 5u] = uint(vhi.z);
  walk[w + 6u] = n, walk[w + 7u] = l;
  for (uint b = 0u; b < (n + 3u) / 4u; ++b) {
    const uint bw = w + 8u + b * 40u;
    for (uint lane = 0u; lane < 4u; ++lane) {
      const uint t = refs[begin + min(b * 4u + lane, n - 1u)];
      for (uint vtx = 0u; vtx < 3u; ++vtx) {
        const vec3 p = vertexAt(indices[3u * t + vtx]);
        for (uint axis = 0u; axis < 3u; ++axis) walk[bw + vtx * 12u + axis * 4u + lane] = floatBitsToUint(p[axis]);
      }
      walk[bw + 36u + lane] = t;
    }
  }
  leaves[l] = unit;
}
