// Evaluation hooks of the effects: an observer sees every traced ray with its answer, and the
// effects know nothing of what it does with them (eval/ implements observers that compare with
// an oracle or classify against a geometric reference).
#pragma once

#include <cstdint>
#include <span>

#include "layertrace/trace/tracer.h"

namespace lt {

/// One traced ray as the effect issued it.
struct RayEvent {
  const Ray* ray = nullptr;
  const TraceHit* hit = nullptr;
  int x = 0, y = 0;  ///< the pixel whose path issued the ray
  int bounce = 0;    ///< 0 for a pixel's first wave of rays, 1 for rays from their hits, …
  int sample = 0;    ///< index among the pixel's rays of this wave (AO sample, light, refraction stage)
  Query query = Query::Closest;
};

class RayObserver {
 public:
  virtual ~RayObserver() = default;
  /// Called after each batch of rays is traced, from worker threads, concurrently for
  /// different batches: implementations keep per-thread state. Not timed as tracing.
  virtual void observe(std::span<const RayEvent> events) = 0;
};

}  // namespace lt
