// Hybrid tracing: screen space where the layers know the answer, geometry only where
// they do not.
//
// Layer: hybrid/ composes a screen-space tracer and a geometric one through the Tracer
// interface. It holds the certainty rules (known_space.h) and includes screen/ and hssr/ (the
// march), geometry/ (the exact local checks) and the layers below them; nothing above.
//
// Per ray (docs/methods/hybrid.md):
//  1. KnownSpace gives knownUntil, where the ray leaves the space the layers describe (its
//     rules are in known_space.h; with HSSR or Hi-Z the march itself meets rule 3).
//  2. The screen tracer traces the ray cut at knownUntil. With HSSR / Hi-Z it marches the
//     solid intervals of known_space.h: a ray cannot pass behind a stored surface between two
//     pixel samples unnoticed, it "hits" that surface's interval.
//  3. Every screen hit is checked exactly, the guard against thickness false hits: the ray is
//     intersected with the triangles of the hit pixel's layers up to the hit one, anywhere up to
//     two pixels past the hit pixel (a grazing ray meets the surface a few pixels before its
//     samples say so). No crossing means the ray got behind a stored surface without a crossing
//     where the samples looked: the march's "empty so far" is not trusted either, and geometry
//     answers the ray from its origin. A crossing is a candidate that a short geometric window
//     decides — from two pixels before the hit pixel (or the crossing, if earlier) to two pixels
//     past it, within the ray: the window's nearest hit is the answer (it may be a neighbouring
//     triangle the pixel samples missed), and a window that finds nothing rejects the hit.
//  4. A miss over a ray that stayed in known space is certain up to the pixel sampling. Any-hit
//     queries accept it; a closest-hit miss (it returns the environment, the most visible error)
//     is certified by geometry from the origin — 0.1 % of reflection rays on the real views.
//  5. Otherwise the geometric tracer continues from KnownSpace's geoFrom (one pixel before the
//     knowledge ended) to the ray's end — not from the origin: the known part was answered.
//     It continues the very ray, started there (GeoHitQueries' segments), so what it finds past
//     geoFrom is plain Embree's answer for the whole ray bit for bit; so do the windows.
//  6. Screen tracers never test the ray's own pixel (Hofmann et al. 2017, §5.1): a geometric
//     window covers the ray from its origin to two pixels past its pixel, and the screen march
//     starts where the window ends.
// Windows are a few pixels of ray: on FZK-Haus they cost about a fifth of whole geometric rays.
// Every hit the hybrid returns is an exact triangle intersection (layer = -1, like a geometric
// tracer's), so it shades exactly as the reference does. The solid intervals start at the
// nearest depth any triangle has inside each pixel's square (a conservative rasterization,
// raster/unsampled.h), so a ray cannot cross a surface in front of a pixel's centre sample
// unseen either. What it can still get wrong: a triangle seen exactly edge-on
// that the thin-triangle rule misses (shorter than two pixels), and rounding at the pixel and
// interval boundaries.
#pragma once

#include <cstdint>
#include <vector>

#include <tbb/enumerable_thread_specific.h>

#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"
#include "layertrace/hybrid/known_space.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// Who answered the rays of a run (sums since the last reset).
struct HybridStats {
  uint64_t rays = 0;
  /// Answered where screen space located the answer: a checked screen hit (the geometric
  /// windows that certify it may move it to a neighbouring triangle) or a hit in the origin
  /// pixel's window.
  uint64_t screenHits = 0;
  uint64_t certainMisses = 0;    ///< answered by a miss in known space (any-hit queries only)
  uint64_t geoRays = 0;          ///< handed to the geometric tracer
  /// Geometric window queries (the origin's pixel, a checked hit's surroundings): with geoRays,
  /// every query the geometric tracer answered — plain Embree answers each ray with one.
  uint64_t windowQueries = 0;
  uint64_t rejectedHits = 0;     ///< of those: screen hits the exact check rejected
  double geoLengthSum = 0.0;     ///< geometric segment length / the ray's length in the scene
  /// Wall time summed over the threads' batches: screen march and checks, the geometric
  /// windows that certify screen answers, the geometric remainders.
  double screenMs = 0.0, windowMs = 0.0, geoMs = 0.0;
  double screenFraction() const { return rays ? double(screenHits + certainMisses) / double(rays) : 0.0; }
  double geoFraction() const { return rays ? double(geoRays) / double(rays) : 0.0; }
  double geoLengthMean() const { return geoRays ? geoLengthSum / double(geoRays) : 0.0; }
  double geoQueriesPerRay() const { return rays ? double(windowQueries + geoRays) / double(rays) : 0.0; }
};

class HybridTracer : public Tracer {
 public:
  /// `screen` traces camera-space rays through `layers`; `geo` answers the rest. All are
  /// borrowed and must outlive the tracer.
  ///
  /// `worldMargin` > 0 declares a world-space screen tracer (the layered depth cube): it samples
  /// every surface in the scene box from three axes, so no ray leaves its knowledge (`known` is
  /// not asked). Each of its hits (layer −1) is certified by a geometric window from
  /// `worldMargin` before it to `worldMargin` past it (nothing there: rejected, geometry from the
  /// origin); `worldMargin` also bounds the origin's window, where the tracer ignores its own
  /// surface (ldc.h: a texel).
  ///
  /// `uncertainEmptySpace`: the screen tracer's "nothing here" is not certain — it does not march
  /// solid intervals (the quad-tree marches its own thin planes and can pass a stored surface
  /// between two samples; the layered depth cube's texels can miss a thin surface). Then a ray
  /// without a checked hit goes to geometry from its origin (a miss in known space as well as the
  /// remainder after knowledge ended), and a hit's window reaches back to the origin: the screen
  /// tracer proposes, geometry certifies.
  HybridTracer(const Scene& scene, const Camera& camera, const LayerArrays& layers, const KnownSpace& known, const Tracer& screen,
               const GeoHitQueries& geo, float worldMargin = 0.0f, bool uncertainEmptySpace = false);
  const char* name() const override { return "hybrid"; }
  const Tracer& screen() const { return screen_; }       ///< the image-space half
  const GeoHitQueries& geometry() const { return geo_; }  ///< the geometric half
  float worldMargin() const { return worldMargin_; }      ///< see the constructor
  bool uncertainEmptySpace() const { return uncertainEmptySpace_; }
  TraceHit trace(const Ray& ray, RayCounters& counters) const override;
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override;

  HybridStats stats() const;
  void resetStats();

 protected:
  /// Adds the sums of a run made elsewhere (the GPU's passes: gpu/gpu_hybrid.h) to stats().
  void addStats(const HybridStats& s) const;
  /// The ray's length inside the scene's bounds (the denominator of geo_length_mean).
  float lengthInScene(glm::vec3 worldOrigin, glm::vec3 worldDir, float maxDistance) const;
  const Camera& camera() const { return camera_; }
  const LayerArrays& layers() const { return layers_; }
  const KnownSpace& known() const { return known_; }
  const GeometricHits& geometricHits() const { return hits_; }
  float offsetUnit() const { return offsetUnit_; }

 private:
  struct Scratch;
  void run(Query q, std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const;
  /// Queues [from, to] of ray i (its `ray`) for the geometric tracer: the same ray, started at
  /// `from` (GeoHitQueries: its hits are the whole ray's bit for bit).
  static void askGeo(Scratch& s, const Ray& ray, size_t i, float from, float to);
  /// The geometric tracer on the queued segments: closest hits into s.geoBare or any hits into
  /// s.geoBlocked; counts go to the rays of s.geoIndex.
  void geoQuery(Query q, Scratch& s, std::span<RayCounters> counters) const;
  /// Did queued segment j of geoQuery's last run hit?
  static bool geoHit(Query q, const Scratch& s, size_t j);
  /// [from, to] of `ray` as a ray from free space, for the screen tracer (its hits' points are
  /// camera-space points of the original ray).
  static Ray segment(const Ray& ray, float from, float to);
  /// Ray (world space) against one scene triangle, t in (tmin, tmax].
  bool hitsTriangle(glm::vec3 o, glm::vec3 d, uint32_t triangle, float tmin, float tmax, float& t) const;
  /// The nearest intersection with the triangles of the first `layers` layers of pixel (x, y),
  /// t in (tmin, tmax].
  GeoHit pixelHit(glm::vec3 worldOrigin, glm::vec3 worldDir, int x, int y, int layers, float tmin, float tmax) const;

  const Scene& scene_;
  float offsetUnit_;  ///< GeometricHits::offsetUnit(scene_): the geometric tracers' origin offset
  const Camera& camera_;
  const LayerArrays& layers_;
  const KnownSpace& known_;
  const Tracer& screen_;
  /// Bare hits of segments: a window only decides where a ray stops, so its TraceHit is not
  /// built, and a segment is its whole ray started later.
  const GeoHitQueries& geo_;
  GeometricHits hits_;
  Bounds bounds_;
  float worldMargin_ = 0.0f;  ///< > 0: the screen tracer answers in world space (see the constructor)
  bool uncertainEmptySpace_ = false;

  struct Scratch {
    std::vector<Ray> screenRays;
    std::vector<TraceHit> screenHits;
    /// The queued geometric segments: whole rays (maxDistance = the segment's end), where each
    /// starts, and the ray each belongs to; the answers of geoQuery.
    std::vector<Ray> geoRays;
    std::vector<float> geoFrom;
    std::vector<uint32_t> geoIndex;
    std::vector<GeoHit> geoBare;
    std::vector<uint8_t> geoBlocked;
    std::vector<float> from;  ///< per ray: where geometry must take over (+∞: answered)
    std::vector<float> windowEnd;  ///< per ray: where the origin's geometric window ends (≤ 0: none)
    std::vector<ScreenSegment> segs;  ///< per ray: its screen segment (where a window or a check needs it)
    std::vector<KnownSpace::Boundary> boundaries;
    std::vector<GeoHit> best;
    std::vector<RayCounters> geoCounters;
  };
  mutable tbb::enumerable_thread_specific<Scratch> scratch_;
  struct Sums {
    uint64_t rays = 0, screenHits = 0, certainMisses = 0, geoRays = 0, rejectedHits = 0, windowQueries = 0;
    double geoLengthSum = 0.0, screenMs = 0.0, windowMs = 0.0, geoMs = 0.0;
  };
  mutable tbb::enumerable_thread_specific<Sums> sums_;
};

}  // namespace lt
