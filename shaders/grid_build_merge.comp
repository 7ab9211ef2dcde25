#version 450
// The irregular grid's cell merging on the GPU (Pérard-Gayot et al. 2017, step 3;
// gpu/gpu_grid_build.h), its first passes, one invocation per cell:
//  - init: every leaf a cell — its box, its references sorted by triangle, its voxel-map entry;
//  - candidates: a live cell's merge partner along the pass's axis, as mergeCandidate of
//    grid/irregular_grid_build.cpp decides it (the neighbour beyond the upper face with the same
//    extent across the axis, accepted by the SAH test), and the size of their references' union.
//    The partner's pred is set to the cell: each cell is the partner of at most one cell (its one
//    lower neighbour of the same extent), so the candidates form disjoint chains along the axis;
//  - clear (before candidates): no candidate, no pred;
//  - owners (one invocation per leaf, after a round's passes): the voxel map follows the cells
//    that died.
// Candidates and clear run over the live cells only.
layout(local_size_x = 64) in;
#include "grid_build_cells.glsl"
// Init: per leaf its first reference, [leaves] their total. Otherwise: the live cells, in
// increasing id (the invocations of candidates and clear run over these).
layout(std430, binding = 0) readonly buffer Words { uint words[]; };
// Per cell: kNone while it lives, else the cell that absorbed it.
layout(std430, binding = 1) buffer Fates { uint fates[]; };
// Per cell: (candidate, pred, union size, unused); kNone where none.
layout(std430, binding = 7) buffer Scratch { uvec4 scratch[]; };

uniform int uFirst, uCells, uTopCells;  // uCells: the invocations (cells, live cells or leaves)
uniform int uMode;  // 0: init, 1: candidates, 2: clear, 3: owners
uniform int uAxis;
uniform vec3 uVoxel;
uniform float uTraversalCost;

const uint kNone = 0xFFFFFFFFu;

// GridBuilder::area: the surface area of a box of voxels over two.
float area(ivec3 lo, ivec3 hi) {
  precise vec3 e = vec3(hi - lo) * uVoxel;
  precise float a = e.x * e.y + e.y * e.z + e.z * e.x;
  return a;
}

void init(uint c) {
  const uint begin = words[c], n = words[c + 1u] - begin;
  for (uint i = 1u; i < n; ++i) {  // insertion sort: a leaf holds a few references
    const uint key = refs[begin + i];
    uint j = i;
    for (; j > 0u && refs[begin + j - 1u] > key; --j) refs[begin + j] = refs[begin + j - 1u];
    refs[begin + j] = key;
  }
  // The leaf's top cell: the last whose first leaf is at or before c.
  uint lo = 0u, hi = uint(uTopCells);
  while (hi - lo > 1u) {
    const uint mid = (lo + hi) / 2u;
    if (topInfo[mid].x <= c) lo = mid;
    else hi = mid;
  }
  const uvec2 info = topInfo[lo];
  const uint k = c - info.x;
  const ivec3 d = ivec3(info.y & 255u, (info.y >> 8) & 255u, (info.y >> 16) & 255u);
  const ivec3 tc = ivec3(int(lo % uint(uTop.x)), int(lo / uint(uTop.x) % uint(uTop.y)), int(lo / (uint(uTop.x) * uint(uTop.y))));
  const ivec3 n3 = ivec3(1) << d, span = ivec3(1) << (ivec3(uDepth) - d);
  const ivec3 off = ivec3(int(k % uint(n3.x)), int(k / uint(n3.x) % uint(n3.y)), int(k / uint(n3.x * n3.y)));
  const ivec3 vlo = (tc << uDepth) + off * span;
  boxes[2u * c] = ivec4(vlo, 0);
  boxes[2u * c + 1u] = ivec4(vlo + span, 0);
  cellRefs[c] = uvec2(begin, n);
  owners[c] = c;
  fates[c] = kNone;
  scratch[c] = uvec4(kNone, kNone, 0u, 0u);
}

// GridBuilder::mergeCandidate.
uint candidate(uint a, out uint unionSize) {
  unionSize = 0u;
  const int axis = uAxis, u = (axis + 1) % 3, w = (axis + 2) % 3;
  const ivec3 alo = boxLo(a), ahi = boxHi(a);
  if (ahi[axis] >= uVirt[axis]) return kNone;
  ivec3 probe;
  probe[axis] = ahi[axis], probe[u] = alo[u], probe[w] = alo[w];
  uint b = cellAt(probe);
  while (fates[b] != kNone) b = fates[b];  // (the voxel map follows once per round)
  if (b == a) return kNone;
  const ivec3 blo = boxLo(b), bhi = boxHi(b);
  if (blo[axis] != ahi[axis] || blo[u] != alo[u] || bhi[u] != ahi[u] || blo[w] != alo[w] || bhi[w] != ahi[w]) return kNone;
  const uvec2 ra = cellRefs[a], rb = cellRefs[b];
  uint i = 0u, j = 0u, n = 0u;
  while (i < ra.y && j < rb.y) {
    const uint x = refs[ra.x + i], y = refs[rb.x + j];
    i += x <= y ? 1u : 0u;
    j += y <= x ? 1u : 0u;
    ++n;
  }
  n += (ra.y - i) + (rb.y - j);
  ivec3 hi = ahi;
  hi[axis] = bhi[axis];
  const float ct = uTraversalCost;
  precise float before = area(alo, ahi) * (ct + float(ra.y)) + area(blo, bhi) * (ct + float(rb.y));
  precise float after = area(alo, hi) * (ct + float(n));
  unionSize = n;
  return after > before ? kNone : b;
}

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uCells)) return;
  if (uMode == 0) {
    init(id);
    return;
  }
  if (uMode == 3) {  // id: a leaf
    uint o = owners[id];
    while (fates[o] != kNone) o = fates[o];
    owners[id] = o;
    return;
  }
  const uint c = words[id];
  if (uMode == 2) {
    scratch[c] = uvec4(kNone, kNone, 0u, 0u);
    return;
  }
  if (fates[c] != kNone) return;  // merged away earlier in this round
  uint unionSize;
  const uint b = candidate(c, unionSize);
  scratch[c].x = b;
  scratch[c].z = unionSize;
  if (b != kNone) scratch[b].y = c;
}
