#version 450
// The quad-tree's construction (Widmer et al. 2015, supplement, Algorithms 1 and 2): the GLSL
// twin of src/layertrace/quadtree/quadtree_build.cpp. With uLevel 0, Algorithm 1 fits one plane
// per pixel of each layer (leafNode); above, Algorithm 2 merges four children into a proxy
// plane or a box (parentNode), one dispatch per level. One invocation per node of every layer;
// each work group adds its nodes of each kind to the level's counts.
layout(local_size_x = 64) in;
#include "glm_float.glsl"
#include "quadtree_common.glsl"
// Each slot's depth, k per pixel: the CPU's layers uploaded, or (LT_LEVEL0) a resident frame's
// level 0, whose intervals begin at the depth (gpu/gpu_frame.h).
#ifdef LT_LEVEL0
layout(std430, binding = 0) readonly buffer Level0 { vec2 level0[]; };
float depthOf(uint slot) { return level0[slot].x; }
#else
layout(std430, binding = 0) readonly buffer Depths { float depths[]; };
float depthOf(uint slot) { return depths[slot]; }
#endif
layout(std430, binding = 1) readonly buffer Counts { uint counts[]; };
layout(std430, binding = 2) buffer Nodes { QuadNode nodes[]; };
layout(std430, binding = 3) readonly buffer Scale { float depthScale; };
layout(std430, binding = 4) buffer Kinds { uint kinds[]; };  // per level: empty, plane, box
uniform int uFirst;
uniform int uLevel, uK;
uniform float uLambdaH, uLambdaD, uGammaNorm, uGammaDist;
uniform bool uPrintedLine8, uPrintedLine10;
shared uint sKinds[3];

bool present(int x, int y, int layer) {
  return counts[uint(y) * uint(uLevelWidth[0]) + uint(x)] > uint(layer);
}

// w = depthScale / depth of a pixel the layer holds.
float wAt(int x, int y, int layer) {
  precise float w = depthScale / depthOf((uint(y) * uint(uLevelWidth[0]) + uint(x)) * uint(uK) + uint(layer));
  return w;
}

// leafNode (Algorithm 1). The CPU marks a missing neighbour with NaN; here `present` says so.
QuadNode leafNode(int x, int y, int layer) {
  QuadNode n = QuadNode(0.0, 0.0, 0.0, 0u);
  if (!present(x, y, layer)) return n;
  const int W = uLevelWidth[0], H = uLevelHeight[0];
  const float w = wAt(x, y, layer);
  bool discontinuity = false;
  float grad[2] = float[2](0.0, 0.0);
  precise float laplacian = 0.0;
  for (int axis = 0; axis < 2; ++axis) {
    const int dx = axis == 0 ? 1 : 0, dy = axis == 1 ? 1 : 0;
    const bool hasPrev = axis == 0 ? x > 0 : y > 0, hasNext = axis == 0 ? x + 1 < W : y + 1 < H;
    const bool prevOk = hasPrev && present(x - dx, y - dy, layer), nextOk = hasNext && present(x + dx, y + dy, layer);
    if ((hasPrev && !prevOk) || (hasNext && !nextOk)) discontinuity = true;
    precise float fwd = 0.0, bwd = 0.0;
    if (nextOk) fwd = wAt(x + dx, y + dy, layer) - w;
    if (prevOk) bwd = w - wAt(x - dx, y - dy, layer);
    float d = 0.0;
    if (nextOk && prevOk) {
      const bool forwardSmaller = abs(fwd) < abs(bwd);
      d = forwardSmaller != uPrintedLine8 ? fwd : bwd;
      laplacian += abs(fwd - bwd);
    } else if (nextOk) {
      d = fwd;
    } else if (prevOk) {
      d = bwd;
    }
    if (uPrintedLine10) grad[axis] = abs(d) >= uLambdaH ? d : 0.0;
    else grad[axis] = abs(d) > uLambdaH ? 0.0 : d;
  }
  if (laplacian >= uLambdaD) discontinuity = true;
  n.a = w;
  n.b = grad[0];
  n.c = grad[1];
  n.flags = kQuadPlane | (discontinuity ? kQuadDiscontinuity : 0u);
  return n;
}

// nodeRange: [lo, hi] of w over a node `size` pixels wide.
void nodeRange(QuadNode n, float size, out float lo, out float hi) {
  if ((n.flags & kQuadKindMask) == kQuadPlane) {
    precise float r = 0.5 * size * (abs(n.b) + abs(n.c));
    precise float l = n.a - r, u = n.a + r;
    lo = l;
    hi = u;
  } else {
    lo = n.a;
    hi = n.b;
  }
}

// parentNode (Algorithm 2) from the four children ch (Empty outside the child level).
QuadNode parentNode(QuadNode ch[4], float childSize, float rootSize) {
  uint discontinuity = 0u;
  bool allPlanes = true, any = false;
  for (int i = 0; i < 4; ++i) {
    discontinuity |= ch[i].flags & kQuadDiscontinuity;
    allPlanes = allPlanes && (ch[i].flags & kQuadKindMask) == kQuadPlane;
    any = any || (ch[i].flags & kQuadKindMask) != kQuadEmpty;
  }
  QuadNode out_ = QuadNode(0.0, 0.0, 0.0, 0u);
  if (!any) return out_;
  if (allPlanes) {
    vec3 normal[4];
    for (int i = 0; i < 4; ++i) {
      precise float nx = negStd(ch[i].b) * rootSize, ny = negStd(ch[i].c) * rootSize;
      normal[i] = normalizeStd(vec3(nx, ny, 1.0));
    }
    precise vec3 sum = zeroPlus(normal[0]);  // the CPU's sum starts at zero
    for (int i = 1; i < 4; ++i) sum += normal[i];
    const vec3 proxy = normalizeStd(sum);
    float maxAngle = 0.0;
    for (int i = 0; i < 4; ++i) {
      precise float angle = 1.0 - dotStd(proxy, normal[i]);
      maxAngle = maxStd(maxAngle, angle);
    }
    if (maxAngle < uGammaNorm) {
      precise float gx = negStd(proxy.x) / (proxy.z * rootSize), gy = negStd(proxy.y) / (proxy.z * rootSize);
      precise float h = 0.5 * childSize;
      float value[16], residual[16];
      precise float mean = 0.0;  // (its first term goes through zeroPlus below)
      for (int i = 0; i < 4; ++i) {
        const float cx = (i & 1) != 0 ? h : -h, cy = (i & 2) != 0 ? h : -h;
        for (int corner = 0; corner < 4; ++corner) {
          const float ox = (corner & 1) != 0 ? h : -h, oy = (corner & 2) != 0 ? h : -h;
          precise float v = ch[i].a + ch[i].b * ox + ch[i].c * oy;
          precise float r = v - gx * (cx + ox) - gy * (cy + oy);
          value[i * 4 + corner] = v;
          residual[i * 4 + corner] = r;
          mean = i == 0 && corner == 0 ? zeroPlus(r) : mean + r;
        }
      }
      mean *= 1.0 / 16.0;
      float maxError = 0.0;
      for (int j = 0; j < 16; ++j) {
        precise float e = abs(residual[j] - mean) / maxStd(abs(value[j]), 1e-30);
        maxError = maxStd(maxError, e);
      }
      if (maxError < uGammaDist) {
        out_.a = mean;
        out_.b = gx;
        out_.c = gy;
        out_.flags = kQuadPlane | discontinuity;
        return out_;
      }
    }
  }
  // Lines 18–21: a box over the children's depth ranges.
  float lo = uintBitsToFloat(0x7f800000u), hi = -uintBitsToFloat(0x7f800000u);
  for (int i = 0; i < 4; ++i) {
    if ((ch[i].flags & kQuadKindMask) == kQuadEmpty) continue;
    float l, u;
    nodeRange(ch[i], childSize, l, u);
    lo = minStd(lo, l);
    hi = maxStd(hi, u);
  }
  out_.a = lo;
  out_.b = hi;
  out_.flags = kQuadBox | discontinuity;
  return out_;
}

void main() {
  const uint t = gl_LocalInvocationID.x;
  if (t < 3u) sKinds[t] = 0u;
  barrier();
  const int W = uLevelWidth[uLevel], H = uLevelHeight[uLevel];
  const uint perLayer = uint(W) * uint(H), i = gl_GlobalInvocationID.x + uint(uFirst);
  if (i < perLayer * uint(uK)) {
    const int layer = int(i / perLayer), x = int((i % perLayer) % uint(W)), y = int((i % perLayer) / uint(W));
    QuadNode n;
    if (uLevel == 0) {
      n = leafNode(x, y, layer);
    } else {
      const int cw = uLevelWidth[uLevel - 1], chh = uLevelHeight[uLevel - 1];
      QuadNode ch[4];
      for (int c = 0; c < 4; ++c) {
        const int cx = 2 * x + (c & 1), cy = 2 * y + (c >> 1);
        ch[c] = cx < cw && cy < chh ? nodes[nodeIndex(layer, uLevel - 1, cx, cy)] : QuadNode(0.0, 0.0, 0.0, 0u);
      }
      n = parentNode(ch, float(1 << (uLevel - 1)), float(1 << (uLevelCount - 1)));
    }
    nodes[nodeIndex(layer, uLevel, x, y)] = n;
    atomicAdd(sKinds[n.flags & kQuadKindMask], 1u);
  }
  barrier();
  if (t < 3u && sKinds[t] != 0u) atomicAdd(kinds[uint(uLevel) * 3u + t], sKinds[t]);
}
