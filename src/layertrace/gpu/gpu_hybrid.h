// The hybrid tracer with its decisions on the GPU (shaders/hybrid_*.comp): the screen march over
// the solid intervals (HSSR or Hi-Z), the exact checks, the geometric windows and the remainders
// on the GPU grid, one batch of rays without a transfer between the passes. The CPU's rays go up
// once; their answers (triangle, t, normal, who answered) come back once. The GLSL twin of
// hybrid/hybrid_tracer.cpp's run: the same decisions in the same floats, so its answers, counters
// and statistics are the CPU hybrid's (with the grid as its geometric half) ray for ray on an
// IEEE device (tested on llvmpipe).
//
// One batch is five passes and three marches (four with the known space's march):
//   known   — with the quad-tree: the march over the known space's pyramid (rule 3);
//   prepare — per ray, where knowledge ends (known_space.h rules 1–2, and 3 from the known
//             march; the march over the solid intervals meets rule 3 itself), the origin's
//             window and the screen segment (hybrid_prepare.comp);
//   march   — the screen half's march (GpuScreenTracer, GpuQuadtreeTracer or GpuLdcTracer
//             marchResident);
//   check   — the exact crossing of the hit pixel's layers, the two windows as grid queries
//             (hybrid_check.comp);
//   walk    — the grid over the windows (GpuGridTracer::walkResident);
//   combine — the window hits, certain misses, and the remainders as grid queries
//             (hybrid_combine.comp);
//   walk    — the grid over the remainders;
//   resolve — each ray's answer (hybrid_resolve.comp).
// Every pass runs over every ray of the batch: a ray that asks no window or remainder walks an
// empty query. Choice: no compaction between the passes, so no host wait and no scan; the empty
// walks cost one invocation each.
//
// The screen half is the march over the solid intervals (hssr, hiz), the quad-tree or the
// layered depth cube (a world-space tracer: no known space, each hit certified by a window of the
// cube's margin either side). With the quad-tree, whose empty space is not certain either, a
// march over the known space's pyramid of [u, ∞) runs first (known_space.h rule 3: HSSR's march
// with n_up = 1, its entry parameter written beside each hit).
//
// A ray whose query meets an alpha-tested candidate (the grid on the GPU reads no texture) is
// decided again on the CPU (HybridTracer's own run, whose grid queries the CPU grid settles).
#pragma once

#include <cstdint>
#include <memory>
#include <span>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_grid.h"
#include "layertrace/gpu/gpu_ldc.h"
#include "layertrace/gpu/gpu_quadtree.h"
#include "layertrace/gpu/gpu_ray_batch.h"
#include "layertrace/gpu/gpu_screen_tracer.h"
#include "layertrace/hybrid/hybrid_tracer.h"

namespace lt {

class GpuHybridTracer final : public HybridTracer {
 public:
  /// The hybrid of `screen` (canRunOnGpu: a GpuScreenTracer over the solid intervals, a
  /// GpuQuadtreeTracer or a GpuLdcTracer) and `grid` over `layers` and `known`, with
  /// HybridTracer's `worldMargin` and `uncertainEmptySpace`. Uploads the layers' triangle ids and
  /// the scene's triangles for the exact checks, and the known space's pyramid where it marches
  /// rule 3. All are borrowed and must outlive the tracer.
  GpuHybridTracer(GpuContext& gpu, const Scene& scene, const Camera& camera, const LayerArrays& layers, const KnownSpace& known,
                  const Tracer& screen, const GpuGridTracer& grid, float worldMargin = 0.0f, bool uncertainEmptySpace = false);
  ~GpuHybridTracer() override;
  GpuHybridTracer(const GpuHybridTracer&) = delete;
  GpuHybridTracer& operator=(const GpuHybridTracer&) = delete;

  /// Whether the decisions of a hybrid over `screen` and `known` can run on the GPU: a screen
  /// march over a pyramid (hssr, hiz) or the quad-tree, or the layered depth cube.
  static bool canRunOnGpu(const Tracer& screen, const KnownSpace& known);

  TraceHit trace(const Ray& ray, RayCounters& counters) const override;
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;

  /// GPU time of every batch so far (timer queries of all passes and marches, and of the
  /// marches of rays decided on the CPU), milliseconds.
  double totalTraceMs() const;
  /// Rays so far decided on the CPU (an alpha-tested candidate).
  uint64_t cpuDecided() const { return cpuDecided_; }
  /// Rays so far decided on the GPU.
  uint64_t gpuDecided() const { return gpuDecided_; }
  /// Bytes on the GPU beyond the halves': the layers' triangle ids and counts, the scene's
  /// triangles, and the batch's buffers.
  size_t memoryBytes() const;

 private:
  void runOnGpu(Query q, std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const;
  void setCamera(const GpuProgram& program) const;

  GpuContext& gpu_;
  const Scene& scene_;
  const GpuScreenTracer* pyramidScreen_;     ///< the march over the solid intervals, or
  const GpuQuadtreeTracer* quadtreeScreen_;  ///< the quad-tree, or
  const GpuLdcTracer* ldcScreen_;            ///< the layered depth cube
  std::unique_ptr<GpuScreenTracer> knownMarch_;  ///< rule 3's march, where the known space has one
  const GpuGridTracer& grid_;
  GpuBuffer layerTriangles_, layerCounts_, positions_, triangles_;
  mutable GpuRayBatch batch_;  ///< the CPU's rays
  mutable GpuBuffer screenRays_, screenHits_, states_, windows_, windowAnswers_, remainders_, remainderAnswers_, answers_;
  mutable GpuBuffer knownHits_, knownParams_, screenExtra_;  ///< rule 3's march; the quad-tree's extra answers
  mutable GpuTimeline timeline_;
  mutable double totalTraceMs_ = 0.0;
  mutable uint64_t cpuDecided_ = 0, gpuDecided_ = 0;
};

}  // namespace lt
