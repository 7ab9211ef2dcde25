// The irregular grid of Pérard-Gayot et al. 2017 built on the GPU (shaders/grid_build_*.comp):
// step 1 (the top-level cells' references, exact triangle/box overlap), step 2 (each top cell
// fully subdivided to its octree depths, the leaves' references), step 3 (cell merging), step 4
// (cell expansion) and the packing the traversal reads (IrregularGrid::Packed), all as compute
// passes over the scene uploaded once. The decisions the paper makes from counts — the grid box
// and top resolution, each top cell's octree depths from its reference count, when merging stops
// — are the CPU build's own functions and rules (grid/irregular_grid.h gridTopLevel,
// topCellDepth; α), evaluated on the host from counts the GPU reduced. So both builds make the
// same cells, and the CPU's packed structure is the GPU's byte for byte (tested on llvmpipe).
//
// Merging: a pass along an axis finds each live cell's partner (the neighbour beyond its upper
// face with the same extent across the axis, accepted by the SAH test) and the size of their
// references' union. The partners form disjoint chains along the axis, in increasing cell id, so
// the CPU's greedy choice in cell order is "every other pair from the chain's head": pointer
// jumping gives each cell its rank in its chain, an even rank joins its partner. The new
// reference counts are summed, the joined lists written as sorted unions, the voxel map follows
// the cells merged away. The CPU's rounds of three passes stop when a round merged fewer than
// (1 − α) of the cells; the host reads one count per round for that.
//
// Expansion: each live cell moves each face over the neighbours beyond it (the CPU's rule,
// partial expansion too); a cell writes only its own expanded box and reads its neighbours'
// boxes and references, which expansion never changes, so the passes run in parallel.
//
// Host waits: the top cells' counts, the references' total, one per merging round, the walk's
// size, and the cell and face counts at the end.
#pragma once

#include <cstddef>
#include <cstdint>

#include <glm/vec3.hpp>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/grid/irregular_grid.h"
#include "layertrace/scene/scene.h"

namespace lt {

/// What the traversal (shaders/grid_march.comp) reads beside the packed buffers.
struct GpuGridLayout {
  glm::vec3 lo{0.0f}, hi{0.0f}, voxel{1.0f}, invVoxel{1.0f};
  int top[3] = {1, 1, 1}, virt[3] = {1, 1, 1};
  int depth = 0;
  static GpuGridLayout of(const IrregularGrid& grid);
};

class GpuGridBuild {
 public:
  /// Builds the grid of `scene` for `config` on the device. InputError as the CPU build gives it (the grid exceeds 32-bit
  /// indices or the memory limit).
  GpuGridBuild(GpuContext& gpu, const Scene& scene, const GridConfig& config);
  ~GpuGridBuild();
  GpuGridBuild(const GpuGridBuild&) = delete;
  GpuGridBuild& operator=(const GpuGridBuild&) = delete;

  const GpuGridLayout& layout() const { return layout_; }
  /// The packed structure on the device (IrregularGrid::Packed's three parts).
  const GpuBuffer& topCells() const { return topCells_; }
  const GpuBuffer& leaves() const { return leaves_; }
  const GpuBuffer& walk() const { return walk_; }

  size_t cells() const { return cells_; }  ///< after merging
  size_t cellsInitial() const { return cellsInitial_; }  ///< the leaves, before merging
  size_t refs() const { return refs_; }
  int mergeRounds() const { return mergeRounds_; }  ///< rounds of three passes (x, y, z)
  uint64_t expandedFaces() const { return expandedFaces_; }  ///< faces the expansion moved
  /// Bytes of the packed structure on the device (top cells, leaves, walk).
  size_t memoryBytes() const { return topCells_.bytes() + leaves_.bytes() + walk_.bytes(); }
  /// GPU milliseconds (timer queries): steps 1 to 4, the packing, and their sum.
  double topMs() const { return topMs_; }
  double leavesMs() const { return leavesMs_; }
  double mergeMs() const { return mergeMs_; }
  double expandMs() const { return expandMs_; }
  double packMs() const { return packMs_; }
  double gpuMs() const { return topMs_ + leavesMs_ + mergeMs_ + expandMs_ + packMs_; }
  /// Host wall milliseconds of the whole build, uploads and the read-backs included.
  double wallMs() const { return wallMs_; }

 private:
  GpuContext& gpu_;
  GpuGridLayout layout_;
  GpuBuffer topCells_, leaves_, walk_;
  size_t cells_ = 0, cellsInitial_ = 0, refs_ = 0;
  int mergeRounds_ = 0;
  uint64_t expandedFaces_ = 0;
  double topMs_ = 0.0, leavesMs_ = 0.0, mergeMs_ = 0.0, expandMs_ = 0.0, packMs_ = 0.0, wallMs_ = 0.0;
};

}  // namespace lt
