// The trace layer: what every tracer is and what it answers (docs/architecture.md).
//
// Layer: trace/ holds the ray and hit types, the per-ray counters and the Tracer interface —
// nothing that knows how a ray is answered. It may include util/ and scene/ only (plus the
// standard library and glm). The screen-space tracers (ssr/, hssr/, hiz/, quadtree/, ldc/, over
// the shared image-space pieces of screen/) and the geometric ones (geometry/: Embree; grid/:
// the irregular grid) implement the interface and never include each other; hybrid/ composes
// one of each; render/ traces through it without knowing which tracer runs; eval/ observes the
// rays it traces.
//
// The one question: given a camera-space ray and a maximum distance, which stored
// surface does it hit first, if any? Screen-space tracers answer from the layer arrays, geometric
// tracers from the triangles.
#pragma once

#include <algorithm>
#include <cstdint>
#include <new>
#include <span>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace lt {

/// A camera-space ray (camera.h: looking down -z, depth = -z).
struct Ray {
  glm::vec3 origin{0.0f};            ///< camera space, on a visible surface
  glm::vec3 dir{0.0f, 0.0f, -1.0f};  ///< camera space, unit length
  float maxDistance = 1e30f;         ///< the ray ends here (scene units)
  /// The origin lies on a stored surface (a secondary ray): image-space tracers skip its own
  /// pixel (Hofmann et al. 2017, §5.1). False for rays from free space (a camera's eye, view
  /// synthesis): their first pixel is tested like any other.
  bool startsOnSurface = true;
  /// The scene triangle the ray leaves (a secondary ray), or kNoTriangle. Tracer::query never
  /// answers with it (continuePastOrigin).
  uint32_t originTriangle = 0xFFFFFFFFu;
};
inline constexpr uint32_t kNoTriangle = 0xFFFFFFFFu;

/// The surface hit: enough to shade it and to start the next bounce.
struct TraceHit {
  bool hit = false;
  int x = -1, y = -1;     ///< pixel of the hit fragment (screen tracers); projected pixel or -1 (geometric)
  int layer = -1;         ///< layer index of the hit fragment (screen tracers)
  glm::vec3 point{0.0f};  ///< camera-space hit point
  glm::vec3 normal{0.0f, 0.0f, 1.0f};  ///< camera-space shading normal (as stored; not flipped)
  uint32_t albedoSpec = 0;             ///< packed albedo + specular (fragment format)
  uint32_t triangle = 0xFFFFFFFFu;     ///< scene triangle (material lookup, evaluation)
};

#ifndef LAYERTRACE_COUNTERS
#define LAYERTRACE_COUNTERS 1
#endif
/// False in a build configured with LAYERTRACE_COUNTERS=OFF: every tracer then runs the
/// NoCounters instantiation of its traversal even when counters are asked for.
inline constexpr bool kCountersCompiled = LAYERTRACE_COUNTERS != 0;

/// Per-ray traversal counters (one unit for every tracer: one iteration = one visited cell at any
/// level for HSSR, one step for SSR, one visited cell or BVH query for geometric tracers; intervals
/// counted at every visited cell). Tracers count through the methods, which NoCounters
/// implements as no-ops, so the traversal instantiated with NoCounters has no counter code.
struct RayCounters {
  static constexpr int kLevels = 8;  ///< per-level counts kept for levels 0..7 (higher ones go to 7)
  static constexpr bool kEnabled = true;
  uint32_t iterations = 0;
  uint32_t intervals = 0;
  uint32_t pixels = 0;  ///< visited level-0 pixels (screen tracers)
  /// The stored fragments (level-0 intervals) tested at those pixels: fragments / pixels is
  /// Hofmann et al.'s "fragments per visited pixel" (§6), the same quantity for SSR and HSSR
  /// (whose `intervals` also count the coarse cells' intervals).
  uint32_t fragments = 0;
  uint32_t giveUps = 0;  ///< traversals stopped by a step cap (an answer not backed by the data)
  uint32_t levelIterations[kLevels] = {};  ///< HSSR: visited cells per pyramid level
  uint32_t planeNodes = 0;   ///< quadtree: visited plane nodes (the other visits are AABB or empty nodes)
  uint32_t boxNodes = 0;     ///< quadtree: visited AABB nodes
  uint32_t occlusions = 0;   ///< quadtree: occlusion hits (the ray went behind a stored surface)

  void iteration(int level = 0) {
    ++iterations;
    ++levelIterations[level < kLevels ? level : kLevels - 1];
  }
  void addIterations(uint32_t n) { iterations += n, levelIterations[0] += n; }
  void interval() { ++intervals; }
  void pixel() { ++pixels; }
  void fragment() { ++fragments; }
  void giveUp() { ++giveUps; }
  void planeNode() { ++planeNodes; }
  void boxNode() { ++boxNodes; }
  void occlusion() { ++occlusions; }
  RayCounters& operator+=(const RayCounters& o) {
    iterations += o.iterations, intervals += o.intervals, pixels += o.pixels, fragments += o.fragments, giveUps += o.giveUps;
    for (int l = 0; l < kLevels; ++l) levelIterations[l] += o.levelIterations[l];
    planeNodes += o.planeNodes, boxNodes += o.boxNodes, occlusions += o.occlusions;
    return *this;
  }
};

/// The counter type of timing runs: the same calls, no code.
struct NoCounters {
  static constexpr bool kEnabled = false;
  void iteration(int = 0) {}
  void addIterations(uint32_t) {}
  void interval() {}
  void pixel() {}
  void fragment() {}
  void giveUp() {}
  void planeNode() {}
  void boxNode() {}
  void occlusion() {}
};

/// The strict classes of an image-space answer graded against the geometric one (eval/classify.h
/// states the rules; docs/evaluation.md).
enum class RayClass : uint8_t {
  CorrectHit,
  WrongHitThickness,
  WrongHitUnstored,
  WrongHitOther,
  FalseMiss,
  OriginPixelMiss,
  InfoMiss,
  CorrectMiss,
};
inline constexpr int kRayClasses = 8;

/// What a query asks: the closest hit (shading, reflection) or any hit before maxDistance
/// (shadow, AO), where a tracer may stop at the first surface it meets.
enum class Query : uint8_t { Closest, Any };

class Tracer {
 public:
  virtual ~Tracer() = default;
  virtual const char* name() const = 0;

  /// One ray, closest hit, counted into `counters` (added to what it holds). The simple path:
  /// every batched or specialised path is tested against it.
  virtual TraceHit trace(const Ray& ray, RayCounters& counters) const = 0;

  /// A batch of closest-hit queries: hits[i] answers rays[i]. `counters` is either empty (the
  /// rays are not counted: timing runs take the counter-free path) or one per ray, added to.
  /// The default loops over trace(); a tracer overrides it to trace rays in groups.
  virtual void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const;

  /// A batch of any-hit queries: hits[i].hit says whether anything lies on rays[i] before its
  /// maxDistance. The other fields describe a blocker where the tracer knows one (screen
  /// tracers report the first stored fragment; Embree's any-hit query reports none). The
  /// default answers with traceBatch.
  virtual void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
    traceBatch(rays, hits, counters);
  }

  /// Dispatches to traceBatch or occludedBatch, then applies the origin rule: an answer on the
  /// ray's own triangle (Ray::originTriangle) is replaced by the answer of the rest of the ray
  /// (continuePastOrigin), up to kOriginSkips times, then by a miss. Counters add up over the
  /// continuations. Renderers and the oracles' observers ask through query, so every answer and
  /// every verdict follows the same rule.
  void query(Query q, std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const;

  /// traceBatch or occludedBatch, without the origin rule: for a tracer composed of others (the
  /// hybrid asks its screen part through it; the rule applies to the composite's answers).
  void batch(Query q, std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
    if (q == Query::Any) occludedBatch(rays, hits, counters);
    else traceBatch(rays, hits, counters);
  }
};

/// Continuations of one ray past a hit on its own triangle before it counts as a miss.
inline constexpr int kOriginSkips = 4;

/// A ray leaving a triangle cannot meet that (planar) triangle again, yet an image-space tracer
/// reports it where the ray skims the surface within a sample's thickness (interpolated normals
/// on big flat faces), and a geometric one may at a distance of rounding error. As Embree users
/// skip the origin primitive, the answer is then what the rest of the ray meets: `next` is the
/// same ray from the hit's distance along it on, starting on a surface (so an image-space tracer
/// skips the hit's pixel). Returns false when `hit` is not on the ray's origin triangle, or when
/// nothing of the ray is left.
inline bool continuePastOrigin(const Ray& ray, const TraceHit& hit, Ray& next) {
  if (!hit.hit || ray.originTriangle == kNoTriangle || hit.triangle != ray.originTriangle) return false;
  const float t = std::max(glm::dot(hit.point - ray.origin, ray.dir), 0.0f);
  next = ray;
  next.origin = ray.origin + ray.dir * t;
  next.maxDistance = ray.maxDistance - t;
  next.startsOnSurface = true;
  return next.maxDistance > 0.0f;
}

/// Whether `hit` answers `ray` under the origin rule (not on the ray's own triangle).
inline bool onOriginTriangle(const Ray& ray, const TraceHit& hit) {
  return hit.hit && ray.originTriangle != kNoTriangle && hit.triangle == ray.originTriangle;
}

inline void Tracer::query(Query q, std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  batch(q, rays, hits, counters);
  std::vector<size_t> pending;
  for (size_t i = 0; i < rays.size(); ++i)
    if (onOriginTriangle(rays[i], hits[i])) pending.push_back(i);
  std::vector<size_t> index;
  std::vector<Ray> next;
  std::vector<TraceHit> answers;
  std::vector<RayCounters> cost;
  for (int round = 0; round < kOriginSkips && !pending.empty(); ++round) {
    index.clear(), next.clear();
    for (size_t i : pending) {
      Ray r;
      if (continuePastOrigin(rays[i], hits[i], r)) index.push_back(i), next.push_back(r);
      else hits[i] = TraceHit{};  // nothing of the ray is left
    }
    answers.assign(next.size(), TraceHit{});
    cost.assign(counters.empty() ? 0 : next.size(), RayCounters{});
    batch(q, next, answers, cost);
    pending.clear();
    for (size_t j = 0; j < index.size(); ++j) {
      hits[index[j]] = answers[j];
      if (!counters.empty()) counters[index[j]] += cost[j];
      if (onOriginTriangle(rays[index[j]], answers[j])) pending.push_back(index[j]);
    }
  }
  for (size_t i : pending) hits[i] = TraceHit{};  // still on its own triangle: a miss
}

inline void Tracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  RayCounters scratch;
  // (each hit constructed in place, as util/in_place.h's assignInPlace does — this header is
  // installed on its own, so it spells the placement new out)
  for (size_t i = 0; i < rays.size(); ++i)
    ::new (static_cast<void*>(&hits[i])) TraceHit(trace(rays[i], counters.empty() ? scratch : counters[i]));
}

/// The tracer implementations' common base (CRTP): Derived provides
///   template <class C> TraceHit traceImpl(const Ray&, C& counters) const;
/// (and optionally occludedImpl) written once against the counter calls; this base
/// instantiates it with RayCounters for counted calls and with NoCounters for uncounted batches
/// (and for everything when counters are compiled out), and runs batches without a virtual call
/// per ray.
template <class Derived>
class TracerImpl : public Tracer {
 public:
  TraceHit trace(const Ray& ray, RayCounters& counters) const override {
    if constexpr (kCountersCompiled) {
      return self().traceImpl(ray, counters);
    } else {
      NoCounters none;
      return self().traceImpl(ray, none);
    }
  }
  void traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override {
    run(rays, hits, counters, [this](const Ray& r, auto& c) { return self().traceImpl(r, c); });
  }
  void occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const override {
    run(rays, hits, counters, [this](const Ray& r, auto& c) { return self().occludedImpl(r, c); });
  }
  /// Default any-hit answer: the closest hit (a screen march meets the first surface first).
  template <class C>
  TraceHit occludedImpl(const Ray& ray, C& counters) const {
    return self().traceImpl(ray, counters);
  }

 private:
  const Derived& self() const { return static_cast<const Derived&>(*this); }
  // (hits constructed in place, as in Tracer::traceBatch)
  template <class F>
  static void run(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters, F&& f) {
    if (kCountersCompiled && !counters.empty()) {
      for (size_t i = 0; i < rays.size(); ++i) ::new (static_cast<void*>(&hits[i])) TraceHit(f(rays[i], counters[i]));
    } else {
      NoCounters none;
      for (size_t i = 0; i < rays.size(); ++i) ::new (static_cast<void*>(&hits[i])) TraceHit(f(rays[i], none));
    }
  }
};

}  // namespace lt
