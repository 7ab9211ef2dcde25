// The irregular grid of Pérard-Gayot et al. 2017 traversed on the GPU (shaders/grid_march.comp):
// the GLSL twin of grid/irregular_grid_traverse.cpp's one-ray traversal over the CPU's packed
// structure, uploaded once. Its answers are the CPU grid's bit for bit on an IEEE device
// (llvmpipe; tested), and so Embree's within the watertightness tolerance geobench documents.
//
// The structure is the CPU's (grid/irregular_grid.h), uploaded, or one built on the GPU
// (gpu/gpu_grid_build.h: steps 1 and 2 without merging and expansion).
#pragma once

#include <memory>
#include <optional>
#include <span>

#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_effects.h"
#include "layertrace/gpu/gpu_grid_build.h"
#include "layertrace/gpu/gpu_ray_batch.h"
#include "layertrace/grid/irregular_grid.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"
#include "layertrace/trace/tracer.h"

namespace lt {

class GpuGridTracer final : public GpuBatchTracer, public GeoHitQueries, public GpuEffectTracer {
 public:
  /// Uploads `grid`'s packed structure. The context, the scene and the grid must outlive the
  /// tracer. InputError for a structure beyond the shaders' 32-bit word indices.
  ///
  /// Alpha-tested triangles: the traversal on the GPU reads no texture. A ray that meets a
  /// candidate hit on such a triangle stops there, flagged, and the CPU grid answers it (its
  /// one-ray traversal, which tests the texel): the answers stay the CPU grid's.
  GpuGridTracer(GpuContext& gpu, const Scene& scene, const Camera& camera, const IrregularGrid& grid);
  /// Walks a grid built on the GPU (kept by the tracer). A ray that meets an alpha-tested
  /// candidate is answered by `cutOuts`, a CPU grid of the same scene (any configuration: both
  /// answers are exact), which a scene with such triangles must give (InputError otherwise).
  GpuGridTracer(GpuContext& gpu, const Scene& scene, const Camera& camera, std::unique_ptr<GpuGridBuild> built,
                const IrregularGrid* cutOuts);
  ~GpuGridTracer() override;
  GpuGridTracer(const GpuGridTracer&) = delete;
  GpuGridTracer& operator=(const GpuGridTracer&) = delete;

  const char* name() const override { return "grid"; }
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void intersectSegments(std::span<const Ray> rays, std::span<const float> from, std::span<GeoHit> hits,
                         std::span<RayCounters> counters) const override;
  void occludedSegments(std::span<const Ray> rays, std::span<const float> from, std::span<uint8_t> blocked,
                        std::span<RayCounters> counters) const override;

  /// World-space queries (IrregularGrid::Query), answered as IrregularGrid::intersect or
  /// occluded answers them (an any hit: GeoHit::triangle of a blocker), with what each walk did
  /// in `counts` when it is not empty. The timer of the dispatch adds to totalTraceMs().
  void query(std::span<const IrregularGrid::Query> queries, bool anyHit, std::span<GeoHit> hits,
             std::span<TraversalCounts> counts = {}) const;
  /// Walks `n` world-space queries already on the device (`queries`: shaders/grid_march.comp's
  /// two vec4 each, (origin, tnear), (direction, tfar); a tnear past the tfar walks nothing)
  /// into `answers` (its two uvec4 each), without a transfer or a timer: the hybrid's passes on
  /// the GPU (gpu_hybrid.h). An answer flagged undecided (2: an alpha-tested candidate) is the
  /// caller's to settle.
  void walkResident(const GpuBuffer& queries, const GpuBuffer& answers, size_t n, bool anyHit) const;
  /// The effect passes' waves (gpu_effects.h): the rays' world-space queries
  /// (shaders/grid_queries.comp), the walk (any hit for AO and shadow rays), then each closest
  /// hit's surface as GeometricHits::makeHit gives it (shaders/geometry_hit.comp: the
  /// interpolated normal, the material, the texture). The scene's tables are uploaded on the
  /// first wave. A scene with alpha-tested triangles is shaded on the CPU (effectsOnDevice):
  /// there a candidate hit needs the CPU grid's texel test.
  Surfaces surfaces() const override { return Surfaces::Records; }
  const Camera& effectCamera() const override { return hits_.camera(); }
  GpuContext& context() const override { return gpu_; }
  void setEffectCamera(const Camera& camera) override;
  void shareSceneTables(const GpuSceneTables* tables) override;
  bool effectsOnDevice() const override;
  void answerWave(const GpuEffectWave& wave) const override;
  /// GPU time of the last query's dispatch (timer query), milliseconds.
  double lastTraceMs() const { return lastTraceMs_; }

  /// Bytes on the GPU: top cells, leaves, cell records and triangle blocks.
  size_t memoryBytes() const;
  /// The GPU's build, when the structure was built there (else null).
  const GpuGridBuild* gpuBuild() const { return built_.get(); }
  /// GPU time of every batch so far (timer queries), milliseconds.
  double totalTraceMs() const { return totalTraceMs_; }
  /// Rays so far that the CPU grid answered (a candidate on an alpha-tested triangle).
  uint64_t cpuAnswered() const { return cpuAnswered_; }

 private:
  /// The grid's answers to ray i from segmentStart(from[i]) (an empty `from`: whole rays), with
  /// the counters added where `counters` is given.
  void queryRays(std::span<const Ray> rays, std::span<const float> from, bool anyHit, std::span<GeoHit> hits,
                 std::span<RayCounters> counters) const;

  /// The alpha-tested triangles as bits, for a scene that has them.
  void markCutOuts(const Scene& scene);

  struct EffectTables;

  GpuContext& gpu_;
  GeometricHits hits_;
  mutable std::unique_ptr<EffectTables> effectTables_;  ///< answerWave's scene tables and per-ray buffers
  mutable std::optional<bool> effectsOnDevice_;
  Camera frameCamera_;  ///< setEffectCamera's (the hits' camera from then on)
  const GpuSceneTables* sharedTables_ = nullptr;  ///< shareSceneTables
  const IrregularGrid* cpu_;  ///< answers the rays an alpha-tested candidate stopped
  std::unique_ptr<GpuGridBuild> built_;
  GpuGridLayout layout_;
  GpuBuffer ownTopCells_, ownLeaves_, ownWalk_, cutOuts_;  ///< the CPU's structure, uploaded
  const GpuBuffer* topCells_ = &ownTopCells_;
  const GpuBuffer* leaves_ = &ownLeaves_;
  const GpuBuffer* walk_ = &ownWalk_;
  mutable GpuRayBatch batch_;  ///< the answers (the queries are world-space: queries_)
  std::unique_ptr<GpuTimer> timer_;
  mutable double totalTraceMs_ = 0.0, lastTraceMs_ = 0.0;
  mutable uint64_t cpuAnswered_ = 0;
};

}  // namespace lt
