// seed 003 traversal: locate the origin's cell, intersect its primitives, exit if the hit lies
// within the cell, otherwise locate the exit point and move to the next cell. Stackless and
// ordered; the next cell is found in the voxel map from integer virtual-grid coordinates on the
// far side of the exit face, so rounding can never step back or skip a cell along the ray.
#include <algorithm>
#include <cstring>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "layertrace/geometry/irregular_grid.h"
#include "layertrace/geometry/ray_triangle.h"
#include "layertrace/util/cpu_dispatch.h"

namespace lt {
namespace {

// Four lanes with GCC/Clang vector extensions: the compiler emits SSE for the portable copy and
// VEX-encoded code for the dispatched ones, and lane-wise IEEE operations in the order of
// hitTriangleWatertight give its results bit for bit (-ffp-contract=off: no fused multiply-adds).
using Float4 = float __attribute__((vector_size(16)));
using Mask4 = int32_t __attribute__((vector_size(16)));
static_assert(sizeof(Float4) == 4 * sizeof(float));

inline Float4 load4(const float* p) {
  Float4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

inline bool any(Mask4 m) { return (m[0] | m[1] | m[2] | m[3]) != 0; }

/// hitTriangleWatertight for the four triangles of a block: lane i of `t` is the hit distance
/// where lane i of the returned mask is set (all ones), with t in (tmin, tmax]. (A template so
/// that it need not name IrregularGrid's private TriangleBlock.)
template <class Block>
inline Mask4 hitBlock(const WatertightRay& r, const Block& b, float tmin, float tmax, Float4& t) {
  static_assert(sizeof(b.id) == sizeof(Mask4), "one vector lane per triangle of a block");
  const Float4 zero{};
  const Float4 sx = zero + r.sx, sy = zero + r.sy;
  Float4 p[3][3];  // p[vertex][axis] = vertex − origin
  for (int v = 0; v < 3; ++v)
    for (int axis = 0; axis < 3; ++axis) p[v][axis] = load4(b.v[v][axis]) - r.o[axis];
  const Float4 ax = p[0][r.kx] - sx * p[0][r.kz], ay = p[0][r.ky] - sy * p[0][r.kz];
  const Float4 bx = p[1][r.kx] - sx * p[1][r.kz], by = p[1][r.ky] - sy * p[1][r.kz];
  const Float4 cx = p[2][r.kx] - sx * p[2][r.kz], cy = p[2][r.ky] - sy * p[2][r.kz];
  const Float4 u = cx * by - cy * bx, v = ax * cy - ay * cx, w = bx * ay - by * ax;
  const Mask4 inside = ~(((u < zero) | (v < zero) | (w < zero)) & ((u > zero) | (v > zero) | (w > zero))) & (u + v + w != zero);
  if (!any(inside)) return inside;  // most blocks: the ray passes beside all four triangles
  // The plane's distance (see hitTriangleWatertight), from the stored vertices.
  Float4 e1[3], e2[3];
  for (int axis = 0; axis < 3; ++axis) {
    const Float4 v0 = load4(b.v[0][axis]);
    e1[axis] = load4(b.v[1][axis]) - v0;
    e2[axis] = load4(b.v[2][axis]) - v0;
  }
  const Float4 nx = e1[1] * e2[2] - e1[2] * e2[1], ny = e1[2] * e2[0] - e1[0] * e2[2], nz = e1[0] * e2[1] - e1[1] * e2[0];
  const Float4 den = nx * r.d.x + ny * r.d.y + nz * r.d.z;
  t = (nx * p[0][0] + ny * p[0][1] + nz * p[0][2]) / den;  // masked where den = 0
  return inside & (den != zero) & (t > zero + tmin) & (t <= zero + tmax);
}

}  // namespace

template <bool AnyHit>
GeoHit IrregularGrid::traverse(glm::vec3 o, glm::vec3 d, float tnear, float tfar, TraversalCounts* counts) const {
  GeoHit best;
  // Clip to the grid's box.
  float t0 = tnear, t1 = tfar;
  const glm::vec3 inv = 1.0f / d;
  for (int i = 0; i < 3; ++i) {
    float a = (lo_[i] - o[i]) * inv[i], b = (hi_[i] - o[i]) * inv[i];
    if (a > b) std::swap(a, b);
    if (!(a == a)) a = -std::numeric_limits<float>::infinity();  // 0 · inf
    if (!(b == b)) b = std::numeric_limits<float>::infinity();
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  if (t0 > t1) return best;
  // Locate the origin's (entry point's) voxel.
  int v[3];
  const glm::vec3 p = (o + d * t0 - lo_) * invVoxel_;
  for (int i = 0; i < 3; ++i) v[i] = std::clamp(int(std::floor(p[i])), 0, virt_[i] - 1);
  float bestT = tfar;
  const WatertightRay ray(o, d);
  const int maxSteps = 4 * (virt_[0] + virt_[1] + virt_[2]) + 16;
  int step = 0;
  uint32_t cellId = cellAt(v);
  for (; step < maxSteps; ++step) {
    const TraversalCell& c = hot_[cellId];
    if (counts) ++counts->steps, counts->tests += cells_[cellId].refEnd - cells_[cellId].refBegin;
    // Exit of the expanded box, and the next cell, before this cell's triangles are tested:
    // neither depends on the tests, and the next cell's chain of loads (top cell, leaf, cell)
    // then runs while the tests do instead of after them.
    float tExit = std::numeric_limits<float>::infinity();
    int axis = 0;
    for (int i = 0; i < 3; ++i) {
      if (d[i] == 0.0f) continue;
      const float bound = lo_[i] + float(d[i] > 0.0f ? c.ehi[i] : c.elo[i]) * voxel_[i];
      const float t = (bound - o[i]) * inv[i];
      if (t < tExit) tExit = t, axis = i;
    }
    bool more = tExit < t1;
    uint32_t nextId = cellId;
    if (more) {
      // The voxel beyond the exit face: integer on the exit axis, clamped to the face
      // elsewhere, and never behind the current voxel along the ray. The last rule matters
      // where the ray passes (within rounding) through an edge of two cells' faces: the rounded
      // exit point of the second cell can lie a hair before its entry, on the first cell's side
      // of the shared plane, and the two cells would hand the ray back and forth until the step
      // cap (seen on engine: 1 diffuse ray in 921 600). A ray's voxel coordinates are monotone
      // along it, so each step now moves forward on the exit axis and not back on the others:
      // the traversal ends after at most the virtual grid's width + height + depth steps.
      const glm::vec3 q = (o + d * tExit - lo_) * invVoxel_;
      for (int i = 0; i < 3; ++i) {
        if (i == axis) {
          v[i] = d[i] > 0.0f ? c.ehi[i] : c.elo[i] - 1;
        } else {
          const int face = std::clamp(int(std::floor(q[i])), c.elo[i], c.ehi[i] - 1);
          v[i] = d[i] > 0.0f ? std::max(face, v[i]) : d[i] < 0.0f ? std::min(face, v[i]) : face;
        }
      }
      more = v[axis] >= 0 && v[axis] < virt_[axis];
      if (more) {
        nextId = cellAt(v);
        __builtin_prefetch(&hot_[nextId]);
      }
    }
    for (uint32_t k = c.blockBegin; k < c.blockEnd; ++k) {
      const TriangleBlock& b = blocks_[k];
      Float4 t;
      const Mask4 hit = hitBlock(ray, b, tnear, bestT, t);
      if (!any(hit)) continue;
      for (int l = 0; l < kLanes; ++l) {
        if (!hit[l]) continue;
        const uint32_t tri = b.id[l];
        if (AnyHit) {
          best.t = t[l], best.triangle = tri;
          return best;
        }
        if (t[l] < bestT || (t[l] == bestT && tri < best.triangle)) bestT = t[l], best.t = t[l], best.triangle = tri;
      }
    }
    if (best.hit() && bestT <= tExit) break;  // the closest hit lies inside this cell
    if (!more) break;
    cellId = nextId;
  }
  if (step == maxSteps && counts) ++counts->giveUps;  // a safety net: the steps move forward (above)
  if (best.hit()) {
    const glm::uvec3 i = scene_->triangles[best.triangle];
    best.ng = glm::cross(scene_->positions[i.y] - scene_->positions[i.x], scene_->positions[i.z] - scene_->positions[i.x]);
  }
  return best;
}

LT_CPU_DISPATCH GeoHit IrregularGrid::intersect(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts) const {
  return traverse<false>(origin, dir, tnear, tfar, counts);
}

LT_CPU_DISPATCH bool IrregularGrid::occluded(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts) const {
  return traverse<true>(origin, dir, tnear, tfar, counts).hit();
}

}  // namespace lt
