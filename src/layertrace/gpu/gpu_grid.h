// The irregular grid of Pérard-Gayot et al. 2017 traversed on the GPU (shaders/grid_march.comp):
// the GLSL twin of grid/irregular_grid_traverse.cpp's one-ray traversal over the CPU's packed
// structure, uploaded once. Its answers are the CPU grid's bit for bit on an IEEE device
// (llvmpipe; tested), and so Embree's within the watertightness tolerance geobench documents.
//
// The build stays on the CPU (grid/irregular_grid.h); the paper builds on the GPU too.
#pragma once

#include <memory>
#include <span>

#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_ray_batch.h"
#include "layertrace/grid/irregular_grid.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"
#include "layertrace/trace/tracer.h"

namespace lt {

class GpuGridTracer final : public GpuBatchTracer, public GeoHitQueries {
 public:
  /// Uploads `grid`'s packed structure. The context, the scene and the grid must outlive the
  /// tracer. InputError for a structure beyond the shaders' 32-bit word indices.
  ///
  /// Alpha-tested triangles: the traversal on the GPU reads no texture. A ray that meets a
  /// candidate hit on such a triangle stops there, flagged, and the CPU grid answers it (its
  /// one-ray traversal, which tests the texel): the answers stay the CPU grid's.
  GpuGridTracer(GpuContext& gpu, const Scene& scene, const Camera& camera, const IrregularGrid& grid);
  ~GpuGridTracer() override;
  GpuGridTracer(const GpuGridTracer&) = delete;
  GpuGridTracer& operator=(const GpuGridTracer&) = delete;

  const char* name() const override { return "grid"; }
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void intersectSegments(std::span<const Ray> rays, std::span<const float> from, std::span<GeoHit> hits,
                         std::span<RayCounters> counters) const override;
  void occludedSegments(std::span<const Ray> rays, std::span<const float> from, std::span<uint8_t> blocked,
                        std::span<RayCounters> counters) const override;

  /// World-space queries (IrregularGrid::Query), answered as IrregularGrid::intersect or
  /// occluded answers them (an any hit: GeoHit::triangle of a blocker), with what each walk did
  /// in `counts` when it is not empty. The timer of the dispatch adds to totalTraceMs().
  void query(std::span<const IrregularGrid::Query> queries, bool anyHit, std::span<GeoHit> hits,
             std::span<TraversalCounts> counts = {}) const;
  /// GPU time of the last query's dispatch (timer query), milliseconds.
  double lastTraceMs() const { return lastTraceMs_; }

  /// Bytes on the GPU: top cells, leaves, cell records and triangle blocks.
  size_t memoryBytes() const;
  /// GPU time of every batch so far (timer queries), milliseconds.
  double totalTraceMs() const { return totalTraceMs_; }
  /// Rays so far that the CPU grid answered (a candidate on an alpha-tested triangle).
  uint64_t cpuAnswered() const { return cpuAnswered_; }

 private:
  /// The grid's answers to ray i from segmentStart(from[i]) (an empty `from`: whole rays), with
  /// the counters added where `counters` is given.
  void queryRays(std::span<const Ray> rays, std::span<const float> from, bool anyHit, std::span<GeoHit> hits,
                 std::span<RayCounters> counters) const;

  GpuContext& gpu_;
  GeometricHits hits_;
  const IrregularGrid& grid_;
  GpuBuffer topCells_, leaves_, walk_, cutOuts_;
  mutable GpuRayBatch batch_;  ///< the answers (the queries are world-space: queries_)
  std::unique_ptr<GpuTimer> timer_;
  mutable double totalTraceMs_ = 0.0, lastTraceMs_ = 0.0;
  mutable uint64_t cpuAnswered_ = 0;
};

}  // namespace lt
