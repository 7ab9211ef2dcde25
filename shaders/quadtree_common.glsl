// The plane/box quad-tree of Widmer et al. 2015 on the GPU: the node of
// src/layertrace/quadtree/quadtree.h (QuadNode, 16 bytes) in the same layer-major layout
// ([layer][level offset + y · level width + x]), so that the CPU's build and the GPU's compare
// node for node. Each function is the GLSL twin of a CPU function named beside it and computes
// the same floats in the same order; `precise` keeps the compiler from contracting or
// reassociating them (the CPU build uses -ffp-contract=off).
struct QuadNode {
  float a, b, c;
  uint flags;
};
const uint kQuadEmpty = 0u, kQuadPlane = 1u, kQuadBox = 2u, kQuadKindMask = 3u, kQuadDiscontinuity = 4u;

#define kMaxQuadLevels 24
uniform int uLevelCount;
uniform int uLevelWidth[kMaxQuadLevels], uLevelHeight[kMaxQuadLevels], uLevelOffset[kMaxQuadLevels];
uniform int uNodesPerLayer;

uint nodeIndex(int layer, int level, int x, int y) {
  return uint(layer) * uint(uNodesPerLayer) + uint(uLevelOffset[level]) + uint(y) * uint(uLevelWidth[level]) + uint(x);
}
