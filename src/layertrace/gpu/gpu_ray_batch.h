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
