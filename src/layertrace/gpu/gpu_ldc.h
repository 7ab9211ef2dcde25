// The layered depth cube of Bürger et al. 2007 (VMV 2007, §1.4) traced on the GPU
// (shaders/ldc_march.comp): the GLSL twin of ldc/ldc_tracer.cpp, ray for ray (tested bit for bit
// on llvmpipe). The cube — three orthographic LDIs with their per-texel sample lists and coarse
// block intervals — is built by the CPU (ldc/ldc.h) and uploaded once; the traversal, closest
// and any hit, runs on the device.
#pragma once

#include <memory>
#include <span>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_effects.h"
#include "layertrace/gpu/gpu_ray_batch.h"
#include "layertrace/ldc/ldc.h"
#include "layertrace/scene/camera.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// shaders/ldc_march.comp's answer, std430 (two uvec4 a ray): the distance to the hit sample,
/// the sample (its index over the three views; 0xFFFFFFFF: a miss), its view, and the counters.
struct GpuLdcAnswer {
  float t;
  uint32_t sample, view, iterations;
  uint32_t intervals, pixels, level0, level1;
  bool hit() const { return sample != 0xFFFFFFFFu; }
  /// Adds the march's counters to `c` (LdcTracer's: iterations, intervals, pixels, levels 0 and 1).
  void addCounters(RayCounters& c) const {
    c.iterations += iterations, c.intervals += intervals, c.pixels += pixels;
    c.levelIterations[0] += level0, c.levelIterations[1] += level1;
  }
};
static_assert(sizeof(GpuLdcAnswer) == 32);

class GpuLdcTracer final : public GpuBatchTracer, public GpuEffectTracer {
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

  /// Marches `n` camera-space rays already on the device (`rays`: shaders/ray_io.glsl GpuRay)
  /// into `answers` (GpuLdcAnswer each), without a transfer or a timer: the hybrid's passes on
  /// the GPU (gpu_hybrid.h).
  void marchResident(const GpuBuffer& rays, const GpuBuffer& answers, size_t n, bool anyHit) const;
  /// The effect passes' waves (gpu_effects.h): marchResident (any hit for shadow rays), then
  /// each hit's surface as LdcTracer gives it (shaders/ldc_surface.comp).
  Surfaces surfaces() const override { return Surfaces::Records; }
  const Camera& effectCamera() const override { return camera_; }
  GpuContext& context() const override { return gpu_; }
  void setEffectCamera(const Camera& camera) override { camera_ = camera; }
  void answerWave(const GpuEffectWave& wave) const override;
  /// Bytes on the GPU: offsets, samples, their triangles and block intervals.
  size_t memoryBytes() const;
  /// GPU time of every batch so far (timer queries), milliseconds.
  double totalTraceMs() const { return totalTraceMs_; }

 private:
  void march(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters, bool anyHit) const;

  GpuContext& gpu_;
  Camera camera_;
  const LayeredDepthCube& ldc_;
  GpuBuffer offsets_, samples_, blocks_, sampleTriangles_;
  mutable GpuBuffer waveAnswers_;  ///< answerWave's GpuLdcAnswer per ray
  int offsetBase_[3] = {}, sampleBase_[3] = {}, blockBase_[3] = {};
  mutable GpuRayBatch batch_;  ///< the CPU's rays and their answers
  std::unique_ptr<GpuTimer> timer_;
  mutable double totalTraceMs_ = 0.0;
};

}  // namespace lt
