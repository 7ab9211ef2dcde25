// The secondary effects on the GPU: ray generation, the origin rule and shading as compute
// passes (shaders/effect_step.comp, effect_resolve.comp) around a GPU tracer's march, so that
// no ray leaves the device between bounces. They are the GLSL twins of render/effects.cpp (the
// same rays, the same Blinn-Phong shading) and work with every GpuScreenTracer: SSR, SSR over
// all layers, the Hi-Z march, HSSR and the exhaustive march.
//
// What the passes read is uploaded once per frame: the layer arrays (depth, normal, albedo and
// specular, scene triangle per slot) and per scene triangle its camera-space geometric normal
// and material. Every effect of render/effects.h runs here: shade, reflection (1–16 bounces),
// refraction through one transmissive layer, AO, shadows and view synthesis.
#pragma once

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

class GpuScreenTracer;

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
  GpuWarp warp;  ///< GpuEffectKind::Warp
  /// The frame's pixels run in chunks of whole 8×8 tiles whose per-ray buffers (208 bytes a ray
  /// slot) stay under this many bytes (at least one tile a chunk), so that a large frame with
  /// many rays per pixel fits the GPU. Choice: 512 MiB, 2.5 M ray slots, more rays than any GPU
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

struct GpuEffectOutput {
  int width = 0, height = 0;
  std::vector<glm::vec3> image, traced;  ///< row-major, width × height
  std::vector<GpuPixelTally> tally;      ///< row-major, width × height
  std::vector<uint32_t> histogram;       ///< rays per iteration count, the last bin holds ≥ 65536 (countRays)
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
  ~GpuEffects();
  GpuEffects(const GpuEffects&) = delete;
  GpuEffects& operator=(const GpuEffects&) = delete;

  /// Renders one effect with `tracer`, which must trace the same layers with the same camera.
  GpuEffectOutput run(const GpuScreenTracer& tracer, const GpuEffectParams& params) const;

  /// Bytes held on the GPU for the frame (the per-run buffers included once run).
  size_t memoryBytes() const;

 private:
  void resize(size_t pixelSlots, size_t chunkSlots, size_t raySlots) const;

  GpuContext& gpu_;
  const Camera& camera_;
  int lights_ = 0;
  GpuProgram step_, resolve_;
  GpuBuffer fragments_, triangles_;
  mutable GpuBuffer rays_, hits_, effectRays_, answers_, states_, out_, tally_, pending_;
  std::unique_ptr<GpuTimer> traceTimer_, shadeTimer_;
};

}  // namespace lt
