// Tile-local capture (docs/architecture.md): rasterize every fragment and
// keep each pixel's k front-most ones in a single pass over screen tiles, so a tile's fragments
// are sorted while they are in cache and no fragment is ever stored twice.
//
// The reference pipeline — rasterize() into per-pixel lists in a pool (Hofmann et al. 2017,
// §4.1), then sortAndTruncate() (§4.2) — stays: it is what a fixed --pool selects, and what this
// pass is tested against bit for bit (capture_test.cpp). Whole lists, for `layers --verify` and the
// whole-list options, come from this pass too (captureWithLists). Equal depths are kept in the reference's order: its
// lists are last-generated-first and its insertion sort is stable, so among equal depths the
// fragment generated last (the higher sub-triangle index) comes first.
//
// A LayerCapture owns its scratch memory (transformed vertices, clipped triangles, tile bins);
// capturing the next frame of the same scene and size into the same LayerArrays allocates
// nothing.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "layertrace/raster/fragment_lists.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/raster/rasterizer.h"

namespace lt {

namespace raster {
struct RasterSetup;
}

struct CaptureStats {
  double setupMs = 0.0;  ///< transform, clip, bin to tiles
  double tilesMs = 0.0;  ///< rasterize + sort to k per tile
  uint64_t generated = 0;     ///< fragments the rasterizer produced (all of them are considered)
  uint64_t subTriangles = 0;  ///< triangles after clipping
  double ms() const { return setupMs + tilesMs; }
};

/// Called on the worker thread right after a tile's k layers are final, with the tile's
/// inclusive pixel bounds, while they are still in cache (the pipeline writes the interval
/// pyramid's level 0 there).
using TileDone = std::function<void(int x0, int y0, int x1, int y1)>;

class LayerCapture {
 public:
  LayerCapture();
  ~LayerCapture();
  LayerCapture(LayerCapture&&) noexcept;
  LayerCapture& operator=(LayerCapture&&) noexcept;
  /// Scratch memory only: a copy starts with none.
  LayerCapture(const LayerCapture&);
  LayerCapture& operator=(const LayerCapture&);

  /// Rasterizes `scene` for `camera` straight into `layers` (k front-most fragments per pixel
  /// with their thickness, as sortAndTruncate) and `complexity` (fragments per pixel). Reuses the
  /// memory of both. Throws InputError for a bad LayerConfig, and for adaptive thickness or a
  /// minimum separation (they need whole lists: use the reference pipeline).
  void capture(const Scene& scene, const Camera& camera, const RasterConfig& raster, const LayerConfig& config,
               LayerArrays& layers, std::vector<uint32_t>& complexity, CaptureStats* stats = nullptr,
               const TileDone* onTile = nullptr);

  /// The same pass, and every fragment in per-pixel lists as well (what `layers --verify` and
  /// the whole-list options read): a counting pass sizes the node storage exactly — no pool
  /// guessed at 8 fragments per pixel, no overflow, no shared counter — and each tile then
  /// writes its pixels' nodes in generation order, linked last-generated-first as the
  /// reference's lists are. `lists` keeps its memory from frame to frame; the k layers are
  /// those of capture().
  void captureWithLists(const Scene& scene, const Camera& camera, const RasterConfig& raster, const LayerConfig& config,
                        LayerArrays& layers, FragmentLists& lists, CaptureStats* stats = nullptr, const TileDone* onTile = nullptr);

  /// Depth peeling (Everitt 2001; the baseline of Hofmann et al. 2017, Fig. 8): k geometry
  /// passes over the whole scene, pass L keeping per pixel the nearest fragment behind layer
  /// L − 1 (farther, or at its depth from a lower triangle index; with a minimum separation, at
  /// least that far behind it). Equal depths rank the higher triangle first, as the lists do, so
  /// the layers are capture()'s bit for bit (with a minimum separation, sortAndTruncate's).
  /// No fragment is stored. `stats->generated` counts the fragments of all k passes.
  /// InputError for a bad LayerConfig and for adaptive thickness (it needs every fragment).
  void capturePeeled(const Scene& scene, const Camera& camera, const RasterConfig& raster, const LayerConfig& config,
                     LayerArrays& layers, std::vector<uint32_t>& complexity, CaptureStats* stats = nullptr);

  /// Bytes of scratch the object holds between frames.
  size_t scratchBytes() const;

 private:
  std::unique_ptr<raster::RasterSetup> setup_;
};

}  // namespace lt
