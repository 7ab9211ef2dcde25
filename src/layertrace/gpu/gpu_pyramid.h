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
  /// A resident build (buildPyramidResident): per level the intervals its `intervals` buffer
  /// holds, and on the device per level ≥ 1 the intervals the level needed (kStatusWords words),
  /// read at the frame's end with the frame's other counters.
  std::vector<uint32_t> capacity;
  GpuBuffer status;
  static constexpr size_t kStatusWords = kMaxLevels;
  size_t memoryBytes() const;
  /// After a resident build: whether every level fit (`needed`: the status words read back),
  /// else the buffers grow (at least doubling) for the build to be run again.
  bool fits(const uint32_t* needed);
};

/// Levels 1..config.levels − 1 over `level0` (k intervals per pixel, pixel-major) and `counts`
/// (intervals per pixel) of a W × H view. InputError for an invalid configuration.
void buildPyramidOnGpu(GpuContext& gpu, const GpuBuffer& level0, const GpuBuffer& counts, int W, int H, int k, const Camera& camera,
                       const PyramidConfig& config, GpuPyramid& out);

/// The same levels into `out`'s buffers of the frame before (allocated on the first build or a
/// change of size), with no read-back: the scan writes each level's total into `out.status`,
/// and a level whose intervals do not fit its buffer writes what fits (the caller checks
/// GpuPyramid::fits at the frame's end and builds again). No timer is read.
void buildPyramidResident(GpuContext& gpu, const GpuBuffer& level0, const GpuBuffer& counts, int W, int H, int k, const Camera& camera,
                          const PyramidConfig& config, GpuPyramid& out);

/// The GPU's levels in the CPU's form (offsets, intervals, cells; `base` is left to the caller).
IntervalPyramid downloadPyramid(const GpuPyramid& pyramid);

}  // namespace lt
