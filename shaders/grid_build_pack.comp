#version 450
// The irregular grid's build on the GPU, last step (gpu/gpu_grid_build.h): the cells as the
// traversal reads them (IrregularGrid::packForTraversal), one invocation per cell. The first
// run gives each live cell's size in walk units (0 for a cell merged away); after their prefix
// sum, the second writes its 32-byte record (expanded box in virtual voxels, reference count,
// id among the live cells) and its blocks of four triangles (vertex coordinates lane by lane,
// then the ids; spare lanes repeat the last triangle).
layout(local_size_x = 64) in;
#include "glm_float.glsl"
#include "grid_build_common.glsl"
layout(std430, binding = 2) readonly buffer Expanded { ivec4 expanded[]; };  // per cell: [lo, hi)
layout(std430, binding = 3) readonly buffer CellRefs { uvec2 cellRefs[]; };   // first reference, count
layout(std430, binding = 4) readonly buffer Refs { uint refs[]; };
layout(std430, binding = 5) buffer Units { uint units[]; };                   // first run: sizes; second: first unit
layout(std430, binding = 6) writeonly buffer Walk { uint walk[]; };
// The exclusive prefix sum of the cells' liveness: a live cell's id after merging.
layout(std430, binding = 7) readonly buffer Ids { uint ids[]; };

uniform int uFirst, uCells;
uniform bool uWrite;

void main() {
  const uint c = gl_GlobalInvocationID.x + uint(uFirst);
  if (c >= uint(uCells)) return;
  const bool live = ids[c + 1u] != ids[c];
  const uint begin = cellRefs[c].x, n = cellRefs[c].y;
  if (!uWrite) {
    const uint size = 1u + (n + 3u) / 4u * 5u;  // grid/irregular_grid.h cellUnits
    units[c] = live ? size + size % 2u : 0u;
    return;
  }
  if (!live) return;
  const ivec3 lo = expanded[2u * c].xyz, hi = expanded[2u * c + 1u].xyz;
  const uint w = units[c] * 8u;
  walk[w] = uint(lo.x), walk[w + 1u] = uint(lo.y), walk[w + 2u] = uint(lo.z);
  walk[w + 3u] = uint(hi.x), walk[w + 4u] = uint(hi.y), walk[w + 5u] = uint(hi.z);
  walk[w + 6u] = n, walk[w + 7u] = ids[c];
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
}
