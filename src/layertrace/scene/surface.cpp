#include "layertrace/scene/surface.h"

#include <algorithm>
#include <cmath>

#include <glm/common.hpp>

namespace lt {
namespace {

glm::vec2 interpolate(const std::vector<glm::vec2>& coords, glm::uvec3 t, float b1, float b2) {
  return coords[t.x] * (1.0f - b1 - b2) + coords[t.y] * b1 + coords[t.z] * b2;
}

}  // namespace

bool surfacePresent(const Scene& scene, uint32_t tri, float b1, float b2) {
  if (!scene.cutOut(tri)) return true;
  const Material& m = scene.material(tri);
  const glm::vec2 uv = interpolate(scene.texcoords, scene.triangles[tri], b1, b2);
  return alphaNearest(*scene.textures[size_t(m.baseTexture)], uv, m.wrapU, m.wrapV) >= m.alphaCutoff;
}

float textureFootprint(float pixelFootprintAtDepth, float cosine) {
  return pixelFootprintAtDepth / std::max(std::abs(cosine), 1.0f / 64.0f);
}

SurfaceColor surfaceColor(const Scene& scene, uint32_t tri, float b1, float b2, float footprint) {
  const Material& m = scene.material(tri);
  SurfaceColor c{m.albedo, m.specular};
  const glm::uvec3 t = scene.triangles[tri];
  if (!scene.texcoords.empty() && (m.baseTexture >= 0 || m.specularTexture >= 0)) {
    const glm::vec2 uv = interpolate(scene.texcoords, t, b1, b2);
    // lod = log2(texels per world unit × world units per sample), per texture.
    // (A scene that skipped finalize() has no scale terms: level 0's scale then.)
    const float scale = tri < scene.triUvScaleLog2.size() ? scene.triUvScaleLog2[tri] : 0.0f;
    const float lodBase = scale + std::log2(std::max(footprint, 1e-30f));
    if (m.baseTexture >= 0) {
      const Texture& tex = *scene.textures[size_t(m.baseTexture)];
      c.albedo *= glm::vec3(sampleTrilinear(tex, uv, lodBase + tex.texelsLog2, m.wrapU, m.wrapV));
    }
    if (m.specularTexture >= 0) {
      const Texture& tex = *scene.textures[size_t(m.specularTexture)];
      const glm::vec4 s = sampleTrilinear(tex, uv, lodBase + tex.texelsLog2, m.wrapU, m.wrapV);
      c.specular *= 0.2126f * s.x + 0.7152f * s.y + 0.0722f * s.z;
    }
  }
  if (!scene.lightmapCoords.empty() && m.lightmap >= 0) {
    // Lightmaps are a few texels per surface: bilinear from level 0, clamped at their edges.
    const Texture& tex = *scene.textures[size_t(m.lightmap)];
    c.albedo *= glm::vec3(sampleTrilinear(tex, interpolate(scene.lightmapCoords, t, b1, b2), 0.0f, TextureWrap::Clamp, TextureWrap::Clamp));
  }
  c.albedo = glm::clamp(c.albedo, 0.0f, 1.0f);
  c.specular = std::clamp(c.specular, 0.0f, 1.0f);
  return c;
}

}  // namespace lt
