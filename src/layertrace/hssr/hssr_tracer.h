// Hierarchical multi-layer screen-space ray tracing (Hofmann et al. 2017, §5): a conservative
// Amanatides–Woo DDA over the interval pyramid. Start at level 0 skipping the origin pixel;
// after n_up cells without an overlap ascend a level (unless the coarser cell contains the
// origin pixel); on an overlap above level 0 advance to the interval's entry and descend one
// level; report hits only at level 0. With levels = 1 this is the exhaustive image-space oracle
// (docs/evaluation.md): every pixel the 2D line touches, every stored interval.
#pragma once

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/trace/tracer.h"

namespace lt {

struct HssrConfig {
  int nUp = 2;  ///< Hofmann et al. 2017, §5.2: cells traversed without an overlap before ascending a level
  int maxLevels = 16;  ///< use at most this many pyramid levels (1 = the exhaustive oracle)
  const char* name = "hssr";  ///< "hssr", or "hiz" over a min/max pyramid (hiz_pyramid.h)
  /// Also ascend on entering another parent cell (AscentRule); false is the paper's pure n_up rule.
  bool parentAscent = true;
  /// The GPU march only: persistent threads pull rays from a queue (Hofmann et al. 2017, §5.3):
  /// where the driver has subgroup operations, with warp early termination and in-warp
  /// reloading as published, else in work-group batches (gpu/gpu_screen_tracer.h). The same
  /// answers, another schedule; the CPU march ignores it.
  bool rayReloading = false;
};

class HssrTracer : public TracerImpl<HssrTracer> {
 public:
  HssrTracer(const Camera& camera, const LayerArrays& layers, const IntervalPyramid& pyramid, const HssrConfig& config = {});
  const char* name() const override { return levels_ == 1 ? "exhaustive" : config_.name; }
  /// The march of Hofmann et al. 2017, §5, written once against the counter calls (trace/tracer.h).
  template <class C>
  TraceHit traceImpl(const Ray& ray, C& counters) const;
  /// Uncounted batches (timing runs, renders without stats) run the march in vector lanes on
  /// the best vector target of the CPU (hssr_march_lanes.h): the same answers bit for bit (no
  /// FMA contraction anywhere), tested against traceImpl.
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  /// Any hit is the closest hit for a screen march (it meets the first surface first): the
  /// same batch path.
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override {
    traceBatch(rays, hits, counters);
  }

 private:
  const Camera& camera_;
  const LayerArrays& layers_;
  const IntervalPyramid& pyramid_;
  HssrConfig config_;
  int levels_;
};

}  // namespace lt
