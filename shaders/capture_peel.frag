#version 450
// Depth peeling (Everitt 2001; the baseline of Hofmann et al. 2017, Fig. 8): layer L of every
// pixel is the nearest fragment behind layer L − 1, found by rasterizing the whole scene again.
// Each layer takes two geometry passes with 32-bit atomics: pass 0 finds the layer's depth
// (atomicMin on the depth's bits, order-preserving for positive floats), pass 1 the triangle
// among the fragments at exactly that depth (the later triangle first, as the list capture's
// order). Nothing is stored per fragment: capture_peel_resolve.comp evaluates the winners.

#include "capture_common.glsl"
#include "capture_surface.glsl"

layout(std430, binding = 0) readonly buffer Setups { TriangleSetup setups[]; };
layout(std430, binding = 1) buffer PeelDepth { uint peelDepth[]; };      // per pixel and layer; 0xFFFFFFFF: none
layout(std430, binding = 2) buffer PeelTriangle { uint peelTriangle[]; };  // triangle + 1; 0: none
layout(std430, binding = 3) buffer Complexity { uint complexity[]; };
uniform int uLayer, uPass, uK;
uniform float uMinSeparation;

void main() {
  const int px = int(gl_FragCoord.x), py = int(gl_FragCoord.y);
  const uint t = uint(gl_PrimitiveID);
  const TriangleSetup ts = setups[t];
  if (ts.v0.w != 0.0) return;
  vec3 origin, dir;
  pixelRay(px, py, origin, dir);
  const float depth = fragmentDepth(ts, origin, dir);
  uint unused;
  if (!fragmentSurface(ts, t, origin, dir, depth, false, unused)) return;  // cut away by the alpha test
  const uint pixel = uint(py) * uint(uWidth) + uint(px);
  if (uLayer == 0 && uPass == 0) atomicAdd(complexity[pixel], 1u);
  const uint slot = pixel * uint(uK) + uint(uLayer);
  if (uLayer > 0) {
    // Only what lies behind the previous layer (depth, then triangle descending).
    const uint prevBits = peelDepth[slot - 1u];
    if (prevBits == 0xFFFFFFFFu) return;
    const float prev = uintBitsToFloat(prevBits);
    const uint prevTri = peelTriangle[slot - 1u] - 1u;
    if (uMinSeparation > 0.0) {
      if (depth < prev + uMinSeparation) return;
    } else if (!(depth > prev || (depth == prev && t < prevTri))) {
      return;
    }
  }
  const uint bits = floatBitsToUint(depth);
  if (uPass == 0) atomicMin(peelDepth[slot], bits);
  else if (bits == peelDepth[slot]) atomicMax(peelTriangle[slot], t + 1u);
}
