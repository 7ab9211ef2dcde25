#version 450
// The irregular grid's cell merging on the GPU (gpu/gpu_grid_build.h): which candidate pairs a
// pass joins. The CPU build's pass takes the pairs greedily in cell order, skipping a pair
// whose cell was merged already in the pass. Along a chain of candidates (cell → its partner
// beyond its upper face) the ids increase, as a leaf's id grows with its coordinates and a
// merged cell keeps the lower id, so that greedy choice takes the chain's first pair, skips the
// second, takes the third: a cell joins its partner when its rank from the chain's head is even.
// The ranks come from pointer jumping over the pred links (a round doubles the distance a link
// spans). Then each cell's fate and new reference count are written, the counts for the prefix
// sum that places the joined lists. One invocation per cell.
layout(local_size_x = 64) in;
// Per cell: (candidate, pred, union size, unused).
layout(std430, binding = 7) readonly buffer Scratch { uvec4 scratch[]; };
layout(std430, binding = 0) readonly buffer RankIn { uvec2 rankIn[]; };  // (distance to the head so far, link)
layout(std430, binding = 1) writeonly buffer RankOut { uvec2 rankOut[]; };
layout(std430, binding = 2) buffer Status { uint status[]; };  // [0]: the pairs joined this round
// Choose: per live cell (in the live list's order) its reference count after the pass. Alive:
// per cell 1 where it lives, for the prefix sum that numbers the live cells (list).
layout(std430, binding = 3) buffer NewCounts { uint newCounts[]; };
layout(std430, binding = 4) readonly buffer CellRefs { uvec2 cellRefs[]; };
// Per cell: kNone while it lives, else the cell that absorbed it.
layout(std430, binding = 5) buffer Fates { uint fates[]; };
// The live cells in increasing id; every mode but alive and list runs over these.
layout(std430, binding = 6) buffer Live { uint live[]; };

uniform int uFirst, uCells;  // the invocations: live cells, or all cells (alive, list)
uniform int uMode;  // 0: init, 1: a jumping round, 2: choose, 3: alive, 4: list

const uint kNone = 0xFFFFFFFFu;

bool joins(uint c) { return scratch[c].x != kNone && (rankIn[c].x & 1u) == 0u; }

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uCells)) return;
  if (uMode == 3) {
    newCounts[id] = fates[id] == kNone ? 1u : 0u;
    return;
  }
  if (uMode == 4) {
    if (fates[id] == kNone) live[newCounts[id]] = id;
    return;
  }
  const uint c = live[id];
  const uint pred = scratch[c].y;
  if (uMode == 0) {
    rankOut[c] = uvec2(pred != kNone ? 1u : 0u, pred);
  } else if (uMode == 1) {
    const uvec2 r = rankIn[c];
    rankOut[c] = r.y == kNone ? r : uvec2(r.x + rankIn[r.y].x, rankIn[r.y].y);
  } else {
    uint n = 0u;
    if (fates[c] != kNone) {
      // merged away earlier in this round
    } else if (joins(c)) {
      n = scratch[c].z;
      atomicAdd(status[0], 1u);
    } else if (pred != kNone && joins(pred)) {
      fates[c] = pred;  // absorbed: its pred writes the union
    } else {
      n = cellRefs[c].y;
    }
    newCounts[id] = n;
  }
}
