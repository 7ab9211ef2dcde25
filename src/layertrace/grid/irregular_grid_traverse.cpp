// The traversal of Pérard-Gayot et al. 2017: locate the origin's cell, intersect its primitives,
// exit if the hit lies within the cell, otherwise locate the exit point and move to the next cell.
// Stackless and ordered; the next cell is found in the voxel map from integer virtual-grid
// coordinates on the far side of the exit face, so rounding can never step back or skip a cell
// along the ray.
#include <algorithm>
#include <cstring>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "layertrace/grid/irregular_grid.h"
#include "layertrace/geometry/ray_triangle.h"
#include "layertrace/util/cpu_dispatch.h"
#include "layertrace/util/simd512.h"

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

#if LT_SIMD512
// Sixteen rays in the lanes of AVX-512 registers (SIMD over rays). Where a ray spends
// its time is the walk from cell to cell — the exit of the cell's expanded box, the voxel beyond
// it and the voxel-map lookup (with its triangle tests skipped, an AO ray costs 85 % of its full
// time) — and sixteen rays' walks are the same operations on different data: here they run in
// lanes, with exitCell's float expressions in the same order and selects for its branches, the
// top cells and leaves gathered, and rays enter sixteen at a time. Lanes in an empty cell are
// answered in the registers by testCell's rule; the others' triangles are tested by testCell
// itself, one lane after the other — so the answers are the one-ray traversal's bit for bit (the
// batch tests compare them). Three groups of lanes step in turn (traverseLanes says why).
#pragma GCC push_options
#pragma GCC target("avx512f,avx512vl,avx512bw,avx512dq")

struct IrregularGrid::GridLanes {
  static constexpr int kL = simd512::kLanes;
  alignas(64) float o[3][kL], d[3][kL], inv[3][kL], t1[kL], tExit[kL];
  alignas(64) int32_t v[3][kL];
  alignas(64) uint32_t unit[kL];  ///< walk_ unit of the cell each lane visits next
  alignas(64) int32_t ray[kL];    ///< the query's index; −1 for an empty lane
  alignas(64) int32_t leaf[kL];   ///< the pending lanes' next leaf (walkLeaf_ index)
  alignas(64) int32_t step[kL];
  alignas(64) float bestT[kL];    ///< the walks' bestT, for the lanes answered without testCell
  __mmask16 hasBest = 0;          ///< lanes whose walk has a hit
  __mmask16 pending = 0;          ///< lanes whose next cell is still to be read from their leaf
  Walk walk[kL];  ///< what testCell and finish read (the ray, its best hit, the cell's exit)
};

template <bool AnyHit>
void IrregularGrid::traverseLanes(std::span<const Query> queries, std::span<GeoHit> hits, std::span<uint8_t> anyHits) const {
  using namespace simd512;
  const int maxSteps = 4 * (virt_[0] + virt_[1] + virt_[2]) + 16;
  const unsigned char* walkBase = reinterpret_cast<const unsigned char*>(walk_.data());
  const int32_t* topWords = reinterpret_cast<const int32_t*>(topCells_.data());
  const int32_t* leaves = reinterpret_cast<const int32_t*>(walkLeaf_.data());
  auto output = [&](size_t i, const GeoHit& h) {
    if (AnyHit) anyHits[i] = h.hit();
    else hits[i] = h;
  };
  // The voxel map (leafIndex) for the lanes of `m`: the top cell's leaf offset and shifts give
  // the leaf; the leaf holds the cell's record (unitsOf).
  auto leafOf = [&](const I v[3], M m) {
    const I zero = I{};
    const I mask = zero + ((1 << depth_) - 1);
    const I top = ((v[2] >> depth_) * top_[1] + (v[1] >> depth_)) * top_[0] + (v[0] >> depth_);
    const I topByte = sel(m, top, zero) * int32_t(sizeof(TopCell));
    const I offset = (I)_mm512_mask_i32gather_epi32((__m512i)zero, m.bits, (__m512i)topByte, topWords, 1);
    const I shifts = (I)_mm512_mask_i32gather_epi32((__m512i)zero, m.bits, (__m512i)topByte, topWords + 1, 1);
    const I byte = zero + 0xff, s0 = shifts & byte, s1 = (shifts >> 8) & byte, s2 = (shifts >> 16) & byte;
    const I bits1 = (shifts >> 24) & byte, bits2 = bits1 + (depth_ - s1);  // d0 and d0 + d1, d_a = D − shift_a
    const I l0 = (v[0] & mask) >> s0, l1 = (v[1] & mask) >> s1, l2 = (v[2] & mask) >> s2;  // (non-negative: >> is logical)
    return sel(m, offset + (((l2 << bits2) + (l1 << bits1)) + l0), zero);
  };
  auto unitsOf = [&](I leaf, M m) { return (I)_mm512_mask_i32gather_epi32((__m512i)I{}, m.bits, (__m512i)leaf, leaves, 4); };
  // Rays enter the lanes from a buffer that `enter` fills for sixteen queries at once: the clip to
  // the grid's box, the first voxel and its cell, the watertight test's shear — enter's and
  // WatertightRay's expressions in lanes, with selects for their branches.
  constexpr int kL = GridLanes::kL;  // (not the class's kLanes: a triangle block's four)
  struct alignas(64) Entered {
    float o[3][kL], d[3][kL], inv[3][kL], tnear[kL], tfar[kL], t1[kL], sx[kL], sy[kL];
    int32_t v[3][kL], k[3][kL];  ///< the first voxel; the shear's axes kx, ky, kz
    uint32_t unit[kL];
    uint32_t in = 0;  ///< the queries that enter the grid
    size_t first = 0, count = 0, taken = 0;  ///< queries [first, first + count), `taken` of them used
  } ent;
  static_assert(sizeof(Query) == 8 * sizeof(float), "a query is one 32-byte row");
  size_t next = 0;
  auto enterSixteen = [&] {
    constexpr float inf = std::numeric_limits<float>::infinity();
    const size_t n = std::min<size_t>(kL, queries.size() - next);
    ent.first = next, ent.count = n, ent.taken = 0;
    next += n;
    F r[8];
    for (int j = 0; j < 8; ++j) {
      F8 lo{}, hi{};
      if (size_t(j) < n) std::memcpy(&lo, &queries[ent.first + size_t(j)], sizeof lo);
      if (size_t(j) + 8 < n) std::memcpy(&hi, &queries[ent.first + size_t(j) + 8], sizeof hi);
      r[j] = joinRows(lo, hi);
    }
    F q[8];
    transposeRows8(r, q);
    const F* o = q;
    const F* d = q + 3;
    F t0 = q[6], t1 = q[7], inv[3];
    for (int a = 0; a < 3; ++a) {
      inv[a] = 1.0f / d[a];
      F lo = (lo_[a] - o[a]) * inv[a], hi = (hi_[a] - o[a]) * inv[a];
      const M swap = gt(lo, hi);
      const F near = sel(swap, hi, lo), far = sel(swap, lo, hi);
      lo = sel(eq(near, near), near, F{} - inf);  // 0 · inf
      hi = sel(eq(far, far), far, F{} + inf);
      t0 = vmax(t0, lo);
      t1 = vmin(t1, hi);
    }
    const M in = M{__mmask16((1u << n) - 1u)} & ~gt(t0, t1);
    I v[3];
    for (int a = 0; a < 3; ++a) {
      const F p = ((o[a] + d[a] * t0) - lo_[a]) * invVoxel_[a];
      v[a] = imin(imax(__builtin_convertvector(vfloor(p), I), I{}), I{} + (virt_[a] - 1));  // std::clamp
      store(ent.o[a], o[a]), store(ent.d[a], d[a]), store(ent.inv[a], inv[a]), store(ent.v[a], v[a]);
    }
    store(ent.tnear, q[6]), store(ent.tfar, q[7]), store(ent.t1, t1);
    store(ent.unit, unitsOf(leafOf(v, in), in));
    // WatertightRay: z along the largest |d|, x and y after it, swapped where d_z < 0.
    const I zero = I{}, one = zero + 1, two = zero + 2;
    const F ax = vabs(d[0]), ay = vabs(d[1]), az = vabs(d[2]);
    const I kz = sel(ge(ax, ay), sel(ge(ax, az), zero, two), sel(ge(ay, az), one, two));
    I kx = sel(eq(kz, two), zero, kz + 1);
    I ky = sel(eq(kx, two), zero, kx + 1);
    auto pick = [&](I k) { return sel(eq(k, zero), d[0], sel(eq(k, one), d[1], d[2])); };
    const F dz = pick(kz);
    const M flip = lt(dz, F{});
    const I kx0 = kx;
    kx = sel(flip, ky, kx), ky = sel(flip, kx0, ky);
    store(ent.sx, pick(kx) / dz), store(ent.sy, pick(ky) / dz);
    store(ent.k[0], kx), store(ent.k[1], ky), store(ent.k[2], kz);
    ent.in = in.bits;
  };
  auto fill = [&](GridLanes& ln, int j) {
    ln.ray[j] = -1;
    ln.unit[j] = 0;  // an empty lane reads cell 0 (a valid record) and stays out of every mask
    for (;;) {
      if (ent.taken == ent.count) {
        if (next == queries.size()) return false;
        enterSixteen();
        for (uint32_t m = ent.in; m; m &= m - 1) prefetchCell(&walkCell(ent.unit[__builtin_ctz(m)]));
      }
      const size_t e = ent.taken++, i = ent.first + e;
      if (!(ent.in >> e & 1)) {
        output(i, GeoHit{});
        continue;
      }
      Walk& w = ln.walk[j];
      for (int a = 0; a < 3; ++a) {
        ln.o[a][j] = ent.o[a][e], ln.d[a][j] = ent.d[a][e], ln.inv[a][j] = ent.inv[a][e], ln.v[a][j] = ent.v[a][e];
        w.ray.o[a] = ent.o[a][e], w.ray.d[a] = ent.d[a][e];
      }
      w.ray.kx = ent.k[0][e], w.ray.ky = ent.k[1][e], w.ray.kz = ent.k[2][e], w.ray.sx = ent.sx[e], w.ray.sy = ent.sy[e];
      w.tnear = ent.tnear[e], w.bestT = ent.tfar[e];
      w.best = GeoHit{};
      ln.bestT[j] = ent.tfar[e];
      ln.hasBest &= __mmask16(~(1u << j));
      ln.t1[j] = ent.t1[e];
      ln.step[j] = 0;
      ln.ray[j] = int32_t(i);
      ln.unit[j] = ent.unit[e];
      return true;
    }
  };
  auto done = [&](GridLanes& ln, int j) { output(size_t(ln.ray[j]), AnyHit ? ln.walk[j].best : finish(ln.walk[j])); };
  auto step = [&](GridLanes& ln) -> uint32_t {
    constexpr float inf = std::numeric_limits<float>::infinity();
    const I zero = I{};
    const M live = ge(load<I>(ln.ray), zero);
    // The lanes' cell records (exit box and reference count): one 32-byte row per lane.
    F r[8];
    for (int j = 0; j < 8; ++j) {
      F8 lo, hi;
      std::memcpy(&lo, walkBase + size_t(ln.unit[j]) * kUnit, sizeof lo);
      std::memcpy(&hi, walkBase + size_t(ln.unit[j + 8]) * kUnit, sizeof hi);
      r[j] = joinRows(lo, hi);
    }
    F field[8];
    transposeRows8(r, field);
    I elo[3], ehi[3];
    for (int a = 0; a < 3; ++a) elo[a] = (I)field[a], ehi[a] = (I)field[3 + a];
    // exitCell: the first axis with the smallest exit distance.
    F o[3], dir[3], t[3];
    M pos[3], neg[3];
    for (int a = 0; a < 3; ++a) {
      o[a] = load<F>(ln.o[a]), dir[a] = load<F>(ln.d[a]);
      pos[a] = gt(dir[a], F{}), neg[a] = lt(dir[a], F{});
      const F bound = lo_[a] + __builtin_convertvector(sel(pos[a], ehi[a], elo[a]), F) * voxel_[a];
      t[a] = sel(eq(dir[a], F{}), F{} + inf, (bound - o[a]) * load<F>(ln.inv[a]));
    }
    const M y = lt(t[1], t[0]);
    const F t01 = sel(y, t[1], t[0]);
    const M z = lt(t[2], t01);
    const F tExit = sel(z, t[2], t01);
    store(ln.tExit, tExit);
    M more = lt(live, tExit, load<F>(ln.t1));
    const M onAxis[3] = {andNot(~y, z), andNot(y, z), z};
    I v[3];
    for (int a = 0; a < 3; ++a) {
      const F q = ((o[a] + dir[a] * tExit) - lo_[a]) * invVoxel_[a];
      const I cell = __builtin_convertvector(vfloor(q), I);
      const I face = imin(imax(cell, elo[a]), ehi[a] - 1);  // std::clamp (elo < ehi)
      const I vOld = load<I>(ln.v[a]);
      const I beside = sel(pos[a], imax(face, vOld), sel(neg[a], imin(face, vOld), face));
      v[a] = sel(onAxis[a], sel(pos[a], ehi[a], elo[a] - 1), beside);
      more = andNot(more, onAxis[a] & outside(v[a], zero + virt_[a]));
      store(ln.v[a], sel(more, v[a], vOld));
    }
    store(ln.leaf, leafOf(v, more));
    // The lanes in empty cells are answered here, as testCell answers them — the closest hit so
    // far lies inside this cell, or there is no next cell — and the others' triangles are tested
    // by testCell itself, lane after lane.
    const M tested = ne(live, (I)field[6], zero);
    const M empty = andNot(live, tested);
    const M answered = andNot(empty, more) | le(empty & M{ln.hasBest}, load<F>(ln.bestT), tExit);
    uint32_t finished = answered.bits;
    for (uint32_t m = tested.bits; m; m &= m - 1) {
      const int j = __builtin_ctz(m);
      Walk& w = ln.walk[j];
      w.tExit = ln.tExit[j];
      if (testCell<AnyHit>(w, walkCell(ln.unit[j]), (more.bits >> j) & 1)) finished |= 1u << j;
      ln.bestT[j] = w.bestT;
      ln.hasBest |= __mmask16(w.best.hit()) << j;
    }
    // The step cap (a safety net: the steps move forward), as traverse() counts it.
    const M stepped = andNot(live, M{__mmask16(finished)});
    const I steps = load<I>(ln.step) + 1;
    store(ln.step, sel(stepped, steps, load<I>(ln.step)));
    finished |= eq(stepped, steps, zero + maxSteps).bits;
    ln.pending = andNot(more, M{__mmask16(finished)}).bits;
    for (uint32_t m = ln.pending; m; m &= m - 1) __builtin_prefetch(&walkLeaf_[uint32_t(ln.leaf[__builtin_ctz(m)])]);
    return finished;
  };
  // The leaves a group's last step asked for (arrived meanwhile) give its lanes' next cells.
  auto advance = [&](GridLanes& ln) {
    const M pending{ln.pending};
    if (!pending.bits) return;
    store(ln.unit, sel(pending, unitsOf(load<I>(ln.leaf), pending), load<I>(ln.unit)));
    for (uint32_t m = pending.bits; m; m &= m - 1) prefetchCell(&walkCell(ln.unit[__builtin_ctz(m)]));
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
    for (int j = 0; j < kL; ++j) live += fill(ln, j);
  while (live > 0)
    for (int g = 0; g < kGroups; ++g) {
      GridLanes& ln = lanes[g];
      const uint32_t finished = step(ln);
      advance(lanes[(g + 2) % kGroups]);
      for (uint32_t m = finished; m; m &= m - 1) {
        const int j = __builtin_ctz(m);
        done(ln, j);
        live += int(fill(ln, j)) - 1;
      }
    }
}

template void IrregularGrid::traverseLanes<false>(std::span<const Query>, std::span<GeoHit>, std::span<uint8_t>) const;
template void IrregularGrid::traverseLanes<true>(std::span<const Query>, std::span<GeoHit>, std::span<uint8_t>) const;

#pragma GCC pop_options
#endif

/// The lanes need AVX-512, a cell 0 for empty lanes to read, and voxel-map indices (top cells'
/// byte offsets, leaves) that fit 32-bit lanes.
bool IrregularGrid::lanesAvailable() const {
#if LT_SIMD512
  return simd512Available() && !walk_.empty() && topCells_.size() * sizeof(TopCell) < (size_t(1) << 31) &&
         walkLeaf_.size() < (size_t(1) << 31);
#else
  return false;
#endif
}

LT_CPU_DISPATCH GeoHit IrregularGrid::intersect(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts) const {
  return traverse<false>(origin, dir, tnear, tfar, counts);
}

LT_CPU_DISPATCH bool IrregularGrid::occluded(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts) const {
  return traverse<true>(origin, dir, tnear, tfar, counts).hit();
}

void IrregularGrid::intersect(std::span<const Query> queries, std::span<GeoHit> hits) const {
#if LT_SIMD512
  if (lanesAvailable()) return traverseLanes<false>(queries, hits, {});
#endif
  intersectPortable(queries, hits);
}

void IrregularGrid::occluded(std::span<const Query> queries, std::span<uint8_t> hits) const {
#if LT_SIMD512
  if (lanesAvailable()) return traverseLanes<true>(queries, {}, hits);
#endif
  occludedPortable(queries, hits);
}

LT_CPU_DISPATCH void IrregularGrid::intersectPortable(std::span<const Query> queries, std::span<GeoHit> hits) const {
  traverseBatch<false>(queries, [&hits](size_t i, const GeoHit& h) { hits[i] = h; });
}

LT_CPU_DISPATCH void IrregularGrid::occludedPortable(std::span<const Query> queries, std::span<uint8_t> hits) const {
  traverseBatch<true>(queries, [&hits](size_t i, const GeoHit& h) { hits[i] = h.hit(); });
}

}  // namespace lt
