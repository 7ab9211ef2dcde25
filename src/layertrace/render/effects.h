// The secondary effects, written once against the Tracer interface (trace/tracer.h): they work with
// every tracer, screen-space or geometric.
//
// Layer: render/ turns a pipeline Frame and a Tracer into an image — ray generation, the
// effects and shading. It includes pipeline/ and the layers below (trace/, raster/, scene/,
// util/), never eval/ or app/: evaluation watches through a RayObserver (ray_observer.h).
//
// Shading model (documented choice): Blinn-Phong per point light, diffuse albedo·max(0, n·l),
// specular s·((e+8)/8)·max(0, n·h)^e, both times intensity / d², plus an ambient term
// 0.05·albedo. Mirror and transmission weights of the material blend in the traced colours.
//
// Execution: the image is processed in bands of rows; each pixel's path is a small state
// machine advanced wave by wave (wave b holds every ray of bounce b of the band). A wave's rays
// are laid out in 8×8-pixel tiles so that neighbouring pixels' rays sit together, and are traced
// in batches of kBatchRays through Tracer::traceBatch (closest hit) or occludedBatch (shadow and
// AO rays). The time inside those calls is `traceMs`; everything else (ray generation, shading,
// counter bookkeeping, observers) is `shadeMs`.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/ext/vector_double3.hpp>
#include <glm/vec3.hpp>

#include "layertrace/pipeline/frame.h"
#include "layertrace/render/ray_observer.h"
#include "layertrace/trace/tracer.h"
#include "layertrace/util/image.h"

namespace lt {

/// Warp: view synthesis (the application of Widmer et al. 2015) — the image of a second camera
/// (warpEye, warpTarget; the first camera's up, field of view and clip planes) made by tracing its
/// primary rays through the first camera's k layers. A ray that finds nothing is a hole.
enum class Effect { Shade, Reflection, Refraction, AO, Shadow, Warp };

/// Parses "shade|reflection|refraction|ao|shadow|warp"; InputError naming --effect otherwise.
Effect parseEffect(const std::string& name);
const char* effectName(Effect e);

struct EffectConfig {
  Effect effect = Effect::Reflection;
  int bounces = 1;           ///< reflection bounces traced from every covered pixel
  int aoSamples = 8;         ///< cosine-weighted AO rays per pixel
  float aoRadius = 0.0f;     ///< AO ray length; 0 = 5 % of the scene diagonal
  float maxDistance = 0.0f;  ///< ray length for reflection/refraction; 0 = the scene diagonal
  uint64_t seed = 1;         ///< per-pixel random streams derive from it (thread-count independent)
  bool progress = false;     ///< progress on stderr for runs longer than a second
  /// Count traversal work per ray (iterations, intervals, per-pixel counter images). Off for
  /// timing runs: tracers then run their counter-free instantiation (trace/tracer.h).
  bool countRays = true;
  /// Trace each wave of the whole frame in one tracer call, on the calling thread: a GPU tracer
  /// (gpu/) then dispatches every ray of the wave at once. Ray generation and shading stay on
  /// the CPU, between the waves (unless shadeOnDevice); the answers are the same as with bands.
  bool wholeWaves = false;
  /// With a GPU tracer (gpu/gpu_screen_tracer.h) and wholeWaves: generate the rays and shade on
  /// the GPU as well (gpu/gpu_effects.h), so that no ray leaves the device between bounces.
  /// Applies to every effect with at most 16 lights and no observer; otherwise ray generation
  /// and shading stay on the CPU (EffectResult::onDevice says which ran). traceMs and shadeMs
  /// are then GPU timer-query times.
  bool shadeOnDevice = false;
  /// A secondary direction below the geometric surface it leaves (interpolated normals on a
  /// flat face): mirrored about the geometric plane (true) or bent to graze it (false).
  bool mirrorBelowSurface = true;
  /// --warp-eye: the second camera's eye, Effect::Warp. World coordinates (those of the scene file),
  /// like --eye: warpCamera subtracts the scene's origin (Scene::origin).
  std::optional<glm::dvec3> warpEye;
  std::optional<glm::dvec3> warpTarget;  ///< --warp-target: its target; default the first camera's target
};

/// The second camera of Effect::Warp beside the frame's (InputError naming --warp-eye if the view
/// is degenerate).
Camera warpCamera(const Frame& frame, const EffectConfig& config);

struct EffectResult {
  Image image;
  /// What the rays brought back, unweighted by materials: reflection — the local shading at the
  /// path's last hit (as if every surface before it were a perfect mirror), the environment
  /// where the path left the scene; refraction — the colour seen through the surface;
  /// AO and shadow — the image itself; shade — the local shading. Comparing it with Embree's
  /// scores what was traced even in scenes without mirrors.
  Image traced;
  Image iterations;  ///< per pixel: traversal iterations summed over the pixel's rays (countRays)
  Image intervals;   ///< per pixel: intervals tested summed over the pixel's rays (countRays)
  uint64_t rays = 0, hits = 0;
  uint64_t iterationSum = 0, intervalSum = 0, pixelSum = 0, giveUps = 0;
  uint64_t fragmentSum = 0;  ///< level-0 fragments tested (RayCounters::fragments; CPU tracers)
  uint64_t planeNodeSum = 0, boxNodeSum = 0, occlusionSum = 0;  ///< quadtree: visited plane / box nodes, occlusion hits
  uint64_t bentRays = 0;
  std::vector<uint8_t> holes;  ///< Effect::Warp: per pixel 1 where the second camera's ray found nothing  ///< secondary rays bent out of their geometric surface (effects.cpp keepOutside)
  uint64_t iterationsP99 = 0;
  uint64_t levelIterations[RayCounters::kLevels] = {};  ///< HSSR: visited cells per level, summed
  bool onDevice = false;  ///< rays generated and shaded on the GPU (EffectConfig::shadeOnDevice)
  size_t deviceBytes = 0;  ///< onDevice: the GPU buffers the effect held (layers, triangles, rays, paths, picture)
  double traceMs = 0.0;  ///< wall time inside the tracer's batch calls
  double shadeMs = 0.0;  ///< wall time of the rest of the effect (rays, shading, observers)
};

/// Throws InputError naming the option for an invalid value (commands call it before the
/// expensive frame build; renderEffect calls it again).
void validateEffectConfig(const EffectConfig& config);

/// Renders the effect with `tracer`; `observer` (optional) sees every traced ray and its answer.
EffectResult renderEffect(const Frame& frame, const Tracer& tracer, const EffectConfig& config, RayObserver* observer = nullptr);

/// The trace time every command reports (docs/cli.md, "How times are measured"): medians over
/// `repeat` passes of the effect's rays through `tracer` without counters (the counter-free
/// instantiation, which is also the one the vector marches serve), no observer. Run it after a
/// first pass over the same rays (the command's counted pass, or a discarded one): that pass is
/// the warm-up that pays for cold caches and first-touch page faults.
struct TraceTiming {
  double traceMs = 0.0;  ///< median time inside the tracer's batch calls
  double shadeMs = 0.0;  ///< median time of the rest: ray generation, shading, bookkeeping
};
TraceTiming measureTrace(const Frame& frame, const Tracer& tracer, const EffectConfig& config, int repeat);

}  // namespace lt
