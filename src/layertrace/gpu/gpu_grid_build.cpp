#include "layertrace/gpu/gpu_grid_build.h"

#include <algorithm>
#include <chrono>
#include <vector>

#include <epoxy/gl.h>
#include <glm/geometric.hpp>

#include "layertrace/gpu/shader_sources.h"
#include "layertrace/grid/grid_method.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"

namespace lt {

namespace {
enum Stage { kTop, kLeaves, kMerge, kExpand, kPack, kStages };

/// The exclusive prefix sum of `n` counts in `buffer`, in place, the total at [n]
/// (shaders/pyramid_scan.comp: one work group).
void scan(GpuContext& gpu, const GpuBuffer& buffer, size_t n) {
  const GpuProgram& p = gpu.computeProgram("pyramid_scan.comp", shader_source::pyramid_scan_comp);
  buffer.bindStorage(4);
  p.set("uCount", int(n));
  p.set("uStatusSlot", -1);
  gpu.dispatchGroups(p, 1);
}

/// The word at `index` of `buffer` (a read-back: the host waits for the passes before it).
uint32_t wordAt(const GpuBuffer& buffer, size_t index) {
  uint32_t v = 0;
  buffer.read(&v, sizeof v, index * sizeof v);
  return v;
}
}  // namespace

GpuGridLayout GpuGridLayout::of(const IrregularGrid& grid) {
  GpuGridLayout l;
  l.lo = grid.origin(), l.hi = grid.boxMax(), l.voxel = grid.voxelSize(), l.invVoxel = grid.inverseVoxelSize();
  for (int i = 0; i < 3; ++i) l.top[i] = grid.topResolution(i), l.virt[i] = grid.virtualResolution(i);
  l.depth = grid.depth();
  return l;
}

GpuGridBuild::GpuGridBuild(GpuContext& gpu, const Scene& scene, const GridConfig& config) : gpu_(gpu) {
  validateGridConfig(config);
  if (scene.triangles.empty()) inputError("scene ", scene.name, ": no triangles for the irregular grid");
  const auto start = std::chrono::steady_clock::now();
  gpu_.makeCurrent();
  GpuDebugGroup group("grid build");
  const GridTopLevel level = gridTopLevel(scene, config);
  const glm::vec3 topSize = level.topSize();
  const size_t numTop = level.cells(), numTris = scene.triangles.size();
  checkAllocation(cat("the irregular grid's top level (", numTop, " cells)"), uint64_t(numTop) * 24);
  const GpuBuffer positions(scene.positions.size() * sizeof(glm::vec3), scene.positions.data());
  const GpuBuffer indices(numTris * sizeof(glm::uvec3), scene.triangles.data());
  const GpuProgram& top = gpu_.computeProgram("grid_build_top.comp", shader_source::grid_build_top_comp);
  const GpuProgram& leavesPass = gpu_.computeProgram("grid_build_leaves.comp", shader_source::grid_build_leaves_comp);
  const GpuProgram& pack = gpu_.computeProgram("grid_build_pack.comp", shader_source::grid_build_pack_comp);
  GpuTimeline timeline;
  const int topDims[3] = {level.top[0], level.top[1], level.top[2]};

  // Step 1: count each top cell's references.
  timeline.begin(kTop);
  const GpuBuffer topCounts((numTop + 1) * sizeof(uint32_t));
  topCounts.fill(0u);
  positions.bindStorage(0), indices.bindStorage(1), topCounts.bindStorage(2);
  top.setVec3("uLo", &level.lo.x);
  top.setVec3("uTopSize", &topSize.x);
  top.setIvec3("uTop", topDims);
  top.set("uEps", 1e-5f * glm::length(topSize));
  top.set("uTriangles", int(numTris));
  top.set("uEmit", 0);
  gpu_.dispatch(top, numTris);
  timeline.end(kTop);
  std::vector<uint32_t> counts(numTop);
  topCounts.read(counts.data(), numTop * sizeof(uint32_t));

  // The counts decide, on the host with the CPU build's functions: each top cell's octree
  // depths, the virtual resolution, where each top cell's leaves start.
  std::vector<uint32_t> topOffsets(numTop + 1);
  std::vector<glm::uvec2> topInfo(numTop);
  std::vector<IrregularGrid::TopCell> topRecords(numTop);
  std::vector<std::array<uint8_t, 3>> depths(numTop);
  uint64_t topRefs = 0, leaves = 0;
  int D = 0;
  for (size_t c = 0; c < numTop; ++c) {
    topOffsets[c] = uint32_t(topRefs);
    topRefs += counts[c];
    depths[c] = topCellDepth(config, topSize, counts[c]);
    D = std::max({D, int(depths[c][0]), int(depths[c][1]), int(depths[c][2])});
  }
  if (topRefs > 0xFFFFFFFFull) inputError("irregular grid: ", topRefs, " top-level references exceed the 32-bit reference index");
  topOffsets[numTop] = uint32_t(topRefs);
  for (size_t c = 0; c < numTop; ++c) {
    const std::array<uint8_t, 3> d = depths[c];
    topInfo[c] = {uint32_t(leaves), uint32_t(d[0]) | uint32_t(d[1]) << 8 | uint32_t(d[2]) << 16};
    topRecords[c] = {uint32_t(leaves), {uint8_t(D - d[0]), uint8_t(D - d[1]), uint8_t(D - d[2])}, d[0], uint8_t(d[0] + d[1])};
    leaves += uint64_t(1) << (d[0] + d[1] + d[2]);
  }
  if (leaves > 0xFFFFFFFEull) inputError("irregular grid: ", leaves, " cells exceed the 32-bit cell index (use lower --lambda1/--lambda2)");
  checkAllocation(cat("the irregular grid (", leaves, " cells)"), leaves * 16 + topRefs * 8);
  GpuGridLayout& L = layout_;
  L.lo = level.lo, L.hi = level.hi, L.depth = D;
  for (int i = 0; i < 3; ++i) L.top[i] = level.top[i], L.virt[i] = level.top[i] << D;
  L.voxel = (level.hi - level.lo) / glm::vec3(float(L.virt[0]), float(L.virt[1]), float(L.virt[2]));
  L.invVoxel = 1.0f / L.voxel;

  // Step 1: the references, at the counts' prefix sum.
  timeline.begin(kTop);
  const GpuBuffer offsets((numTop + 1) * sizeof(uint32_t), topOffsets.data());
  const GpuBuffer refsTop(std::max<size_t>(topRefs * 4, 16)), refCells(std::max<size_t>(topRefs * 4, 16));
  topCounts.fill(0u);
  topCounts.bindStorage(2), offsets.bindStorage(3), refsTop.bindStorage(4), refCells.bindStorage(5);
  top.set("uEmit", 1);
  gpu_.dispatch(top, numTris);
  timeline.end(kTop);

  // Step 2: the leaves' references, counted, summed on the device, emitted.
  timeline.begin(kLeaves);
  const GpuBuffer info(numTop * sizeof(glm::uvec2), topInfo.data());
  const GpuBuffer leafOffsets((leaves + 1) * sizeof(uint32_t)), cursors(leaves * sizeof(uint32_t));
  leafOffsets.fill(0u);
  positions.bindStorage(0), indices.bindStorage(1), refsTop.bindStorage(2), refCells.bindStorage(3), info.bindStorage(4);
  leafOffsets.bindStorage(5);
  leavesPass.setVec3("uLo", &L.lo.x);
  leavesPass.setVec3("uVoxel", &L.voxel.x);
  leavesPass.setIvec3("uTop", topDims);
  leavesPass.set("uDepth", D);
  leavesPass.set("uTopRefCount", int(topRefs));
  leavesPass.set("uEmit", 0);
  gpu_.dispatch(leavesPass, topRefs);
  scan(gpu_, leafOffsets, leaves);
  timeline.end(kLeaves);
  refs_ = wordAt(leafOffsets, leaves);
  checkAllocation(cat("the irregular grid's references (", refs_, ")"), uint64_t(refs_) * 4);
  timeline.begin(kLeaves);
  const GpuBuffer refs(std::max<size_t>(refs_ * 4, 16));
  cursors.fill(0u);
  positions.bindStorage(0), indices.bindStorage(1), refsTop.bindStorage(2), refCells.bindStorage(3), info.bindStorage(4);
  cursors.bindStorage(5), leafOffsets.bindStorage(6), refs.bindStorage(7);
  leavesPass.set("uEmit", 1);
  gpu_.dispatch(leavesPass, topRefs);
  timeline.end(kLeaves);

  // Step 3, merging: every leaf a cell with its references sorted, then passes along x, y and z
  // (gpu_grid_build.h).
  timeline.begin(kMerge);
  const size_t cells = size_t(leaves);
  checkAllocation(cat("the irregular grid's cells (", cells, ")"), uint64_t(cells) * 100 + uint64_t(refs_) * 4);
  const GpuBuffer boxes(cells * 32), cellRefs(cells * 8), owners(cells * 4), fates(cells * 4), scratch(cells * 16);
  const GpuBuffer ids((cells + 1) * sizeof(uint32_t));  // the prefix sums of the new counts, then of the liveness
  const GpuProgram& merge = gpu_.computeProgram("grid_build_merge.comp", shader_source::grid_build_merge_comp);
  const GpuProgram& rank = gpu_.computeProgram("grid_build_rank.comp", shader_source::grid_build_rank_comp);
  const GpuProgram& join = gpu_.computeProgram("grid_build_join.comp", shader_source::grid_build_join_comp);
  const int virt[3] = {L.virt[0], L.virt[1], L.virt[2]};
  merge.setIvec3("uTop", topDims);
  merge.set("uDepth", D);
  merge.setIvec3("uVirt", virt);
  merge.set("uTopCells", int(numTop));
  merge.setVec3("uVoxel", &L.voxel.x);
  merge.set("uTraversalCost", config.traversalCost);
  const GpuBuffer* cellList = &refs;  // the live cells' references: `refs` or, after merging, `otherList`
  const GpuBuffer otherList(config.merge ? std::max<size_t>(refs_ * 4, 16) : 16);
  auto bindCells = [&] {
    leafOffsets.bindStorage(0), fates.bindStorage(1), info.bindStorage(2), boxes.bindStorage(3), cellRefs.bindStorage(4);
    cellList->bindStorage(5), owners.bindStorage(6), scratch.bindStorage(7);
  };
  auto runMerge = [&](int mode, size_t n) {
    bindCells();
    merge.set("uMode", mode);
    merge.set("uCells", int(n));
    gpu_.dispatch(merge, n);
  };
  runMerge(0, cells);
  timeline.end(kMerge);
  if (config.merge) {
    timeline.begin(kMerge);
    const GpuBuffer live(cells * 4), rankA(cells * 8), rankB(cells * 8), status(16);
    const GpuBuffer* spare = &otherList;
    const GpuBuffer* in = &rankA;
    const GpuBuffer* out = &rankB;
    auto runRank = [&](int mode, size_t n) {
      in->bindStorage(0), out->bindStorage(1), status.bindStorage(2), ids.bindStorage(3), cellRefs.bindStorage(4);
      fates.bindStorage(5), live.bindStorage(6), scratch.bindStorage(7);
      rank.set("uMode", mode);
      rank.set("uCells", int(n));
      gpu_.dispatch(rank, n);
      if (mode == 0 || mode == 1) std::swap(in, out);  // the ranks just written are read next
    };
    auto runOnLive = [&](int mode, size_t n) {  // merge.comp's clear and candidates over the live cells
      bindCells();
      live.bindStorage(0);
      merge.set("uMode", mode);
      merge.set("uCells", int(n));
      gpu_.dispatch(merge, n);
    };
    size_t count = cells;
    for (int round = 0; round < 64; ++round) {
      // The live cells in increasing id: the passes of this round run over them.
      runRank(3, cells);
      scan(gpu_, ids, cells);
      runRank(4, cells);
      status.fill(0u);
      for (int axis = 0; axis < 3; ++axis) {
        merge.set("uAxis", axis);
        runOnLive(2, count);  // no candidates, no preds
        runOnLive(1, count);  // the candidates, their preds
        // The ranks along the chains: a round per doubling of the links' span.
        runRank(0, count);
        for (int span = 1; span < virt[axis]; span *= 2) runRank(1, count);
        runRank(2, count);  // the choice and the new counts, in the live list's order
        scan(gpu_, ids, count);
        ids.bindStorage(0), spare->bindStorage(1), in->bindStorage(2), boxes.bindStorage(3), cellRefs.bindStorage(4);
        cellList->bindStorage(5), live.bindStorage(6), scratch.bindStorage(7);
        join.set("uCells", int(count));
        join.set("uAxis", axis);
        gpu_.dispatch(join, count);
        std::swap(cellList, spare);
      }
      runMerge(3, leaves);  // the voxel map follows the cells merged away
      ++mergeRounds_;
      const uint32_t merged = wordAt(status, 0);
      refs_ = wordAt(ids, count);  // the last pass's total (its prefix sum ran over `count` cells)
      const size_t after = count - merged;
      const bool done = float(after) >= config.alpha * float(count);  // the CPU build's rule
      count = after;
      if (done) break;
    }
    timeline.end(kMerge);
  }
  // The live cells' ids: the prefix sum of their liveness.
  timeline.begin(kMerge);
  ids.bindStorage(3), fates.bindStorage(5), scratch.bindStorage(7);
  rank.set("uMode", 3);
  rank.set("uCells", int(cells));
  gpu_.dispatch(rank, cells);
  scan(gpu_, ids, cells);
  timeline.end(kMerge);

  // Step 4, expansion: each live cell's faces over the neighbours beyond them, the CPU's passes.
  timeline.begin(kExpand);
  const GpuBuffer expanded(cells * 32 + 16);
  const GpuProgram& expand = gpu_.computeProgram("grid_build_expand.comp", shader_source::grid_build_expand_comp);
  positions.bindStorage(0), indices.bindStorage(1), info.bindStorage(2), boxes.bindStorage(3), cellRefs.bindStorage(4);
  cellList->bindStorage(5), owners.bindStorage(6), expanded.bindStorage(7);
  expanded.fill(0u);
  expand.setVec3("uLo", &L.lo.x);
  expand.setVec3("uVoxel", &L.voxel.x);
  expand.setIvec3("uTop", topDims);
  expand.set("uDepth", D);
  expand.setIvec3("uVirt", virt);
  expand.set("uPartial", int(config.partialExpansion));
  expand.set("uCells", int(cells));
  expand.set("uMode", 0);
  gpu_.dispatch(expand, cells);
  expand.set("uMode", 1);
  for (int p = 0; p < config.expansionPasses; ++p) gpu_.dispatch(expand, cells);
  timeline.end(kExpand);

  // The packing: each live cell sized, the sizes summed, then written; the leaves pointed at
  // their cells.
  timeline.begin(kPack);
  const GpuBuffer units((cells + 1) * sizeof(uint32_t));
  positions.bindStorage(0), indices.bindStorage(1), expanded.bindStorage(2), cellRefs.bindStorage(3), cellList->bindStorage(4);
  units.bindStorage(5), ids.bindStorage(7);
  pack.set("uCells", int(cells));
  pack.set("uWrite", 0);
  gpu_.dispatch(pack, cells);
  scan(gpu_, units, cells);
  timeline.end(kPack);
  const uint64_t totalUnits = wordAt(units, cells);
  checkAllocation(cat("the irregular grid's triangle blocks (", totalUnits * kGridWalkUnit, " bytes)"),
                  totalUnits * kGridWalkUnit + leaves * 4);
  timeline.begin(kPack);
  walk_ = GpuBuffer(std::max<size_t>(totalUnits * kGridWalkUnit, 16));
  walk_.fill(0u);
  leaves_ = GpuBuffer(std::max<size_t>(leaves * 4, 16));
  positions.bindStorage(0), indices.bindStorage(1), expanded.bindStorage(2), cellRefs.bindStorage(3), cellList->bindStorage(4);
  units.bindStorage(5), walk_.bindStorage(6), ids.bindStorage(7);
  pack.set("uWrite", 1);
  gpu_.dispatch(pack, cells);
  const GpuProgram& leafMap = gpu_.computeProgram("grid_build_leafmap.comp", shader_source::grid_build_leafmap_comp);
  owners.bindStorage(0), units.bindStorage(1), leaves_.bindStorage(2);
  leafMap.set("uLeaves", int(leaves));
  gpu_.dispatch(leafMap, leaves);
  timeline.end(kPack);
  topCells_ = GpuBuffer(std::max<size_t>(numTop * sizeof(IrregularGrid::TopCell), 16), topRecords.data());
  cellsInitial_ = cells;
  cells_ = wordAt(ids, cells);
  expandedFaces_ = wordAt(expanded, 2 * cells * 4);
  glUseProgram(0);
  const std::vector<double> ms = timeline.collect(kStages);
  topMs_ = ms[kTop], leavesMs_ = ms[kLeaves], mergeMs_ = ms[kMerge], expandMs_ = ms[kExpand], packMs_ = ms[kPack];
  wallMs_ = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

GpuGridBuild::~GpuGridBuild() {
  gpu_.makeCurrent();  // the buffers go with the context current
}

}  // namespace lt
