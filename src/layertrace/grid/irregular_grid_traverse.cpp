// The traversal of Pérard-Gayot et al. 2017: locate the origin's cell, intersect its primitives,
// exit if the hit lies within the cell, otherwise locate the exit point and move to the next cell.
// Stackless and ordered; the next cell is found in the voxel map from integer virtual-grid
// coordinates on the far side of the exit face, so rounding can never step back or skip a cell
// along the ray.
//
// The batch traversals are compiled for every vector target of Google Highway (this file is
// included once per target through hwy/foreach_target.h; the shared one-ray steps above it only
// once) and run on the best target of the CPU.
#ifndef LAYERTRACE_GRID_TRAVERSE_ONCE
#define LAYERTRACE_GRID_TRAVERSE_ONCE
#include <algorithm>
#include <cstring>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <hwy/cache_control.h>

#include "layertrace/grid/irregular_grid.h"
#include "layertrace/geometry/ray_triangle.h"
#include "layertrace/scene/surface.h"

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
/// `bary`: the hit's unnormalised barycentric weights of the three vertices (divide by their sum).
inline Mask4 hitBlock(const WatertightRay& r, const Block& b, float tmin, float tmax, Float4& t, Float4 (&bary)[3]) {
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
  bary[0] = u, bary[1] = v, bary[2] = w;
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
  /// The block and lane of the closest hit so far: finish() takes its normal from the block's
  /// vertices (the scene's positions, copied), which the test has just read, instead of
  /// looking the triangle up in the scene — two dependent misses per ray (5–6 % of the lanes'
  /// time on diffuse rays).
  const TriangleBlock* bestBlock;
  int bestLane;
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
    Float4 t, bary[3];
    const Mask4 hit = hitBlock(w.ray, b, w.tnear, w.bestT, t, bary);
    if (!any(hit)) continue;
    for (int l = 0; l < kLanes; ++l) {
      if (!hit[l]) continue;
      const uint32_t tri = b.id[l];
      if (cutOuts_ && scene_->cutOut(tri)) {  // alpha-tested: the ray passes where the texel is cut away
        const float sum = bary[0][l] + bary[1][l] + bary[2][l];
        if (!surfacePresent(*scene_, tri, bary[1][l] / sum, bary[2][l] / sum)) continue;
      }
      if (AnyHit) {
        w.best.t = t[l], w.best.triangle = tri;
        return true;
      }
      if (t[l] < w.bestT || (t[l] == w.bestT && tri < w.best.triangle))
        w.bestT = t[l], w.best.t = t[l], w.best.triangle = tri, w.bestBlock = &b, w.bestLane = l;
    }
  }
  return (w.best.hit() && w.bestT <= w.tExit) || !more;  // the closest hit lies inside this cell
}

inline GeoHit IrregularGrid::finish(const Walk& w) const {
  GeoHit best = w.best;
  if (best.hit()) {
    const TriangleBlock& b = *w.bestBlock;
    const int l = w.bestLane;
    glm::vec3 p[3];
    for (int v = 0; v < 3; ++v) p[v] = {b.v[v][0][l], b.v[v][1][l], b.v[v][2][l]};
    best.ng = glm::cross(p[1] - p[0], p[2] - p[0]);  // as from the scene's positions: the same floats
  }
  return best;
}

namespace {
/// A cell's record and its first triangle block: three 64-byte lines.
inline void prefetchCell(const void* cell) {
  const char* p = static_cast<const char*>(cell);
  hwy::Prefetch(p);
  hwy::Prefetch(p + 64);
  hwy::Prefetch(p + 128);
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
        hwy::Prefetch(&walkLeaf_[walks[s].leaf]);
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
        hwy::Prefetch(&walkLeaf_[w.leaf]);
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

/// What the vector lanes (compiled per target below) use of the grid's private parts.
struct IrregularGrid::LaneAccess {
  using Walk = IrregularGrid::Walk;
  using Query = IrregularGrid::Query;
  static constexpr size_t kUnit = IrregularGrid::kUnit;
  static constexpr size_t kTopCellBytes = sizeof(TopCell);
  const IrregularGrid& g;
  glm::vec3 lo() const { return g.lo_; }
  glm::vec3 hi() const { return g.hi_; }
  glm::vec3 voxel() const { return g.voxel_; }
  glm::vec3 invVoxel() const { return g.invVoxel_; }
  int top(int a) const { return g.top_[a]; }
  int depth() const { return g.depth_; }
  int virt(int a) const { return g.virt_[a]; }
  const unsigned char* walkBase() const { return reinterpret_cast<const unsigned char*>(g.walk_.data()); }
  const int32_t* topWords() const { return reinterpret_cast<const int32_t*>(g.topCells_.data()); }
  const int32_t* leaves() const { return reinterpret_cast<const int32_t*>(g.walkLeaf_.data()); }
  void prefetchCellAt(uint32_t unit) const { prefetchCell(&g.walkCell(unit)); }
  template <bool AnyHit>
  bool testCell(Walk& w, uint32_t unit, bool more) const { return g.testCell<AnyHit>(w, g.walkCell(unit), more); }
  GeoHit finish(const Walk& w) const { return g.finish(w); }
  template <bool AnyHit>
  GeoHit traverse(glm::vec3 o, glm::vec3 d, float tnear, float tfar, TraversalCounts* counts) const {
    return g.traverse<AnyHit>(o, d, tnear, tfar, counts);
  }
  template <bool AnyHit, class Out>
  void traverseBatch(std::span<const Query> queries, Out out) const { g.traverseBatch<AnyHit>(queries, out); }
};

}  // namespace lt
#endif  // LAYERTRACE_GRID_TRAVERSE_ONCE

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "layertrace/grid/irregular_grid_traverse.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <hwy/highway.h>

#include "layertrace/util/lanes-inl.h"

HWY_BEFORE_NAMESPACE();
namespace lt::HWY_NAMESPACE {
namespace {

using namespace lanes;
using Access = IrregularGrid::LaneAccess;
using Query = IrregularGrid::Query;
constexpr size_t kL = kMaxLanes;

// Rays in vector lanes (SIMD over rays). Where a ray spends its time is the walk from cell to
// cell — the exit of the cell's expanded box, the voxel beyond it and the voxel-map lookup (with
// its triangle tests skipped, an AO ray costs 85 % of its full time) — and the lanes' walks are
// the same operations on different data: here they run in lanes, with exitCell's float
// expressions in the same order and selects for its branches, the top cells and leaves gathered,
// and rays enter a vector's count at a time. Lanes in an empty cell are answered in the registers
// by testCell's rule; the others' triangles are tested by testCell itself, one lane after the
// other — so the answers are the one-ray traversal's bit for bit (the batch tests compare them
// on every target). Three groups of lanes step in turn (gridLanes says why).
struct GridLanes {
  HWY_ALIGN float o[3][kL], d[3][kL], inv[3][kL], t1[kL], tExit[kL];
  HWY_ALIGN int32_t v[3][kL];
  HWY_ALIGN int32_t unit[kL];     ///< walk_ unit of the cell each lane visits next
  HWY_ALIGN int32_t ray[kL];      ///< the query's index; −1 for an empty lane
  HWY_ALIGN int32_t leaf[kL];     ///< the pending lanes' next leaf (walkLeaf_ index)
  HWY_ALIGN int32_t step[kL];
  HWY_ALIGN float bestT[kL];      ///< the walks' bestT, for the lanes answered without testCell
  HWY_ALIGN int32_t hasBest[kL];  ///< flags (0 / −1): the lane's walk has a hit
  uint64_t pending = 0;           ///< lanes whose next cell is still to be read from their leaf
  Access::Walk walk[kL];  ///< what testCell and finish read (the ray, its best hit, the cell's exit)
};

/// Rays enter the lanes from a buffer that `enter` fills for a vector's count of queries at once:
/// the clip to the grid's box, the first voxel and its cell, the watertight test's shear —
/// enter's and WatertightRay's expressions in lanes, with selects for their branches.
struct Entered {
  HWY_ALIGN float o[3][kL], d[3][kL], inv[3][kL], tnear[kL], tfar[kL], t1[kL], sx[kL], sy[kL];
  HWY_ALIGN int32_t v[3][kL], k[3][kL];  ///< the first voxel; the shear's axes kx, ky, kz
  HWY_ALIGN int32_t unit[kL];
  uint64_t in = 0;  ///< the queries that enter the grid
  size_t first = 0, count = 0, taken = 0;  ///< queries [first, first + count), `taken` of them used
};

template <bool AnyHit>
void gridLanes(const Access& g, std::span<const Query> queries, std::span<GeoHit> hits, std::span<uint8_t> anyHits) {
  constexpr float inf = std::numeric_limits<float>::infinity();
  const int virt[3] = {g.virt(0), g.virt(1), g.virt(2)};
  const int depth = g.depth();
  const glm::vec3 lo = g.lo(), hi = g.hi(), voxel = g.voxel(), invVoxel = g.invVoxel();
  const int maxSteps = 4 * (virt[0] + virt[1] + virt[2]) + 16;
  const unsigned char* walkBase = g.walkBase();
  const int32_t* topWords = g.topWords();
  const int32_t* leaves = g.leaves();
  const size_t N = laneCount();
  const VI zero = splat(int32_t(0));
  auto output = [&](size_t i, const GeoHit& h) {
    if (AnyHit) anyHits[i] = h.hit();
    else hits[i] = h;
  };
  // The voxel map (leafIndex) for the lanes of `m`: the top cell's leaf offset and shifts give
  // the leaf; the leaf holds the cell's record (unitsOf). (Lanes outside m read top cell 0.)
  auto leafOf = [&](const VI v[3], M m) {
    const VI mask = splat(int32_t((1 << depth) - 1));
    const VI top = ((hn::ShiftRightSame(v[2], depth) * splat(int32_t(g.top(1))) + hn::ShiftRightSame(v[1], depth)) *
                    splat(int32_t(g.top(0)))) + hn::ShiftRightSame(v[0], depth);
    const VI topByte = sel(m, top, zero) * splat(int32_t(Access::kTopCellBytes));
    const VI offset = hn::GatherOffset(DI(), topWords, topByte);
    const VI shifts = hn::GatherOffset(DI(), topWords + 1, topByte);
    const VI byte = splat(int32_t(0xff));
    const VI s0 = shifts & byte, s1 = hn::ShiftRight<8>(shifts) & byte, s2 = hn::ShiftRight<16>(shifts) & byte;
    const VI bits1 = hn::ShiftRight<24>(shifts) & byte, bits2 = bits1 + (splat(int32_t(depth)) - s1);  // d0 and d0 + d1, d_a = D − shift_a
    const VI l0 = (v[0] & mask) >> s0, l1 = (v[1] & mask) >> s1, l2 = (v[2] & mask) >> s2;  // (non-negative: >> is logical)
    return sel(m, offset + (((l2 << bits2) + (l1 << bits1)) + l0), zero);
  };
  auto unitsOf = [&](VI leaf, M m) { return sel(m, hn::GatherIndex(DI(), leaves, sel(m, leaf, zero)), zero); };
  Entered ent;
  static_assert(sizeof(Query) == 8 * sizeof(float), "a query is one 32-byte row");
  size_t next = 0;
  auto enterLanes = [&] {
    const size_t n = std::min(N, queries.size() - next);
    ent.first = next, ent.count = n, ent.taken = 0;
    next += n;
    static constexpr float kNoQuery[8] = {};
    const float* rows[kL] = {};
    for (size_t j = 0; j < N; ++j) rows[j] = j < n ? reinterpret_cast<const float*>(&queries[ent.first + j]) : kNoQuery;
    VF q[8];
    transposeRecords(rows, q);
    const VF* o = q;
    const VF* d = q + 3;
    VF t0 = q[6], t1 = q[7], inv[3];
    for (int a = 0; a < 3; ++a) {
      inv[a] = splat(1.0f) / d[a];
      VF l = (splat(lo[a]) - o[a]) * inv[a], h = (splat(hi[a]) - o[a]) * inv[a];
      const M swap = gt(l, h);
      const VF near = sel(swap, h, l), far = sel(swap, l, h);
      l = sel(eq(near, near), near, splat(-inf));  // 0 · inf
      h = sel(eq(far, far), far, splat(inf));
      t0 = vmax(t0, l);
      t1 = vmin(t1, h);
    }
    const M in = andNot(hn::FirstN(DF(), n), gt(t0, t1));
    VI v[3];
    for (int a = 0; a < 3; ++a) {
      const VF p = ((o[a] + d[a] * t0) - splat(lo[a])) * splat(invVoxel[a]);
      v[a] = imin(imax(toInt(vfloor(p)), zero), splat(int32_t(virt[a] - 1)));  // std::clamp
      store(ent.o[a], o[a]), store(ent.d[a], d[a]), store(ent.inv[a], inv[a]), store(ent.v[a], v[a]);
    }
    store(ent.tnear, q[6]), store(ent.tfar, q[7]), store(ent.t1, t1);
    store(ent.unit, unitsOf(leafOf(v, in), in));
    // WatertightRay: z along the largest |d|, x and y after it, swapped where d_z < 0.
    const VI one = splat(int32_t(1)), two = splat(int32_t(2));
    const VF ax = vabs(d[0]), ay = vabs(d[1]), az = vabs(d[2]);
    const VI kz = sel(ge(ax, ay), sel(ge(ax, az), zero, two), sel(ge(ay, az), one, two));
    VI kx = sel(eq(kz, two), zero, kz + one);
    VI ky = sel(eq(kx, two), zero, kx + one);
    auto pick = [&](VI k) { return sel(eq(k, zero), d[0], sel(eq(k, one), d[1], d[2])); };
    const VF dz = pick(kz);
    const M flip = lt(dz, splat(0.0f));
    const VI kx0 = kx;
    kx = sel(flip, ky, kx), ky = sel(flip, kx0, ky);
    store(ent.sx, pick(kx) / dz), store(ent.sy, pick(ky) / dz);
    store(ent.k[0], kx), store(ent.k[1], ky), store(ent.k[2], kz);
    ent.in = bits(in);
  };
  auto fill = [&](GridLanes& ln, int j) {
    ln.ray[j] = -1;
    ln.unit[j] = 0;  // an empty lane reads cell 0 (a valid record) and stays out of every mask
    for (;;) {
      if (ent.taken == ent.count) {
        if (next == queries.size()) return false;
        enterLanes();
        for (uint64_t m = ent.in; m; m &= m - 1) g.prefetchCellAt(uint32_t(ent.unit[std::countr_zero(m)]));
      }
      const size_t e = ent.taken++, i = ent.first + e;
      if (!(ent.in >> e & 1)) {
        output(i, GeoHit{});
        continue;
      }
      Access::Walk& w = ln.walk[j];
      for (int a = 0; a < 3; ++a) {
        ln.o[a][j] = ent.o[a][e], ln.d[a][j] = ent.d[a][e], ln.inv[a][j] = ent.inv[a][e], ln.v[a][j] = ent.v[a][e];
        w.ray.o[a] = ent.o[a][e], w.ray.d[a] = ent.d[a][e];
      }
      w.ray.kx = ent.k[0][e], w.ray.ky = ent.k[1][e], w.ray.kz = ent.k[2][e], w.ray.sx = ent.sx[e], w.ray.sy = ent.sy[e];
      w.tnear = ent.tnear[e], w.bestT = ent.tfar[e];
      w.best = GeoHit{};
      ln.bestT[j] = ent.tfar[e];
      ln.hasBest[j] = 0;
      ln.t1[j] = ent.t1[e];
      ln.step[j] = 0;
      ln.ray[j] = int32_t(i);
      ln.unit[j] = ent.unit[e];
      return true;
    }
  };
  auto done = [&](GridLanes& ln, int j) { output(size_t(ln.ray[j]), AnyHit ? ln.walk[j].best : g.finish(ln.walk[j])); };
  auto step = [&](GridLanes& ln) -> uint64_t {
    const M live = ge(loadI(ln.ray), zero);
    // The lanes' cell records (exit box and reference count): one 32-byte row per lane.
    const float* rows[kL] = {};
    for (size_t j = 0; j < N; ++j) rows[j] = reinterpret_cast<const float*>(walkBase + size_t(uint32_t(ln.unit[j])) * Access::kUnit);
    VF field[8];
    transposeRecords(rows, field);
    VI elo[3], ehi[3];
    for (int a = 0; a < 3; ++a) elo[a] = asInt(field[a]), ehi[a] = asInt(field[3 + a]);
    // exitCell: the first axis with the smallest exit distance.
    VF o[3], dir[3], t[3];
    M pos[3], neg[3];
    for (int a = 0; a < 3; ++a) {
      o[a] = loadF(ln.o[a]), dir[a] = loadF(ln.d[a]);
      pos[a] = gt(dir[a], splat(0.0f)), neg[a] = lt(dir[a], splat(0.0f));
      const VF bound = splat(lo[a]) + toFloat(sel(pos[a], ehi[a], elo[a])) * splat(voxel[a]);
      t[a] = sel(eq(dir[a], splat(0.0f)), splat(inf), (bound - o[a]) * loadF(ln.inv[a]));
    }
    const M y = lt(t[1], t[0]);
    const VF t01 = sel(y, t[1], t[0]);
    const M z = lt(t[2], t01);
    const VF tExit = sel(z, t[2], t01);
    store(ln.tExit, tExit);
    M more = lt(live, tExit, loadF(ln.t1));
    const M onAxis[3] = {andNot(~y, z), andNot(y, z), z};
    VI v[3];
    for (int a = 0; a < 3; ++a) {
      const VF q = ((o[a] + dir[a] * tExit) - splat(lo[a])) * splat(invVoxel[a]);
      const VI cell = toInt(vfloor(q));
      const VI face = imin(imax(cell, elo[a]), ehi[a] - splat(int32_t(1)));  // std::clamp (elo < ehi)
      const VI vOld = loadI(ln.v[a]);
      const VI beside = sel(pos[a], imax(face, vOld), sel(neg[a], imin(face, vOld), face));
      v[a] = sel(onAxis[a], sel(pos[a], ehi[a], elo[a] - splat(int32_t(1))), beside);
      more = andNot(more, onAxis[a] & outside(v[a], splat(int32_t(virt[a]))));
      store(ln.v[a], sel(more, v[a], vOld));
    }
    store(ln.leaf, leafOf(v, more));
    // The lanes in empty cells are answered here, as testCell answers them — the closest hit so
    // far lies inside this cell, or there is no next cell — and the others' triangles are tested
    // by testCell itself, lane after lane.
    const M tested = ne(live, asInt(field[6]), zero);
    const M empty = andNot(live, tested);
    const M answered = andNot(empty, more) | le(empty & flags(ln.hasBest), loadF(ln.bestT), tExit);
    uint64_t finished = bits(answered);
    const uint64_t moreBits = bits(more);
    for (uint64_t m = bits(tested); m; m &= m - 1) {
      const int j = std::countr_zero(m);
      Access::Walk& w = ln.walk[j];
      w.tExit = ln.tExit[j];
      if (g.testCell<AnyHit>(w, uint32_t(ln.unit[j]), (moreBits >> j) & 1)) finished |= uint64_t(1) << j;
      ln.bestT[j] = w.bestT;
      if (w.best.hit()) ln.hasBest[j] = -1;
    }
    // The step cap (a safety net: the steps move forward), as traverse() counts it.
    const M stepped = andNot(live, fromBits(finished));
    const VI stepsBefore = loadI(ln.step), steps = stepsBefore + splat(int32_t(1));
    store(ln.step, sel(stepped, steps, stepsBefore));
    finished |= bits(eq(stepped, steps, splat(int32_t(maxSteps))));
    ln.pending = moreBits & ~finished;
    for (uint64_t m = ln.pending; m; m &= m - 1) hwy::Prefetch(&leaves[uint32_t(ln.leaf[std::countr_zero(m)])]);
    return finished;
  };
  // The leaves a group's last step asked for (arrived meanwhile) give its lanes' next cells.
  auto advance = [&](GridLanes& ln) {
    if (!ln.pending) return;
    const M pending = fromBits(ln.pending);
    store(ln.unit, sel(pending, unitsOf(loadI(ln.leaf), pending), loadI(ln.unit)));
    for (uint64_t m = ln.pending; m; m &= m - 1) g.prefetchCellAt(uint32_t(ln.unit[std::countr_zero(m)]));
    ln.pending = 0;
  };
  // Three groups, each lane's cell a chain of two misses (the leaf, then the cell's lines): round
  // after round, group g steps — its cells were requested a whole step earlier — and asks for its
  // next leaves; then group g + 2 reads the leaves it asked for a step earlier and requests the
  // cells. Every request has another group's step to arrive in. (Two groups with the leaf read
  // in the same step: the gather waited 26 % of the step on am_thornish's diffuse rays.)
  constexpr int kGroups = 3;
  GridLanes lanes[kGroups]{};
  int live = 0;
  for (GridLanes& ln : lanes)
    for (size_t j = 0; j < N; ++j) live += fill(ln, int(j));
  while (live > 0)
    for (int gi = 0; gi < kGroups; ++gi) {
      GridLanes& ln = lanes[gi];
      const uint64_t finished = step(ln);
      advance(lanes[(gi + 2) % kGroups]);
      for (uint64_t m = finished; m; m &= m - 1) {
        const int j = std::countr_zero(m);
        done(ln, j);
        live += int(fill(ln, j)) - 1;
      }
    }
}

}  // namespace

void gridIntersectLanes(const IrregularGrid::LaneAccess& g, std::span<const Query> queries, std::span<GeoHit> hits) {
  gridLanes<false>(g, queries, hits, {});
}
void gridOccludedLanes(const IrregularGrid::LaneAccess& g, std::span<const Query> queries, std::span<uint8_t> hits) {
  gridLanes<true>(g, queries, {}, hits);
}

// The one-ray traversal and the scalar batch, compiled per target too (flatten: the traversal
// inlined, so compiled for the target): the compiler's own code for the CPU it runs on.
[[gnu::flatten]] GeoHit gridIntersectOne(const IrregularGrid::LaneAccess& g, glm::vec3 o, glm::vec3 d, float tnear, float tfar,
                                         TraversalCounts* counts) {
  return g.traverse<false>(o, d, tnear, tfar, counts);
}
[[gnu::flatten]] GeoHit gridOccludedOne(const IrregularGrid::LaneAccess& g, glm::vec3 o, glm::vec3 d, float tnear, float tfar,
                                        TraversalCounts* counts) {
  return g.traverse<true>(o, d, tnear, tfar, counts);
}
[[gnu::flatten]] void gridIntersectEach(const IrregularGrid::LaneAccess& g, std::span<const Query> queries, std::span<GeoHit> hits) {
  g.traverseBatch<false>(queries, [&hits](size_t i, const GeoHit& h) { hits[i] = h; });
}
[[gnu::flatten]] void gridOccludedEach(const IrregularGrid::LaneAccess& g, std::span<const Query> queries, std::span<uint8_t> hits) {
  g.traverseBatch<true>(queries, [&hits](size_t i, const GeoHit& h) { hits[i] = h.hit(); });
}

}  // namespace lt::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lt {

HWY_EXPORT(gridIntersectLanes);
HWY_EXPORT(gridOccludedLanes);
HWY_EXPORT(gridIntersectOne);
HWY_EXPORT(gridOccludedOne);
HWY_EXPORT(gridIntersectEach);
HWY_EXPORT(gridOccludedEach);

/// The lanes need a cell 0 for empty lanes to read, a top cell and a leaf for the lanes outside a
/// mask to gather, and voxel-map indices (top cells' byte offsets, leaves) that fit 32-bit lanes.
bool IrregularGrid::lanesAvailable() const {
  return !walk_.empty() && !topCells_.empty() && !walkLeaf_.empty() && topCells_.size() * sizeof(TopCell) < (size_t(1) << 31) &&
         walkLeaf_.size() < (size_t(1) << 31);
}

GeoHit IrregularGrid::intersect(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts) const {
  return HWY_DYNAMIC_DISPATCH(gridIntersectOne)(LaneAccess{*this}, origin, dir, tnear, tfar, counts);
}

bool IrregularGrid::occluded(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts) const {
  return HWY_DYNAMIC_DISPATCH(gridOccludedOne)(LaneAccess{*this}, origin, dir, tnear, tfar, counts).hit();
}

void IrregularGrid::intersect(std::span<const Query> queries, std::span<GeoHit> hits) const {
  if (lanesAvailable()) return HWY_DYNAMIC_DISPATCH(gridIntersectLanes)(LaneAccess{*this}, queries, hits);
  intersectPortable(queries, hits);
}

void IrregularGrid::occluded(std::span<const Query> queries, std::span<uint8_t> hits) const {
  if (lanesAvailable()) return HWY_DYNAMIC_DISPATCH(gridOccludedLanes)(LaneAccess{*this}, queries, hits);
  occludedPortable(queries, hits);
}

void IrregularGrid::intersectPortable(std::span<const Query> queries, std::span<GeoHit> hits) const {
  HWY_DYNAMIC_DISPATCH(gridIntersectEach)(LaneAccess{*this}, queries, hits);
}

void IrregularGrid::occludedPortable(std::span<const Query> queries, std::span<uint8_t> hits) const {
  HWY_DYNAMIC_DISPATCH(gridOccludedEach)(LaneAccess{*this}, queries, hits);
}

}  // namespace lt
#endif
