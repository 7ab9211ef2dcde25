#include "layertrace/gpu/gpu_capture.h"

#include <algorithm>
#include <bit>

#include <epoxy/gl.h>
#include <glm/gtc/type_ptr.hpp>

#include "layertrace/gpu/gpu_scene_tables.h"
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

/// The CPU's projection with y negated: OpenGL's window rows grow upwards, the CPU's pixel
/// rows (Camera::project) downwards, so row 0 of both is the top of the view.
glm::mat4 projectionRowsDown(const Camera& camera) {
  glm::mat4 p = camera.clipProjection();
  for (int c = 0; c < 4; ++c) p[c][1] = -p[c][1];
  return p;
}

}  // namespace

std::string GpuCapture::limit(GpuContext& gpu, const Scene& scene) { return GpuSceneTables::limit(gpu, scene); }

GpuCapture::GpuCapture(GpuContext& gpu, const Scene& scene) : gpu_(gpu), scene_(scene) {
  const size_t V = scene.positions.size(), T = scene.triangles.size();
  if (T > size_t(0x7FFFFFFF) / 3) inputError("scene ", scene.name, ": ", T, " triangles exceed one GPU draw");
  gpu.makeCurrent();
  sceneBuffers_ = std::make_unique<GpuSceneTables>(gpu, scene);
  const GpuSceneTables& b = *sceneBuffers_;
  camPos_ = GpuBuffer(V * 16);
  camNormals_ = GpuBuffer(V * 16);
  setups_ = GpuBuffer(T * kSetupBytes);
  counter_ = GpuBuffer(4);
  glCreateVertexArrays(1, &vao_);
  glVertexArrayElementBuffer(vao_, b.indices.id());
  glCreateFramebuffers(1, &fbo_);
}

const GpuBuffer& GpuCapture::positions() const { return sceneBuffers_->positions; }
const GpuBuffer& GpuCapture::normals() const { return sceneBuffers_->normals; }
const GpuBuffer& GpuCapture::triMaterial() const { return sceneBuffers_->triMaterial; }

GpuCapture::~GpuCapture() {
  gpu_.makeCurrent();  // the buffers go with the context current
  glDeleteFramebuffers(1, &fbo_);
  glDeleteVertexArrays(1, &vao_);
}

size_t GpuCapture::memoryBytes() const {
  size_t bytes = sceneBuffers_->memoryBytes();
  for (const GpuBuffer* g : {&camPos_, &camNormals_, &setups_, &complexity_, &slots_, &counts_, &slotTriangle_, &nodes_, &nodeTriangle_, &fullNodes_, &heads_,
                             &peelDepth_, &peelTriangle_})
    bytes += g->bytes();
  return bytes;
}

void GpuCapture::bindScene(uint32_t positions, uint32_t indices, uint32_t triMaterial) const {
  sceneBuffers_->positions.bindStorage(positions);
  sceneBuffers_->indices.bindStorage(indices);
  sceneBuffers_->triMaterial.bindStorage(triMaterial);
}

double GpuCapture::setupMs() const { return setupTimer_.ms(); }
double GpuCapture::rasterMs() const { return rasterTimer_.ms(); }
double GpuCapture::sortMs() const { return sortTimer_.ms(); }

void GpuCapture::growPool(uint64_t fragments) { capacity_ = fragments; }

void GpuCapture::prepareView(int width, int height, int k) {
  // Per-view buffers, allocated when the size or k changes.
  const size_t pixels = size_t(width) * size_t(height);
  if (pixels != pixels_ || k != k_) {
    complexity_ = GpuBuffer(pixels * 4);
    slots_ = GpuBuffer(pixels * size_t(k) * 16);
    counts_ = GpuBuffer(pixels * 4);
    slotTriangle_ = GpuBuffer(pixels * size_t(k) * 4);
    heads_ = GpuBuffer(pixels * 4);
    peelDepth_ = GpuBuffer();
    peelTriangle_ = GpuBuffer();
    pixels_ = pixels, k_ = k;
  }
  width_ = width, height_ = height;
}

void GpuCapture::submitLayers(const Camera& camera, int k, const GpuBuffer& slots, const GpuBuffer& counts, const GpuBuffer* materials,
                              uint32_t materialCount) {
  const size_t pixels = size_t(camera.width()) * size_t(camera.height());
  LT_CHECK(slots.bytes() >= pixels * size_t(k) * 16 && counts.bytes() >= pixels * 4, slots.bytes(), counts.bytes(), pixels, k);
  gpu_.makeCurrent();
  GpuDebugGroup group("layers in");
  prepareView(camera.width(), camera.height(), k);
  // No pool: the count the frame checks against it is at most every slot.
  capacity_ = std::max<uint64_t>(capacity_, uint64_t(pixels) * uint64_t(k));
  peel_ = false;
  geometryPasses_ = 0;
  const GpuProgram& input = gpu_.computeProgram("layers_input.comp", shader_source::layers_input_comp);
  counter_.fill(0u);
  slots.bindStorage(0), counts.bindStorage(1), slots_.bindStorage(3), counts_.bindStorage(4), slotTriangle_.bindStorage(5);
  complexity_.bindStorage(6), counter_.bindStorage(7);
  (materials ? *materials : counts).bindStorage(2);  // (read only with materials)
  input.set("uPixels", int(pixels));
  input.set("uK", k);
  input.set("uMaterialCount", int(std::max<uint32_t>(materialCount, 1)));
  input.set("uHaveMaterials", materials != nullptr);
  setupTimer_.begin(), setupTimer_.end(), rasterTimer_.begin(), rasterTimer_.end();
  sortTimer_.begin();
  gpu_.dispatch(input, pixels);
  sortTimer_.end();
}

void GpuCapture::submit(const Camera& camera, const GpuCaptureConfig& config) {
  validateLayerConfig(config.layers);
  const bool peel = config.method == GpuCaptureMethod::Peel;
  if (peel && config.layers.adaptiveThickness)
    inputError("--adaptive-thickness: needs every fragment of a pixel, which depth peeling does not keep (use --capture lists)");
  const int W = camera.width(), H = camera.height(), k = config.layers.k;
  const size_t pixels = size_t(W) * size_t(H), V = scene_.positions.size(), T = scene_.triangles.size();
  gpu_.makeCurrent();
  GpuDebugGroup group("capture");
  const GpuSceneTables& b = *sceneBuffers_;
  const auto bindSurface = [&](const GpuProgram& p) { b.bindSurface(p); };
  prepareView(W, H, k);
  if (W != fboWidth_ || H != fboHeight_) {
    glNamedFramebufferParameteri(fbo_, GL_FRAMEBUFFER_DEFAULT_WIDTH, W);
    glNamedFramebufferParameteri(fbo_, GL_FRAMEBUFFER_DEFAULT_HEIGHT, H);
    if (glCheckNamedFramebufferStatus(fbo_, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      inputError("--device gpu: a ", W, "x", H, " view is larger than the GPU's framebuffers");
    fboWidth_ = W, fboHeight_ = H;
  }
  // Every triangle once, in scene order (gl_PrimitiveID = the triangle's index), into a
  // framebuffer without attachments: the geometry passes write buffers only.
  const auto draw = [&](const GpuProgram& program) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glViewport(0, 0, W, H);
    // Every fragment of every triangle, whatever state a caller's context left (layertrace/gpu.h).
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glDisable(GL_STENCIL_TEST);
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_RASTERIZER_DISCARD);
    glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
    glUseProgram(program.id());
    glBindVertexArray(vao_);
    glDrawElements(GL_TRIANGLES, GLsizei(3 * T), GL_UNSIGNED_INT, nullptr);
    noteGpuDraw();
    glBindVertexArray(0);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  };

  // Vertices and triangles to camera space.
  const GpuProgram& vertices = gpu_.computeProgram("capture_vertices.comp", shader_source::capture_vertices_comp);
  const GpuProgram& triangles = gpu_.computeProgram("capture_triangles.comp", shader_source::capture_triangles_comp);
  setupTimer_.begin();
  b.positions.bindStorage(0), b.normals.bindStorage(1), camPos_.bindStorage(2), camNormals_.bindStorage(3);
  vertices.set("uVertexCount", int(V));
  vertices.setMatrix("uView", glm::value_ptr(camera.view()));
  gpu_.dispatch(vertices, V);
  b.indices.bindStorage(0), camPos_.bindStorage(1), setups_.bindStorage(2), b.materialTable.bindStorage(3), b.triMaterial.bindStorage(4);
  setCamera(triangles, camera);
  triangles.set("uTriangleCount", int(T));
  triangles.set("uFrontFacesOnly", config.frontFacesOnly);
  gpu_.dispatch(triangles, T);
  setupTimer_.end();
  const uint32_t zero = 0, none = 0xFFFFFFFFu;
  const LayerConfig& lc = config.layers;
  peel_ = peel;

  if (!peel) {
    const GpuProgram& lists = gpu_.renderProgram("capture.vert + capture_lists.frag", shader_source::capture_vert, shader_source::capture_lists_frag);
    const GpuProgram& sort = gpu_.computeProgram("capture_sort.comp", shader_source::capture_sort_comp);
    if (capacity_ == 0) capacity_ = config.poolCapacity ? config.poolCapacity : std::max<uint64_t>(uint64_t(pixels) * 8, 1u << 20);
    if (capacity_ > kMaxPoolFragments) inputError("fragment pool capacity ", capacity_, " exceeds the 32-bit index limit of ", kMaxPoolFragments);
    // Thin nodes: depth and next (8 bytes), the triangle beside them (4 bytes).
    if (nodes_.bytes() < capacity_ * 8) {
      checkAllocation(cat("the GPU's fragment pool (", capacity_, " fragments)"), capacity_ * 12);
      nodes_ = GpuBuffer(capacity_ * 8);
      nodeTriangle_ = GpuBuffer(capacity_ * 4);
    }
    setCamera(lists, camera);
    bindSurface(lists);
    lists.setMatrix("uProjection", glm::value_ptr(projectionRowsDown(camera)));
    heads_.fill(none);
    complexity_.fill(zero);
    counter_.fill(zero);
    setups_.bindStorage(0), nodes_.bindStorage(2), heads_.bindStorage(3), nodeTriangle_.bindStorage(4);
    complexity_.bindStorage(5), counter_.bindStorage(6), camPos_.bindStorage(7);
    lists.set("uCapacity", uint32_t(capacity_));
    rasterTimer_.begin();
    draw(lists);
    rasterTimer_.end();
    // The sort reads only the nodes the pool stored (a full pool links no more).
    nodes_.bindStorage(0), heads_.bindStorage(1), nodeTriangle_.bindStorage(2), slots_.bindStorage(3), counts_.bindStorage(4),
        slotTriangle_.bindStorage(5), setups_.bindStorage(6), camNormals_.bindStorage(7);
    setCamera(sort, camera);
    bindSurface(sort);
    sort.set("uPixels", int(pixels));
    sort.set("uK", k);
    sort.set("uThickness", lc.thickness);
    sort.set("uThicknessPerDepth", lc.thicknessPerDepth);
    sort.set("uMinSeparation", lc.minSeparation);
    sort.set("uAdaptive", lc.adaptiveThickness);
    GpuDebugGroup sortGroup("sort");
    sortTimer_.begin();
    gpu_.dispatch(sort, pixels);
    sortTimer_.end();
    geometryPasses_ = 1;
    if (config.keepLists) {
      // Every stored fragment in the CPU's 16-byte node, for the download (verification only).
      const GpuProgram& expand = gpu_.computeProgram("capture_expand.comp", shader_source::capture_expand_comp);
      if (fullNodes_.bytes() < capacity_ * 16) {
        checkAllocation(cat("the fragment lists for verification (", capacity_, " fragments)"), capacity_ * 16);
        fullNodes_ = GpuBuffer(capacity_ * 16);
      }
      nodes_.bindStorage(0), heads_.bindStorage(1), nodeTriangle_.bindStorage(2), fullNodes_.bindStorage(3), setups_.bindStorage(6),
          camNormals_.bindStorage(7);
      setCamera(expand, camera);
      bindSurface(expand);
      gpu_.dispatch(expand, pixels);
    }
  } else {
    // Depth peeling: per layer, its depth, then its triangle, from the whole scene each time.
    const GpuProgram& peelPass = gpu_.renderProgram("capture.vert + capture_peel.frag", shader_source::capture_vert, shader_source::capture_peel_frag);
    const GpuProgram& resolve = gpu_.computeProgram("capture_peel_resolve.comp", shader_source::capture_peel_resolve_comp);
    if (peelDepth_.bytes() < pixels * size_t(k) * 4) peelDepth_ = GpuBuffer(pixels * size_t(k) * 4), peelTriangle_ = GpuBuffer(pixels * size_t(k) * 4);
    peelDepth_.fill(none);
    peelTriangle_.fill(zero);
    complexity_.fill(zero);
    setCamera(peelPass, camera);
    bindSurface(peelPass);
    peelPass.setMatrix("uProjection", glm::value_ptr(projectionRowsDown(camera)));
    peelPass.set("uK", k);
    peelPass.set("uMinSeparation", lc.minSeparation);
    setups_.bindStorage(0), peelDepth_.bindStorage(1), peelTriangle_.bindStorage(2), complexity_.bindStorage(3), camPos_.bindStorage(7);
    rasterTimer_.begin();
    geometryPasses_ = 0;
    for (int layer = 0; layer < k; ++layer)
      for (int pass = 0; pass < 2; ++pass) {
        peelPass.set("uLayer", layer);
        peelPass.set("uPass", pass);
        draw(peelPass);
        ++geometryPasses_;
      }
    rasterTimer_.end();
    setups_.bindStorage(0), camNormals_.bindStorage(1), peelTriangle_.bindStorage(2), slots_.bindStorage(3), counts_.bindStorage(4),
        slotTriangle_.bindStorage(5);
    setCamera(resolve, camera);
    bindSurface(resolve);
    resolve.set("uK", k);
    resolve.set("uThickness", lc.thickness);
    resolve.set("uThicknessPerDepth", lc.thicknessPerDepth);
    sortTimer_.begin();
    gpu_.dispatch(resolve, pixels);
    sortTimer_.end();
  }
}

void GpuCapture::download(const GpuCaptureConfig& config, uint64_t generated, GpuCaptureResult& out) const {
  const size_t pixels = pixels_;
  const int k = k_;
  out.layers = LayerArrays{};
  out.lists = FragmentLists{};
  FragmentLists& fl = out.lists;
  fl.complexity.resize(pixels);
  complexity_.read(fl.complexity.data(), pixels * 4);
  if (peel_) {
    uint64_t total = 0;
    for (uint32_t c : fl.complexity) total += c;
    out.generated = out.stored = total;
  } else {
    out.generated = generated;
    out.stored = std::min<uint64_t>(generated, capacity_);
    out.poolCapacity = capacity_;
    if (config.keepLists) {
      fl.head.resize(pixels);
      heads_.read(fl.head.data(), pixels * 4);
      fl.nodes.resize(out.stored);
      fl.triangle.resize(out.stored);
      if (out.stored > 0) {
        fullNodes_.read(fl.nodes.data(), out.stored * sizeof(FragmentNode));
        nodeTriangle_.read(fl.triangle.data(), out.stored * 4);
      }
    }
  }
  out.geometryPasses = geometryPasses_;
  fl.width = width_, fl.height = height_;
  fl.generated = out.generated, fl.stored = out.stored;
  LayerArrays& L = out.layers;
  checkAllocation(cat("the k-layer arrays (k = ", k, ")"), pixels * (size_t(k) * (sizeof(FragmentNode) + sizeof(uint32_t)) + 1));
  L.width = width_, L.height = height_, L.k = k;
  L.slots.resize(pixels * size_t(k));
  L.triangle.resize(pixels * size_t(k));
  slots_.read(L.slots.data(), L.slots.size() * sizeof(FragmentNode));
  slotTriangle_.read(L.triangle.data(), L.triangle.size() * 4);
  std::vector<uint32_t> n(pixels);
  counts_.read(n.data(), pixels * 4);
  L.count.assign(n.begin(), n.end());
  out.setupMs = setupMs();
  out.rasterMs = rasterMs();
  out.sortMs = sortMs();
  out.memoryBytes = memoryBytes();
}

void captureOnGpu(GpuContext& gpu, const Scene& scene, const Camera& camera, const GpuCaptureConfig& config, GpuCaptureResult& out) {
  validateLayerConfig(config.layers);
  GpuCapture capture(gpu, scene);
  out = GpuCaptureResult{};
  uint64_t generated = 0, lost = 0;
  int passes = 0;
  for (;;) {
    capture.submit(camera, config);
    ++passes;
    if (config.method == GpuCaptureMethod::Peel) break;
    uint32_t g = 0;
    capture.counter().read(&g, 4);
    generated = g;
    lost = generated - std::min<uint64_t>(generated, capture.poolCapacity());
    if (lost > 0 && config.growOnOverflow && passes == 1) {
      out.overflowLost = lost;
      capture.growPool(generated);
      continue;
    }
    if (lost > 0)
      inputError("--pool ", config.poolCapacity, ": fragment pool overflow: ", generated, " fragments generated, ", generated - lost,
                 " stored, ", lost, " lost (use --pool ", generated, " or more, or 0 for automatic)");
    break;
  }
  const uint64_t overflowLost = out.overflowLost;
  capture.download(config, generated, out);
  out.overflowLost = overflowLost;
  out.passes = config.method == GpuCaptureMethod::Peel ? 1 : passes;
  if (config.method != GpuCaptureMethod::Peel) out.geometryPasses = passes;
}

}  // namespace lt
