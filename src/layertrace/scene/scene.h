// The scene: world-space triangles with a material per triangle, point lights, named cameras.
//
// Every loader (assimp model, Quake 3 archive, JSON composition, built-in shapes) produces this
// one flat representation; rasterizer and geometric tracers read it and nothing else.
//
// Layer: scene/ holds the scene, the camera (and with it the depth convention) and the loaders.
// It includes util/ only.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/ext/vector_double3.hpp>

#include "layertrace/scene/texture.h"

namespace lt {

/// Surface description used for shading and for the secondary effects.
struct Material {
  std::string name;
  glm::vec3 albedo{0.7f};     ///< diffuse reflectance, linear RGB
  float specular = 0.1f;      ///< Blinn-Phong specular weight in [0,1] (the 8-bit field of Hofmann et al. 2017, §4.1)
  float shininess = 32.0f;    ///< Blinn-Phong exponent
  float mirror = 0.0f;        ///< weight of the mirror-reflected colour in [0,1]
  float transmission = 0.0f;  ///< weight of the refracted colour in [0,1]
  float ior = 1.5f;           ///< index of refraction for transmission
  /// Textures (indices into Scene::textures, -1: none). The base colour texture multiplies
  /// `albedo` (glTF's base colour factor, OBJ's Kd) at the surface's texture coordinates; the
  /// specular texture's luminance multiplies `specular`; a lightmap (Quake 3 levels, behind
  /// --lightmaps) multiplies the albedo at the lightmap coordinates.
  int32_t baseTexture = -1;
  int32_t specularTexture = -1;
  int32_t lightmap = -1;
  TextureWrap wrapU = TextureWrap::Repeat, wrapV = TextureWrap::Repeat;
  /// Alpha test: where the base texture's alpha (alphaNearest) is below it, there is no surface.
  /// Negative: opaque (the alpha is ignored; blended transparency is drawn opaque).
  float alphaCutoff = -1.0f;
};

struct PointLight {
  glm::vec3 position{0.0f};
  glm::vec3 intensity{1.0f};  ///< radiant intensity, linear RGB; falls off with 1/d²
};

/// A named view. `fovY` is the vertical field of view in degrees.
struct CameraDesc {
  std::string name;
  glm::vec3 eye{0.0f, 0.0f, 5.0f};
  glm::vec3 target{0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float fovY = 60.0f;
  float near = 0.0f;  ///< 0 = derive from the scene size (see Scene::defaultNearFar)
  float far = 0.0f;   ///< 0 = derive from the scene size
  /// > 0: an orthographic view this many scene units high (fovY is then unused). Only internal
  /// captures use it (the layered depth cube's axis views, Bürger et al. 2007); scene files cannot
  /// ask.
  float orthoHeight = 0.0f;
};

struct Bounds {
  glm::vec3 lo{1e30f};
  glm::vec3 hi{-1e30f};
  void extend(glm::vec3 p);
  bool empty() const { return lo.x > hi.x; }
  glm::vec3 center() const { return (lo + hi) * 0.5f; }
  float diagonal() const;
  /// Distance from p to the farthest corner of the box (0 when empty).
  float farthestFrom(glm::vec3 p) const;
};

struct Scene {
  std::string name;
  std::vector<glm::vec3> positions;      ///< world-space vertex positions
  std::vector<glm::vec3> normals;        ///< per-vertex shading normals (same size as positions)
  std::vector<glm::vec2> texcoords;      ///< per vertex (same size as positions), or empty: no texture mapping
  std::vector<glm::vec2> lightmapCoords; ///< per vertex, or empty
  std::vector<glm::uvec3> triangles;     ///< vertex indices
  std::vector<uint32_t> triMaterial;     ///< material index per triangle
  std::vector<Material> materials;
  /// Decoded textures, shared between copies of a scene (they are never changed once loaded).
  std::vector<std::shared_ptr<const Texture>> textures;
  /// Derived by finalize() where there are texture coordinates: per triangle, log2 of its texture
  /// coordinates' scale (sqrt of uv area over world area), the ray-cone texture LOD's
  /// triangle term (Akenine-Möller et al., "Improved Shader and Texture Level of Detail Using Ray
  /// Cones", JCGT 10(1), 2021, §3).
  std::vector<float> triUvScaleLog2;
  std::vector<PointLight> lights;
  std::vector<CameraDesc> cameras;
  glm::vec3 environment{0.05f, 0.06f, 0.08f};  ///< colour of rays that leave the scene
  /// Where the scene's coordinates start, in the coordinates of the file it came from (world
  /// coordinates): positions, lights and cameras are stored relative to it. Zero unless
  /// recentre() moved the scene; every coordinate a user gives or reads is a world coordinate
  /// (toWorld / fromWorld).
  glm::dvec3 origin{0.0};

  glm::dvec3 toWorld(glm::vec3 p) const { return origin + glm::dvec3(p); }
  glm::vec3 fromWorld(const glm::dvec3& p) const { return glm::vec3(p - origin); }

  Bounds bounds() const;
  size_t triangleCount() const { return triangles.size(); }

  /// The material of triangle t.
  const Material& material(uint32_t t) const { return materials[triMaterial[t]]; }
  /// Whether material `m` has an alpha test here (a cut-out that rays may pass): a cut-off, a
  /// base texture and texture coordinates to read it at. The one statement of the rule.
  bool cutOut(const Material& m) const { return m.alphaCutoff >= 0.0f && m.baseTexture >= 0 && !texcoords.empty(); }
  /// Whether triangle t's material has an alpha test.
  bool cutOut(uint32_t t) const { return cutOut(material(t)); }
  bool anyCutOut() const;
  /// Bytes the textures hold.
  size_t textureBytes() const;

  /// Appends another scene's geometry (materials and textures re-indexed), lights and cameras.
  void append(const Scene& other);

  /// Replaces missing vertex normals by area-weighted face normals; validates indices.
  /// Throws InputError naming `source` when the scene is empty or an index is out of range.
  void finalize(const std::string& source);
};

/// `--textures off`: every texture replaced by its mean colour (multiplied into the material's
/// albedo and specular weight), no alpha tests, and the textures and texture coordinates dropped
/// — the untextured scene that experiments measuring only the tracers use. Lightmaps (when kept)
/// are averaged the same way.
void flattenTextures(Scene& scene);
/// `--lightmaps` not given: materials keep no lightmap (their texture alone colours them).
void dropLightmaps(Scene& scene);

/// Moves a scene that lies far from the origin of its coordinates next to it, so that every
/// tracer computes with coordinates a few scene diagonals large instead of 10⁵ (a float has 24
/// bits: a house 10⁵ units out keeps ~6 mm of resolution, and plain Embree then disagrees with
/// robust Embree on 0.1–0.3 % of the rays). An axis moves when the bounding box's centre lies
/// at least 4 units out on it, for a unit of the smallest power of two ≥ the diagonal; it moves
/// by a multiple of that unit, which makes every vertex's new coordinate exact (the geometry is
/// the file's, bit for bit). Lights and cameras move with it; Scene::origin records the shift.
void recentre(Scene& scene);

}  // namespace lt
