// The interval pyramid of Hofmann et al. 2017, §4.3, built on the GPU (shaders/pyramid_merge.comp,
// pyramid_scan.comp) over a level 0 already there: per level, a counting pass, a prefix sum
// and a writing pass give the CPU's CSR intervals and fixed-slot κ cells, bit for bit on an IEEE
// device (the same merges of the same floats; tested against buildIntervalPyramid). With τ = ∞
// it is the Hi-Z min/max pyramid (hiz/hiz_pyramid.h).
#pragma once

#include <array>
#include <vector>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/scene/camera.h"

namespace lt {

struct GpuPyramid {
  static constexpr int kMaxLevels = 16;
  int levels = 0;
  std::array<int, kMaxLevels> width{}, height{};
  std::array<int, kMaxLevels> cellBase{};  ///< the first cell of each level ≥ 1 in `cells`
  GpuBuffer cells;                          ///< levels 1… as CoarseCell, one after the other
  std::vector<GpuBuffer> offsets, intervals;  ///< per level ≥ 1: the CSR lists ([0] unused)
  std::vector<uint32_t> intervalCounts;       ///< per level: intervals held ([0]: level 0's)
  double buildMs = 0.0;                       ///< GPU time (timer queries)
  size_t memoryBytes() const;
};

/// Levels 1..config.levels − 1 over `level0` (k intervals per pixel, pixel-major) and `counts`
/// (intervals per pixel) of a W × H view. InputError for an invalid configuration.
void buildPyramidOnGpu(GpuContext& gpu, const GpuBuffer& level0, const GpuBuffer& counts, int W, int H, int k, const Camera& camera,
                       const PyramidConfig& config, GpuPyramid& out);

/// The GPU's levels in the CPU's form (offsets, intervals, cells; `base` is left to the caller).
IntervalPyramid downloadPyramid(const GpuPyramid& pyramid);

}  // namespace lt
