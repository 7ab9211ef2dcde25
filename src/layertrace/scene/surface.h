// What a point of a scene triangle looks like: its textured albedo and specular weight, and
// whether it is there at all (alpha-tested cut-outs). Every consumer of surfaces calls these:
// the capture for each fragment, the geometric tracers' hit shading, Embree's intersection
// filter and the grid tracer's triangle test — so a texel and a hole are the same everywhere.
//
// A point is named by its barycentric weights (b1, b2) of the triangle's second and third
// vertices (the first has 1 - b1 - b2).
//
// Layer: scene/.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <glm/vec3.hpp>

#include "layertrace/scene/scene.h"

namespace lt {

/// False where triangle `tri`'s alpha test removes the point: the nearest level-0 texel of its
/// base texture has alpha below the material's cut-off. True for every triangle without one.
bool surfacePresent(const Scene& scene, uint32_t tri, float b1, float b2);

struct SurfaceColor {
  glm::vec3 albedo;  ///< linear RGB
  float specular;
};

/// The material's albedo and specular at (b1, b2), textures sampled trilinearly with mip level
/// log2(texels per world unit · `footprint`): `footprint` is the world-space width the sample
/// stands for (a pixel's footprint over the cosine of its incidence; see textureFootprint).
SurfaceColor surfaceColor(const Scene& scene, uint32_t tri, float b1, float b2, float footprint);

/// The 32-bit albedo-and-specular field of a fragment (sRGB-encoded RGB8 and an 8-bit weight,
/// as packAlbedoSpec) for a sampled colour.
inline uint32_t packSurfaceColor(const SurfaceColor& c) {
  const auto spec = uint32_t(std::lround(std::clamp(c.specular, 0.0f, 1.0f) * 255.0f));
  return linearToSrgb8(c.albedo.x) | linearToSrgb8(c.albedo.y) << 8 | linearToSrgb8(c.albedo.z) << 16 | spec << 24;
}

/// The footprint of one pixel of a camera at a surface point seen at depth `depth` with
/// incidence cosine `cosine` (between the surface normal and the view direction): the pixel's
/// width there, stretched by 1 / |cos| (ray cones, Akenine-Möller et al. 2021, eq. 34 with the
/// cone's width at the hit). Cosines below 1/64 count as 1/64.
float textureFootprint(float pixelFootprintAtDepth, float cosine);

/// What a material's surfaces need per point: kSurfaceSampled, a textured colour (surfaceColor);
/// kSurfaceCutOut, the alpha test (surfacePresent). 0: its constant colour, always present.
inline constexpr uint8_t kSurfaceSampled = 1, kSurfaceCutOut = 2;
inline uint8_t surfaceFlags(const Scene& scene, const Material& m) {
  const bool sampled = (!scene.texcoords.empty() && (m.baseTexture >= 0 || m.specularTexture >= 0)) ||
                       (m.lightmap >= 0 && !scene.lightmapCoords.empty());
  return uint8_t((sampled ? kSurfaceSampled : 0) | (scene.cutOut(m) ? kSurfaceCutOut : 0));
}

/// Whether triangle `tri` needs surfaceColor (kSurfaceSampled) or its material's constant
/// colour suffices.
inline bool surfaceTextured(const Scene& scene, uint32_t tri) {
  return (surfaceFlags(scene, scene.material(tri)) & kSurfaceSampled) != 0;
}

}  // namespace lt
