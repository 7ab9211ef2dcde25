// The secondary effects on the GPU: ray generation, the origin rule and shading as compute
// passes (shaders/effect_step.comp, effect_resolve.comp) around a GPU tracer's march, so that
// no ray leaves the device between bounces. They are the GLSL twins of render/effects.cpp (the
// same rays, the same Blinn-Phong shading) and work with every GpuEffectTracer: the screen
// tracers (SSR, SSR over all layers, the Hi-Z march, HSSR, the exhaustive march), whose answers
// name a fragment of the layers, and the quad-tree, the layered depth cube and the irregular grid,
// which answer with the surface they met (a SurfaceRecord: point, normal, triangle, material).
//
// What the passes read is uploaded once per frame: the layer arrays (depth, normal, albedo and
// specular, scene triangle per slot) and per scene triangle its camera-space geometric normal
// and material. Every effect of render/effects.h runs here: shade, reflection (1–16 bounces),
// refraction through one transmissive layer, AO, shadows and view synthesis.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"

namespace lt {

class GpuEffects;
class GpuSceneTables;

/// One wave of effect rays for a tracer to answer on the device (GpuEffectTracer::answerWave).
struct GpuEffectWave {
  const GpuBuffer& rays;     ///< n shaders/ray_io.glsl GpuRay (camera space; a negative length: no ray)
  const GpuBuffer& hits;     ///< n GpuHit to write: layer ≥ 0 for a hit, and the ray's counters
  const GpuBuffer& records;  ///< n shaders/effect_common.glsl SurfaceRecord to write, for tracers that write them
  size_t n = 0;
  /// The origin rule's later rounds: the work groups in this buffer (indirect dispatch, sized
  /// on the device; null in round 0). A tracer may ignore it and answer all n rays.
  const GpuBuffer* groups = nullptr;
  bool counters = true;  ///< count per ray (else a counter-free variant may run)
  bool anyHit = false;   ///< the wave's rays are any-hit queries (AO and shadows, as the CPU renderer asks them: Tracer::occludedBatch)
};

/// Counters a tracer keeps beside the effect's per-pixel tally, summed over every ray of a run
/// (GpuEffectTracer::effectSums): the quad-tree's node visits (RayCounters' of the same names).
struct GpuTracerSums {
  uint64_t planeNodes = 0, boxNodes = 0, occlusions = 0;
};

/// A GPU tracer the effect passes run around (GpuEffects::run): it answers a wave of rays on the
/// device, without a transfer or a host wait.
class GpuEffectTracer {
 public:
  /// How the answers name the surface they met (shaders/effect_resolve.comp uSurfaces).
  enum class Surfaces : int {
    Fragments = 0,          ///< the hit fragment (x, y, layer) of the frame's layers: screen tracers
    Records = 1,            ///< a SurfaceRecord per hit: point, normal, triangle, material (geometric hits)
    FragmentsAtPoints = 2,  ///< the hit fragment, at the point of the record (the quad-tree's exact ray–plane point)
  };
  virtual ~GpuEffectTracer() = default;
  virtual Surfaces surfaces() const = 0;
  virtual const Camera& effectCamera() const = 0;
  virtual GpuContext& context() const = 0;
  virtual void answerWave(const GpuEffectWave& wave) const = 0;
  /// Whether the tracer can answer every wave on the device (otherwise the renderer shades on
  /// the CPU, asking the tracer batch by batch).
  virtual bool effectsOnDevice() const { return true; }
  /// A tracer of the scene (its structure independent of the view: the cube, the grid) traced
  /// frame after frame (gpu_frame.h): the next frame's camera, whose space its rays are in.
  virtual void setEffectCamera(const Camera& camera);
  /// The same scene's tables already on the device (a resident frame's capture), for a tracer
  /// that reads them to read those rather than upload its own, until called with null (the
  /// frame's end).
  virtual void shareSceneTables(const GpuSceneTables* tables) { (void)tables; }
  /// Called by GpuEffects::run before its first wave: the tracer's own sums start from zero.
  virtual void beginEffect() const {}
  /// The tracer's own sums over the last run's rays (read from the device: a host wait).
  virtual GpuTracerSums effectSums() const { return {}; }
  /// The passes for `layers` captured with the tracer's camera from `scene` and `lights`:
  /// uploaded on the first call and kept while the scene, the layers and the lights stay the
  /// same, so that repeated renders of the frame (the timed repeats of render and bench) upload
  /// and compile once.
  const GpuEffects& effects(const Scene& scene, const LayerArrays& layers, std::span<const PointLight> lights) const;

 private:
  mutable std::unique_ptr<GpuEffects> effects_;
  mutable const Scene* effectsScene_ = nullptr;
  mutable const LayerArrays* effectsLayers_ = nullptr;
  mutable std::vector<PointLight> effectsLights_;
};

enum class GpuEffectKind : int { Shade = 0, Reflection = 1, AO = 2, Shadow = 3, Refraction = 4, Warp = 5 };

/// View synthesis: the second camera (the frame's size), its eye in the first camera's space,
/// and its rays' length.
struct GpuWarp {
  Camera camera;
  glm::vec3 origin{0.0f};
  float maxDistance = 1.0f;
};

/// render/effects.h EffectConfig, with its scene-dependent defaults resolved by the caller.
struct GpuEffectParams {
  GpuEffectKind kind = GpuEffectKind::Reflection;
  int bounces = 1;            ///< reflection bounces, 1..16
  int aoSamples = 8;          ///< AO rays per pixel, 1..4096
  float aoRadius = 1.0f;      ///< AO ray length
  float maxDistance = 1.0f;   ///< reflection ray length
  float eps = 1e-4f;          ///< a shadow ray stops this short of its light
  uint64_t seed = 1;          ///< AO: per-pixel random streams derive from it
  bool countRays = true;      ///< per-ray counters and their histogram
  bool mirrorBelowSurface = true;
  /// Whether a ray never answers with the triangle it leaves (the CPU renderer's rule). Off for
  /// a caller's layers (layertrace/gpu.h), whose slots name a material, not a triangle: there
  /// the origin pixel's rule alone keeps a ray off its own surface.
  bool excludeOriginTriangle = true;
  GpuWarp warp;  ///< GpuEffectKind::Warp
  /// The frame's pixels run in chunks of whole 8×8 tiles whose per-ray buffers (256 bytes a ray
  /// slot) stay under this many bytes (at least one tile a chunk), so that a large frame with
  /// many rays per pixel fits the GPU. Choice: 512 MiB, 2 M ray slots, more rays than any GPU
  /// runs at once.
  size_t chunkBytes = size_t(512) << 20;
};

/// One pixel's counters, summed over its rays (render/effects.h EffectResult).
struct GpuPixelTally {
  uint32_t rays, hits, iterations, intervals, pixels, giveUps, bent;
  uint32_t hole;  ///< view synthesis: 1 where the second camera's ray found nothing
  uint32_t levelIterations[8];
};
static_assert(sizeof(GpuPixelTally) == 64);

/// What GpuEffects::run reads back once its passes are issued: the picture (image and traced),
/// the per-pixel tally, the histogram of iterations, and the frame's sums (GpuEffectOutput::sums,
/// reduced on the device). A resident frame asks for nothing and reads the sums with its own
/// counters (gpu_frame.h).
struct GpuEffectReadback {
  bool image = true, tally = true, histogram = true, sums = false;
};

/// The 16 sums of GpuPixelTally's fields over the frame (rays, hits, iterations, intervals,
/// pixels, give-ups, bent, holes, iterations per level 0…7), 64 bits each.
using GpuTallySums = std::array<uint64_t, 16>;
/// GpuEffects::sums(): the 16 sums as (low, high) 32-bit words, then the 99th percentile of the
/// iterations per ray (with countRays), then a word unused.
inline constexpr size_t kPercentileWord = 32, kSumsWords = 34;

struct GpuEffectOutput {
  int width = 0, height = 0;
  std::vector<glm::vec3> image, traced;  ///< row-major, width × height
  std::vector<GpuPixelTally> tally;      ///< row-major, width × height
  std::vector<uint32_t> histogram;       ///< rays per iteration count, the last bin holds ≥ 65536 (countRays)
  GpuTallySums sums{};                   ///< GpuEffectReadback::sums
  uint64_t iterationsP99 = 0;            ///< GpuEffectReadback::sums with countRays, computed on the device
  double traceMs = 0.0;  ///< GPU time of the marches and the origin rule (timer queries)
  double shadeMs = 0.0;  ///< GPU time of ray generation and shading (timer queries)
};

class GpuEffects {
 public:
  /// At most this many lights (the shaders hold them in uniforms).
  static constexpr int kMaxLights = 16;
  /// Whether the passes can shade a scene with `lights` lights.
  static bool supports(int lights) { return lights <= kMaxLights; }

  /// Uploads what the passes read for one frame: `layers` captured with `camera` from `scene`,
  /// `lights` in scene coordinates. The context must outlive the object.
  GpuEffects(GpuContext& gpu, const Scene& scene, const Camera& camera, const LayerArrays& layers, std::span<const PointLight> lights);
  /// The passes for a frame that stays on the device (gpu_frame.h): what they read comes from
  /// setFrame, frame by frame.
  GpuEffects(GpuContext& gpu, const Scene& scene, std::span<const PointLight> lights);
  ~GpuEffects();
  GpuEffects(const GpuEffects&) = delete;
  GpuEffects& operator=(const GpuEffects&) = delete;

  /// The next frame's camera and, on the device, its layer arrays as the passes read them
  /// (shaders/effect_common.glsl Fragments, k a pixel) and its per-triangle records (Triangles).
  void setFrame(const Camera& camera, const GpuBuffer& fragments, const GpuBuffer& triangles, int k);

  /// Renders one effect with `tracer`, which must trace the same layers with the same camera (or,
  /// for a tracer of the scene, the camera's size).
  /// No host wait between passes: the origin rule's rounds run as indirect dispatches sized on
  /// the device. With a readback, the GPU times are read after it; without one, call
  /// collectTimes after the frame's own read-back.
  GpuEffectOutput run(const GpuEffectTracer& tracer, const GpuEffectParams& params, const GpuEffectReadback& readback = {}) const;
  /// GPU milliseconds of the runs since the last collection: trace (marches and the origin
  /// rule), shade (ray generation and shading).
  void collectTimes(double& traceMs, double& shadeMs) const;
  /// The device's sums of the last run (kSumsWords words: GpuTallySums as 16 × (low, high)
  /// 32-bit words, then the percentile).
  const GpuBuffer& sums() const { return sums_; }
  /// The last run's output per pixel slot (8×8 tiles, effect_common.glsl slotPixel): the
  /// picture and the traced colour, two RGBA floats.
  const GpuBuffer& picture() const { return out_; }

  /// Bytes held on the GPU for the frame (the per-run buffers included once run).
  size_t memoryBytes() const;

 private:
  void resize(size_t pixelSlots, size_t chunkSlots, size_t raySlots) const;
  void setUniforms() const;

  GpuContext& gpu_;
  Camera camera_;
  int k_ = 0;
  int lights_ = 0;
  std::vector<glm::vec3> lightPosition_, lightIntensity_;  ///< scene coordinates
  uint32_t triangleCount_ = 0;
  glm::vec3 environment_{0.0f};
  const GpuProgram* step_ = nullptr;
  const GpuProgram* resolve_ = nullptr;
  const GpuProgram* rounds_ = nullptr;
  const GpuProgram* sum_ = nullptr;
  const GpuProgram* percentile_ = nullptr;
  GpuBuffer ownFragments_, ownTriangles_;
  const GpuBuffer* fragments_ = &ownFragments_;
  const GpuBuffer* triangles_ = &ownTriangles_;
  mutable GpuBuffer rays_, hits_, effectRays_, answers_, states_, out_, tally_, pending_, groups_, sums_;
  mutable GpuBuffer records_;  ///< the tracer's SurfaceRecord per ray slot (GpuEffectTracer::Surfaces)
  mutable GpuTimeline timeline_;
};

}  // namespace lt
