// The layered depth cube of Bürger et al. 2007 (VMV 2007, §1.4) traced on the GPU
// (shaders/ldc_march.comp): the GLSL twin of ldc/ldc_tracer.cpp, ray for ray (tested bit for bit
// on llvmpipe). The cube — three orthographic LDIs with their per-texel sample lists and coarse
// block intervals — is built by the CPU (ldc/ldc.h) and uploaded once; the traversal, closest
// and any hit, runs on the device.
#pragma once

#include <memory>
#include <span>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_ray_batch.h"
#include "layertrace/ldc/ldc.h"
#include "layertrace/scene/camera.h"
#include "layertrace/trace/tracer.h"

namespace lt {

class GpuLdcTracer final : public GpuBatchTracer {
 public:
  /// Uploads `ldc` (its offsets, samples and block intervals). The context and the cube must
  /// outlive the tracer. InputError where the cube exceeds the shaders' 32-bit indices.
  GpuLdcTracer(GpuContext& gpu, const Camera& camera, const LayeredDepthCube& ldc);
  ~GpuLdcTracer() override;
  GpuLdcTracer(const GpuLdcTracer&) = delete;
  GpuLdcTracer& operator=(const GpuLdcTracer&) = delete;

  const char* name() const override { return "ldc"; }
  /// The whole batch in one dispatch: the hit sample, its point, normal, material and triangle
  /// as LdcTracer gives them, and the counters.
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;

  /// Bytes on the GPU: offsets, samples and block intervals.
  size_t memoryBytes() const;
  /// GPU time of every batch so far (timer queries), milliseconds.
  double totalTraceMs() const { return totalTraceMs_; }

 private:
  void march(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters, bool anyHit) const;

  GpuContext& gpu_;
  Camera camera_;
  const LayeredDepthCube& ldc_;
  GpuBuffer offsets_, samples_, blocks_;
  int offsetBase_[3] = {}, sampleBase_[3] = {}, blockBase_[3] = {};
  mutable GpuRayBatch batch_;  ///< the CPU's rays and their answers
  std::unique_ptr<GpuTimer> timer_;
  mutable double totalTraceMs_ = 0.0;
};

}  // namespace lt
