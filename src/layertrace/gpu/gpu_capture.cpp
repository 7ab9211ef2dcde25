#include "layertrace/gpu/gpu_capture.h"

#include <algorithm>
#include <bit>

#include <epoxy/gl.h>
#include <glm/gtc/type_ptr.hpp>

#include "layertrace/gpu/shader_sources.h"
#include "layertrace/raster/fragment.h"
#include "layertrace/raster/rasterizer.h"
#include "layertrace/scene/surface.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"

namespace lt {

namespace {

constexpr size_t kSetupBytes = 96;  ///< capture_common.glsl TriangleSetup

/// The camera uniforms of shaders/capture_common.glsl.
void setCamera(const GpuProgram& p, const Camera& c) {
  p.set("uWidth", c.width());
  p.set("uHeight", c.height());
  p.set("uNear", c.near());
  p.set("uFar", c.far());
  p.set("uPixelScale", c.pixelFootprint(1.0f));
  p.set("uOrtho", c.orthographic());
}

/// An empty vertex array with the scene's index buffer and a framebuffer without attachments
/// the size of the view: the geometry passes write buffers only.
struct RasterTarget {
  uint32_t vao = 0, fbo = 0;
  RasterTarget(const GpuBuffer& indices, int W, int H) {
    glCreateVertexArrays(1, &vao);
    glVertexArrayElementBuffer(vao, indices.id());
    glCreateFramebuffers(1, &fbo);
    glNamedFramebufferParameteri(fbo, GL_FRAMEBUFFER_DEFAULT_WIDTH, W);
    glNamedFramebufferParameteri(fbo, GL_FRAMEBUFFER_DEFAULT_HEIGHT, H);
    if (glCheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      inputError("--device gpu: a ", W, "x", H, " view is larger than the GPU's framebuffers");
  }
  ~RasterTarget() {
    glDeleteFramebuffers(1, &fbo);
    glDeleteVertexArrays(1, &vao);
  }
  RasterTarget(const RasterTarget&) = delete;
  RasterTarget& operator=(const RasterTarget&) = delete;
  /// Every triangle once, in scene order (gl_PrimitiveID = the triangle's index).
  void draw(const GpuProgram& program, int W, int H, size_t triangles) const {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, W, H);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glDisable(GL_STENCIL_TEST);
    glUseProgram(program.id());
    glBindVertexArray(vao);
    glDrawElements(GL_TRIANGLES, GLsizei(3 * triangles), GL_UNSIGNED_INT, nullptr);
    glBindVertexArray(0);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
};

/// What shaders/capture_surface.glsl reads of the scene's textured materials: one array of
/// 32-bit words in sections (their offsets, in words, are the shader's uniforms) and the texels.
struct SurfaceTables {
  std::vector<uint32_t> words, texels;
  uint32_t texcoords = 0, lightmapCoords = 0, uvScale = 0, materials = 0, textures = 0, levels = 0, decode = 0, thresholds = 0;

  explicit SurfaceTables(const Scene& scene) {
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

  void setUniforms(const GpuProgram& p, const Scene& scene) const {
    p.set("uTexcoords", texcoords), p.set("uLightmapCoords", lightmapCoords), p.set("uUvScale", uvScale);
    p.set("uMaterials", materials), p.set("uTextures", textures), p.set("uLevels", levels);
    p.set("uDecode", decode), p.set("uThresholds", thresholds);
    p.set("uHaveTexcoords", int(!scene.texcoords.empty()));
    p.set("uHaveLightmapCoords", int(!scene.lightmapCoords.empty()));
  }
};

/// The CPU's projection with y negated: OpenGL's window rows grow upwards, the CPU's pixel
/// rows (Camera::project) downwards, so row 0 of both is the top of the view.
glm::mat4 projectionRowsDown(const Camera& camera) {
  glm::mat4 p = camera.clipProjection();
  for (int c = 0; c < 4; ++c) p[c][1] = -p[c][1];
  return p;
}

}  // namespace

void captureOnGpu(GpuContext& gpu, const Scene& scene, const Camera& camera, const GpuCaptureConfig& config, GpuCaptureResult& out) {
  validateLayerConfig(config.layers);
  const bool peel = config.method == GpuCaptureMethod::Peel;
  if (peel && config.layers.adaptiveThickness)
    inputError("--adaptive-thickness: needs every fragment of a pixel, which depth peeling does not keep (use --capture lists)");
  const int W = camera.width(), H = camera.height(), k = config.layers.k;
  const size_t pixels = size_t(W) * size_t(H), V = scene.positions.size(), T = scene.triangles.size();
  if (T > size_t(0x7FFFFFFF) / 3) inputError("scene ", scene.name, ": ", T, " triangles exceed one GPU draw");
  gpu.makeCurrent();
  out = GpuCaptureResult{};

  // The scene, as the CPU holds it (packed materials as the CPU rasterizer packs them).
  std::vector<uint32_t> materials;
  for (const Material& m : scene.materials) materials.push_back(packAlbedoSpec(m.albedo, m.specular));
  const GpuBuffer positions(V * sizeof(glm::vec3), scene.positions.data()), normals(V * sizeof(glm::vec3), scene.normals.data());
  const GpuBuffer indices(T * sizeof(glm::uvec3), scene.triangles.data());
  const GpuBuffer triMaterial(T * sizeof(uint32_t), scene.triMaterial.data()), materialTable(materials.size() * 4, materials.data());
  const GpuBuffer camPos(V * 16), camNormals(V * 16), setups(T * kSetupBytes);
  const GpuBuffer complexity(pixels * 4), slots(pixels * size_t(k) * 16), counts(pixels * 4), slotTriangle(pixels * size_t(k) * 4);
  const GpuTimer setupBegin, rasterBegin, sortBegin;
  const SurfaceTables surface(scene);
  GLint64 largestBlock = 0;
  glGetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &largestBlock);
  for (const size_t bytes : {surface.words.size() * 4, surface.texels.size() * 4})
    if (int64_t(bytes) > largestBlock)
      inputError("--device gpu: the scene's textures take ", bytes, " bytes, more than the GPU's largest storage buffer of ", largestBlock,
                 " bytes (use --textures off)");
  const GpuBuffer surfaceWords(surface.words.size() * 4, surface.words.data()), surfaceTexels(surface.texels.size() * 4, surface.texels.data());
  const auto bindSurface = [&](const GpuProgram& p) {
    surfaceWords.bindStorage(8), surfaceTexels.bindStorage(9);
    surface.setUniforms(p, scene);
  };

  // Vertices and triangles to camera space.
  const GpuProgram vertices = gpu.computeProgram("capture_vertices.comp", shader_source::capture_vertices_comp);
  const GpuProgram triangles = gpu.computeProgram("capture_triangles.comp", shader_source::capture_triangles_comp);
  setupBegin.begin();
  positions.bindStorage(0), normals.bindStorage(1), camPos.bindStorage(2), camNormals.bindStorage(3);
  vertices.set("uVertexCount", int(V));
  vertices.setMatrix("uView", glm::value_ptr(camera.view()));
  gpu.dispatch(vertices, V);
  indices.bindStorage(0), camPos.bindStorage(1), setups.bindStorage(2), materialTable.bindStorage(3), triMaterial.bindStorage(4);
  setCamera(triangles, camera);
  triangles.set("uTriangleCount", int(T));
  triangles.set("uFrontFacesOnly", config.frontFacesOnly);
  gpu.dispatch(triangles, T);
  setupBegin.end();
  const RasterTarget target(indices, W, H);
  const uint32_t zero = 0, none = 0xFFFFFFFFu;
  const LayerConfig& lc = config.layers;

  if (!peel) {
    const GpuProgram lists = gpu.renderProgram("capture.vert + capture_lists.frag", shader_source::capture_vert, shader_source::capture_lists_frag);
    const GpuProgram sort = gpu.computeProgram("capture_sort.comp", shader_source::capture_sort_comp);
    setCamera(lists, camera);
    bindSurface(lists);
    lists.setMatrix("uProjection", glm::value_ptr(projectionRowsDown(camera)));
    uint64_t capacity = config.poolCapacity ? config.poolCapacity : std::max<uint64_t>(uint64_t(pixels) * 8, 1u << 20);
    for (;;) {
      if (capacity > kMaxPoolFragments) inputError("fragment pool capacity ", capacity, " exceeds the 32-bit index limit of ", kMaxPoolFragments);
      ++out.passes;
      checkAllocation(cat("the GPU's fragment pool (", capacity, " fragments)"), capacity * 20);
      const GpuBuffer nodes(capacity * 16), nodeTriangle(capacity * 4), heads(pixels * 4), counter(4, &zero);
      heads.fill(none);
      complexity.fill(zero);
      setups.bindStorage(0), camNormals.bindStorage(1), nodes.bindStorage(2), heads.bindStorage(3), nodeTriangle.bindStorage(4);
      complexity.bindStorage(5), counter.bindStorage(6), camPos.bindStorage(7);
      lists.set("uCapacity", uint32_t(capacity));
      rasterBegin.begin();
      target.draw(lists, W, H, T);
      rasterBegin.end();
      uint32_t generated = 0;
      counter.read(&generated, 4);
      out.generated = generated;
      out.stored = std::min<uint64_t>(generated, capacity);
      out.poolCapacity = capacity;
      const uint64_t lost = out.generated - out.stored;
      if (lost > 0 && config.growOnOverflow && out.passes == 1) {
        out.overflowLost = lost;
        capacity = out.generated;
        continue;
      }
      if (lost > 0)
        inputError("--pool ", config.poolCapacity, ": fragment pool overflow: ", out.generated, " fragments generated, ", out.stored,
                   " stored, ", lost, " lost (use --pool ", out.generated, " or more, or 0 for automatic)");
      nodes.bindStorage(0), heads.bindStorage(1), nodeTriangle.bindStorage(2), slots.bindStorage(3), counts.bindStorage(4),
          slotTriangle.bindStorage(5);
      sort.set("uPixels", int(pixels));
      sort.set("uK", k);
      sort.set("uThickness", lc.thickness);
      sort.set("uThicknessPerDepth", lc.thicknessPerDepth);
      sort.set("uMinSeparation", lc.minSeparation);
      sort.set("uAdaptive", lc.adaptiveThickness);
      sortBegin.begin();
      gpu.dispatch(sort, pixels);
      sortBegin.end();
      if (config.keepLists) {
        FragmentLists& fl = out.lists;
        fl.head.resize(pixels);
        heads.read(fl.head.data(), pixels * 4);
        fl.nodes.resize(out.stored);
        fl.triangle.resize(out.stored);
        if (out.stored > 0) {
          nodes.read(fl.nodes.data(), out.stored * sizeof(FragmentNode));
          nodeTriangle.read(fl.triangle.data(), out.stored * 4);
        }
      }
      out.memoryBytes = nodes.bytes() + nodeTriangle.bytes() + heads.bytes();
      out.geometryPasses = out.passes;
      break;
    }
  } else {
    // Depth peeling: per layer, its depth, then its triangle, from the whole scene each time.
    const GpuProgram peelPass = gpu.renderProgram("capture.vert + capture_peel.frag", shader_source::capture_vert, shader_source::capture_peel_frag);
    const GpuProgram resolve = gpu.computeProgram("capture_peel_resolve.comp", shader_source::capture_peel_resolve_comp);
    const GpuBuffer peelDepth(pixels * size_t(k) * 4), peelTriangle(pixels * size_t(k) * 4);
    peelDepth.fill(none);
    peelTriangle.fill(zero);
    complexity.fill(zero);
    setCamera(peelPass, camera);
    bindSurface(peelPass);
    peelPass.setMatrix("uProjection", glm::value_ptr(projectionRowsDown(camera)));
    peelPass.set("uK", k);
    peelPass.set("uMinSeparation", lc.minSeparation);
    setups.bindStorage(0), peelDepth.bindStorage(1), peelTriangle.bindStorage(2), complexity.bindStorage(3), camPos.bindStorage(7);
    rasterBegin.begin();
    for (int layer = 0; layer < k; ++layer)
      for (int pass = 0; pass < 2; ++pass) {
        peelPass.set("uLayer", layer);
        peelPass.set("uPass", pass);
        target.draw(peelPass, W, H, T);
        ++out.geometryPasses;
      }
    rasterBegin.end();
    setups.bindStorage(0), camNormals.bindStorage(1), peelTriangle.bindStorage(2), slots.bindStorage(3), counts.bindStorage(4),
        slotTriangle.bindStorage(5);
    setCamera(resolve, camera);
    bindSurface(resolve);
    resolve.set("uK", k);
    resolve.set("uThickness", lc.thickness);
    resolve.set("uThicknessPerDepth", lc.thicknessPerDepth);
    sortBegin.begin();
    gpu.dispatch(resolve, pixels);
    sortBegin.end();
    out.passes = 1;
    out.memoryBytes = peelDepth.bytes() + peelTriangle.bytes();
  }

  // Download into the CPU's layout.
  FragmentLists& fl = out.lists;
  fl.width = W, fl.height = H;
  fl.complexity.resize(pixels);
  complexity.read(fl.complexity.data(), pixels * 4);
  if (peel) {
    uint64_t total = 0;
    for (uint32_t c : fl.complexity) total += c;
    out.generated = out.stored = total;
  }
  fl.generated = out.generated, fl.stored = out.stored;
  LayerArrays& L = out.layers;
  L.width = W, L.height = H, L.k = k;
  checkAllocation(cat("the k-layer arrays (k = ", k, ")"), pixels * (size_t(k) * (sizeof(FragmentNode) + sizeof(uint32_t)) + 1));
  L.slots.resize(pixels * size_t(k));
  L.triangle.resize(pixels * size_t(k));
  slots.read(L.slots.data(), L.slots.size() * sizeof(FragmentNode));
  slotTriangle.read(L.triangle.data(), L.triangle.size() * 4);
  std::vector<uint32_t> n(pixels);
  counts.read(n.data(), pixels * 4);
  L.count.assign(n.begin(), n.end());
  out.setupMs = setupBegin.ms();
  out.rasterMs = rasterBegin.ms();
  out.sortMs = sortBegin.ms();
  out.memoryBytes += surfaceWords.bytes() + surfaceTexels.bytes() + positions.bytes() + normals.bytes() + indices.bytes() + triMaterial.bytes() + materialTable.bytes() + camPos.bytes() +
                     camNormals.bytes() + setups.bytes() + complexity.bytes() + slots.bytes() + counts.bytes() + slotTriangle.bytes();
}

}  // namespace lt
