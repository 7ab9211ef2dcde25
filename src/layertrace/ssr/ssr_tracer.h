// The screen-space ray tracer of McGuire and Mara 2014 ("Efficient GPU Screen-Space Ray
// Tracing", JCGT): a 2D DDA along the projected ray with perspective-correct depth, stride,
// jitter and z-thickness.
//   ssr         tests the front layer only (the classic effect)
//   ssr-layers  tests every interval of all k layers at each step (deep G-buffer style)
#pragma once

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/screen/interval_layers.h"
#include "layertrace/ssr/ssr_march.h"
#include "layertrace/trace/tracer.h"

namespace lt {

struct SsrConfig {
  float stride = 1.0f;   ///< pixels per step along the major axis (McGuire and Mara 2014: "stride", >= 1)
  float jitter = 0.0f;   ///< fraction of a stride to offset the start, in [0, 1] (McGuire and Mara 2014: "jitter")
  int maxSteps = 0;      ///< step limit; 0 = max(width, height) / stride + 1: always reaches the viewport edge
  bool allLayers = false;  ///< ssr-layers: test all k intervals per pixel instead of the front one
  /// Binary refinement of the hit between the last two samples for stride > 1 (the extension
  /// McGuire and Mara 2014 suggest): log2(stride) extra samples.
  bool refine = true;
};

/// The march's step limit for a width × height view: config.maxSteps, or where it is 0 enough
/// samples to reach the viewport edge from anywhere.
inline int ssrMaxSteps(const SsrConfig& config, int width, int height) {
  return config.maxSteps > 0 ? config.maxSteps : int(float(width > height ? width : height) / config.stride) + 2;
}

class SsrTracer : public TracerImpl<SsrTracer> {
 public:
  SsrTracer(const Camera& camera, const LayerArrays& layers, const SsrConfig& config = {});
  const char* name() const override { return config_.allLayers ? "ssr-layers" : "ssr"; }
  /// The march of McGuire and Mara 2014, written once against the counter calls (trace/tracer.h).
  template <class C>
  TraceHit traceImpl(const Ray& ray, C& counters) const;
  /// Uncounted batches march a ray per vector lane (ssr_march_lanes.h): the same samples and hits
  /// bit for bit as traceImpl (tested on every vector target).
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  /// Any hit is the closest hit for a screen march: the same batch path.
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override {
    traceBatch(rays, hits, counters);
  }

 private:
  /// The hit at sample (x, y, layer) of parameter s: refined between the previous sample and
  /// this one when the stride skips pixels, then turned into a fragment hit.
  template <class C>
  TraceHit finish(const SsrStart& m, float s, int x, int y, int layer, C& counters) const;

  const Camera& camera_;
  const LayerArrays& layers_;
  IntervalLayers depth_;  ///< what the march reads: the front layer (ssr) or all k (ssr-layers)
  SsrConfig config_;
};

}  // namespace lt
