#include "layertrace/scene/scene.h"

#include <algorithm>
#include <cmath>

#include <glm/common.hpp>
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

bool Scene::anyCutOut() const {
  return std::any_of(materials.begin(), materials.end(), [&](const Material& m) { return cutOut(m); });
}

size_t Scene::textureBytes() const {
  size_t bytes = 0;
  for (const auto& t : textures) bytes += t ? t->bytes() : 0;
  return bytes;
}

void Scene::append(const Scene& other) {
  const auto vbase = uint32_t(positions.size());
  const auto mbase = uint32_t(materials.size());
  const auto tbase = int32_t(textures.size());
  // Per-vertex attributes one side lacks read (0, 0) there.
  auto appendCoords = [&](std::vector<glm::vec2>& mine, const std::vector<glm::vec2>& theirs) {
    if (mine.empty() && theirs.empty()) return;
    mine.resize(vbase, glm::vec2(0.0f));
    mine.insert(mine.end(), theirs.begin(), theirs.end());
    mine.resize(vbase + other.positions.size(), glm::vec2(0.0f));
  };
  appendCoords(texcoords, other.texcoords);
  appendCoords(lightmapCoords, other.lightmapCoords);
  positions.insert(positions.end(), other.positions.begin(), other.positions.end());
  normals.insert(normals.end(), other.normals.begin(), other.normals.end());
  normals.resize(positions.size(), glm::vec3(0.0f));
  for (const glm::uvec3& t : other.triangles) triangles.push_back(t + glm::uvec3(vbase));
  for (uint32_t m : other.triMaterial) triMaterial.push_back(m + mbase);
  for (Material m : other.materials) {
    for (int32_t* t : {&m.baseTexture, &m.specularTexture, &m.lightmap})
      if (*t >= 0) *t += tbase;
    materials.push_back(std::move(m));
  }
  textures.insert(textures.end(), other.textures.begin(), other.textures.end());
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
  for (std::vector<glm::vec2>* coords : {&texcoords, &lightmapCoords}) {
    if (coords->empty()) continue;
    coords->resize(positions.size(), glm::vec2(0.0f));
    for (glm::vec2& c : *coords)
      if (!std::isfinite(c.x) || !std::isfinite(c.y)) c = glm::vec2(0.0f);  // a texture coordinate is never worth a failure
  }
  for (Material& m : materials)
    for (int32_t* t : {&m.baseTexture, &m.specularTexture, &m.lightmap})
      if (*t >= int32_t(textures.size()) || (*t >= 0 && !textures[size_t(*t)])) *t = -1;
  triUvScaleLog2.clear();
  if (!texcoords.empty()) {
    triUvScaleLog2.resize(triangles.size());
    for (size_t i = 0; i < triangles.size(); ++i) {
      const glm::uvec3 t = triangles[i];
      const float world = glm::length(glm::cross(positions[t.y] - positions[t.x], positions[t.z] - positions[t.x]));
      const glm::vec2 a = texcoords[t.y] - texcoords[t.x], b = texcoords[t.z] - texcoords[t.x];
      const float uv = std::abs(a.x * b.y - a.y * b.x);
      // Degenerate either way: no minification from this triangle's shape (level 0 up close).
      triUvScaleLog2[i] = world > 0.0f && uv > 0.0f ? 0.5f * std::log2(uv / world) : -64.0f;
    }
  }
}

void flattenTextures(Scene& scene) {
  auto mean = [&](int32_t t) { return t >= 0 ? scene.textures[size_t(t)]->mean() : glm::vec4(1.0f); };
  for (Material& m : scene.materials) {
    m.albedo *= glm::vec3(mean(m.baseTexture)) * glm::vec3(mean(m.lightmap));
    const glm::vec4 s = mean(m.specularTexture);
    m.specular *= 0.2126f * s.x + 0.7152f * s.y + 0.0722f * s.z;
    m.albedo = glm::clamp(m.albedo, 0.0f, 1.0f);
    m.baseTexture = m.specularTexture = m.lightmap = -1;
    m.alphaCutoff = -1.0f;
  }
  scene.textures.clear();
  scene.texcoords.clear();
  scene.lightmapCoords.clear();
  scene.triUvScaleLog2.clear();
}

void dropLightmaps(Scene& scene) {
  for (Material& m : scene.materials) m.lightmap = -1;
  scene.lightmapCoords.clear();
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
