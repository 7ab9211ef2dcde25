#version 450
// The irregular grid's cell expansion on the GPU (Pérard-Gayot et al. 2017, step 4;
// gpu/gpu_grid_build.h), one invocation per cell: GridBuilder::expandFace of
// grid/irregular_grid_build.cpp for the six faces in the CPU's order. A face moves over the
// voxel layers beyond it, by the thinnest neighbour's depth, when every neighbour there
// references only triangles the cell references (or, with partial expansion, none of its
// others overlaps the swept part). A cell changes only its own expanded box and reads its
// neighbours' boxes and references, which expansion never changes: the passes give the CPU's
// boxes whatever the order of the invocations.
layout(local_size_x = 64) in;
#include "glm_float.glsl"
#include "grid_build_common.glsl"
#include "grid_build_cells.glsl"
// Per cell: its expanded box [lo, hi), two ivec4 (w unused); after the cells, [2 · cells].x
// counts the faces moved.
layout(std430, binding = 7) buffer Expanded { ivec4 expanded[]; };

uniform int uFirst, uCells;
uniform int uMode;  // 0: the expanded boxes start as the boxes, 1: a pass
uniform vec3 uVoxel;
uniform bool uPartial;

#define k1e5 uintBitsToFloat(0x3727C5ACu)  // 1e-5f

vec3 voxelLo(ivec3 v) {
  precise vec3 p = uLo + vec3(v) * uVoxel;
  return p;
}

// The neighbours of face (axis, side) of cell a with expanded box [elo, ehi): the walk over the
// voxel layer beyond the face, as expandFace makes it. With `check`, whether every neighbour may
// be swept over the slab [slo, shi); else the thinnest neighbour's depth.
int neighbours(uint a, ivec3 elo, ivec3 ehi, int axis, int side, bool check, ivec3 slo, ivec3 shi) {
  const int u = (axis + 1) % 3, w = (axis + 2) % 3;
  const int face = side != 0 ? ehi[axis] : elo[axis];
  const int layer = side != 0 ? face : face - 1;
  int depth = 1 << 30;
  for (int vw = elo[w]; vw < ehi[w];) {
    int nextW = ehi[w];
    for (int vu = elo[u]; vu < ehi[u];) {
      ivec3 p;
      p[axis] = layer, p[u] = vu, p[w] = vw;
      const uint b = cellAt(p);
      const ivec3 blo = boxLo(b), bhi = boxHi(b);
      if (check && b != a && !includesRefs(cellRefs[a], cellRefs[b])) {
        if (!uPartial) return 0;
        // Partial expansion: only b's triangles inside the swept part of b must be a's.
        const vec3 lo = voxelLo(max(slo, blo)), hi = voxelLo(min(shi, bhi));
        precise vec3 size = hi - lo;
        precise float eps = k1e5 * sqrt(dotStd(size, size));
        const uvec2 ra = cellRefs[a], rb = cellRefs[b];
        for (uint k = 0u; k < rb.y; ++k) {
          const uint t = refs[rb.x + k];
          if (holdsRef(ra, t)) continue;
          vec3 v0, v1, v2;
          triangleAt(t, v0, v1, v2);
          if (triangleBoxOverlap(v0, v1, v2, lo, hi, eps)) return 0;
        }
      }
      depth = min(depth, side != 0 ? bhi[axis] - face : face - blo[axis]);
      nextW = min(nextW, bhi[w]);
      vu = bhi[u];
    }
    vw = nextW;
  }
  return depth;
}

void main() {
  const uint a = gl_GlobalInvocationID.x + uint(uFirst);
  if (a >= uint(uCells)) return;
  if (uMode == 0) {
    expanded[2u * a] = boxes[2u * a];
    expanded[2u * a + 1u] = boxes[2u * a + 1u];
    return;
  }
  if (boxes[2u * a].w != 0) return;  // merged away
  ivec3 elo = expanded[2u * a].xyz, ehi = expanded[2u * a + 1u].xyz;
  uint moved = 0u;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int face = side != 0 ? ehi[axis] : elo[axis];
      if ((side != 0 && face >= uVirt[axis]) || (side == 0 && face <= 0)) continue;
      const int depth = neighbours(a, elo, ehi, axis, side, false, ivec3(0), ivec3(0));
      if (depth <= 0 || depth == (1 << 30)) continue;
      ivec3 slo = elo, shi = ehi;
      slo[axis] = side != 0 ? face : face - depth;
      shi[axis] = side != 0 ? face + depth : face;
      if (neighbours(a, elo, ehi, axis, side, true, slo, shi) == 0) continue;
      if (side != 0) ehi[axis] += depth;
      else elo[axis] -= depth;
      ++moved;
    }
  expanded[2u * a] = ivec4(elo, 0);
  expanded[2u * a + 1u] = ivec4(ehi, 0);
  if (moved > 0u) atomicAdd(expanded[2u * uint(uCells)].x, int(moved));
}
