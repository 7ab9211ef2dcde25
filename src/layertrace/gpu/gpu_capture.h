// Capture on the GPU (Hofmann et al. 2017, §4.1–4.2): the scene rasterized by the OpenGL
// pipeline, every fragment kept, sorted to the k-layer arrays — the same 16-byte nodes, layout
// and precision as the CPU capture (raster/), which the result is compared with. Two captures:
//   lists  every fragment linked into per-pixel lists in one geometry pass (an atomic counter
//          over a pool, an atomic exchange on the pixel's head), then a compute pass sorts
//          each pixel to its k front-most fragments with the minimum separation or the
//          adaptive thickness of §4.2;
//   peel   depth peeling, the baseline of Fig. 8: the nearest remaining layer per geometry
//          pass pair, k times (no pool, no lists).
#pragma once

#include <cstdint>
#include <vector>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/raster/fragment_lists.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"

namespace lt {

enum class GpuCaptureMethod { Lists, Peel };

struct GpuCaptureConfig {
  GpuCaptureMethod method = GpuCaptureMethod::Lists;
  LayerConfig layers;
  /// The pool in fragments (lists); 0 = 8 per pixel, at least 2^20.
  uint64_t poolCapacity = 0;
  /// On overflow capture again with a pool that holds every fragment (the count is exact).
  bool growOnOverflow = true;
  bool frontFacesOnly = false;
  /// Lists: also download every fragment's list (GpuCaptureResult::lists), for verification.
  bool keepLists = false;
};

struct GpuCaptureResult {
  LayerArrays layers;
  /// Every fragment in its pixel's list (GpuCaptureConfig::keepLists, lists capture), as the CPU
  /// capture's lists: heads, pool, triangles. Otherwise only the sizes and counts.
  FragmentLists lists;
  uint64_t generated = 0;            ///< fragments the rasterizer produced (of the last pass)
  uint64_t stored = 0;               ///< of them in the pool (lists); = generated when nothing was lost
  uint64_t overflowLost = 0;         ///< fragments lost by a first pass that overflowed (before growing)
  uint64_t poolCapacity = 0;         ///< the pool of the last pass (lists)
  int passes = 0;                    ///< capture passes (2 when the pool grew)
  int geometryPasses = 0;            ///< times the scene was rasterized (peel: 2k)
  /// GPU milliseconds (timer queries): the vertex and triangle setup, the geometry passes, and
  /// the sort (or the peel's resolve).
  double setupMs = 0.0, rasterMs = 0.0, sortMs = 0.0;
  size_t memoryBytes = 0;  ///< GPU memory the capture held: scene, pool, lists and arrays
};

/// Captures `scene` seen by `camera` on the GPU into `out` (its layers downloaded to the CPU).
/// InputError for an invalid layer configuration, for adaptive thickness with depth peeling
/// (it needs every fragment), and for a pool that overflows with growOnOverflow off (with the
/// exact counts).
void captureOnGpu(GpuContext& gpu, const Scene& scene, const Camera& camera, const GpuCaptureConfig& config, GpuCaptureResult& out);

}  // namespace lt
