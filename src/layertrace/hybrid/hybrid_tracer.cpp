#include "layertrace/hybrid/hybrid_tracer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "layertrace/geometry/ray_triangle.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/util/error.h"
#include "layertrace/util/in_place.h"

namespace lt {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
/// Pixels of screen motion around a pixel that an exact check or a geometric segment covers.
constexpr float kPixelMargin = 2.0f;

double msBetween(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

HybridTracer::HybridTracer(const Scene& scene, const Camera& camera, const LayerArrays& layers, const KnownSpace& known,
                           const Tracer& screen, const GeoHitQueries& geo, float worldMargin, bool uncertainEmptySpace)
    : scene_(scene),
      offsetUnit_(GeometricHits::offsetUnit(scene)),
      camera_(camera),
      layers_(layers),
      known_(known),
      screen_(screen),
      geo_(geo),
      hits_(scene, camera),
      bounds_(scene.bounds()),
      worldMargin_(worldMargin),
      uncertainEmptySpace_(uncertainEmptySpace) {
  LT_CHECK(worldMargin >= 0.0f, worldMargin);
}

TraceHit HybridTracer::trace(const Ray& ray, RayCounters& counters) const {
  TraceHit h;
  run(Query::Closest, std::span<const Ray>(&ray, 1), std::span<TraceHit>(&h, 1), std::span<RayCounters>(&counters, 1));
  return h;
}

void HybridTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  run(Query::Closest, rays, hits, counters);
}

void HybridTracer::occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  run(Query::Any, rays, hits, counters);
}

bool HybridTracer::hitsTriangle(glm::vec3 o, glm::vec3 d, uint32_t tri, float tmin, float tmax, float& t) const {
  if (tri >= scene_.triangles.size()) return false;
  const glm::uvec3 v = scene_.triangles[tri];
  const glm::vec3 a = scene_.positions[v.x];
  return hitTriangle(o, d, a, scene_.positions[v.y] - a, scene_.positions[v.z] - a, tmin, tmax, t);
}

GeoHit HybridTracer::pixelHit(glm::vec3 o, glm::vec3 d, int x, int y, int layers, float tmin, float tmax) const {
  GeoHit best;
  const uint32_t* tris = &layers_.triangle[layers_.pixelIndex(x, y) * size_t(layers_.k)];
  for (int i = 0; i < std::min(layers, layers_.countAt(x, y)); ++i) {
    float t;
    if (hitsTriangle(o, d, tris[i], tmin, best.hit() ? best.t : tmax, t)) best.t = t, best.triangle = tris[i];
  }
  return best;
}

float HybridTracer::lengthInScene(glm::vec3 o, glm::vec3 d, float maxDistance) const {
  float tExit = maxDistance;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0f) continue;
    const float t = ((d[a] > 0.0f ? bounds_.hi[a] : bounds_.lo[a]) - o[a]) / d[a];
    tExit = std::min(tExit, t);
  }
  return tExit > 0.0f ? tExit : maxDistance;
}

Ray HybridTracer::segment(const Ray& ray, float from, float to) {
  Ray g = ray;
  g.origin = ray.origin + ray.dir * from;
  g.maxDistance = std::max(to - from, 0.0f);
  g.startsOnSurface = ray.startsOnSurface && from == 0.0f;
  return g;
}

void HybridTracer::askGeo(Scratch& s, const Ray& ray, size_t i, float from, float to) {
  Ray g = ray;
  g.maxDistance = to;
  s.geoRays.push_back(g);
  s.geoFrom.push_back(from);
  s.geoIndex.push_back(uint32_t(i));
}

void HybridTracer::geoQuery(Query q, Scratch& s, std::span<RayCounters> counters) const {
  const size_t m = s.geoRays.size();
  std::span<RayCounters> gc;
  if (!counters.empty()) s.geoCounters.assign(m, RayCounters{}), gc = s.geoCounters;
  if (q == Query::Closest) s.geoBare.resize(m), geo_.intersectSegments(s.geoRays, s.geoFrom, s.geoBare, gc);
  else s.geoBlocked.resize(m), geo_.occludedSegments(s.geoRays, s.geoFrom, s.geoBlocked, gc);
  for (size_t j = 0; j < gc.size(); ++j) {  // each query's counts go to the ray it belongs to
    RayCounters& c = counters[s.geoIndex[j]];
    c.addIterations(gc[j].iterations);
    c.giveUps += gc[j].giveUps;
  }
}

bool HybridTracer::geoHit(Query q, const Scratch& s, size_t j) {
  return q == Query::Closest ? s.geoBare[j].hit() : s.geoBlocked[j] != 0;
}

void HybridTracer::run(Query q, std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  Scratch& s = scratch_.local();
  Sums& sum = sums_.local();
  const size_t n = rays.size();
  if (!kCountersCompiled) counters = {};
  // 1–2: where knowledge ends, and the screen tracer inside it.
  s.screenRays.assign(rays.begin(), rays.end());
  s.screenHits.resize(n);
  s.from.resize(n);
  s.best.assign(n, GeoHit{});
  const bool world = worldMargin_ > 0.0f;
  if (world) std::fill(s.from.begin(), s.from.end(), kInf);  // the screen tracer knows all space
  s.segs.resize(n);
  bool segsMade = false;  // by the known space, which makes them anyway
  if (!world) {
    s.boundaries.resize(n);
    if (counters.empty()) known_.boundaries(rays, s.boundaries, s.segs), segsMade = true;
    else
      for (size_t i = 0; i < n; ++i) s.boundaries[i] = known_.boundary(rays[i], counters[i]);
  }
  // 6: the ray's own pixel, which screen tracers skip, up to two pixels past it is answered by a
  // geometric window (a world tracer: at least worldMargin, past the texel it skips). The screen
  // march starts where that window ends: a hit inside it would be the window's to
  // find, and a ray leaving a surface overlaps that surface's solid interval, which starts at its
  // nearest depth in each pixel (known_space.h), for a pixel or two — 74 % of the screen hits of
  // FZK-Haus's reflection rays lay inside the window and were rejected by the exact check.
  s.windowEnd.assign(n, -1.0f);
  for (size_t i = 0; i < n; ++i) {
    const Ray& r = rays[i];
    int x, y;
    const bool onScreen = r.startsOnSurface && camera_.pixelOf(r.origin, x, y);
    // The ray's pixels, made once: for the origin's window and a screen hit's check (a world
    // tracer's hits need none).
    if (!segsMade && (onScreen || !world)) s.segs[i] = makeScreenSegment(camera_, r);
    if (onScreen) s.windowEnd[i] = std::max(rayParamAfterPixel(camera_, r, s.segs[i], x, y, kPixelMargin), worldMargin_);
    else if (world && r.startsOnSurface) s.windowEnd[i] = worldMargin_;
  }
  for (size_t i = 0; i < n && !world; ++i) {
    const KnownSpace::Boundary& b = s.boundaries[i];
    const float end = std::min(rays[i].maxDistance, b.knownUntil);
    if (s.windowEnd[i] > 0.0f) s.screenRays[i] = segment(rays[i], std::min(s.windowEnd[i], end), end);
    else s.screenRays[i].maxDistance = end;
    s.from[i] = b.certain(rays[i]) ? kInf : b.geoFrom;
  }
  screen_.batch(q, s.screenRays, s.screenHits, counters);
  // 3 and 6: the exact checks, and the windows geometry certifies. A window query is short —
  // a few pixels of the ray — and costs a fraction of a whole geometric ray.
  s.geoRays.clear();
  s.geoFrom.clear();
  s.geoIndex.clear();
  uint64_t rejected = 0;
  const auto originWindow = [&](size_t i) {  // 6
    if (s.windowEnd[i] > 0.0f) askGeo(s, rays[i], i, 0.0f, s.windowEnd[i]);
  };
  for (size_t i = 0; i < n; ++i) {
    const Ray& r = rays[i];
    const TraceHit& sh = s.screenHits[i];
    if (!sh.hit || world) originWindow(i);
    if (!sh.hit) continue;
    if (world) {
      // A world-space hit lies on its sample's triangle plane within the sample's widened
      // texel: geometry over worldMargin either side of it finds that surface, or a neighbour
      // the texels missed, with the geometric tracer's own rules (a ray sliding in a wall's
      // plane crosses it for the texels, not for Embree). A window that finds nothing rejects
      // the hit, and geometry answers the ray from its origin.
      const float tScreen = glm::dot(sh.point - r.origin, r.dir);
      s.from[i] = 0.0f;
      const float from = uncertainEmptySpace_ ? 0.0f : std::max(0.0f, tScreen - worldMargin_);
      askGeo(s, r, i, from, std::min(tScreen + worldMargin_, r.maxDistance));
      continue;
    }
    // 3: the ray against the triangles of the hit pixel's layers up to the hit one, anywhere
    // up to two pixels past the hit pixel (a grazing ray meets the surface a few pixels before
    // its samples say so).
    const ParamSpan span = rayParamsAroundPixel(camera_, r, s.segs[i], sh.x, sh.y, kPixelMargin);
    const GeoHit v = pixelHit(camera_.toWorld(r.origin), camera_.dirToWorld(r.dir), sh.x, sh.y, sh.layer + 1,
                              GeometricHits::originOffset(r, offsetUnit_), span.after);
    // No crossing: the ray passed behind the stored surface (a thickness false hit) or met a
    // neighbour of the sampled triangle. It got behind a surface without a crossing where the
    // samples looked, so the march's "empty so far" is not to be trusted for this ray either:
    // geometry answers it from the origin (measured: from two pixels before the hit pixel
    // instead, 3× the wrong answers on FZK-Haus and 2× on am_thornish, for 4 % less time). That
    // geometric ray covers the origin's window too, which is then not asked (measured: 40 % of
    // FZK-Haus's one-bounce reflection rays; with the windows' bare hits, the hybrid went from
    // 0.370× to 0.423× plain Embree's speed there, medians of 4 alternating runs).
    s.from[i] = 0.0f;
    if (!v.hit()) continue;
    originWindow(i);
    // A crossing is a candidate, not the answer (our ray–triangle test and Embree's
    // can disagree on a triangle's edge; on assimp's regr01.obj 0.15 % of reflection rays took a
    // crossing Embree does not see). Geometry over the window from two pixels before the hit
    // pixel (or the crossing, if earlier; the origin where empty space is uncertain) to two pixels
    // past it (or just past the crossing, if later), never beyond the ray's end, decides: its
    // nearest hit is the answer — a neighbour triangle the samples missed may come first — and
    // nothing there rejects the hit like a missing crossing.
    const float to = std::min(std::max(span.after, v.t * (1.0f + 1e-5f)), r.maxDistance);
    askGeo(s, r, i, uncertainEmptySpace_ ? 0.0f : std::min(v.t, span.before), to);
  }
  sum.windowQueries += s.geoRays.size();
  const auto t1 = Clock::now();
  // A window's hit is the answer: the origin window precedes everything else on the ray, and
  // the space before a hit window is known to be empty. Its t is the whole ray's (GeoHitQueries).
  geoQuery(q, s, counters);
  for (size_t j = 0; j < s.geoRays.size(); ++j) {
    if (!geoHit(q, s, j)) continue;
    const uint32_t i = s.geoIndex[j];
    GeoHit& b = s.best[i];
    s.from[i] = kInf;
    if (q == Query::Any) b.t = 0.0f, b.triangle = 0;  // occluded: any-hit answers name no blocker (trace/tracer.h)
    else if (const GeoHit& g = s.geoBare[j]; !b.hit() || g.t <= b.t) b = g;
  }
  const auto t2 = Clock::now();
  // 4–5: certain misses are answered; the rest goes to geometry from where knowledge ended.
  s.geoRays.clear();
  s.geoFrom.clear();
  s.geoIndex.clear();
  uint64_t screenHits = 0, certainMisses = 0;
  double geoLength = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const Ray& r = rays[i];
    const GeoHit& b = s.best[i];
    if (s.screenHits[i].hit && s.from[i] == 0.0f) ++rejected;  // no crossing, or its window found nothing
    const float end = b.hit() ? b.t : r.maxDistance;
    // A closest-hit miss in known space returns the environment, the most visible error, and
    // the layers can miss a silhouette thinner than a pixel between two samples: geometry
    // certifies it (0.1 % of reflection rays on am_thornish; it removes two thirds of the false
    // misses there). Any-hit misses (half of all AO and shadow rays) are accepted where the
    // screen tracer marched solid intervals; where it did not (uncertainEmptySpace_: the
    // quad-tree, the layered depth cube), no part of a ray without a checked hit is known to be
    // empty.
    if (q == Query::Closest && !b.hit() && !(s.from[i] < end)) s.from[i] = 0.0f;
    if (uncertainEmptySpace_ && !b.hit()) s.from[i] = 0.0f;
    if ((q == Query::Any && b.hit()) || !(s.from[i] < end)) {
      if (b.hit()) ++screenHits;
      else ++certainMisses;
      continue;
    }
    askGeo(s, r, i, s.from[i], end);
    const float inScene = lengthInScene(camera_.toWorld(r.origin), camera_.dirToWorld(r.dir), r.maxDistance);
    geoLength += inScene > s.from[i] ? double(std::min(end, inScene) - s.from[i]) / double(inScene) : 0.0;
  }
  const auto t3 = Clock::now();
  geoQuery(q, s, counters);
  const auto t4 = Clock::now();
  for (size_t i = 0; i < n; ++i) {
    const GeoHit& b = s.best[i];
    if (!b.hit()) hits[i] = TraceHit{};
    else if (q == Query::Any) hits[i] = GeometricHits::occludedHit(true);
    else assignInPlace(hits[i], [&] { return hits_.makeHit(rays[i], b); });
  }
  for (size_t j = 0; j < s.geoRays.size(); ++j) {
    if (!geoHit(q, s, j)) continue;
    TraceHit& h = hits[s.geoIndex[j]];
    if (q == Query::Any) h = GeometricHits::occludedHit(true);
    else assignInPlace(h, [&] { return hits_.makeHit(rays[s.geoIndex[j]], s.geoBare[j]); });
  }
  sum.rays += n;
  sum.screenHits += screenHits;
  sum.certainMisses += certainMisses;
  sum.geoRays += s.geoRays.size();
  sum.rejectedHits += rejected;
  sum.geoLengthSum += geoLength;
  sum.screenMs += msBetween(t0, t1) + msBetween(t2, t3);
  sum.windowMs += msBetween(t1, t2);
  sum.geoMs += msBetween(t3, t4);
}

HybridStats HybridTracer::stats() const {
  HybridStats h;
  for (const Sums& s : sums_) {
    h.rays += s.rays;
    h.screenHits += s.screenHits;
    h.certainMisses += s.certainMisses;
    h.geoRays += s.geoRays;
    h.rejectedHits += s.rejectedHits;
    h.windowQueries += s.windowQueries;
    h.geoLengthSum += s.geoLengthSum;
    h.screenMs += s.screenMs;
    h.windowMs += s.windowMs;
    h.geoMs += s.geoMs;
  }
  return h;
}

void HybridTracer::addStats(const HybridStats& h) const {
  Sums& s = sums_.local();
  s.rays += h.rays;
  s.screenHits += h.screenHits;
  s.certainMisses += h.certainMisses;
  s.geoRays += h.geoRays;
  s.rejectedHits += h.rejectedHits;
  s.windowQueries += h.windowQueries;
  s.geoLengthSum += h.geoLengthSum;
  s.screenMs += h.screenMs;
  s.windowMs += h.windowMs;
  s.geoMs += h.geoMs;
}

void HybridTracer::resetStats() {
  for (Sums& s : sums_) s = Sums{};
}

}  // namespace lt
