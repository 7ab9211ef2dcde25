// A scene's triangles and surfaces on the GPU, as the passes that rasterize or shade them read
// them: vertex positions and normals, the triangles' vertex indices and materials, the packed
// albedo and specular of each material, and the tables of shaders/capture_surface.glsl (texture
// coordinates, materials, textures with their mip levels, the sRGB tables) with the texels.
// Uploaded once per scene; the capture (gpu_capture.h) and the grid's hit surfaces (gpu_grid.h)
// read them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/scene/scene.h"

namespace lt {

/// What shaders/capture_surface.glsl reads of the scene's textured materials: one array of
/// 32-bit words in sections (their offsets, in words, are the shader's uniforms) and the texels.
struct SurfaceTables {
  std::vector<uint32_t> words, texels;
  uint32_t texcoords = 0, lightmapCoords = 0, uvScale = 0, materials = 0, textures = 0, levels = 0, decode = 0, thresholds = 0;

  explicit SurfaceTables(const Scene& scene);
  void setUniforms(const GpuProgram& p, const Scene& scene) const;
};

class GpuSceneTables {
 public:
  /// Uploads `scene` (the context current). InputError where its textures exceed the GPU's
  /// largest storage buffer (limit).
  GpuSceneTables(GpuContext& gpu, const Scene& scene);
  /// Why `scene`'s surface tables do not fit `gpu`'s storage buffers, or empty when they do.
  static std::string limit(GpuContext& gpu, const Scene& scene);

  /// Binds the surface words and texels at shaders/capture_surface.glsl's bindings (8, 9) and
  /// sets its uniforms on `p`.
  void bindSurface(const GpuProgram& p) const;
  size_t memoryBytes() const;

  const Scene& scene;
  SurfaceTables surface;
  /// Positions and normals: three floats a vertex; indices: three a triangle; triMaterial: one a
  /// triangle; materialTable: the packed albedo and specular of each material (raster/fragment.h
  /// packAlbedoSpec, as the CPU rasterizer packs them).
  GpuBuffer positions, normals, indices, triMaterial, materialTable, surfaceWords, surfaceTexels;
};

}  // namespace lt
