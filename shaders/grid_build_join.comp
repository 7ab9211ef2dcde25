#version 450
// The irregular grid's cell merging on the GPU (gpu/gpu_grid_build.h), the end of a pass, one
// invocation per live cell: a joining cell's references become the sorted union of its own and
// its partner's, at the prefix sum of the new counts, and its box reaches over the partner's
// (GridBuilder::join); every other live cell's references move over unchanged.
layout(local_size_x = 64) in;
// In the live list's order: the new counts' exclusive prefix sum.
layout(std430, binding = 0) readonly buffer NewBegin { uint newBegin[]; };
layout(std430, binding = 1) writeonly buffer RefsOut { uint refsOut[]; };
layout(std430, binding = 2) readonly buffer Rank { uvec2 rank[]; };  // (distance to the chain's head, link)
layout(std430, binding = 3) buffer Boxes { ivec4 boxes[]; };
layout(std430, binding = 4) buffer CellRefs { uvec2 cellRefs[]; };
layout(std430, binding = 5) readonly buffer RefsIn { uint refsIn[]; };
layout(std430, binding = 6) readonly buffer Live { uint live[]; };  // the live cells in increasing id
layout(std430, binding = 7) readonly buffer Scratch { uvec4 scratch[]; };  // (candidate, pred, union size, unused)

uniform int uFirst, uCells;
uniform int uAxis;

const uint kNone = 0xFFFFFFFFu;

bool joins(uint c) { return scratch[c].x != kNone && (rank[c].x & 1u) == 0u; }

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uCells)) return;
  const uint c = live[id];
  if (boxes[2u * c].w != 0) return;  // merged away earlier in this round
  const uint pred = scratch[c].y;
  if (pred != kNone && joins(pred)) {
    boxes[2u * c].w = 1;  // merged away (the expansion skips it)
    return;
  }
  const uint out0 = newBegin[id];
  const uvec2 ra = cellRefs[c];
  const uint b = scratch[c].x;
  if (joins(c)) {
    const uvec2 rb = cellRefs[b];
    // std::set_union of two sorted lists without duplicates.
    uint i = 0u, j = 0u, o = out0;
    while (i < ra.y && j < rb.y) {
      const uint x = refsIn[ra.x + i], y = refsIn[rb.x + j];
      refsOut[o++] = x <= y ? x : y;
      i += x <= y ? 1u : 0u;
      j += y <= x ? 1u : 0u;
    }
    for (; i < ra.y; ++i) refsOut[o++] = refsIn[ra.x + i];
    for (; j < rb.y; ++j) refsOut[o++] = refsIn[rb.x + j];
    cellRefs[c] = uvec2(out0, o - out0);
    boxes[2u * c + 1u][uAxis] = boxes[2u * b + 1u][uAxis];
  } else {
    for (uint i = 0u; i < ra.y; ++i) refsOut[out0 + i] = refsIn[ra.x + i];
    cellRefs[c] = uvec2(out0, ra.y);
  }
}
