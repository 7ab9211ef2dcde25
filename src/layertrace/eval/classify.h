// Per-ray classification of an image-space answer against the geometric one
// (docs/evaluation.md): the strict classes.
//
// Layer: eval/ measures what the layers below produce — observers of the effects' rays that
// classify them against a geometric reference or compare them with an oracle, the layer
// verification against Embree, metrics. It may include every layer except app/ (the CLI).
//
// The rules (docs/evaluation.md; the classifier reads no tracer option and no
// --thickness — only the stored intervals — so the same rays get the same classes whatever
// produced them). P is the true
// (Embree) hit point, (x, y) the reported pixel, F the reported fragment (front depth z_F):
//
//   correct hit         P projects into (x, y) or one of its 8 neighbours, AND either P is on
//                       F's triangle, or depth(P) lies in F's interval [z_F, z_F + thickness]
//                       widened by δ on both sides, where δ = 1.5 × (the ray's depth change
//                       across one pixel of screen motion + the stored surface's depth change
//                       across one pixel, from its normal, at most 20 footprints).
//   A hit on no camera layer (geometric tracers, ldc: layer -1) is correct when it is on P's
//   triangle, at P's distance (10^-4 relative), or within 1.5 pixel footprints of P across the
//   ray and along it (up to 20 footprints along it for a surface seen at a grazing angle), the
//   footprint taken at P's distance from the eye so that the rule also holds off screen.
//   wrong hit, split by cause:
//     thickness         no true hit, or P lies farther along the ray than F: the ray passed
//                       behind F's surface inside its z-thickness.
//     origin pixel      (see below: the true hit in the origin pixel was skipped)
//     unstored          the true surface is not in the k layers, so the tracer went on.
//     other             the true surface is stored and was skipped.
//   misses:
//     origin_pixel_miss P projects into the ray's own origin pixel, which image-space tracers
//                       do not test (Hofmann et al. 2017, §5.1).
//     false miss        the true surface is stored (below) and was missed.
//     information miss  not stored: off-screen, outside the frustum, or behind layer k.
//     correct miss      neither hits.
//   stored              P is in front of the near plane and inside the viewport, and the pixel
//                       it projects into or a neighbour holds a fragment of P's triangle, or
//                       that pixel holds an interval that, widened by δ, contains depth(P).
// Any-hit rays (shadow, AO) ask only whether something blocks them: a hit is correct when the
// reference also hits something before maxDistance, and a thickness wrong hit when it does not.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>
#include <tbb/enumerable_thread_specific.h>

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/render/ray_observer.h"
#include "layertrace/scene/camera.h"
#include "layertrace/trace/tracer.h"
#include "layertrace/util/image.h"

namespace lt {

// RayClass, kRayClasses: trace/tracer.h (the public API grades hits with them too).
const char* rayClassName(RayClass c);  ///< "correct_hit", "wrong_hit_thickness", ...
glm::vec3 rayClassColor(RayClass c);   ///< legend colours of the classification image
inline bool isWrongHit(RayClass c) { return c == RayClass::WrongHitThickness || c == RayClass::WrongHitUnstored || c == RayClass::WrongHitOther; }

/// δ of the rules above at camera-space point p for a ray along `dir`, against a stored surface
/// with camera-space normal `n`.
float depthTolerance(const Camera& camera, glm::vec3 p, glm::vec3 dir, glm::vec3 n);

/// Is the surface hit by `truth` stored in the layers (rules above)?
bool storedInLayers(const TraceHit& truth, glm::vec3 dir, const Camera& camera, const LayerArrays& layers);

RayClass classifyRay(const Ray& ray, const TraceHit& tracer, const TraceHit& truth, Query query, const Camera& camera,
                     const LayerArrays& layers);

/// Classifies every observed ray against `reference` (a geometric tracer, asked for the closest
/// hit of the same ray).
class ClassifyObserver : public RayObserver {
 public:
  ClassifyObserver(const Tracer& reference, const Camera& camera, const LayerArrays& layers);
  void observe(std::span<const RayEvent> events) override;
  /// Rays per class, summed over threads.
  std::array<uint64_t, kRayClasses> counts() const;
  /// Per pixel the legend colour of its first ray's class; black where a pixel traced no ray.
  const Image& classImage() const { return image_; }

 private:
  const Tracer& reference_;
  const Camera& camera_;
  const LayerArrays& layers_;
  Image image_;
  struct Local {
    std::array<uint64_t, kRayClasses> counts{};
    std::vector<Ray> rays;
    std::vector<TraceHit> truth;
  };
  tbb::enumerable_thread_specific<Local> local_;
};

}  // namespace lt
