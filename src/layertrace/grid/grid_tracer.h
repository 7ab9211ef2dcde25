// The irregular grid (Perard-Gayot, Kalojanov and Slusallek 2017) behind the tracer interface:
// the geometric answer of GeometricTracer, with the grid's batch queries for uncounted batches.
#pragma once

#include <memory>
#include <span>

#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/grid/irregular_grid.h"

namespace lt {

/// The irregular grid as a tracer: uncounted batches trace with several rays in flight
/// (IrregularGrid's batch queries, the same answers bit for bit); counted runs one ray at a time.
class GridTracer : public GeometricTracer<IrregularGrid> {
 public:
  GridTracer(const Scene& scene, const Camera& camera, const IrregularGrid& grid)
      : GeometricTracer<IrregularGrid>("grid", scene, camera, grid) {}
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void intersectSegments(std::span<const Ray> rays, std::span<const float> from, std::span<GeoHit> hits,
                         std::span<RayCounters> counters) const override;
  void occludedSegments(std::span<const Ray> rays, std::span<const float> from, std::span<uint8_t> blocked,
                        std::span<RayCounters> counters) const override;

 private:
  static constexpr size_t kChunk = 256;
  /// Calls f(queries, first) for each chunk of up to kChunk rays, as world-space grid queries
  /// from each ray's segment start (GeoHitQueries).
  template <class F>
  void chunks(std::span<const Ray> rays, std::span<const float> from, F f) const;
};

inline std::unique_ptr<Tracer> makeGridTracer(const Scene& scene, const Camera& camera, const IrregularGrid& grid) {
  return std::make_unique<GridTracer>(scene, camera, grid);
}

}  // namespace lt
