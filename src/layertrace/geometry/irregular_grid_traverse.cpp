// seed 003 traversal: locate the origin's cell, intersect its primitives, exit if the hit lies
// within the cell, otherwise locate the exit point and move to the next cell. Stackless and
// ordered; the next cell is found in the voxel map from integer virtual-grid coordinates on the
// far side of the exit face, so rounding can never step back or skip a cell along the ray.
#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "layertrace/geometry/irregular_grid.h"
#include "layertrace/geometry/ray_triangle.h"
#include "layertrace/util/cpu_dispatch.h"

namespace lt {

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
  const glm::vec3 p = (o + d * t0 - lo_) / voxel_;
  for (int i = 0; i < 3; ++i) v[i] = std::clamp(int(std::floor(p[i])), 0, virt_[i] - 1);
  float bestT = tfar;
  const int maxSteps = 4 * (virt_[0] + virt_[1] + virt_[2]) + 16;
  int step = 0;
  for (; step < maxSteps; ++step) {
    const TraversalCell& c = hot_[cellAt(v)];
    if (counts) ++counts->steps, counts->tests += c.refEnd - c.refBegin;
    for (uint32_t r = c.refBegin; r < c.refEnd; ++r) {
      const uint32_t tri = refs_[r];
      float t;
      const Triangle& T = tris_[tri];
      if (hitTriangle(o, d, T.v0, T.e1, T.e2, tnear, bestT, t)) {
        if (AnyHit) {
          best.t = t, best.triangle = tri;
          return best;
        }
        if (t < bestT || (t == bestT && tri < best.triangle)) bestT = t, best.t = t, best.triangle = tri;
      }
    }
    // Exit of the expanded box.
    float tExit = std::numeric_limits<float>::infinity();
    int axis = 0;
    for (int i = 0; i < 3; ++i) {
      if (d[i] == 0.0f) continue;
      const float bound = lo_[i] + float(d[i] > 0.0f ? c.ehi[i] : c.elo[i]) * voxel_[i];
      const float t = (bound - o[i]) * inv[i];
      if (t < tExit) tExit = t, axis = i;
    }
    if (best.hit() && bestT <= tExit) break;  // the closest hit lies inside this cell
    if (tExit >= t1) break;
    // The voxel beyond the exit face: integer on the exit axis, clamped to the face elsewhere.
    const glm::vec3 q = (o + d * tExit - lo_) / voxel_;
    for (int i = 0; i < 3; ++i) {
      if (i == axis) {
        v[i] = d[i] > 0.0f ? c.ehi[i] : c.elo[i] - 1;
      } else {
        v[i] = std::clamp(int(std::floor(q[i])), c.elo[i], c.ehi[i] - 1);
      }
    }
    if (v[axis] < 0 || v[axis] >= virt_[axis]) break;
  }
  if (step == maxSteps && counts) ++counts->giveUps;  // never seen: the grid's steps are finite
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
