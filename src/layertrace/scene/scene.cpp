#include "layertrace/scene/scene.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "layertrace/util/error.h"

namespace lt {

void Bounds::extend(glm::vec3 p) {
  lo = glm::min(lo, p);
  hi = glm::max(hi, p);
}

float Bounds::diagonal() const { return empty() ? 0.0f : glm::length(hi - lo); }

float Bounds::farthestFrom(glm::vec3 p) const {
  if (empty()) return 0.0f;
  float farthest = 0.0f;
  for (int i = 0; i < 8; ++i)
    farthest = std::max(farthest, glm::length(glm::vec3((i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z) - p));
  return farthest;
}

Bounds Scene::bounds() const {
  Bounds b;
  for (const glm::uvec3& t : triangles)
    for (int i = 0; i < 3; ++i) b.extend(positions[t[i]]);
  return b;
}

void Scene::append(const Scene& other) {
  const auto vbase = uint32_t(positions.size());
  const auto mbase = uint32_t(materials.size());
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
  normals.insert(normals.end(), other.normals.begin(), other.normals.end());
  normals.resize(positions.size(), glm::vec3(0.0f));
  for (const glm::uvec3& t : other.triangles) triangles.push_back(t + glm::uvec3(vbase));
  for (uint32_t m : other.triMaterial) triMaterial.push_back(m + mbase);
  materials.insert(materials.end(), other.materials.begin(), other.materials.end());
  lights.insert(lights.end(), other.lights.begin(), other.lights.end());
  cameras.insert(cameras.end(), other.cameras.begin(), other.cameras.end());
}

void Scene::finalize(const std::string& source) {
  if (triangles.empty()) inputError("scene ", source, ": contains no triangles");
  if (materials.empty()) materials.push_back(Material{"default"});
  triMaterial.resize(triangles.size(), 0);
  normals.resize(positions.size(), glm::vec3(0.0f));
  const auto nv = uint32_t(positions.size());
  std::vector<glm::vec3> accum(positions.size(), glm::vec3(0.0f));
  for (size_t i = 0; i < triangles.size(); ++i) {
    const glm::uvec3 t = triangles[i];
    if (t.x >= nv || t.y >= nv || t.z >= nv)
      inputError("scene ", source, ": triangle ", i, " has a vertex index beyond ", nv, " vertices");
    if (triMaterial[i] >= materials.size())
      inputError("scene ", source, ": triangle ", i, " has material index ", triMaterial[i]);
    const glm::vec3 n = glm::cross(positions[t.y] - positions[t.x], positions[t.z] - positions[t.x]);
    for (int k = 0; k < 3; ++k) accum[t[k]] += n;
  }
  for (const glm::vec3& p : positions)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      inputError("scene ", source, ": a vertex position is not finite");
  for (size_t v = 0; v < normals.size(); ++v) {
    const float len = glm::length(normals[v]);
    if (!(len > 1e-12f) || !std::isfinite(len)) {
      const float a = glm::length(accum[v]);
      normals[v] = a > 0.0f ? accum[v] / a : glm::vec3(0.0f, 0.0f, 1.0f);
    } else {
      normals[v] /= len;
    }
  }
  const float diagonal = bounds().diagonal();
  if (!std::isfinite(diagonal)) {
    float largest = 0.0f;
    for (const glm::vec3& p : positions) largest = std::max({largest, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
    inputError("scene ", source, ": coordinates up to ", largest, " overflow float arithmetic (the bounding-box diagonal is not finite)");
  }
  if (diagonal <= 0.0f) inputError("scene ", source, ": all vertices coincide");
}

void recentre(Scene& scene) {
  const Bounds b = scene.bounds();
  if (b.empty()) return;
  // The unit: the smallest power of two >= the diagonal (ldexp/frexp are exact).
  int exponent = 0;
  std::frexp(double(std::max(b.diagonal(), 1e-30f)), &exponent);
  const double unit = std::ldexp(1.0, exponent);
  // Per axis: a centre c with |c| >= 4 units moves by s = round(c / unit) · unit. Each vertex v
  // on that axis then has |v| >= 4·unit - unit/2 > 2·unit, so its float spacing is at least
  // 2·unit·2⁻²³, while |v - s| <= unit: v - s is a multiple of v's spacing that needs at most
  // 22 bits, and float(v - s) is exact. Centres nearer than 4 units (<= 8 diagonals) stay.
  glm::dvec3 shift(0.0);
  const glm::vec3 c = b.center();
  for (int a = 0; a < 3; ++a)
    if (std::abs(double(c[a])) >= 4.0 * unit) shift[a] = std::nearbyint(double(c[a]) / unit) * unit;
  if (shift == glm::dvec3(0.0)) return;
  auto move = [&](glm::vec3& p) { p = glm::vec3(glm::dvec3(p) - shift); };
  for (glm::vec3& p : scene.positions) move(p);
  for (PointLight& l : scene.lights) move(l.position);
  for (CameraDesc& d : scene.cameras) move(d.eye), move(d.target);
  scene.origin += shift;
}

}  // namespace lt
