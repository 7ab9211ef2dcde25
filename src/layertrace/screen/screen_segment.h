// A camera-space ray as a 2D line in pixel space with homogeneous perspective-correct
// interpolation (McGuire and Mara 2014): k = 1/depth is linear in the screen-space parameter
// s ∈ [0, 1] from P0 to P1, so depth(s) = 1 / (k0 + s (k1 - k0)). (McGuire and Mara 2014 also
// interpolate Q = point/depth to return the hit point; our tracers return the hit fragment's own
// point, so Q is not kept.)
// The 3D segment is clipped to the near plane and its end to the viewport; a
// ray that starts outside the view is clipped to where it enters it (clippedStart).
#pragma once

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "layertrace/scene/camera.h"
#include "layertrace/trace/tracer.h"

namespace lt {

struct ScreenSegment {
  glm::vec2 p0{0.0f}, p1{0.0f};  ///< pixel coordinates
  float k0 = 1.0f, k1 = 1.0f;    ///< 1 / depth at the ends
  bool valid = false;            ///< false when nothing of the ray is in front of the near plane
  /// The ray does not start on a surface: it started outside the view (behind the near plane
  /// or off-screen, e.g. at another camera's eye) and p0 is where it enters, or it starts in
  /// free space (Ray::startsOnSurface false). Its first pixel holds no surface of its own, so
  /// tracers test it instead of skipping it.
  bool clippedStart = false;
  /// The ray's origin lies outside the view (behind the near plane or off-screen): p0 is where
  /// it enters. Nothing the layers store describes the way in.
  bool startOutside = false;
  /// The segment ends before the ray does: it leaves the view through the near plane or the
  /// viewport's border at p1.
  bool clippedEnd = false;

  float depthAt(float s) const { return 1.0f / (k0 + s * (k1 - k0)); }
  glm::vec2 pointAt(float s) const { return p0 + s * (p1 - p0); }
  /// The screen parameter `pixels` pixels of motion along the segment's major axis span.
  float pixelParam(float pixels) const;
  /// Screen parameter where the ray's depth equals `depth` (any s if the depth is constant).
  float paramAtDepth(float depth) const { return k1 != k0 ? (1.0f / depth - k0) / (k1 - k0) : 0.0f; }
};

ScreenSegment makeScreenSegment(const Camera& camera, const Ray& ray);

/// The parameter t along `ray` of the segment's point at screen parameter s (its depth on the
/// line of sight through that screen point), clamped to [0, ray.maxDistance].
float rayParamAt(const Camera& camera, const Ray& ray, const ScreenSegment& seg, float s);

/// The ray parameters `margin` pixels of screen motion before the ray's projection enters
/// pixel (x, y) and after it leaves it (clamped to [0, ray.maxDistance]; {0, maxDistance} when
/// nothing of the ray is on screen). Screen tracers answer at pixel resolution: the surface that
/// decided a pixel may lie a pixel or two before or after it along the ray.
struct ParamSpan {
  float before = 0.0f, after = 0.0f;
};
/// `seg` = makeScreenSegment(camera, ray).
ParamSpan rayParamsAroundPixel(const Camera& camera, const Ray& ray, const ScreenSegment& seg, int x, int y, float margin);
/// rayParamsAroundPixel(…).after alone.
float rayParamAfterPixel(const Camera& camera, const Ray& ray, const ScreenSegment& seg, int x, int y, float margin);

}  // namespace lt
