#include "layertrace/hybrid/hybrid_tracer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "layertrace/geometry/ray_triangle.h"
#include "layertrace/screen/screen_segment.h"

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
                           const Tracer& screen, const Tracer& geo)
    : scene_(scene),
      camera_(camera),
      layers_(layers),
      known_(known),
      screen_(screen),
      geo_(geo),
      hits_(scene, camera),
      bounds_(scene.bounds()) {}

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

GeoHit HybridTracer::originHit(const Ray& ray, glm::vec3 o, glm::vec3 d, float tmin) const {
  GeoHit best;
  int x, y;
  if (!ray.startsOnSurface || !camera_.pixelOf(ray.origin, x, y)) return best;
  const float tmax = rayParamsAroundPixel(camera_, ray, x, y, kPixelMargin).after;
  const uint32_t* tris = &layers_.triangle[layers_.pixelIndex(x, y) * size_t(layers_.k)];
  for (int i = 0; i < layers_.countAt(x, y); ++i) {
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

void HybridTracer::run(Query q, std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  const auto t0 = std::chrono::steady_clock::now();
  Scratch& s = scratch_.local();
  Sums& sum = sums_.local();
  const size_t n = rays.size();
  const bool counted = kCountersCompiled && !counters.empty();
  // 1–2: where knowledge ends, and the screen tracer inside it.
  s.screenRays.assign(rays.begin(), rays.end());
  s.screenHits.resize(n);
  s.geoStart.resize(n);
  NoCounters none;
  for (size_t i = 0; i < n; ++i) {
    const KnownSpace::Boundary b = counted ? known_.boundary(rays[i], counters[i]) : known_.boundary(rays[i], none);
    s.screenRays[i].maxDistance = std::min(rays[i].maxDistance, b.knownUntil);
    s.geoStart[i] = b.certain(rays[i]) ? kInf : b.geoFrom;
  }
  screen_.query(q, s.screenRays, s.screenHits, counters);
  // 3–6: check screen hits exactly; collect what geometry must answer.
  s.geoRays.clear();
  s.geoIndex.clear();
  s.best.assign(n, GeoHit{});
  uint64_t screenHits = 0, certainMisses = 0, rejected = 0;
  double geoLength = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const Ray& r = rays[i];
    const glm::vec3 o = camera_.toWorld(r.origin), d = camera_.dirToWorld(r.dir);
    const float tmin = GeometricHits::originOffset(r);
    GeoHit& best = s.best[i];
    best = originHit(r, o, d, tmin);
    float from = s.geoStart[i];
    const TraceHit& sh = s.screenHits[i];
    if (sh.hit) {
      // 3: the ray against the triangle the screen tracer reported, anywhere up to the pixel
      // after the hit pixel (a grazing ray may meet it a few pixels before its samples say so).
      const ParamSpan span = rayParamsAroundPixel(camera_, r, sh.x, sh.y, kPixelMargin);
      float t;
      if (hitsTriangle(o, d, sh.triangle, tmin, span.after, t)) {
        if (!best.hit() || t < best.t) best.t = t, best.triangle = sh.triangle;
        from = kInf;
      } else {
        // The ray passed behind the stored surface (a thickness false hit) or met a neighbour
        // of the sampled triangle: geometry takes over shortly before the hit pixel.
        ++rejected;
        from = span.before;
      }
    }
    const float end = best.hit() ? best.t : r.maxDistance;
    if ((q == Query::Any && best.hit()) || !(from < end)) {
      if (best.hit()) ++screenHits;
      else ++certainMisses;
      continue;
    }
    Ray g = r;
    g.origin = r.origin + r.dir * from;
    g.maxDistance = end - from;
    g.startsOnSurface = false;
    s.geoRays.push_back(g);
    s.geoIndex.push_back(uint32_t(i));
    const float inScene = lengthInScene(o, d, r.maxDistance);
    geoLength += inScene > from ? double(std::min(end, inScene) - from) / double(inScene) : 0.0;
  }
  const auto t1 = std::chrono::steady_clock::now();
  // 5: the geometric tracer on the unknown remainders.
  s.geoHits.resize(s.geoRays.size());
  if (counted) {
    std::vector<RayCounters>& gc = s.geoCounters;
    gc.assign(s.geoRays.size(), RayCounters{});
    geo_.query(q, s.geoRays, s.geoHits, gc);
    for (size_t j = 0; j < gc.size(); ++j) {
      RayCounters& c = counters[s.geoIndex[j]];
      c.addIterations(gc[j].iterations);
      c.giveUps += gc[j].giveUps;
    }
  } else {
    geo_.query(q, s.geoRays, s.geoHits, {});
  }
  const auto t2 = std::chrono::steady_clock::now();
  for (size_t i = 0; i < n; ++i) {
    const GeoHit& b = s.best[i];
    hits[i] = !b.hit() ? TraceHit{} : q == Query::Any ? GeometricHits::occludedHit(true) : hits_.makeHit(rays[i], b);
  }
  for (size_t j = 0; j < s.geoRays.size(); ++j)
    if (s.geoHits[j].hit) hits[s.geoIndex[j]] = s.geoHits[j];
  sum.rays += n;
  sum.screenHits += screenHits;
  sum.certainMisses += certainMisses;
  sum.geoRays += s.geoRays.size();
  sum.rejectedHits += rejected;
  sum.geoLengthSum += geoLength;
  sum.screenMs += msBetween(t0, t1);
  sum.geoMs += msBetween(t1, t2);
}

HybridStats HybridTracer::stats() const {
  HybridStats h;
  for (const Sums& s : sums_) {
    h.rays += s.rays;
    h.screenHits += s.screenHits;
    h.certainMisses += s.certainMisses;
    h.geoRays += s.geoRays;
    h.rejectedHits += s.rejectedHits;
    h.geoLengthSum += s.geoLengthSum;
    h.screenMs += s.screenMs;
    h.geoMs += s.geoMs;
  }
  return h;
}

void HybridTracer::resetStats() {
  for (Sums& s : sums_) s = Sums{};
}

}  // namespace lt
