// The irregular grid of Pérard-Gayot et al. 2017 ("GPU Ray Tracing Using Irregular Grids",
// Pérard-Gayot, Kalojanov, Slusallek, EG 2017), on the CPU.
//
// Construction (irregular_grid_build.cpp):
//   1. a coarse uniform top-level grid, resolution R = d · cbrt(λ1 N / V) per axis (Cleary);
//   2. in each top cell an octree of depth D_i from the same formula with λ2 and the cell's own
//      object count and volume, clamped to a power of two — stored fully subdivided, so the
//      voxel map is a compact two-level grid (top cell → depths, offset → leaf cell ids);
//      all cells are aligned on a virtual grid of resolution R · 2^D, D = max D_i. Our default
//      departs from the paper: the depth is per axis (the formula on each side of the cell), so a
//      top cell longer on one axis is not cut as finely on the others — the paper's cubic
//      octree cut a flat slab's 0.35 × 0.35 × 1 cells to the depth the long side needs, 26.6 M
//      initial cells for 240 k triangles (GridConfig::oneDepthPerCell gives the paper's rule);
//   3. cell merging: a cell and its neighbour whose union is a box merge when the SAH criterion
//      holds, for empty and non-empty cells, repeated until N_after ≥ α N_before;
//   4. cell expansion: each cell's exit boundaries grow over neighbours whose references are a
//      subset of its own (traversal stays correct: every primitive of the skipped region was
//      already tested), a fixed number of passes (3 for static scenes); optionally partial.
// Traversal (irregular_grid_traverse.cpp): stackless and ordered — locate the origin's cell in
// the voxel map, intersect its primitives (four at a time, watertight), stop when the closest
// hit lies inside the (expanded) cell, otherwise move to the cell beyond the exit point.
#pragma once

#include <array>
#include <cstdint>
#include <new>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "layertrace/geometry/embree_scene.h"
#include "layertrace/scene/scene.h"

namespace lt {

struct GridConfig {
  /// Top-level density. Pérard-Gayot et al. 2017 use λ1 = 0.12; a sweep (`geobench --sweep` on
  /// FZK-Haus, am_thornish and engine, then 2 × 3 runs of the three best against Embree in the
  /// same run; docs/methods/grid.md) found 0.5 faster to traverse: primary rays 0.62–0.64 →
  /// 0.92–0.93× Embree on FZK-Haus, 0.84–0.86 → 0.95× on engine, 0.56–0.57 → 0.53× on
  /// am_thornish, for about twice the build time and 1.3–1.5× the memory.
  float lambda1 = 0.5f;
  float lambda2 = 2.4f;       ///< second-level density (the paper: λ2 = 2.4; the sweep agrees)
  /// Cap on the per-cell octree depth (2^6 = 64 leaves per axis). The slides allow up to 2^15
  /// per axis (4 bits of depth); every top cell is stored fully subdivided here, so the build
  /// refuses, with the cell count, an octree that would not fit (irregular_grid_build.cpp).
  int maxDepth = 6;
  /// One octree depth per top cell, from its longest side: D = ⌈log2 max(R_x, R_y, R_z)⌉ (the
  /// slides, "Initialization"; hagrid's compute_log_dims). Off (the default), each axis gets the
  /// formula on its own side (the header comment: a flat slab is not cut as finely across).
  bool oneDepthPerCell = false;
  bool merge = true;          ///< cell merging
  /// Merge passes find their candidates and join the chosen pairs in parallel; false runs the
  /// serial greedy pass they reproduce exactly (the tests' reference).
  bool parallelMerge = true;
  float alpha = 0.995f;       ///< stop merging when N_after ≥ α N_before
  /// Cost of one traversal step relative to one intersection, in the SAH merge test:
  /// merge A, B when SA(A∪B)(C_t + |R(A∪B)|) ≤ SA(A)(C_t + |R(A)|) + SA(B)(C_t + |R(B)|).
  /// This is the test of the authors' released code (hagrid, src/merge.cu, unit_cost = 1).
  /// The slides print |R(A)| SA(A) + |R(B)| SA(B) ≥ |R(A∪B)| SA(A∪B) − C_t, which subtracts
  /// one C_t from the union's cost instead of charging each cell a step; we follow the code.
  float traversalCost = 1.0f;
  int expansionPasses = 3;    ///< the paper: 3 for static scenes, 1 for dynamic ones
  /// Partial expansion (the slides' expansion is all-or-nothing per neighbour; hagrid's
  /// released code expands partially): a face may also sweep into a neighbour B whose
  /// references are not a subset of A's, as long as every primitive of B that overlaps the
  /// swept part of B is referenced by A. On by default: 5–10 % faster traversal on the real
  /// scenes for ~10–30 % more build time, the same agreement with Embree (docs/methods/grid.md).
  bool partialExpansion = true;
  /// --device gpu: build the grid on the GPU (gpu/gpu_grid_build.h: steps 1 and 2, no merging
  /// or expansion) instead of uploading the CPU's. No effect on the CPU's own grid.
  bool gpuBuild = false;
};

/// Bytes of a walk unit (IrregularGrid::Packed: the leaves address the walk in these).
inline constexpr size_t kGridWalkUnit = 32;

struct GridCell {
  int lo[3], hi[3];    ///< the cell in virtual-grid voxels [lo, hi)
  int elo[3], ehi[3];  ///< the expanded box used to find the exit point (⊇ [lo, hi))
  uint32_t refBegin = 0, refEnd = 0;
};

struct GridStats {
  double buildMs = 0.0;
  double initialMs = 0.0, mergeMs = 0.0, expandMs = 0.0;  ///< build time by phase
  int top[3] = {0, 0, 0};
  int depth = 0;  ///< D: virtual resolution = top · 2^D
  size_t cellsInitial = 0, cellsAfterMerge = 0, refs = 0, expandedFaces = 0;
  int mergePasses = 0;
};

class IrregularGrid {
 public:
  IrregularGrid(const Scene& scene, const GridConfig& config = {});

  /// Closest hit with t in (tnear, tfar] (Embree's rule: a ray starting on a triangle does not
  /// hit it at t = tnear); `steps` counts visited cells.
  GeoHit intersect(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts = nullptr) const;
  /// Any hit with t in (tnear, tfar].
  bool occluded(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts = nullptr) const;

  /// One query of a batch.
  struct Query {
    glm::vec3 origin, dir;
    float tnear, tfar;
  };
  /// The answers of intersect / occluded for many rays, bit for bit, with several rays in flight
  /// (uncounted): each ray's next cell is prefetched while the other rays of its group step, so
  /// the traversal's chain of dependent loads (leaf → cell → triangles) overlaps across rays
  /// instead of stalling each ray (incoherent rays were latency-bound). A ray per vector lane on
  /// the best vector target of the CPU (16 with AVX-512, 8 with AVX2, 4 with SSE4 or NEON).
  void intersect(std::span<const Query> queries, std::span<GeoHit> hits) const;
  void occluded(std::span<const Query> queries, std::span<uint8_t> hits) const;
  /// The batch without the vector lanes (sixteen scalar rays in flight): the reference the tests
  /// hold the lanes to, besides the one-ray traversal.
  void intersectPortable(std::span<const Query> queries, std::span<GeoHit> hits) const;
  void occludedPortable(std::span<const Query> queries, std::span<uint8_t> hits) const;

  /// What the vector lanes (compiled once per vector target) see of the private parts; defined in
  /// irregular_grid_traverse.cpp.
  struct LaneAccess;

  const GridStats& stats() const { return stats_; }
  size_t memoryBytes() const;
  const std::vector<GridCell>& cells() const { return cells_; }
  const std::vector<uint32_t>& refs() const { return refs_; }
  /// The cell containing virtual voxel v (the voxel map lookup), an index in cells().
  uint32_t cellAt(const int v[3]) const { return walkCell(walkLeaf_[leafIndex(v)]).id; }
  int virtualResolution(int axis) const { return virt_[axis]; }
  glm::vec3 voxelSize() const { return voxel_; }
  glm::vec3 inverseVoxelSize() const { return invVoxel_; }
  glm::vec3 origin() const { return lo_; }  ///< the grid box's lower corner
  glm::vec3 boxMax() const { return hi_; }   ///< the grid box's upper corner
  int topResolution(int axis) const { return top_[axis]; }
  int depth() const { return depth_; }  ///< D: the virtual grid is topResolution · 2^D

  /// The traversal's packed structure as bytes, for a device that walks it as the CPU does
  /// (gpu/gpu_grid.h). Top cells: 12 bytes each, the first leaf (uint32), then the shifts of x,
  /// y and z and bits1 (one byte each), then bits2 (a byte, 3 bytes of padding); see TopCell.
  /// Leaves: the walk unit (32 bytes) of each leaf's cell. Walk: per cell a 32-byte record
  /// (elo[3], ehi[3], references, cell id) followed by its triangle blocks (160 bytes: vertex
  /// coordinates v[vertex][axis][lane] for four triangles, then their four ids).
  /// A top cell's subdivision: 2^d_a leaves along axis a, leaf entries from `offset` in x-fastest
  /// order; shift_a = D − d_a turns a virtual voxel into a leaf coordinate, and the leaf
  /// (l0, l1, l2) is entry l0 + (l1 << bits1) + (l2 << bits2), bits1 = d_0, bits2 = d_0 + d_1.
  struct TopCell {
    uint32_t offset;
    uint8_t shift[3], bits1, bits2;
    uint8_t padding[3] = {};  ///< zero: the packed bytes are the same from build to build
  };
  struct Packed {
    std::span<const unsigned char> topCells;
    std::span<const uint32_t> leaves;
    std::span<const unsigned char> walk;
  };
  Packed packed() const;
  /// Whether any triangle is alpha-tested (a hit on it needs the texture: surfacePresent).
  bool hasCutOuts() const { return cutOuts_; }

 private:
  template <bool AnyHit>
  GeoHit traverse(glm::vec3 o, glm::vec3 d, float tnear, float tfar, TraversalCounts* counts) const;
  friend struct GridBuilder;

  /// What the traversal reads, packed apart from the builder's data (the same values). Each cell
  /// is one 32-byte record — its exit box and reference count — followed directly by its
  /// triangles in blocks of four, vertex coordinates lane by lane, ready for the 4-wide watertight
  /// test; records start on 64-byte lines, so a cell and its first block are exactly three lines
  /// that one leaf lookup locates and prefetches together (no reference list to follow, one
  /// dependent load per cell after the leaf). A triangle referenced by several cells
  /// is copied into each: 160 bytes per four references instead of 4 per reference plus 36 per
  /// triangle.
  static constexpr int kLanes = 4;
  static constexpr size_t kUnit = kGridWalkUnit;  ///< walk_ is addressed in 32-byte units
  struct alignas(kUnit) TraversalCell {
    int elo[3], ehi[3];
    uint32_t refs;  ///< references; its ⌈refs / 4⌉ blocks follow the record
    uint32_t id;    ///< index in cells_ (what cellAt answers)
  };
  /// Four triangles: v[vertex][axis][lane], and their scene ids. A cell whose reference count is
  /// not a multiple of four repeats its last triangle in the spare lanes — the same triangle
  /// tested twice gives the same answer, so no lane mask is needed.
  struct alignas(kUnit) TriangleBlock {
    float v[3][3][kLanes];
    uint32_t id[kLanes];
  };
  static_assert(sizeof(TraversalCell) == kUnit && sizeof(TriangleBlock) % kUnit == 0);
  struct alignas(64) Line {
    unsigned char bytes[64];
  };
  const TraversalCell& walkCell(uint32_t unit) const {
    return *std::launder(reinterpret_cast<const TraversalCell*>(reinterpret_cast<const unsigned char*>(walk_.data()) + size_t(unit) * kUnit));
  }
  static const TriangleBlock* walkBlocks(const TraversalCell& c) { return std::launder(reinterpret_cast<const TriangleBlock*>(&c + 1)); }
  /// Index in walkLeaf_ of virtual voxel v (the voxel map's first level).
  size_t leafIndex(const int v[3]) const {
    const TopCell& t = topCells_[(size_t(v[2] >> depth_) * size_t(top_[1]) + size_t(v[1] >> depth_)) * size_t(top_[0]) + size_t(v[0] >> depth_)];
    const int mask = (1 << depth_) - 1;
    const uint32_t l0 = uint32_t((v[0] & mask) >> t.shift[0]), l1 = uint32_t((v[1] & mask) >> t.shift[1]),
                   l2 = uint32_t((v[2] & mask) >> t.shift[2]);
    return t.offset + ((l2 << t.bits2) + (l1 << t.bits1) + l0);
  }
  /// During the build, before walkLeaf_ exists: the builder's cell id of voxel v.
  uint32_t buildCellAt(const int v[3]) const { return leaf_[leafIndex(v)]; }
  /// One ray's traversal state; the steps below are what the one-ray and the batched traversal
  /// share, so both answer alike.
  struct Walk;
  bool enter(Walk& w, glm::vec3 o, glm::vec3 d, float tnear, float tfar) const;
  bool exitCell(Walk& w, const TraversalCell& c) const;
  template <bool AnyHit>
  bool testCell(Walk& w, const TraversalCell& c, bool more) const;
  GeoHit finish(const Walk& w) const;
  template <bool AnyHit, class Out>
  void traverseBatch(std::span<const Query> queries, Out out) const;
  /// Whether the batch queries run in vector lanes (a ray per lane: the exit, the next voxel and
  /// the voxel-map lookup of a vector's count of cells at once, each lane's triangles tested by
  /// testCell; irregular_grid_traverse.cpp).
  bool lanesAvailable() const;
  void packForTraversal();

  const Scene* scene_;
  bool cutOuts_ = false;  ///< the scene has alpha-tested triangles (surfacePresent decides each hit on them)
  glm::vec3 lo_{0.0f}, hi_{0.0f}, voxel_{1.0f};
  glm::vec3 invVoxel_{1.0f};  ///< 1 / voxel_: the traversal multiplies instead of dividing
  int top_[3] = {1, 1, 1};
  int depth_ = 0;
  int virt_[3] = {1, 1, 1};
  // The voxel map as the builder makes and rewrites it; released once packForTraversal has made
  // topCells_ and walkLeaf_ from it.
  std::vector<std::array<uint8_t, 3>> topDepth_;  ///< level 1: octree depth of each top cell, per axis
  std::vector<uint32_t> topOffset_; ///< level 1: first leaf entry of each top cell
  std::vector<uint32_t> leaf_;      ///< level 2: cell id of each leaf
  std::vector<GridCell> cells_;
  std::vector<uint32_t> refs_;
  std::vector<TopCell> topCells_;
  std::vector<uint32_t> walkLeaf_;  ///< voxel map, level 2, for the traversal: the leaf's cell record in walk_
  std::vector<Line> walk_;          ///< every cell's record and triangle blocks, cell after cell
  GridStats stats_;
};

/// Step 1's decisions, shared by the CPU build and the GPU's (gpu/gpu_grid_build.h), so that both
/// make the same cells: the grid's box (the scene box padded) and the top-level resolution.
struct GridTopLevel {
  glm::vec3 lo{0.0f}, hi{0.0f};
  int top[3] = {1, 1, 1};
  glm::vec3 topSize() const { return (hi - lo) / glm::vec3(float(top[0]), float(top[1]), float(top[2])); }
  size_t cells() const { return size_t(top[0]) * size_t(top[1]) * size_t(top[2]); }
};
GridTopLevel gridTopLevel(const Scene& scene, const GridConfig& config);
/// Step 2's decision for a top cell of `refs` references: its octree depth per axis.
std::array<uint8_t, 3> topCellDepth(const GridConfig& config, glm::vec3 topSize, size_t refs);
/// Walk units of a cell of `refs` references: its record, its triangle
/// blocks, and padding to the next 64-byte line.
inline uint64_t cellUnits(uint64_t refs) {
  const uint64_t units = 1 + (refs + 3) / 4 * 5;
  return units + units % 2;
}

/// Triangle / axis-aligned box overlap (separating axis theorem, Akenine-Möller), with the box
/// grown by `eps` so that references are conservative.
bool triangleBoxOverlap(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 boxLo, glm::vec3 boxHi, float eps);

}  // namespace lt
