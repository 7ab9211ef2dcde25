#include "layertrace/geometry/geometric_tracer.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "layertrace/raster/fragment.h"
#include "layertrace/scene/surface.h"
#include "layertrace/util/in_place.h"

namespace lt {

GeometricHits::GeometricHits(const Scene& scene, const Camera& camera) : scene_(scene), camera_(&camera), unit_(offsetUnit(scene)) {
  for (const Material& m : scene.materials) packed_.push_back(packAlbedoSpec(m.albedo, m.specular));
}

float GeometricHits::offsetUnit(const Scene& scene) {
  const float d = scene.bounds().diagonal();
  return d > 0.0f ? std::min(1.0f, d) : 1.0f;
}

TraceHit GeometricHits::makeHit(const Ray& ray, const GeoHit& g) const {
  TraceHit h;
  if (!g.hit()) return h;
  h.hit = true;
  h.point = ray.origin + ray.dir * g.t;
  const glm::uvec3 t = scene_.triangles[g.triangle];
  const glm::vec3 pw = camera_->toWorld(h.point);
  // Barycentric interpolation of the vertex normals at the hit.
  const glm::vec3 a = scene_.positions[t.x], b = scene_.positions[t.y], cc = scene_.positions[t.z];
  const glm::vec3 n = glm::cross(b - a, cc - a);
  const float area = glm::dot(n, n);
  glm::vec3 normal = glm::normalize(n);
  float u = 1.0f, v = 0.0f;  // the weights of the first and second vertex
  if (area > 0.0f) {
    u = glm::dot(glm::cross(cc - b, pw - b), n) / area, v = glm::dot(glm::cross(a - cc, pw - cc), n) / area;
    const glm::vec3 s = scene_.normals[t.x] * u + scene_.normals[t.y] * v + scene_.normals[t.z] * (1.0f - u - v);
    if (glm::length(s) > 0.0f) normal = glm::normalize(s);
  }
  h.normal = glm::normalize(camera_->dirToCamera(normal));
  h.albedoSpec = packed_[scene_.triMaterial[g.triangle]];
  if (surfaceTextured(scene_, g.triangle)) {
    // The texture's level of detail as the capture chooses it for a fragment at this point: the
    // frame camera's pixel footprint at the point's depth over the cosine between the geometric
    // normal and the camera's view ray (raster::fragmentAlbedoSpec), so that the reference and
    // the layers sample the same texels.
    const float depth = std::max(-h.point.z, camera_->near());
    const glm::vec3 view = camera_->orthographic() ? glm::vec3(0.0f, 0.0f, -1.0f) : h.point;
    const glm::vec3 nc = camera_->dirToCamera(n);
    const float nl = glm::length(nc), vl = glm::length(view);
    const float cosine = nl > 0.0f && vl > 0.0f ? glm::dot(nc, view) / (nl * vl) : 1.0f;
    h.albedoSpec = packSurfaceColor(surfaceColor(scene_, g.triangle, std::clamp(v, 0.0f, 1.0f), std::clamp(1.0f - u - v, 0.0f, 1.0f),
                                                 textureFootprint(camera_->pixelFootprint(depth), cosine)));
  }
  h.triangle = g.triangle;
  if (h.point.z < 0.0f) {
    const glm::vec2 p = camera_->project(h.point);
    if (p.x >= 0 && p.y >= 0 && p.x < float(camera_->width()) && p.y < float(camera_->height())) h.x = int(p.x), h.y = int(p.y);
  }
  return h;
}

template <class F>
void EmbreePacketTracer::packets(std::span<const Ray> rays, std::span<const float> from, F f) const {
  const Camera& cam = single_.hits().camera();
  for (size_t b = 0; b < rays.size(); b += 16) {
    const size_t n = std::min<size_t>(16, rays.size() - b);
    glm::vec3 o[16], d[16];
    float tnear[16], tfar[16];
    for (size_t i = 0; i < n; ++i) {
      const Ray& r = rays[b + i];
      o[i] = cam.toWorld(r.origin), d[i] = cam.dirToWorld(r.dir);
      tnear[i] = segmentStart(startOf(from, b + i), single_.hits().originOffset(r), o[i]), tfar[i] = r.maxDistance;
    }
    f(o, d, tnear, tfar, n, b);
  }
}

void EmbreePacketTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return TracerImpl::traceBatch(rays, hits, counters);
  packets(rays, {}, [&](const glm::vec3* o, const glm::vec3* d, const float* tnear, const float* tfar, size_t n, size_t b) {
    GeoHit g[16];
    embree_.intersectPackets(o, d, tnear, tfar, n, g);
    for (size_t i = 0; i < n; ++i) assignInPlace(hits[b + i], [&] { return single_.hits().makeHit(rays[b + i], g[i]); });
  });
}

void EmbreePacketTracer::intersectSegments(std::span<const Ray> rays, std::span<const float> from, std::span<GeoHit> hits,
                                           std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return single_.intersectSegments(rays, from, hits, counters);
  packets(rays, from, [&](const glm::vec3* o, const glm::vec3* d, const float* tnear, const float* tfar, size_t n, size_t b) {
    embree_.intersectPackets(o, d, tnear, tfar, n, &hits[b]);
  });
}

void EmbreePacketTracer::occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return TracerImpl::occludedBatch(rays, hits, counters);
  packets(rays, {}, [&](const glm::vec3* o, const glm::vec3* d, const float* tnear, const float* tfar, size_t n, size_t b) {
    bool blocked[16];
    embree_.occludedPackets(o, d, tnear, tfar, n, blocked);
    for (size_t i = 0; i < n; ++i) hits[b + i] = GeometricHits::occludedHit(blocked[i]);
  });
}

void EmbreePacketTracer::occludedSegments(std::span<const Ray> rays, std::span<const float> from, std::span<uint8_t> blocked,
                                          std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return single_.occludedSegments(rays, from, blocked, counters);
  packets(rays, from, [&](const glm::vec3* o, const glm::vec3* d, const float* tnear, const float* tfar, size_t n, size_t b) {
    bool any[16];
    embree_.occludedPackets(o, d, tnear, tfar, n, any);
    for (size_t i = 0; i < n; ++i) blocked[b + i] = any[i];
  });
}

}  // namespace lt
