#include "layertrace/hssr/hssr_tracer.h"

#include <algorithm>
#include <vector>

#include "layertrace/screen/fragment_hit.h"
#include "layertrace/hssr/hssr_march.h"
#include "layertrace/hssr/hssr_march_lanes.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/util/error.h"
#include "layertrace/util/in_place.h"

namespace lt {

HssrTracer::HssrTracer(const Camera& camera, const LayerArrays& layers, const IntervalPyramid& pyramid, const HssrConfig& config)
    : camera_(camera), layers_(layers), pyramid_(pyramid), config_(config) {
  if (config.nUp < 1) inputError("--n-up ", config.nUp, ": must be >= 1");
  levels_ = std::max(1, std::min(config.maxLevels, pyramid.levelCount()));
}

template <class C>
TraceHit HssrTracer::traceImpl(const Ray& ray, C& c) const {
  const ScreenSegment seg = makeScreenSegment(camera_, ray);
  if (!seg.valid) return {};
  const MarchHit m = hssrMarch(pyramid_, levels_, AscentRule(config_.nUp, config_.parentAscent), seg, camera_.width(), camera_.height(), c);
  return m.hit() ? fragmentHit(camera_, layers_, m.x, m.y, m.interval) : TraceHit{};
}

void HssrTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return TracerImpl::traceBatch(rays, hits, counters);
  // Uncounted: the batch's segments through the lane march (hssr_march_lanes.h), a ray per
  // vector lane on the CPU's best target.
  thread_local std::vector<ScreenSegment> segs;
  thread_local std::vector<MarchHit> marched;
  segs.resize(rays.size());
  marched.resize(rays.size());
  // (results constructed in place, util/in_place.h: assigned, they were ~60 % of this
  // function's samples, FZK-Haus)
  for (size_t i = 0; i < rays.size(); ++i) assignInPlace(segs[i], [&] { return makeScreenSegment(camera_, rays[i]); });
  hssrMarchBatch(pyramid_, levels_, AscentRule(config_.nUp, config_.parentAscent), segs, camera_.width(), camera_.height(), marched);
  // The hit fragments are scattered over the layer arrays: ask for all of them before reading
  // any, so that their cache misses overlap (3–5 % of HSSR's time, measured by alternating
  // passes with and without in one run, FZK-Haus and am_thornish).
  for (const MarchHit& m : marched)
    if (m.hit()) {
      const size_t slot = layers_.pixelIndex(m.x, m.y) * size_t(layers_.k) + size_t(m.interval);
      __builtin_prefetch(&layers_.slots[slot]);
      __builtin_prefetch(&layers_.triangle[slot]);
    }
  for (size_t i = 0; i < rays.size(); ++i) {
    const MarchHit& m = marched[i];
    assignInPlace(hits[i], [&] { return m.hit() ? fragmentHit(camera_, layers_, m.x, m.y, m.interval) : TraceHit{}; });
  }
}

template TraceHit HssrTracer::traceImpl(const Ray&, RayCounters&) const;
template TraceHit HssrTracer::traceImpl(const Ray&, NoCounters&) const;

}  // namespace lt
