// The software rasterizer: every fragment of every triangle, no depth test, no culling (unless
// RasterConfig::frontFacesOnly).
//
// One sample at each pixel centre, top-left fill rule on 8-bit sub-pixel fixed-point edge
// functions (watertight: a pixel centre on an edge shared by two triangles belongs to exactly
// one), homogeneous clipping against the near and far planes and a guard band. Depth and
// attributes are perspective-correct: they are evaluated where the pixel-centre ray meets the
// triangle's plane, which is also what the Embree verification measures. Parallel over screen
// tiles with TBB; the result is identical for any thread count.
//
// Layer: raster/ captures fragments — the rasterizer, fragment lists, sort/truncate to the k
// layer arrays. It includes scene/ and util/; it knows no tracer.
#pragma once

#include <cstdint>
#include <span>

#include "layertrace/raster/fragment_lists.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"

namespace lt {

struct RasterConfig {
  /// Pool capacity in fragments; 0 = 8 per pixel (at least 2^20).
  uint64_t poolCapacity = 0;
  /// On overflow, rasterize again with a pool that fits every fragment (exact count known).
  /// When false, an overflow is reported in FragmentLists::lost() and left to the caller.
  bool growOnOverflow = true;
  int tileSize = 32;  ///< screen tile edge in pixels (the unit of parallel work)
  /// Keep only triangles whose winding faces the camera (back-face culling). The k layers then
  /// hold the k nearest *front* surfaces: for view synthesis the second layer is the surface a
  /// closed object hides, not the object's own back (docs/results.md, view synthesis).
  bool frontFacesOnly = false;
  /// When not empty (one entry per scene triangle): rasterize only the triangles whose entry
  /// equals maskValue (the layered depth cube gives each triangle to one axis view,
  /// Bürger et al. 2007).
  std::span<const uint8_t> triangleMask;
  uint8_t maskValue = 1;
};

struct RasterStats {
  double ms = 0.0;             ///< wall time of the successful pass
  uint64_t overflowLost = 0;   ///< fragments lost in the first pass when it overflowed (before growing)
  int passes = 0;              ///< 1, or 2 when the pool was grown
  uint64_t subTriangles = 0;   ///< triangles after clipping
};

/// Rasterizes `scene` seen by `camera` (pinhole or orthographic) into per-pixel fragment lists.
FragmentLists rasterize(const Scene& scene, const Camera& camera, const RasterConfig& config = {},
                        RasterStats* stats = nullptr);

/// Largest pool (in fragments) addressable by a 32-bit next index.
inline constexpr uint64_t kMaxPoolFragments = 0xFFFFFFF0ull;

}  // namespace lt
