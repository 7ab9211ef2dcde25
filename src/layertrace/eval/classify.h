// Per-ray classification of a screen-space answer against the geometric one (DESIGN.md,
// "Ground truth, two kinds").
#pragma once

#include <array>
#include <cstdint>

#include <glm/vec3.hpp>

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/screen/tracer.h"

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

}  // namespace lt
