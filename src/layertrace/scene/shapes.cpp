#include <cmath>
#include <utility>

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>
#include <glm/gtc/matrix_inverse.hpp>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"

namespace lt {

namespace {
void addQuad(Scene& s, glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, glm::vec3 n) {
  const auto base = uint32_t(s.positions.size());
  for (glm::vec3 p : {a, b, c, d}) {
    s.positions.push_back(p);
    s.normals.push_back(n);
  }
  s.triangles.push_back({base, base + 1, base + 2});
  s.triangles.push_back({base, base + 2, base + 3});
  s.triMaterial.push_back(0);
  s.triMaterial.push_back(0);
}
}  // namespace

Scene makeQuad(glm::vec3 corner, glm::vec3 u, glm::vec3 v) {
  Scene s;
  const glm::vec3 n = glm::cross(u, v);
  if (!(glm::length(n) > 0.0f)) inputError("quad: edges u and v are parallel or zero");
  addQuad(s, corner, corner + u, corner + u + v, corner + v, glm::normalize(n));
  s.materials.push_back(Material{"default"});
  return s;
}

Scene makeBox(glm::vec3 lo, glm::vec3 hi) {
  if (!(hi.x > lo.x && hi.y > lo.y && hi.z > lo.z)) inputError("box: max must exceed min on every axis");
  Scene s;
  const glm::vec3 e = hi - lo;
  const glm::vec3 X(e.x, 0, 0), Y(0, e.y, 0), Z(0, 0, e.z);
  addQuad(s, lo, lo + Y, lo + Y + X, lo + X, {0, 0, -1});           // z = lo
  addQuad(s, lo + Z, lo + Z + X, lo + Z + X + Y, lo + Z + Y, {0, 0, 1});  // z = hi
  addQuad(s, lo, lo + Z, lo + Z + Y, lo + Y, {-1, 0, 0});           // x = lo
  addQuad(s, lo + X, lo + X + Y, lo + X + Y + Z, lo + X + Z, {1, 0, 0});  // x = hi
  addQuad(s, lo, lo + X, lo + X + Z, lo + Z, {0, -1, 0});           // y = lo
  addQuad(s, lo + Y, lo + Y + Z, lo + Y + Z + X, lo + Y + X, {0, 1, 0});  // y = hi
  s.materials.push_back(Material{"default"});
  return s;
}

Scene makeSphere(glm::vec3 center, float radius, int segments) {
  if (!(radius > 0.0f)) inputError("sphere: radius ", radius, " must be positive");
  if (segments < 3 || segments > 4096) inputError("sphere: segments ", segments, " not in [3, 4096]");
  Scene s;
  const int rings = segments / 2 + 1;
  const uint64_t vertices = uint64_t(rings + 1) * uint64_t(segments + 1), triangles = 2 * uint64_t(rings) * uint64_t(segments);
  checkAllocation(cat("sphere of ", segments, " segments (", triangles, " triangles)"),
                  vertices * 2 * sizeof(glm::vec3) + triangles * (sizeof(glm::uvec3) + sizeof(uint32_t)));
  for (int r = 0; r <= rings; ++r) {
    const float theta = glm::pi<float>() * float(r) / float(rings);
    for (int k = 0; k <= segments; ++k) {
      const float phi = 2.0f * glm::pi<float>() * float(k) / float(segments);
      const glm::vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi));
      s.positions.push_back(center + radius * n);
      s.normals.push_back(n);
    }
  }
  const auto row = uint32_t(segments + 1);
  for (uint32_t r = 0; r < uint32_t(rings); ++r)
    for (uint32_t k = 0; k < uint32_t(segments); ++k) {
      const uint32_t a = r * row + k, b = a + 1, c = a + row, d = c + 1;
      if (r != 0) s.triangles.push_back({a, b, c});
      if (r + 1 != uint32_t(rings)) s.triangles.push_back({b, d, c});
    }
  s.triMaterial.assign(s.triangles.size(), 0);
  s.materials.push_back(Material{"default"});
  return s;
}

void transformScene(Scene& scene, const glm::mat4& m) {
  const glm::mat3 nm = glm::inverseTranspose(glm::mat3(m));
  for (glm::vec3& p : scene.positions) p = glm::vec3(m * glm::vec4(p, 1.0f));
  for (glm::vec3& n : scene.normals) {
    const glm::vec3 t = nm * n;
    const float len = glm::length(t);
    n = len > 0.0f ? t / len : n;
  }
  // A mirroring transform (negative determinant) reverses the winding: swap two corners so each
  // triangle keeps its front face (what --front-faces-only and back-face tests read).
  if (glm::determinant(glm::mat3(m)) < 0.0f)
    for (glm::uvec3& t : scene.triangles) std::swap(t.y, t.z);
  for (PointLight& l : scene.lights) l.position = glm::vec3(m * glm::vec4(l.position, 1.0f));
  for (CameraDesc& c : scene.cameras) {
    c.eye = glm::vec3(m * glm::vec4(c.eye, 1.0f));
    c.target = glm::vec3(m * glm::vec4(c.target, 1.0f));
    c.up = glm::normalize(glm::vec3(m * glm::vec4(c.up, 0.0f)));
  }
}

}  // namespace lt
