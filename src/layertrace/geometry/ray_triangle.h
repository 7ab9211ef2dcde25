// One ray against one triangle: the test the irregular grid and the hybrid's local checks share.
#pragma once

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace lt {

/// Möller–Trumbore with edges widened by a few ulps of the barycentrics (1e-6): a ray through
/// a shared edge or vertex hits at least one of the triangles there instead of slipping
/// through a rounding crack (Embree's robust mode gives the same guarantee). The triangle is
/// v0 + a e1 + b e2; true with t in [tmin, tmax].
inline bool hitTriangle(glm::vec3 o, glm::vec3 d, glm::vec3 v0, glm::vec3 e1, glm::vec3 e2, float tmin, float tmax, float& t) {
  const glm::vec3 p = glm::cross(d, e2);
  const float det = glm::dot(e1, p);
  if (det == 0.0f) return false;
  const float inv = 1.0f / det;
  const glm::vec3 s = o - v0;
  const float u = glm::dot(s, p) * inv;
  constexpr float eps = 1e-6f;
  if (u < -eps || u > 1.0f + eps) return false;
  const glm::vec3 q = glm::cross(s, e1);
  const float v = glm::dot(d, q) * inv;
  if (v < -eps || u + v > 1.0f + eps) return false;
  t = glm::dot(e2, q) * inv;
  return t >= tmin && t <= tmax;
}

}  // namespace lt
