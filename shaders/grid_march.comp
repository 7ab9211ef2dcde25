#version 450
// The irregular grid's traversal (Pérard-Gayot et al. 2017): the GLSL twin of
// src/layertrace/grid/irregular_grid_traverse.cpp's one-ray traversal, one invocation per
// query, over the CPU's packed structure (IrregularGrid::Packed). Locate the entry voxel's cell
// in the two-level voxel map, test its triangles four at a time with the watertight test of
// Woop, Benthin and Wald (JCGT 2013), stop where the closest hit lies inside the cell's expanded
// box, else step to the voxel beyond the exit face.
layout(local_size_x = 64) in;
#include "glm_float.glsl"
// A query: world-space origin and tnear, direction and tfar.
layout(std430, binding = 0) readonly buffer Queries { vec4 queries[]; };
// Per query two words of four: (t's bits, triangle or 0xFFFFFFFF, cells visited, triangles
// tested) and (the geometric normal's x, y, z bits; flags: 1 where a step cap ended the walk,
// 2 where a candidate hit lay on an alpha-tested triangle, which this pass cannot decide).
layout(std430, binding = 1) writeonly buffer Answers { uvec4 answers[]; };
layout(std430, binding = 2) readonly buffer TopCells { uint topCells[]; };  // three words each
layout(std430, binding = 3) readonly buffer Leaves { uint leaves[]; };      // walk unit of each leaf's cell
layout(std430, binding = 4) readonly buffer Walk { uint walk[]; };          // records and triangle blocks
layout(std430, binding = 5) readonly buffer CutOuts { uint cutOutBits[]; }; // a bit per triangle: alpha-tested

uniform int uQueryCount, uFirst;
uniform vec3 uLo, uHi, uVoxel, uInvVoxel;
uniform ivec3 uTop, uVirt;
uniform int uDepth;
uniform bool uAnyHit;
uniform bool uCutOuts;  // the scene has alpha-tested triangles (cutOutBits holds them)

#define kInf uintBitsToFloat(0x7f800000u)
const uint kMiss = 0xFFFFFFFFu;

// IrregularGrid::leafIndex: the walk unit of the cell holding voxel v.
uint cellAt(ivec3 v) {
  const uint top = 3u * ((uint(v.z >> uDepth) * uint(uTop.y) + uint(v.y >> uDepth)) * uint(uTop.x) + uint(v.x >> uDepth));
  const uint offset = topCells[top], shifts = topCells[top + 1u], bits2 = topCells[top + 2u] & 255u;
  const int mask = (1 << uDepth) - 1;
  const uint l0 = uint(v.x & mask) >> (shifts & 255u), l1 = uint(v.y & mask) >> ((shifts >> 8) & 255u),
             l2 = uint(v.z & mask) >> ((shifts >> 16) & 255u);
  return leaves[offset + ((l2 << bits2) + (l1 << (shifts >> 24)) + l0)];
}

// Walk: one ray's state (IrregularGrid::Walk).
vec3 wo, wd, winv;
int kx, ky, kz;
float sx, sy;
float tnear, t1, bestT, tExit;
uint bestTriangle = kMiss;
uint bestWord = 0u;  // the block's first word, of the closest hit
int bestLane = 0;
ivec3 wv;
bool undecided = false;  // a candidate hit on an alpha-tested triangle: the texture decides (on the CPU)

float at(vec3 v, int i) { return i == 0 ? v.x : i == 1 ? v.y : v.z; }

// IrregularGrid::enter.
bool enter(vec3 o, vec3 d, float tn, float tf) {
  float t0 = tn;
  t1 = tf;
  precise vec3 inv = vec3(1.0) / d;
  for (int i = 0; i < 3; ++i) {
    precise float a = (uLo[i] - o[i]) * inv[i], b = (uHi[i] - o[i]) * inv[i];
    if (a > b) {
      const float s = a;
      a = b;
      b = s;
    }
    if (isnan(a)) a = -kInf;  // 0 · inf
    if (isnan(b)) b = kInf;
    t0 = maxStd(t0, a);
    t1 = minStd(t1, b);
  }
  if (t0 > t1) return false;
  precise vec3 p = (o + d * t0 - uLo) * uInvVoxel;
  wv = clamp(ivec3(floor(p)), ivec3(0), uVirt - 1);
  wo = o;
  wd = d;
  winv = inv;
  // WatertightRay.
  const vec3 a = abs(d);
  kz = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
  kx = kz == 2 ? 0 : kz + 1;
  ky = kx == 2 ? 0 : kx + 1;
  if (at(d, kz) < 0.0) {
    const int s = kx;
    kx = ky;
    ky = s;
  }
  precise float shx = at(d, kx) / at(d, kz), shy = at(d, ky) / at(d, kz);
  sx = shx;
  sy = shy;
  tnear = tn;
  bestT = tf;
  return true;
}

ivec3 recordBox(uint word, int which) {
  return ivec3(int(walk[word + uint(which)]), int(walk[word + uint(which) + 1u]), int(walk[word + uint(which) + 2u]));
}

// IrregularGrid::exitCell for the record at `word`.
bool exitCell(uint word) {
  const ivec3 elo = recordBox(word, 0), ehi = recordBox(word, 3);
  float t[3];
  for (int i = 0; i < 3; ++i) {
    precise float bound = uLo[i] + float(wd[i] > 0.0 ? ehi[i] : elo[i]) * uVoxel[i];
    precise float ti = (bound - wo[i]) * winv[i];
    t[i] = wd[i] == 0.0 ? kInf : ti;
  }
  const bool y = t[1] < t[0];
  const float t01 = y ? t[1] : t[0];
  const bool z = t[2] < t01;
  const int axis = z ? 2 : (y ? 1 : 0);
  tExit = z ? t[2] : t01;
  if (!(tExit < t1)) return false;
  precise vec3 q = (wo + wd * tExit - uLo) * uInvVoxel;
  for (int i = 0; i < 3; ++i) {
    const int face = clamp(int(floor(q[i])), elo[i], ehi[i] - 1);
    const int beside = wd[i] > 0.0 ? max(face, wv[i]) : wd[i] < 0.0 ? min(face, wv[i]) : face;
    const int beyond = wd[i] > 0.0 ? ehi[i] : elo[i] - 1;
    wv[i] = i == axis ? beyond : beside;
  }
  return wv[axis] >= 0 && wv[axis] < uVirt[axis];
}

float vertex(uint block, int v, int axis, int lane) { return uintBitsToFloat(walk[block + uint((v * 3 + axis) * 4 + lane)]); }

// IrregularGrid::testCell (hitBlock lane by lane): true when the ray is answered.
bool testCell(uint word, bool more) {
  const uint refs = walk[word + 6u];
  for (uint k = 0u; k < (refs + 3u) / 4u; ++k) {
    const uint block = word + 8u + 40u * k;
    for (int l = 0; l < 4; ++l) {
      vec3 p[3];
      for (int v = 0; v < 3; ++v) {
        precise vec3 pv = vec3(vertex(block, v, 0, l), vertex(block, v, 1, l), vertex(block, v, 2, l)) - wo;
        p[v] = pv;
      }
      precise float ax = at(p[0], kx) - sx * at(p[0], kz), ay = at(p[0], ky) - sy * at(p[0], kz);
      precise float bx = at(p[1], kx) - sx * at(p[1], kz), by = at(p[1], ky) - sy * at(p[1], kz);
      precise float cx = at(p[2], kx) - sx * at(p[2], kz), cy = at(p[2], ky) - sy * at(p[2], kz);
      precise float u = cx * by - cy * bx, v = ax * cy - ay * cx, w = bx * ay - by * ax;
      precise float sum = u + v + w;
      const bool inside = !((u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0)) && sum != 0.0;
      if (!inside) continue;
      const vec3 v0 = vec3(vertex(block, 0, 0, l), vertex(block, 0, 1, l), vertex(block, 0, 2, l));
      precise vec3 e1 = vec3(vertex(block, 1, 0, l), vertex(block, 1, 1, l), vertex(block, 1, 2, l)) - v0;
      precise vec3 e2 = vec3(vertex(block, 2, 0, l), vertex(block, 2, 1, l), vertex(block, 2, 2, l)) - v0;
      precise float nx = e1.y * e2.z - e1.z * e2.y, ny = e1.z * e2.x - e1.x * e2.z, nz = e1.x * e2.y - e1.y * e2.x;
      precise float den = nx * wd.x + ny * wd.y + nz * wd.z;
      precise float t = (nx * p[0].x + ny * p[0].y + nz * p[0].z) / den;
      if (!(den != 0.0 && t > tnear && t <= bestT)) continue;
      const uint tri = walk[block + 36u + uint(l)];
      if (uCutOuts && (cutOutBits[tri >> 5] & (1u << (tri & 31u))) != 0u) {
        undecided = true;  // the ray is answered by the CPU grid, which reads the texture
        return true;
      }
      if (uAnyHit) {
        bestT = t;
        bestTriangle = tri;
        return true;
      }
      if (t < bestT || (t == bestT && tri < bestTriangle)) {
        bestT = t;
        bestTriangle = tri;
        bestWord = block;
        bestLane = l;
      }
    }
  }
  return (bestTriangle != kMiss && bestT <= tExit) || !more;
}

void main() {
  const uint id = gl_GlobalInvocationID.x + uint(uFirst);
  if (id >= uint(uQueryCount)) return;
  const vec4 a = queries[2u * id], b = queries[2u * id + 1u];
  uint steps = 0u, tests = 0u, giveUp = 0u;
  vec3 ng = vec3(0.0);
  if (enter(a.xyz, b.xyz, a.w, b.w)) {
    const int maxSteps = 4 * (uVirt.x + uVirt.y + uVirt.z) + 16;
    uint word = 8u * cellAt(wv);
    for (int step = 0;;) {
      ++steps;
      tests += walk[word + 6u];
      const bool more = exitCell(word);
      const uint current = word;
      if (more) word = 8u * cellAt(wv);
      if (testCell(current, more)) break;
      if (++step == maxSteps) {
        giveUp = 1u;
        break;
      }
    }
    if (bestTriangle != kMiss && !uAnyHit && !undecided) {
      // IrregularGrid::finish: the normal from the block's copy of the vertices.
      vec3 p[3];
      for (int v = 0; v < 3; ++v) p[v] = vec3(vertex(bestWord, v, 0, bestLane), vertex(bestWord, v, 1, bestLane), vertex(bestWord, v, 2, bestLane));
      precise vec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
      ng = crossStd(e1, e2);
    }
  }
  answers[2u * id] = uvec4(floatBitsToUint(bestT), bestTriangle, steps, tests);
  answers[2u * id + 1u] = uvec4(floatBitsToUint(ng.x), floatBitsToUint(ng.y), floatBitsToUint(ng.z), giveUp | (undecided ? 2u : 0u));
}
