// The plane/box quad-tree of Widmer et al. 2015 (HPG 2015, supplement, Algorithms 1–4) built and
// traced on the GPU (shaders/quadtree_*.comp): the GLSL twin of quadtree/quadtree_build.cpp and
// quadtree_tracer.cpp, node for node and ray for ray (tested bit for bit on llvmpipe).
//
// The build runs without a read-back between its passes: the depth scale (the median
// front-layer depth, quadtree.h) by a radix select in one work group, Algorithm 1 in one
// dispatch over every pixel of every layer, Algorithm 2 in one dispatch per level; each pass
// adds its nodes of each kind to per-level counts on the device. The nodes never leave the
// device; summary() reads the scale and the counts once, for the statistics.
//
// Widmer et al. build and trace in GLSL with one quad-tree per layer; so do we. Their tree
// lives in a mip-mapped texture; ours is one storage buffer in the CPU's layout, so that both
// builds compare node for node.
#pragma once

#include <memory>
#include <span>
#include <vector>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_effects.h"
#include "layertrace/gpu/gpu_ray_batch.h"
#include "layertrace/quadtree/quadtree.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// shaders/quadtree_march.comp's answer beside its GpuMarchRecord, std430: the hit's screen
/// parameter and the counters of the plane and box nodes and the occlusion tests.
struct GpuQuadtreeExtra {
  float s;
  uint32_t planes, boxes, occlusions;
  /// Adds the march's counters (of `march` and these) to `c` as QuadtreeTracer counts them.
  void addCounters(const GpuMarchRecord& march, RayCounters& c) const {
    c.iterations += march.iterations, c.pixels += march.pixels, c.giveUps += march.giveUps;
    for (int l = 0; l < RayCounters::kLevels; ++l) c.levelIterations[l] += march.levelIterations[l];
    c.planeNodes += planes, c.boxNodes += boxes, c.occlusions += occlusions;
  }
};
static_assert(sizeof(GpuQuadtreeExtra) == 16);

class GpuQuadtreeTracer final : public GpuBatchTracer, public GpuEffectTracer {
 public:
  /// Uploads each slot's depth and the per-pixel counts of `layers` and builds the quad-trees on
  /// the GPU. The context and the layers must outlive the tracer. InputError for a bad config
  /// (validateQuadtreeConfig) or an image whose levels exceed the shaders' 24.
  GpuQuadtreeTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const QuadtreeConfig& config);
  /// A resident quad-tree for a frame that stays on the device (gpu_frame.h): no tree until
  /// rebuild(). It answers marchResident and the effect passes' waves; it has no CPU layers for
  /// traceBatch.
  GpuQuadtreeTracer(GpuContext& gpu, const QuadtreeConfig& config);
  ~GpuQuadtreeTracer() override;
  /// The resident tree's next frame: the trees over `level0` (a resident frame's level 0, k
  /// intervals a pixel beginning at each slot's depth) and `counts` for `camera`, built on the
  /// device without a read-back into the kept buffers (made anew when the size or k changes).
  void rebuild(const Camera& camera, const GpuBuffer& level0, const GpuBuffer& counts, int k);
  GpuQuadtreeTracer(const GpuQuadtreeTracer&) = delete;
  GpuQuadtreeTracer& operator=(const GpuQuadtreeTracer&) = delete;

  const char* name() const override { return "quadtree"; }
  /// The whole batch in one dispatch: the hit fragment, the exact ray–plane point (from the hit's
  /// parameter on the screen segment, as the CPU tracer computes it) and the counters.
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;

  /// Marches `n` camera-space rays already on the device (`rays`: shaders/ray_io.glsl GpuRay)
  /// into `hits` (GpuMarchRecord each) and `extra` (GpuQuadtreeExtra each), without a transfer
  /// or a timer: the hybrid's passes on the GPU (gpu_hybrid.h). Without `counters` the march's
  /// counter-free variant runs.
  void marchResident(const GpuBuffer& rays, const GpuBuffer& hits, const GpuBuffer& extra, size_t n, bool counters) const;
  /// The effect passes' waves (gpu_effects.h): marchResident, then the exact ray–plane point of
  /// each hit (shaders/quadtree_point.comp), so the passes shade the hit fragment at that point
  /// as the CPU renderer does. The plane, box and occlusion counters are summed over the run
  /// on the device (effectSums), beside the effect's per-pixel tally.
  Surfaces surfaces() const override { return Surfaces::FragmentsAtPoints; }
  const Camera& effectCamera() const override { return camera_; }
  GpuContext& context() const override { return gpu_; }
  void answerWave(const GpuEffectWave& wave) const override;
  void beginEffect() const override;
  GpuTracerSums effectSums() const override;
  /// The buffer effectSums reads (six words: plane, box and occlusion sums, low and high each),
  /// for a resident frame to copy with its counters.
  const GpuBuffer& effectSumsBuffer() const { return nodeSums_; }
  /// The trees' shape, depth scale, nodes of each kind per level and GPU build time (the kind
  /// counts and the scale are read back on the first call); `nodes` stays empty.
  const Quadtree& summary() const;
  /// Every node, read back from the device in Quadtree::nodes' layout (an explicit request: the
  /// tests compare it with the CPU's build).
  std::vector<QuadNode> readNodes() const;
  /// Bytes on the GPU: the nodes, the depths and the counts.
  size_t memoryBytes() const;
  /// GPU time of every batch so far (timer queries), milliseconds.
  double totalTraceMs() const { return totalTraceMs_; }
  static constexpr int kMaxLevels = 24;  ///< shaders/quadtree_common.glsl kMaxQuadLevels

 private:
  void setLevels(const GpuProgram& program) const;
  /// The levels of a width × height × k tree, and its node buffers.
  void shape(int width, int height, int k);
  /// The depth scale and the trees from each slot's depth (`level0`: a resident frame's level 0)
  /// and the counts.
  void build(const GpuBuffer& depths, const GpuBuffer& counts, bool level0);

  GpuContext& gpu_;
  Camera camera_;
  const LayerArrays* layers_ = nullptr;  ///< the CPU's layers (null: a resident tree)
  mutable Quadtree summary_;  ///< levels and config at construction; scale and counts on first summary()
  mutable bool summaryRead_ = false;
  GpuBuffer depths_, counts_, nodes_, scale_, kinds_;
  mutable GpuBuffer waveExtra_;  ///< answerWave's GpuQuadtreeExtra per ray
  GpuBuffer nodeSums_;           ///< the effect run's plane, box and occlusion sums (low, high words each)
  mutable GpuRayBatch batch_;  ///< the CPU's rays and their answers
  std::unique_ptr<GpuTimer> timer_;
  mutable double totalTraceMs_ = 0.0;
};

}  // namespace lt
