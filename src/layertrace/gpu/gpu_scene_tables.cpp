#include "layertrace/gpu/gpu_scene_tables.h"

#include <bit>

#include <epoxy/gl.h>

#include "layertrace/raster/fragment.h"
#include "layertrace/scene/surface.h"
#include "layertrace/scene/texture.h"
#include "layertrace/util/error.h"

namespace lt {

SurfaceTables::SurfaceTables(const Scene& scene) {
  auto f = [](float v) { return std::bit_cast<uint32_t>(v); };
  auto section = [&](uint32_t& at) { at = uint32_t(words.size()); };
  section(texcoords);
  for (const glm::vec2& c : scene.texcoords) words.insert(words.end(), {f(c.x), f(c.y)});
  section(lightmapCoords);
  for (const glm::vec2& c : scene.lightmapCoords) words.insert(words.end(), {f(c.x), f(c.y)});
  section(uvScale);
  for (size_t t = 0; t < scene.triangles.size() && !scene.texcoords.empty(); ++t)
    words.push_back(f(t < scene.triUvScaleLog2.size() ? scene.triUvScaleLog2[t] : 0.0f));  // surfaceColor's rule
  section(materials);  // capture_surface.glsl kMaterialWords per material
  for (const Material& m : scene.materials)
    words.insert(words.end(), {f(m.albedo.x), f(m.albedo.y), f(m.albedo.z), f(m.specular), uint32_t(m.baseTexture), uint32_t(m.specularTexture),
                               uint32_t(m.lightmap), uint32_t(m.wrapU) | uint32_t(m.wrapV) << 8, f(m.alphaCutoff), surfaceFlags(scene, m)});
  section(textures);  // per texture: its first level (an index into the levels), its level count, texelsLog2
  uint32_t level = 0;
  for (const auto& t : scene.textures) {
    words.insert(words.end(), {level, uint32_t(t->levels.size()), f(t->texelsLog2)});
    level += uint32_t(t->levels.size());
  }
  section(levels);  // per level: width, height, first texel
  for (const auto& t : scene.textures) {
    const auto base = uint32_t(texels.size());
    for (const Texture::Level& l : t->levels) words.insert(words.end(), {uint32_t(l.width), uint32_t(l.height), base + uint32_t(l.offset)});
    texels.insert(texels.end(), t->texels.begin(), t->texels.end());
  }
  section(decode);
  for (uint32_t c = 0; c < 256; ++c) words.push_back(f(srgb8ToLinear(c)));
  section(thresholds);
  for (uint32_t c = 0; c < 255; ++c) words.push_back(f(srgb8Threshold(c)));
}

void SurfaceTables::setUniforms(const GpuProgram& p, const Scene& scene) const {
  p.set("uTexcoords", texcoords), p.set("uLightmapCoords", lightmapCoords), p.set("uUvScale", uvScale);
  p.set("uMaterials", materials), p.set("uTextures", textures), p.set("uLevels", levels);
  p.set("uDecode", decode), p.set("uThresholds", thresholds);
  p.set("uHaveTexcoords", int(!scene.texcoords.empty()));
  p.set("uHaveLightmapCoords", int(!scene.lightmapCoords.empty()));
}

namespace {

/// Why the surface tables do not fit the current context's storage buffers, or empty.
std::string surfaceLimit(const SurfaceTables& surface) {
  GLint64 largestBlock = 0;
  glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &largestBlock);
  for (const size_t bytes : {surface.words.size() * 4, surface.texels.size() * 4})
    if (int64_t(bytes) > largestBlock)
      return cat("--device gpu: the scene's textures take ", bytes, " bytes, more than the GPU's largest storage buffer of ", largestBlock,
                 " bytes (use --textures off)");
  return {};
}

}  // namespace

std::string GpuSceneTables::limit(GpuContext& gpu, const Scene& scene) {
  gpu.makeCurrent();
  return surfaceLimit(SurfaceTables(scene));
}

GpuSceneTables::GpuSceneTables(GpuContext& gpu, const Scene& s) : scene(s), surface(s) {
  gpu.makeCurrent();
  GpuDebugGroup group("scene upload");
  if (const std::string why = surfaceLimit(surface); !why.empty()) throw InputError(why);
  std::vector<uint32_t> materials;
  for (const Material& m : scene.materials) materials.push_back(packAlbedoSpec(m.albedo, m.specular));
  positions = GpuBuffer(scene.positions.size() * sizeof(glm::vec3), scene.positions.data());
  normals = GpuBuffer(scene.normals.size() * sizeof(glm::vec3), scene.normals.data());
  indices = GpuBuffer(scene.triangles.size() * sizeof(glm::uvec3), scene.triangles.data());
  triMaterial = GpuBuffer(scene.triangles.size() * sizeof(uint32_t), scene.triMaterial.data());
  materialTable = GpuBuffer(materials.size() * 4, materials.data());
  surfaceWords = GpuBuffer(surface.words.size() * 4, surface.words.data());
  surfaceTexels = GpuBuffer(surface.texels.size() * 4, surface.texels.data());
}

void GpuSceneTables::bindSurface(const GpuProgram& p) const {
  surfaceWords.bindStorage(8), surfaceTexels.bindStorage(9);
  surface.setUniforms(p, scene);
}

size_t GpuSceneTables::memoryBytes() const {
  size_t bytes = 0;
  for (const GpuBuffer* g : {&positions, &normals, &indices, &triMaterial, &materialTable, &surfaceWords, &surfaceTexels}) bytes += g->bytes();
  return bytes;
}

}  // namespace lt
