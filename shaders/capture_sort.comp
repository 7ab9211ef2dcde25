#version 450
// Hofmann et al. 2017, §4.2: each pixel's list sorted to its k front-most fragments, written to
// the k-layer arrays with each fragment's z-thickness in place of the list pointer — the CPU's
// layer_arrays.cpp sortAndTruncate, with its minimum separation and adaptive thickness. The
// CPU keeps equal depths in list order, which is the reverse of triangle order there (its tiles
// emit triangles in ascending order and each new node goes to the list's head); the GPU's lists
// are in atomic order, so the same rule is stated as an order: depth ascending, then triangle
// descending. The pool's nodes are thin (depth, next; capture_lists.frag): the normal and
// material of the k fragments kept are evaluated here, as the list capture's fragment shader
// evaluated them for every fragment before, with the same arithmetic.
layout(local_size_x = 64) in;
uniform int uFirst;  // the first invocation of this dispatch (GpuContext::dispatch)

#include "capture_common.glsl"
#include "capture_surface.glsl"

layout(std430, binding = 0) readonly buffer Nodes { uvec2 nodes[]; };
layout(std430, binding = 1) readonly buffer Heads { uint heads[]; };
layout(std430, binding = 2) readonly buffer NodeTriangle { uint nodeTriangle[]; };
layout(std430, binding = 3) writeonly buffer Slots { uvec4 slots[]; };
layout(std430, binding = 4) writeonly buffer Counts { uint counts[]; };
layout(std430, binding = 5) writeonly buffer SlotTriangle { uint slotTriangle[]; };
layout(std430, binding = 6) readonly buffer Setups { TriangleSetup setups[]; };
layout(std430, binding = 7) readonly buffer CamNormals { vec4 camNormals[]; };
#include "capture_attributes.glsl"
uniform int uPixels, uK;
uniform float uThickness, uThicknessPerDepth, uMinSeparation;
uniform bool uAdaptive;
uniform uint uCapacity;

const uint kNull = 0xFFFFFFFFu;

float thicknessAt(float depth) {
  precise float t = uThickness + uThicknessPerDepth * depth;
  return t;
}
// a before b: nearer, or as near and from a later triangle.
bool before(float da, uint ta, float db, uint tb) { return da < db || (da == db && ta > tb); }

uint keptNode[16];
float keptBack[16];

void main() {
  const uint p = gl_GlobalInvocationID.x + uint(uFirst);
  if (p >= uint(uPixels)) return;
  int n = 0;
  if (!uAdaptive && uMinSeparation == 0.0) {
    // Insertion into k cells; fragments beyond the k-th are shifted out.
    float keptDepth[16];
    uint keptTri[16];
    for (uint i = heads[p]; i != kNull; i = nodes[i].y) {
      const float d = uintBitsToFloat(nodes[i].x);
      const uint t = nodeTriangle[i];
      if (n == uK && !before(d, t, keptDepth[uK - 1], keptTri[uK - 1])) continue;
      int j = min(n, uK - 1);
      while (j > 0 && before(d, t, keptDepth[j - 1], keptTri[j - 1])) {
        keptDepth[j] = keptDepth[j - 1];
        keptTri[j] = keptTri[j - 1];
        keptNode[j] = keptNode[j - 1];
        --j;
      }
      keptDepth[j] = d;
      keptTri[j] = t;
      keptNode[j] = i;
      n = min(n + 1, uK);
    }
    for (int j = 0; j < n; ++j) keptBack[j] = keptDepth[j] + thicknessAt(keptDepth[j]);
  } else {
    // The whole list in order, one fragment at a time: the next is the first after the last
    // one taken (selection; lists are short, and no array bounds their length).
    bool have = false;
    float lastD = 0.0, keptFront = 0.0;
    uint lastT = 0u;
    for (;;) {
      uint best = kNull;
      float bd = 0.0;
      uint bt = 0u;
      for (uint i = heads[p]; i != kNull; i = nodes[i].y) {
        const float d = uintBitsToFloat(nodes[i].x);
        const uint t = nodeTriangle[i];
        if (have && !before(lastD, lastT, d, t)) continue;
        if (best == kNull || before(d, t, bd, bt)) {
          best = i;
          bd = d;
          bt = t;
        }
      }
      if (best == kNull) break;
      have = true;
      lastD = bd;
      lastT = bt;
      if (uAdaptive) {
        // A fragment starting inside the last kept interval extends it.
        if (n > 0 && bd <= keptBack[n - 1]) {
          keptBack[n - 1] = max(keptBack[n - 1], bd + thicknessAt(bd));
          continue;
        }
        if (n == uK) break;
        keptNode[n] = best;
        keptBack[n] = bd + thicknessAt(bd);
        ++n;
      } else {
        // Minimum separation from the last kept fragment.
        if (n == uK) break;
        if (n > 0 && bd < keptFront + uMinSeparation) continue;
        keptNode[n] = best;
        keptBack[n] = bd + thicknessAt(bd);
        keptFront = bd;
        ++n;
      }
    }
  }
  counts[p] = uint(n);
  const uint base = p * uint(uK);
  for (int j = 0; j < uK; ++j) {
    if (j < n) {
      const uint depthBits = nodes[keptNode[j]].x, t = nodeTriangle[keptNode[j]];
      const float d = uintBitsToFloat(depthBits);
      precise float thickness = keptBack[j] - d;
      const uvec2 attributes = fragmentAttributes(setups[t], t, int(p % uint(uWidth)), int(p / uint(uWidth)), d);
      slots[base + uint(j)] = uvec4(depthBits, attributes, floatBitsToUint(uAdaptive ? thickness : thicknessAt(d)));
      slotTriangle[base + uint(j)] = t;
    } else {
      slots[base + uint(j)] = uvec4(0u);
      slotTriangle[base + uint(j)] = kNull;
    }
  }
}
