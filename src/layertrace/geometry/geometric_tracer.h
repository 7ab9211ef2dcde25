// Geometric tracers behind the tracer interface: the answer of Embree (or, through grid/, of the irregular grid)
// for the very rays the screen-space tracers trace (same camera-space origins and directions).
#pragma once

#include <algorithm>
#include <limits>
#include <memory>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "layertrace/geometry/embree_scene.h"
#include "layertrace/scene/camera.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// What both geometric tracers share: camera ↔ world, the offset that keeps a ray off the
/// surface it starts on, and turning a triangle hit into a TraceHit (interpolated normal,
/// material, projected pixel).
class GeometricHits {
 public:
  GeometricHits(const Scene& scene, const Camera& camera);
  /// A relative offset keeps the ray off the surface it starts on (screen tracers skip the
  /// origin pixel for the same reason): 1e-4 of the origin's distance from the eye, at least
  /// 1e-4 of `unit` (offsetUnit).
  static float originOffset(const Ray& ray, float unit) { return 1e-4f * std::max(unit, glm::length(ray.origin)); }
  /// The floor's unit: 1 (scene units) — or the scene's diagonal where that is smaller, so that a
  /// scene a micrometre across is not skipped whole.
  static float offsetUnit(const Scene& scene);
  float originOffset(const Ray& ray) const { return originOffset(ray, unit_); }
  TraceHit makeHit(const Ray& ray, const GeoHit& g) const;
  /// An any-hit answer: hit, no blocker details.
  static TraceHit occludedHit(bool hit) {
    TraceHit h;
    h.hit = hit;
    return h;
  }
  const Camera& camera() const { return *camera_; }
  const Scene& scene() const { return scene_; }
  /// Makes the hits of rays in `camera`'s space (which must outlive this object): a structure of
  /// the scene traced frame after frame (gpu/gpu_frame.h).
  void setCamera(const Camera& camera) { camera_ = &camera; }

 private:
  const Scene& scene_;
  const Camera* camera_;
  float unit_ = 1.0f;  ///< offsetUnit(scene_)
  std::vector<uint32_t> packed_;  ///< per material: albedo + specular as stored in fragments
};

/// Queries about segments of rays, without building a TraceHit: where each ray stops past a given
/// point and on which triangle, or whether anything blocks it there — for a caller that needs no
/// more (the hybrid: its windows only decide where a ray's answer lies, its remainders continue a
/// ray where screen space lost knowledge).
///
/// Ray i is traced from t = from[i] to its maxDistance (an empty `from`: from its origin offset, a
/// whole ray). It is the very float ray a whole-ray query traces, started later (Embree's and the
/// grid's tnear), so a hit at or past from[i] is the whole ray's hit bit for bit (an exact tie
/// between two triangles at one t may name the other one). Two things make that hold:
///  - the ray is not moved to its segment's start: a moved ray is another float ray, and its own
///    origin offset (1e-4 of its distance from the eye) skips the segment's first stretch — on
///    assimp's cube_tristrips.dae seen from 135 units, 0.0135 units, through which 50 reflection
///    rays' hits fell;
///  - tnear lies a little before from[i] (segmentSlack): plain Embree's box and triangle tests
///    round at the scale of the ray's coordinates, so a tnear a few ulps of them before a hit
///    culls it (a segment starting 7·10⁻⁸ before a hit 0.0035 along a ray found nothing).
///    A segment may therefore also return a hit up to that slack before from[i] — a real
///    intersection of the whole ray.
/// GeometricHits::makeHit(rays[i], hits[i]) is the tracer's traceBatch answer bit for bit
/// (TraceInterface.GeoSegmentsAreTheWholeRaysHits). `counters` as in Tracer::traceBatch.
class GeoHitQueries {
 public:
  virtual ~GeoHitQueries() = default;
  virtual void intersectSegments(std::span<const Ray> rays, std::span<const float> from, std::span<GeoHit> hits,
                                 std::span<RayCounters> counters) const = 0;
  /// blocked[i] = 1 where something lies on ray i's segment.
  virtual void occludedSegments(std::span<const Ray> rays, std::span<const float> from, std::span<uint8_t> blocked,
                                std::span<RayCounters> counters) const = 0;
  /// How far before `from` a segment's tnear lies, for a ray from world-space `origin`: 64 float
  /// epsilons of the largest coordinate the ray has there (its direction has unit length).
  static float segmentSlack(glm::vec3 origin, float from) {
    const glm::vec3 a = glm::abs(origin);
    return 64.0f * std::numeric_limits<float>::epsilon() * (std::max({a.x, a.y, a.z}) + from);
  }
  /// The tnear of a segment starting at `from` (0: a whole ray) for a tracer whose origin offset
  /// is `offset`.
  static float segmentStart(float from, float offset, glm::vec3 origin) {
    return from > 0.0f ? std::max(offset, from - segmentSlack(origin, from)) : offset;
  }
  /// Where segment i starts: from[i], or 0 (a whole ray) when `from` is empty.
  static float startOf(std::span<const float> from, size_t i) { return from.empty() ? 0.0f : from[i]; }
};

/// A geometric acceleration structure as a tracer: Accel is EmbreeScene ("embree": one
/// rtcIntersect1 / rtcOccluded1 per ray, counted as one iteration) or IrregularGrid ("grid":
/// iterations count visited cells). Both answer world-space queries
///   intersect(origin, dir, tnear, tfar, TraversalCounts*) and occluded(…, TraversalCounts*).
template <class Accel>
class GeometricTracer : public TracerImpl<GeometricTracer<Accel>>, public GeoHitQueries {
 public:
  GeometricTracer(const char* name, const Scene& scene, const Camera& camera, const Accel& accel)
      : name_(name), hits_(scene, camera), accel_(accel) {}
  const char* name() const override { return name_; }
  const GeometricHits& hits() const { return hits_; }
  const Accel& accel() const { return accel_; }
  template <class C>
  TraceHit traceImpl(const Ray& ray, C& c) const {
    return hits_.makeHit(ray, intersect(ray, c));
  }
  template <class C>
  GeoHit intersect(const Ray& ray, C& c, float from = 0.0f) const {
    return query(ray, c, from, [this](auto... a) { return accel_.intersect(a...); });
  }
  template <class C>
  bool occluded(const Ray& ray, C& c, float from = 0.0f) const {
    return query(ray, c, from, [this](auto... a) { return accel_.occluded(a...); });
  }
  void intersectSegments(std::span<const Ray> rays, std::span<const float> from, std::span<GeoHit> hits,
                         std::span<RayCounters> counters) const override {
    perRay(rays, from, counters, [&](size_t i, float start, auto& c) { hits[i] = intersect(rays[i], c, start); });
  }
  void occludedSegments(std::span<const Ray> rays, std::span<const float> from, std::span<uint8_t> blocked,
                        std::span<RayCounters> counters) const override {
    perRay(rays, from, counters, [&](size_t i, float start, auto& c) { blocked[i] = occluded(rays[i], c, start); });
  }
  template <class C>
  TraceHit occludedImpl(const Ray& ray, C& c) const {
    return GeometricHits::occludedHit(occluded(ray, c));
  }

 private:
  /// f(i, from, counters) for each ray, counted where `counters` is given.
  template <class F>
  static void perRay(std::span<const Ray> rays, std::span<const float> from, std::span<RayCounters> counters, F&& f) {
    NoCounters none;
    for (size_t i = 0; i < rays.size(); ++i) {
      if (kCountersCompiled && !counters.empty()) f(i, startOf(from, i), counters[i]);
      else f(i, startOf(from, i), none);
    }
  }
  template <class C, class Q>
  auto query(const Ray& ray, C& c, float from, Q&& q) const {
    const Camera& cam = hits_.camera();
    TraversalCounts n;
    const glm::vec3 o = cam.toWorld(ray.origin);
    const auto answer =
        q(o, cam.dirToWorld(ray.dir), segmentStart(from, hits_.originOffset(ray), o), ray.maxDistance, C::kEnabled ? &n : nullptr);
    c.addIterations(std::max(n.steps, 1u));
    if (n.giveUps) c.giveUp();
    return answer;
  }
  const char* name_;
  GeometricHits hits_;
  const Accel& accel_;
};
using EmbreeTracer = GeometricTracer<EmbreeScene>;

/// Plain Embree with 16-wide packets (rtcIntersect16 / rtcOccluded16): each batch is cut into
/// packets of 16 consecutive rays — the packet baseline `compare` reports beside single-ray
/// Embree on the same rays, and the hybrid's geometric half. Counted runs trace
/// one ray at a time. Answers are Embree's, packet or not (TraceInterface.EmbreePacketsAnswerAsSingleRays,
/// bit for bit; geobench and compare report the agreement too).
class EmbreePacketTracer : public TracerImpl<EmbreePacketTracer>, public GeoHitQueries {
 public:
  EmbreePacketTracer(const Scene& scene, const Camera& camera, const EmbreeScene& embree)
      : single_("embree-packet16", scene, camera, embree), embree_(embree) {}
  const char* name() const override { return "embree-packet16"; }
  template <class C>
  TraceHit traceImpl(const Ray& ray, C& c) const {
    return single_.traceImpl(ray, c);
  }
  template <class C>
  TraceHit occludedImpl(const Ray& ray, C& c) const {
    return single_.occludedImpl(ray, c);
  }
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void intersectSegments(std::span<const Ray> rays, std::span<const float> from, std::span<GeoHit> hits,
                         std::span<RayCounters> counters) const override;
  void occludedSegments(std::span<const Ray> rays, std::span<const float> from, std::span<uint8_t> blocked,
                        std::span<RayCounters> counters) const override;

 private:
  /// Calls f(origins, dirs, tnear, tfar, n, offset) for each packet of up to 16 rays, tnear at
  /// each ray's segment start (GeoHitQueries).
  template <class F>
  void packets(std::span<const Ray> rays, std::span<const float> from, F f) const;
  EmbreeTracer single_;  ///< the one-ray path, and the hit construction the packets share
  const EmbreeScene& embree_;
};

inline std::unique_ptr<Tracer> makeEmbreeTracer(const Scene& scene, const Camera& camera, const EmbreeScene& embree) {
  return std::make_unique<EmbreeTracer>("embree", scene, camera, embree);
}

}  // namespace lt
