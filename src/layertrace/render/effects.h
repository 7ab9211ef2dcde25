// The secondary effects, written once against the Tracer interface (DESIGN.md): they work with
// every tracer, screen-space or geometric.
//
// Shading model (documented choice): Blinn-Phong per point light, diffuse albedo·max(0, n·l),
// specular s·((e+8)/8)·max(0, n·h)^e, both times intensity / d², plus an ambient term
// 0.05·albedo. Mirror and transmission weights of the material blend in the traced colours.
#pragma once

#include <cstdint>
#include <string>

#include "layertrace/app/frame.h"
#include "layertrace/eval/classify.h"
#include "layertrace/screen/tracer.h"
#include "layertrace/util/image.h"

namespace lt {

enum class Effect { Shade, Reflection, Refraction, AO, Shadow };

/// Parses "shade|reflection|refraction|ao|shadow"; InputError naming --effect otherwise.
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
};

struct EffectResult {
  Image image;
  Image iterations;  ///< per pixel: traversal iterations summed over the pixel's rays
  Image intervals;   ///< per pixel: intervals tested summed over the pixel's rays
  uint64_t rays = 0, hits = 0;
  uint64_t iterationSum = 0, intervalSum = 0, pixelSum = 0;
  uint64_t iterationsP99 = 0;
  uint64_t levelIterations[RayCounters::kLevels] = {};  ///< HSSR: visited cells per level, summed
  uint64_t exhaustiveMismatch = 0;  ///< rays where `oracle` answered differently
  double traceMs = 0.0;
  /// With a geometric reference: rays per class, and per pixel the class of its first ray
  /// (an RGB legend image; pixels without rays stay black).
  uint64_t classCounts[kRayClasses] = {};
  Image classImage;
};

/// Throws InputError naming the option for an invalid value (commands call it before the
/// expensive frame build; renderEffect calls it again).
void validateEffectConfig(const EffectConfig& config);

/// Renders the effect with `tracer`. When `oracle` is given every ray is traced by it too and
/// the answers compared (same hit fragment, or both miss); when `reference` (a geometric
/// tracer) is given every ray is traced by it too and classified (eval/classify.h).
EffectResult renderEffect(const Frame& frame, const Tracer& tracer, const EffectConfig& config, const Tracer* oracle = nullptr,
                          const Tracer* reference = nullptr);

}  // namespace lt
