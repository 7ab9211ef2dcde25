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

}  // namespace lt
