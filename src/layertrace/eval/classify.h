// Per-ray classification of a screen-space answer against the geometric one (DESIGN.md,
// "Ground truth, three kinds").
//
// Layer: eval/ measures what the layers below produce — observers of the effects' rays that
// classify them against a geometric reference or compare them with an oracle, the layer
// verification against Embree, metrics. It may include every layer except app/ (the CLI).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <vector>

#include <tbb/enumerable_thread_specific.h>

#include <glm/vec3.hpp>

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/render/ray_observer.h"
#include "layertrace/trace/tracer.h"
#include "layertrace/util/image.h"

namespace lt {

enum class RayClass : uint8_t {
  CorrectHit,   ///< both hit the same surface
  WrongHit,     ///< the tracer hit something the true ray does not hit first (or at all)
  FalseMiss,    ///< the tracer missed although the true hit surface is among the stored fragments
  InfoMiss,     ///< the tracer missed and the true hit is not stored: off-screen, outside the frustum, behind layer k
  CorrectMiss,  ///< neither hits
};
inline constexpr int kRayClasses = 5;
const char* rayClassName(RayClass c);  ///< "correct_hit", "wrong_hit", ...
glm::vec3 rayClassColor(RayClass c);   ///< legend colours of the classification image

/// The same surface: the same triangle, or hit points closer than the tolerance
/// sameSurfaceTolerance() (a screen-space hit point is reconstructed at the hit pixel's centre
/// and the fragment's front depth, so it may sit up to about a pixel footprint along the
/// surface and one z-thickness along the ray from the true point; we allow 2 footprints).
float sameSurfaceTolerance(const Camera& camera, float depth, float thickness);

/// Is the surface hit by `truth` stored in the layers? True if its point projects into the
/// screen in front of the near plane and that pixel keeps a fragment whose interval contains
/// the true depth, or that pixel or one of its 8 neighbours keeps a fragment of the same
/// triangle (the true point lies anywhere in its pixel, fragments sit at pixel centres).
bool storedInLayers(const TraceHit& truth, const Camera& camera, const LayerArrays& layers);

RayClass classifyRay(const TraceHit& tracer, const TraceHit& truth, const Camera& camera, const LayerArrays& layers,
                     float thickness);

/// Classifies every observed ray against `reference` (a geometric tracer, asked for the closest
/// hit of the same ray). Any-hit rays (shadow, AO) ask only whether something blocks the ray:
/// a hit is correct when the reference also hits anything before maxDistance.
class ClassifyObserver : public RayObserver {
 public:
  ClassifyObserver(const Tracer& reference, const Camera& camera, const LayerArrays& layers, float thickness);
  void observe(std::span<const RayEvent> events) override;
  /// Rays per class, summed over threads.
  std::array<uint64_t, kRayClasses> counts() const;
  /// Per pixel the legend colour of its first ray's class; black where a pixel traced no ray.
  const Image& classImage() const { return image_; }

 private:
  const Tracer& reference_;
  const Camera& camera_;
  const LayerArrays& layers_;
  float thickness_;
  Image image_;
  struct Local {
    std::array<uint64_t, kRayClasses> counts{};
    std::vector<Ray> rays;
    std::vector<TraceHit> truth;
  };
  tbb::enumerable_thread_specific<Local> local_;
};

}  // namespace lt
