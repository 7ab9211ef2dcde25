// What the irregular grid's merging and expansion passes on the GPU share (gpu/gpu_grid_build.h):
// the cells, their references and the voxel map from a virtual voxel to the live cell holding
// it. Cells keep the ids of the leaves they started as (a leaf is a cell until merged away);
// after merging, the live ones are numbered in id order, as the CPU build compacts them.

// Per top cell: its first leaf; its octree depths x | y << 8 | z << 16.
layout(std430, binding = 2) readonly buffer TopInfo { uvec2 topInfo[]; };
// Per cell: its box in virtual voxels [lo, hi), as two ivec4; the first's w is 1 once the cell
// was merged away.
layout(std430, binding = 3) buffer Boxes { ivec4 boxes[]; };
// Per cell: its first reference and their count; the references sorted by triangle.
layout(std430, binding = 4) buffer CellRefs { uvec2 cellRefs[]; };
layout(std430, binding = 5) buffer Refs { uint refs[]; };
// Per leaf: the live cell that holds it (the CPU build's live(leaf_[…])).
layout(std430, binding = 6) buffer Owners { uint owners[]; };

uniform ivec3 uTop;  // top-level resolution
uniform int uDepth;  // D: the virtual grid is top · 2^D
uniform ivec3 uVirt;

// IrregularGrid::leafIndex: the leaf holding virtual voxel v.
uint leafAt(ivec3 v) {
  const ivec3 tc = v >> uDepth;
  const uint c = (uint(tc.z) * uint(uTop.y) + uint(tc.y)) * uint(uTop.x) + uint(tc.x);
  const uvec2 info = topInfo[c];
  const ivec3 d = ivec3(info.y & 255u, (info.y >> 8) & 255u, (info.y >> 16) & 255u);
  const ivec3 l = (v & ((1 << uDepth) - 1)) >> (ivec3(uDepth) - d);
  return info.x + uint((l.z << (d.x + d.y)) + (l.y << d.x) + l.x);
}

uint cellAt(ivec3 v) { return owners[leafAt(v)]; }
ivec3 boxLo(uint c) { return boxes[2u * c].xyz; }
ivec3 boxHi(uint c) { return boxes[2u * c + 1u].xyz; }

// std::includes(big, small) of two cells' sorted references.
bool includesRefs(uvec2 big, uvec2 small) {
  uint i = 0u;
  for (uint j = 0u; j < small.y; ++j) {
    const uint t = refs[small.x + j];
    while (i < big.y && refs[big.x + i] < t) ++i;
    if (i == big.y || refs[big.x + i] != t) return false;
    ++i;
  }
  return true;
}

// std::binary_search of triangle t in a cell's sorted references.
bool holdsRef(uvec2 r, uint t) {
  uint lo = 0u, hi = r.y;
  while (lo < hi) {
    const uint mid = (lo + hi) / 2u;
    const uint v = refs[r.x + mid];
    if (v < t) lo = mid + 1u;
    else hi = mid;
  }
  return lo < r.y && refs[r.x + lo] == t;
}
