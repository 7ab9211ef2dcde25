// What every GPU tracer that answers the CPU's Tracer interface shares: the base whose single
// ray is a batch of one, the march's answer record, and a batch of the CPU's rays on the GPU with
// room for the answers (the buffers grow geometrically and are kept from batch to batch).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// shaders/ray_io.glsl GpuHit, std430: the hit fragment (layer −1: a miss) and the march's
/// counters.
struct GpuMarchRecord {
  int32_t x, y, layer;
  uint32_t iterations, intervals, pixels, giveUps, fragments;
  uint32_t levelIterations[8];
};
static_assert(sizeof(GpuMarchRecord) == 64 && RayCounters::kLevels == 8, "the shaders count 8 levels");

/// Adds the screen march's counters of `a` to `c`.
inline void addCounters(const GpuMarchRecord& a, RayCounters& c) {
  c.iterations += a.iterations, c.intervals += a.intervals, c.pixels += a.pixels;
  c.giveUps += a.giveUps, c.fragments += a.fragments;
  for (int l = 0; l < RayCounters::kLevels; ++l) c.levelIterations[l] += a.levelIterations[l];
}

/// A tracer whose every query is a batch on the device: one ray is a batch of one.
class GpuBatchTracer : public Tracer {
 public:
  TraceHit trace(const Ray& ray, RayCounters& counters) const final {
    TraceHit hit;
    traceBatch(std::span<const Ray>(&ray, 1), std::span<TraceHit>(&hit, 1), std::span<RayCounters>(&counters, 1));
    return hit;
  }
};

/// `buffer` with room for `bytes`: kept, or replaced by one of at least twice its size (its
/// contents are not kept).
void reserve(GpuBuffer& buffer, size_t bytes);

class GpuRayBatch {
 public:
  static constexpr int kAnswerBuffers = 2;
  /// Uploads `rays` as shaders/ray_io.glsl GpuRay records (the context current).
  void upload(std::span<const Ray> rays);
  const GpuBuffer& rays() const { return rays_; }
  /// Answer buffer `slot` (< kAnswerBuffers) with room for at least `bytes`.
  const GpuBuffer& answers(int slot, size_t bytes);

 private:
  GpuBuffer rays_;
  GpuBuffer answers_[kAnswerBuffers];
};

}  // namespace lt
