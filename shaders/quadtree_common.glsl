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

// std::min and std::max: the first argument unless the second is strictly smaller (larger), so
// that the choice between equal values (+0 and −0) is the CPU's.
float minStd(float a, float b) { return b < a ? b : a; }
float maxStd(float a, float b) { return a < b ? b : a; }

// −x with the sign bit flipped, so that −(+0) is −0 as on the CPU (a driver may negate as 0 − x).
float negStd(float x) { return uintBitsToFloat(floatBitsToUint(x) ^ 0x80000000u); }

// 0 + x as IEEE arithmetic gives it (−0 becomes +0): the first term of a CPU sum that starts at
// zero, which a compiler may fold to x.
float zeroPlus(float x) { return floatBitsToUint(x) == 0x80000000u ? 0.0 : x; }
vec3 zeroPlus(vec3 v) { return vec3(zeroPlus(v.x), zeroPlus(v.y), zeroPlus(v.z)); }

uint nodeIndex(int layer, int level, int x, int y) {
  return uint(layer) * uint(uNodesPerLayer) + uint(uLevelOffset[level]) + uint(y) * uint(uLevelWidth[level]) + uint(x);
}
