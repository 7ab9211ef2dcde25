// The screen-space tracers as OpenGL compute shaders (shaders/*.comp): HSSR's multi-level DDA
// (Hofmann et al. 2017, §5), the Hi-Z march and the exhaustive march over the same traversal,
// and the SSR march of McGuire and Mara 2014 over the front layer (ssr) or all k layers
// (ssr-layers). Each reads the same data as its CPU twin, uploaded once: level 0's k intervals
// per pixel, their counts, and the pyramid's coarse cells. One dispatch traces a whole batch,
// one invocation per ray, and returns the hit fragment (pixel, layer) with the CPU's per-ray
// counters; the hit's point, normal and material come from the CPU's layer arrays, as the CPU
// tracers do (screen/fragment_hit.h).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_effects.h"
#include "layertrace/gpu/gpu_pyramid.h"
#include "layertrace/gpu/gpu_ray_batch.h"
#include "layertrace/hssr/hssr_tracer.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/ssr/ssr_tracer.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// One ray's answer on the GPU: the hit fragment (layer −1 for a miss) and its counters.
struct GpuMarchHit {
  int x = -1, y = -1, layer = -1;
  RayCounters counters;
  bool hit() const { return layer >= 0; }
};

class GpuScreenTracer final : public GpuBatchTracer, public GpuEffectTracer {
 public:
  /// HSSR over a pyramid built here on the GPU from `level0` (gpu_pyramid.h): the whole
  /// structure of the CPU's tracer, made on the device. Hi-Z: hizConfig with τ = ∞; the
  /// exhaustive march: one level. The context must outlive the tracer.
  GpuScreenTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const IntervalLayers& level0,
                  const PyramidConfig& pyramid, const HssrConfig& config);
  /// SSR (front layer) or SSR-layers (config.allLayers).
  GpuScreenTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const SsrConfig& config);
  /// A resident HSSR tracer (τ = ∞ and n_up = 1: Hi-Z; one level: exhaustive) for a frame that
  /// stays on the device (gpu_frame.h): no structure until rebuild(), which builds the pyramid
  /// into the buffers of earlier frames. It answers march and marchResident: it has no CPU
  /// layers for traceBatch.
  GpuScreenTracer(GpuContext& gpu, const PyramidConfig& pyramid, const HssrConfig& config);
  /// A resident SSR (front layer) or SSR-layers tracer: rebuild() only takes the frame's level 0
  /// (k intervals a pixel; SSR reads the first).
  GpuScreenTracer(GpuContext& gpu, const SsrConfig& config);
  ~GpuScreenTracer() override;

  /// The resident tracer's structure for the next frame: the pyramid over `level0` and `counts`
  /// (k intervals per pixel, already on the device) for `camera`, built without a read-back into
  /// the kept buffers, whose fill GpuPyramid::status reports at the frame's end.
  void rebuild(const Camera& camera, const GpuBuffer& level0, const GpuBuffer& counts, int k);

  const char* name() const override { return name_; }
  /// The whole batch in one dispatch (call it from the context's thread; large batches pay the
  /// dispatch's fixed cost once).
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  /// HSSR's march with persistent threads pulling rays from a queue (Hofmann et al. 2017, §5.3,
  /// ray reloading): the same answers, another schedule. No effect on SSR.
  /// Where the driver has subgroup operations (GL_ARB_shader_ballot with group_vote, or
  /// GL_KHR_shader_subgroup), as published: each subgroup steps its lanes' rays a cell at a time,
  /// a lane whose ray has answered takes the next ray at once, and the subgroup leaves when the
  /// queue is empty (warp early termination, in-warp reloading). Elsewhere the work groups fetch
  /// batches of 64 rays behind a barrier.
  void setPersistentThreads(bool on) { persistent_ = on; }
  bool persistentThreads() const { return persistent_; }
  /// Whether ray reloading uses the subgroup schedule (true by default where the driver has the
  /// operations); false selects the work-group batches. Returns whether the request holds.
  bool setSubgroupReloading(bool on);
  bool subgroupReloading() const { return !subgroupDefine_.empty() && !subgroupOff_; }
  /// The extension the subgroup schedule uses on `gpu` ("GL_ARB_shader_ballot" or
  /// "GL_KHR_shader_subgroup"), or "none".
  static const char* subgroupExtension(const GpuContext& gpu);
  /// The fragments the rays hit, with their counters.
  void march(std::span<const Ray> rays, std::vector<GpuMarchHit>& out) const;

  /// Marches `n` rays already on the device (`rays` of shaders/screen_common.glsl GpuRay, a
  /// negative length for a slot without a ray) into `hits` (GpuHit), without a transfer or a
  /// timer: the GPU effects (gpu_effects.h) trace their waves through it. With `groups`, the
  /// work groups come from that buffer (indirect dispatch; kPersistentArgs: the offset of the
  /// persistent schedule's), so that the device decides whether a round runs at all.
  /// Without `counters` the march's counter-free variant runs (LT_NO_COUNTERS: the same
  /// answers, every counter 0), as the timed runs read no counter.
  void marchResident(const GpuBuffer& rays, const GpuBuffer& hits, size_t n, const GpuBuffer* groups = nullptr, bool counters = true) const;
  /// marchResident with counters and one invocation per ray, also writing per ray the screen
  /// parameter at which its segment entered the hit pixel (hssr_march.h MarchHit::s; 0 for a
  /// miss) into `params` (a float each): the hybrid's known-space march (gpu_hybrid.h). A
  /// march over a pyramid only.
  void marchResidentWithParams(const GpuBuffer& rays, const GpuBuffer& hits, const GpuBuffer& params, size_t n) const;
  /// Persistent threads: work groups launched (16 per multiprocessor of a 132-SM GPU; choice:
  /// the queue balances the load, so more groups than the GPU holds at once only add idle
  /// launches).
  static constexpr uint32_t kPersistentGroups = 2112;
  /// The persistent march's work groups for `n` rays: kPersistentGroups, more where an
  /// invocation would otherwise take over 8 rays on average, and never more than one per 64
  /// rays. Choice: the bound keeps one invocation's loop iterations within what a driver may
  /// allow a shader run (llvmpipe ends every loop of a run after 65,535 iterations in all), and
  /// the queue still balances the load across the groups.
  static uint32_t persistentGroups(size_t n);
  /// Indirect arguments: three uints for the plain march at offset 0, three for the persistent
  /// march at this offset.
  static constexpr size_t kPersistentArgs = 12;

  /// GPU time of the last batch's dispatches (GL timer query), milliseconds.
  double lastTraceMs() const { return lastTraceMs_; }
  /// GPU time of every batch so far, milliseconds.
  double totalTraceMs() const { return totalTraceMs_; }
  /// Bytes of the structure on the GPU (level 0, counts, coarse cells and their lists).
  size_t memoryBytes() const;

  /// The pyramid built on the GPU (HSSR, Hi-Z, exhaustive), else null (SSR).
  const GpuPyramid* pyramid() const { return pyramid_.get(); }
  GpuPyramid* pyramid() { return pyramid_.get(); }
  const Camera& camera() const { return camera_; }
  /// The effect passes' waves (gpu_effects.h): marchResident, answering with fragments.
  Surfaces surfaces() const override { return Surfaces::Fragments; }
  const Camera& effectCamera() const override { return camera_; }
  GpuContext& context() const override { return gpu_; }
  void answerWave(const GpuEffectWave& w) const override { marchResident(w.rays, w.hits, w.n, w.groups, w.counters); }

 private:
  void upload(const IntervalLayers& level0);
  /// Every uniform of the march, before each dispatch (the program is the context's, shared).
  void setUniforms(const GpuProgram& program, size_t n, bool persistent) const;
  /// The march's program: with or without counters, plain or with subgroup reloading (linked
  /// on first use).
  const GpuProgram& marchProgram(bool counters, bool subgroup) const;

  GpuContext& gpu_;
  Camera camera_;
  const LayerArrays* layers_ = nullptr;  ///< the CPU's layers (fragmentHit); null for a resident tracer
  const char* name_;
  const GpuProgram* program_ = nullptr;
  const GpuProgram* timedProgram_ = nullptr;  ///< the counter-free variant (LT_NO_COUNTERS)
  mutable const GpuProgram* reloadPrograms_[2] = {};  ///< subgroup reloading: without, with counters
  mutable const GpuProgram* paramsProgram_ = nullptr;  ///< marchResidentWithParams' (LT_HIT_PARAM)
  std::string_view subgroupDefine_;  ///< LT_SUBGROUP_ARB or _KHR, empty without the operations
  bool subgroupOff_ = false;
  GpuBuffer ownLevel0_, ownCounts_;
  const GpuBuffer* level0_ = &ownLevel0_;
  const GpuBuffer* counts_ = &ownCounts_;
  int k_ = 0;
  int maxIntervals_ = 16;  ///< of a pixel's k intervals, the ones the march reads (SSR over a resident level 0: 1)
  HssrConfig hssr_;
  PyramidConfig pyramidConfig_;
  SsrConfig ssr_;
  bool isSsr_ = false;
  mutable GpuRayBatch batch_;  ///< march(): the CPU's rays and their answers
  mutable GpuBuffer queue_;
  bool persistent_ = false;
  mutable double lastTraceMs_ = 0.0, totalTraceMs_ = 0.0;
  std::unique_ptr<GpuTimer> timer_;
  std::unique_ptr<GpuPyramid> pyramid_;
};

}  // namespace lt
