// The irregular grid of Pérard-Gayot et al. 2017 built on the GPU (shaders/grid_build_*.comp):
// step 1 (the top-level cells' references, exact triangle/box overlap), step 2 (each top cell
// fully subdivided to its octree depths, the leaves' references) and the packing the traversal
// reads (IrregularGrid::Packed), all as compute passes over the scene uploaded once. The
// decisions the paper makes from counts — the grid box and top resolution, and each top cell's
// octree depths from its reference count — are the CPU build's own functions
// (grid/irregular_grid.h gridTopLevel, topCellDepth), evaluated on the host from the counts the
// GPU reduced: one read-back of a word per top cell, then one of the totals that size the
// references and the walk. So both builds make the same cells, and with merging and expansion
// off the CPU's packed structure is the GPU's byte for byte (tested).
//
// Not on the GPU yet: step 3 (cell merging) and step 4 (cell expansion). The GPU's grid is the
// CPU's with GridConfig::merge off and no expansion passes: exact, but its walks take more
// steps than the merged and expanded grid's.
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
  /// Builds the grid of `scene` for `config` (its merge and expansion settings are not applied:
  /// see above) on the device. InputError as the CPU build gives it (the grid exceeds 32-bit
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

  size_t cells() const { return cells_; }  ///< leaves: every one a cell (nothing merged)
  size_t refs() const { return refs_; }
  /// Bytes of the packed structure on the device (top cells, leaves, walk).
  size_t memoryBytes() const { return topCells_.bytes() + leaves_.bytes() + walk_.bytes(); }
  /// GPU milliseconds (timer queries): step 1, step 2, the packing, and their sum.
  double topMs() const { return topMs_; }
  double leavesMs() const { return leavesMs_; }
  double packMs() const { return packMs_; }
  double gpuMs() const { return topMs_ + leavesMs_ + packMs_; }
  /// Host wall milliseconds of the whole build, uploads and the read-backs included.
  double wallMs() const { return wallMs_; }

 private:
  GpuContext& gpu_;
  GpuGridLayout layout_;
  GpuBuffer topCells_, leaves_, walk_;
  size_t cells_ = 0, refs_ = 0;
  double topMs_ = 0.0, leavesMs_ = 0.0, packMs_ = 0.0, wallMs_ = 0.0;
};

}  // namespace lt
