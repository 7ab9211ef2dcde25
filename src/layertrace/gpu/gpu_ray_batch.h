// A batch of the CPU's rays on the GPU for one march, and room for the march's answers: what
// every GPU tracer that answers the CPU's Tracer interface uploads and reads back. The buffers
// grow geometrically and are kept from batch to batch.
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
