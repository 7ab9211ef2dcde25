#include "layertrace/grid/grid_tracer.h"

#include <algorithm>

#include "layertrace/util/in_place.h"

namespace lt {

template <class F>
void GridTracer::chunks(std::span<const Ray> rays, std::span<const float> from, F f) const {
  const Camera& cam = hits().camera();
  IrregularGrid::Query q[kChunk];
  for (size_t b = 0; b < rays.size(); b += kChunk) {
    const size_t n = std::min(kChunk, rays.size() - b);
    for (size_t i = 0; i < n; ++i) {
      const Ray& r = rays[b + i];
      const glm::vec3 o = cam.toWorld(r.origin);
      q[i] = {o, cam.dirToWorld(r.dir), segmentStart(startOf(from, b + i), hits().originOffset(r), o), r.maxDistance};
    }
    f(std::span<const IrregularGrid::Query>(q, n), b);
  }
}

void GridTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return GeometricTracer::traceBatch(rays, hits, counters);
  chunks(rays, {}, [&](std::span<const IrregularGrid::Query> q, size_t b) {
    GeoHit g[kChunk];
    accel().intersect(q, std::span<GeoHit>(g, q.size()));
    for (size_t i = 0; i < q.size(); ++i) assignInPlace(hits[b + i], [&] { return this->hits().makeHit(rays[b + i], g[i]); });
  });
}

void GridTracer::intersectSegments(std::span<const Ray> rays, std::span<const float> from, std::span<GeoHit> hits,
                                   std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return GeometricTracer::intersectSegments(rays, from, hits, counters);
  chunks(rays, from, [&](std::span<const IrregularGrid::Query> q, size_t b) { accel().intersect(q, hits.subspan(b, q.size())); });
}

void GridTracer::occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return GeometricTracer::occludedBatch(rays, hits, counters);
  chunks(rays, {}, [&](std::span<const IrregularGrid::Query> q, size_t b) {
    uint8_t blocked[kChunk];
    accel().occluded(q, std::span<uint8_t>(blocked, q.size()));
    for (size_t i = 0; i < q.size(); ++i) hits[b + i] = GeometricHits::occludedHit(blocked[i] != 0);
  });
}

void GridTracer::occludedSegments(std::span<const Ray> rays, std::span<const float> from, std::span<uint8_t> blocked,
                                  std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return GeometricTracer::occludedSegments(rays, from, blocked, counters);
  chunks(rays, from, [&](std::span<const IrregularGrid::Query> q, size_t b) { accel().occluded(q, blocked.subspan(b, q.size())); });
}

}  // namespace lt
