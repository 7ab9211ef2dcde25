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

struct IrregularGrid::Walk {
  glm::vec3 o, d, inv;
  WatertightRay ray;
  float tnear, t1, bestT, tExit;
  GeoHit best;
  int v[3];      ///< the voxel of the cell to visit next
  int step;      ///< cells visited
  uint32_t cell; ///< walk_ unit of the cell to visit next
  size_t leaf;   ///< walkLeaf_ index of that cell (the batch's pending lookup)
};

/// Clips the ray to the grid's box and locates the voxel it enters; false if it misses the box.
inline bool IrregularGrid::enter(Walk& w, glm::vec3 o, glm::vec3 d, float tnear, float tfar) const {
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
  if (t0 > t1) return false;
  const glm::vec3 p = (o + d * t0 - lo_) * invVoxel_;
  for (int i = 0; i < 3; ++i) w.v[i] = std::clamp(int(std::floor(p[i])), 0, virt_[i] - 1);
  w.o = o, w.d = d, w.inv = inv, w.ray = WatertightRay(o, d);
  w.tnear = tnear, w.t1 = t1, w.bestT = tfar;
  w.best = GeoHit{};
  w.step = 0;
  return true;
}

/// The exit of cell c's expanded box, and the voxel beyond it (w.v): false if the ray ends or
/// leaves the grid first. Neither depends on c's triangles, so the next cell's lookup can start
/// before they are tested.
inline bool IrregularGrid::exitCell(Walk& w, const TraversalCell& c) const {
  // Selects instead of branches: which face a ray leaves by is what a branch predictor cannot
  // guess (the first axis with the smallest distance, as a loop keeping the first minimum).
  float t[3];
  for (int i = 0; i < 3; ++i) {
    const float bound = lo_[i] + float(w.d[i] > 0.0f ? c.ehi[i] : c.elo[i]) * voxel_[i];
    t[i] = w.d[i] == 0.0f ? std::numeric_limits<float>::infinity() : (bound - w.o[i]) * w.inv[i];
  }
  const bool y = t[1] < t[0];
  const float t01 = y ? t[1] : t[0];
  const bool z = t[2] < t01;
  const int axis = z ? 2 : int(y);
  const float tExit = z ? t[2] : t01;
  w.tExit = tExit;
  if (!(tExit < w.t1)) return false;
  // The voxel beyond the exit face: integer on the exit axis, clamped to the face elsewhere, and
  // never behind the current voxel along the ray. The last rule matters where the ray passes
  // (within rounding) through an edge of two cells' faces: the rounded exit point of the second
  // cell can lie a hair before its entry, on the first cell's side of the shared plane, and the
  // two cells would hand the ray back and forth until the step cap (seen on engine: 1 diffuse
  // ray in 921 600). A ray's voxel coordinates are monotone along it, so each step now moves
  // forward on the exit axis and not back on the others: the traversal ends after at most the
  // virtual grid's width + height + depth steps.
  const glm::vec3 q = (w.o + w.d * tExit - lo_) * invVoxel_;
  int* v = w.v;
  for (int i = 0; i < 3; ++i) {
    const int face = std::clamp(int(std::floor(q[i])), c.elo[i], c.ehi[i] - 1);
    const int beside = w.d[i] > 0.0f ? std::max(face, v[i]) : w.d[i] < 0.0f ? std::min(face, v[i]) : face;
    const int beyond = w.d[i] > 0.0f ? c.ehi[i] : c.elo[i] - 1;
    v[i] = i == axis ? beyond : beside;
  }
  return v[axis] >= 0 && v[axis] < virt_[axis];
}

/// Tests cell c's triangles; true when the ray is answered: an any-hit found, the closest hit
/// lies inside the cell, or (`more` false) there is no next cell.
template <bool AnyHit>
inline bool IrregularGrid::testCell(Walk& w, const TraversalCell& c, bool more) const {
  const TriangleBlock* blocks = walkBlocks(c);
  for (uint32_t k = 0; k < (c.refs + kLanes - 1) / kLanes; ++k) {
    const TriangleBlock& b = blocks[k];
    Float4 t;
    const Mask4 hit = hitBlock(w.ray, b, w.tnear, w.bestT, t);
    if (!any(hit)) continue;
    for (int l = 0; l < kLanes; ++l) {
      if (!hit[l]) continue;
      const uint32_t tri = b.id[l];
      if (AnyHit) {
        w.best.t = t[l], w.best.triangle = tri;
        return true;
      }
      if (t[l] < w.bestT || (t[l] == w.bestT && tri < w.best.triangle)) w.bestT = t[l], w.best.t = t[l], w.best.triangle = tri;
    }
  }
  return (w.best.hit() && w.bestT <= w.tExit) || !more;  // the closest hit lies inside this cell
}

inline GeoHit IrregularGrid::finish(const Walk& w) const {
  GeoHit best = w.best;
  if (best.hit()) {
    const glm::uvec3 i = scene_->triangles[best.triangle];
    best.ng = glm::cross(scene_->positions[i.y] - scene_->positions[i.x], scene_->positions[i.z] - scene_->positions[i.x]);
  }
  return best;
}

namespace {
/// A cell's record and its first triangle block: three 64-byte lines.
inline void prefetchCell(const void* cell) {
  const char* p = static_cast<const char*>(cell);
  __builtin_prefetch(p);
  __builtin_prefetch(p + 64);
  __builtin_prefetch(p + 128);
}
}  // namespace

template <bool AnyHit>
GeoHit IrregularGrid::traverse(glm::vec3 o, glm::vec3 d, float tnear, float tfar, TraversalCounts* counts) const {
  Walk w;
  if (!enter(w, o, d, tnear, tfar)) return GeoHit{};
  const int maxSteps = 4 * (virt_[0] + virt_[1] + virt_[2]) + 16;
  uint32_t cell = walkLeaf_[leafIndex(w.v)];
  for (;;) {
    const TraversalCell& c = walkCell(cell);
    if (counts) ++counts->steps, counts->tests += c.refs;
    // The next cell is looked up before this cell's triangles are tested: its chain of loads
    // (top cell, leaf, cell) then runs while the tests do instead of after them.
    const bool more = exitCell(w, c);
    if (more) {
      cell = walkLeaf_[leafIndex(w.v)];
      prefetchCell(&walkCell(cell));
    }
    if (testCell<AnyHit>(w, c, more)) break;
    if (++w.step == maxSteps) {  // a safety net: the steps move forward (exitCell)
      if (counts) ++counts->giveUps;
      break;
    }
  }
  return AnyHit ? w.best : finish(w);
}

/// Several rays in flight: each round first reads every active ray's pending leaf (prefetched a
/// round earlier) and prefetches its cell, then steps every ray through its cell — whose lines
/// arrived meanwhile — and prefetches the leaf of its next cell. A ray that is answered hands its
/// slot to the next query. Every ray goes through the very steps of traverse() above.
template <bool AnyHit, class Out>
void IrregularGrid::traverseBatch(std::span<const Query> queries, Out out) const {
  // 16 rays: BM_GridBatch with 8 / 16 / 32 in flight, two runs each, is within the noise
  // between 16 and 32 and 5–15 % slower with 8 on the diffuse rays.
  constexpr int kInFlight = 16;
  const int maxSteps = 4 * (virt_[0] + virt_[1] + virt_[2]) + 16;
  Walk walks[kInFlight];
  size_t ray[kInFlight];
  size_t next = 0;
  auto start = [&](int s) {  // the slot's next ray that enters the grid; the others miss
    while (next < queries.size()) {
      const Query& q = queries[next];
      const size_t i = next++;
      if (enter(walks[s], q.origin, q.dir, q.tnear, q.tfar)) {
        ray[s] = i;
        walks[s].leaf = leafIndex(walks[s].v);
        __builtin_prefetch(&walkLeaf_[walks[s].leaf]);
        return true;
      }
      out(i, GeoHit{});
    }
    return false;
  };
  int active = 0;
  while (active < kInFlight && start(active)) ++active;
  while (active > 0) {
    for (int s = 0; s < active; ++s) {
      walks[s].cell = walkLeaf_[walks[s].leaf];
      prefetchCell(&walkCell(walks[s].cell));
    }
    for (int s = 0; s < active; ++s) {
      Walk& w = walks[s];
      const TraversalCell& c = walkCell(w.cell);
      const bool more = exitCell(w, c);
      if (more) {
        w.leaf = leafIndex(w.v);
        __builtin_prefetch(&walkLeaf_[w.leaf]);
      }
      if (!testCell<AnyHit>(w, c, more) && ++w.step != maxSteps) continue;
      out(ray[s], AnyHit ? w.best : finish(w));
      if (start(s)) continue;
      // No ray left for the slot: the last active slot moves here (it has not stepped this round).
      if (s != --active) {
        walks[s] = walks[active];
        ray[s] = ray[active];
        --s;
      }
    }
  }
}

LT_CPU_DISPATCH GeoHit IrregularGrid::intersect(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts) const {
  return traverse<false>(origin, dir, tnear, tfar, counts);
}

LT_CPU_DISPATCH bool IrregularGrid::occluded(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts) const {
  return traverse<true>(origin, dir, tnear, tfar, counts).hit();
}

LT_CPU_DISPATCH void IrregularGrid::intersect(std::span<const Query> queries, std::span<GeoHit> hits) const {
  traverseBatch<false>(queries, [&hits](size_t i, const GeoHit& h) { hits[i] = h; });
}

LT_CPU_DISPATCH void IrregularGrid::occluded(std::span<const Query> queries, std::span<uint8_t> hits) const {
  traverseBatch<true>(queries, [&hits](size_t i, const GeoHit& h) { hits[i] = h.hit(); });
}

}  // namespace lt
