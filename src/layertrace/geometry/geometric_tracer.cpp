#include "layertrace/geometry/geometric_tracer.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "layertrace/raster/fragment.h"

namespace lt {

GeometricHits::GeometricHits(const Scene& scene, const Camera& camera) : scene_(scene), camera_(camera) {
  for (const Material& m : scene.materials) packed_.push_back(packAlbedoSpec(m.albedo, m.specular));
}

float GeometricHits::originOffset(const Ray& ray) { return 1e-4f * std::max(1.0f, glm::length(ray.origin)); }

TraceHit GeometricHits::makeHit(const Ray& ray, const GeoHit& g) const {
  TraceHit h;
  if (!g.hit()) return h;
  h.hit = true;
  h.point = ray.origin + ray.dir * g.t;
  const glm::uvec3 t = scene_.triangles[g.triangle];
  const glm::vec3 pw = camera_.toWorld(h.point);
  // Barycentric interpolation of the vertex normals at the hit.
  const glm::vec3 a = scene_.positions[t.x], b = scene_.positions[t.y], cc = scene_.positions[t.z];
  const glm::vec3 n = glm::cross(b - a, cc - a);
  const float area = glm::dot(n, n);
  glm::vec3 normal = glm::normalize(n);
  if (area > 0.0f) {
    const float u = glm::dot(glm::cross(cc - b, pw - b), n) / area, v = glm::dot(glm::cross(a - cc, pw - cc), n) / area;
    const glm::vec3 s = scene_.normals[t.x] * u + scene_.normals[t.y] * v + scene_.normals[t.z] * (1.0f - u - v);
    if (glm::length(s) > 0.0f) normal = glm::normalize(s);
  }
  h.normal = glm::normalize(camera_.dirToCamera(normal));
  h.albedoSpec = packed_[scene_.triMaterial[g.triangle]];
  h.triangle = g.triangle;
  if (h.point.z < 0.0f) {
    const glm::vec2 p = camera_.project(h.point);
    if (p.x >= 0 && p.y >= 0 && p.x < float(camera_.width()) && p.y < float(camera_.height())) h.x = int(p.x), h.y = int(p.y);
  }
  return h;
}

void EmbreePacketTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  if (kCountersCompiled && !counters.empty()) return TracerImpl::traceBatch(rays, hits, counters);
  const GeometricHits& h = single_.hits();
  const Camera& cam = h.camera();
  for (size_t b = 0; b < rays.size(); b += 16) {
    const size_t n = std::min<size_t>(16, rays.size() - b);
    glm::vec3 o[16], d[16];
    float tnear[16], tfar[16];
    GeoHit g[16];
    for (size_t i = 0; i < n; ++i) {
      const Ray& r = rays[b + i];
      o[i] = cam.toWorld(r.origin), d[i] = cam.dirToWorld(r.dir);
      tnear[i] = GeometricHits::originOffset(r), tfar[i] = r.maxDistance;
    }
    embree_.intersectPackets(o, d, tnear, tfar, n, g);
    for (size_t i = 0; i < n; ++i) hits[b + i] = h.makeHit(rays[b + i], g[i]);
  }
}

}  // namespace lt
