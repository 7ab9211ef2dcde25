// The public GPU API (api/gpu.h): the GPU back end's resident frame (gpu/gpu_frame.h) in the
// caller's context, its picture copied into the caller's texture on the device, its tracer
// marching the caller's ray buffer. Every call checks its arguments before it touches OpenGL and
// runs under a GpuStateGuard, so the caller's state is as it was when the call returns or throws.
#include "layertrace/api/gpu.h"

#include <array>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <utility>

#include "layertrace/api/api_detail.h"
#include "layertrace/pipeline/frame.h"
#include "layertrace/render/effects.h"
#include "layertrace/render/frame_sequence.h"
#if LAYERTRACE_HAS_GPU
#include <epoxy/gl.h>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_frame.h"
#include "layertrace/gpu/shader_sources.h"
#include "layertrace/render/gpu_effect_params.h"
#endif

namespace lt {

using namespace api_detail;

#if LAYERTRACE_HAS_GPU

struct GpuDevice::Impl {
  std::unique_ptr<GpuContext> context;
};

struct GpuRenderer::Impl {
  Impl(GpuContext& context, const std::string& name, TracerOptions params, float px)
      : gpu(context), tracer(name), tracers(std::move(params)), thicknessPx(px) {}
  ~Impl() {
    resident.reset();
    if (feedback) glDeleteTransformFeedbacks(1, &feedback);
    if (primitives) glDeleteQueries(1, &primitives);
    if (framebuffer) glDeleteFramebuffers(1, &framebuffer);
  }
  GpuContext& gpu;
  FrameOptions options;
  std::string tracer;
  TracerOptions tracers;
  float thicknessPx = 0.0f;
  Frame frame;  ///< the scene (a copy), the lights, the last view's camera and z-thickness
  std::unique_ptr<GpuFrame> resident;  ///< made on the first render (its lights follow that view)
  bool rendered = false;

  /// Where the frame's layers come from: the scene's capture, the caller's draw calls
  /// (GpuGeometry), or the caller's layers (GpuLayers, GpuGBuffer).
  enum class Source { Scene, Geometry, Layers } source = Source::Scene;
  std::string sourceName() const {
    return source == Source::Scene ? "its TriangleScene" : source == Source::Geometry ? "your draw calls" : "your layers";
  }
  static constexpr size_t kMaxTriangles = size_t(0x7FFFFFFF) / 3;

  // The caller's geometry (GpuGeometry): the frame captures `drawn`, a scene of as many
  // triangles as the capacity (three vertices each, in draw order) whose positions, normals and
  // materials the caller's draw calls write through transform feedback at the start of each
  // frame. The caller's layers: `drawn` holds a degenerate triangle per material, which the
  // slots' material indices name (their geometric normal is 0: the effects use the slot's).
  const GpuProgram* program = nullptr;  ///< the caller's vertex shader, linked for transform feedback
  Scene drawn;
  GpuBuffer vertexMaterial;  ///< ltMaterial per vertex
  GLuint feedback = 0, primitives = 0, framebuffer = 0;
  const GpuDrawCalls* draw = nullptr;  ///< the callback of the render in progress
  GpuBuffer gslots, gcounts;           ///< a G-buffer's layer (GpuGBuffer)

  void useMaterialsOf(const Scene& scene);
  void resize(size_t triangles);
  void captureGeometry(const GpuCapture& capture) const;
  /// One frame from this renderer's source into `texture`; `input` gives the caller's layers.
  GpuFrameInfo render(const View& view, const GpuEffectRequest& request, uint32_t texture,
                      const std::function<void(GpuCapture&, const Camera&)>& input);
};

namespace {

/// What `render` writes into a texture of `internalFormat`, or invalid_argument.
GpuPicture pictureFor(uint32_t texture, GLint internalFormat) {
  switch (internalFormat) {
    case GL_RGBA8:
    case GL_SRGB8_ALPHA8: return GpuPicture::Srgb8;
    case GL_RGBA16F:
    case GL_RGBA32F: return GpuPicture::Float32;
    default:
      invalid(cat("texture ", texture, ": internal format 0x", std::hex, internalFormat,
                  " (render writes GL_RGBA8, GL_SRGB8_ALPHA8, GL_RGBA16F or GL_RGBA32F)"));
  }
}

/// The size in bytes of the caller's buffer `id`, or invalid_argument naming `what`.
size_t bufferBytes(uint32_t id, const char* what) {
  if (id == 0 || !glIsBuffer(id)) invalid(cat(what, " ", id, ": not a buffer of the current context"));
  GLint64 bytes = 0;
  glGetNamedBufferParameteri64v(id, GL_BUFFER_SIZE, &bytes);
  return size_t(bytes);
}

/// The outputs of a caller's vertex shader that the capture reads (GpuGeometry).
constexpr std::array<const char*, 3> kGeometryOutputs = {"ltPosition", "ltNormal", "ltMaterial"};

}  // namespace

void GpuRenderer::Impl::useMaterialsOf(const Scene& scene) {
  // The materials (their textures off: no texture coordinates come with the caller's vertices
  // or layers), lights and environment of `scene`; the geometry is the caller's.
  drawn = scene;
  drawn.positions.clear(), drawn.normals.clear(), drawn.triangles.clear(), drawn.triMaterial.clear();
  drawn.texcoords.clear(), drawn.lightmapCoords.clear(), drawn.triUvScaleLog2.clear(), drawn.textures.clear();
  for (Material& material : drawn.materials) material.baseTexture = material.specularTexture = material.lightmap = -1;
  if (drawn.materials.empty()) drawn.materials.emplace_back();
}

void GpuRenderer::Impl::resize(size_t triangles) {
  const size_t vertices = 3 * triangles;
  drawn.positions.assign(vertices, glm::vec3(0.0f));
  drawn.normals.assign(vertices, glm::vec3(0.0f));
  drawn.triangles.resize(triangles);
  for (size_t t = 0; t < triangles; ++t) drawn.triangles[t] = glm::uvec3(3 * t, 3 * t + 1, 3 * t + 2);
  drawn.triMaterial.assign(triangles, 0);
  vertexMaterial = GpuBuffer(vertices * sizeof(uint32_t));
  resident.reset();  // its buffers follow the capacity: made again by the next render
}

void GpuRenderer::Impl::captureGeometry(const GpuCapture& capture) const {
  // Triangles beyond those drawn keep zero vertices: degenerate, they make no fragment.
  capture.positions().fill(0u);
  glTransformFeedbackBufferBase(feedback, 0, capture.positions().id());
  glTransformFeedbackBufferBase(feedback, 1, capture.normals().id());
  glTransformFeedbackBufferBase(feedback, 2, vertexMaterial.id());
  glBindTransformFeedback(GL_TRANSFORM_FEEDBACK, feedback);
  // A complete framebuffer (the caller's may be none, or incomplete): draws into an incomplete
  // one are refused even with the rasterizer off.
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, framebuffer);
  glEnable(GL_RASTERIZER_DISCARD);
  glUseProgram(program->id());
  // Every triangle drawn is counted, also those beyond the capacity (not written): the exact
  // number the next attempt needs.
  glBeginQuery(GL_PRIMITIVES_GENERATED, primitives);
  glBeginTransformFeedback(GL_TRIANGLES);
  const auto end = [&] {
    glEndTransformFeedback();
    glEndQuery(GL_PRIMITIVES_GENERATED);
    glDisable(GL_RASTERIZER_DISCARD);
    glBindTransformFeedback(GL_TRANSFORM_FEEDBACK, 0);
  };
  try {
    (*draw)(program->id());
  } catch (...) {
    end();
    throw;
  }
  end();
  const GpuProgram& materials = gpu.computeProgram("geometry_materials.comp", shader_source::geometry_materials_comp);
  vertexMaterial.bindStorage(0), capture.triMaterial().bindStorage(1);
  materials.set("uTriangleCount", int(drawn.triangles.size()));
  materials.set("uMaterialCount", int(std::max<size_t>(drawn.materials.size(), 1)));
  gpu.dispatch(materials, drawn.triangles.size());
}

GpuDevice::GpuDevice() : impl_(std::make_unique<Impl>()) {
  try {
    impl_->context = std::make_unique<GpuContext>(GpuContext::AdoptCurrent{});
  } catch (const InputError& e) {
    throw std::runtime_error(e.what());
  }
}

std::string GpuDevice::renderer() const { return impl_->context->renderer(); }
bool GpuDevice::software() const { return impl_->context->software(); }

GpuRenderer::GpuRenderer(GpuDevice& device, const TriangleScene& scene, const std::string& tracer, const TracerParams& params, int layers,
                         float thicknessPx)
    : impl_(std::make_unique<Impl>(*device.impl().context, tracer, tracerOptions(params), thicknessPx)) {
  if (!isGpuFrameTracer(tracer))
    invalid(cat("tracer \"", tracer, "\": the GPU frame traces with hssr, hiz, exhaustive, ssr or ssr-layers"));
  if (layers < 1 || layers > 16) invalid(cat("layers ", layers, ": must be between 1 and 16"));
  if (!(thicknessPx > 0.0f) || !std::isfinite(thicknessPx)) invalid(cat("thicknessPx ", thicknessPx, ": must be positive"));
  guarded([&] { validateTracerOptions(impl_->tracers); });
  impl_->options.layers = layers;
  impl_->frame.scene = scene.impl().scene;
}

GpuRenderer::GpuRenderer(GpuDevice& device, const TriangleScene& materials, const GpuGeometry& geometry, const std::string& tracer,
                         const TracerParams& params, int layers, float thicknessPx)
    : GpuRenderer(device, materials, tracer, params, layers, thicknessPx) {
  Impl& m = *impl_;
  if (geometry.maxTriangles == 0 || geometry.maxTriangles > Impl::kMaxTriangles)
    invalid(cat("maxTriangles ", geometry.maxTriangles, ": must be between 1 and ", Impl::kMaxTriangles));
  const GpuStateGuard state;
  guarded([&] { m.program = &m.gpu.feedbackProgram(geometry.vertexShader, kGeometryOutputs); });
  for (const char* output : kGeometryOutputs)
    if (glGetProgramResourceIndex(m.program->id(), GL_TRANSFORM_FEEDBACK_VARYING, output) == GL_INVALID_INDEX)
      invalid(cat("vertexShader: writes no ", output, " (GpuGeometry lists the outputs the capture reads)"));
  m.source = Impl::Source::Geometry;
  m.useMaterialsOf(m.frame.scene);
  glCreateTransformFeedbacks(1, &m.feedback);
  glCreateQueries(GL_PRIMITIVES_GENERATED, 1, &m.primitives);
  glCreateFramebuffers(1, &m.framebuffer);
  glNamedFramebufferParameteri(m.framebuffer, GL_FRAMEBUFFER_DEFAULT_WIDTH, 1);
  glNamedFramebufferParameteri(m.framebuffer, GL_FRAMEBUFFER_DEFAULT_HEIGHT, 1);
  m.resize(geometry.maxTriangles);
}

GpuRenderer::GpuRenderer(GpuDevice& device, const TriangleScene& materials, const GpuLayerFormat& format, const std::string& tracer,
                         const TracerParams& params)
    : GpuRenderer(device, materials, tracer, params, format.k, format.thicknessPx) {
  Impl& m = *impl_;
  m.source = Impl::Source::Layers;
  m.useMaterialsOf(m.frame.scene);
  const size_t count = m.drawn.materials.size();
  m.drawn.positions.assign(3 * count, glm::vec3(0.0f));
  m.drawn.normals.assign(3 * count, glm::vec3(0.0f));
  m.drawn.triangles.resize(count);
  m.drawn.triMaterial.resize(count);
  for (uint32_t t = 0; t < count; ++t) m.drawn.triangles[t] = glm::uvec3(3 * t, 3 * t + 1, 3 * t + 2), m.drawn.triMaterial[t] = t;
}

GpuRenderer::~GpuRenderer() = default;

GpuFrameInfo GpuRenderer::render(const View& view, const GpuEffectRequest& request, uint32_t texture) {
  if (impl_->source != Impl::Source::Scene) invalid(cat("render: this renderer takes ", impl_->sourceName(), " with each frame"));
  return impl_->render(view, request, texture, nullptr);
}

GpuFrameInfo GpuRenderer::render(const View& view, const GpuEffectRequest& request, uint32_t texture, const GpuDrawCalls& draw) {
  Impl& m = *impl_;
  if (m.source != Impl::Source::Geometry) invalid(cat("render: this renderer takes ", m.sourceName(), ", not draw calls"));
  if (!draw) invalid("render: no draw calls given (an empty GpuDrawCalls)");
  m.draw = &draw;
  const auto done = [&m] { m.draw = nullptr; };
  try {
    const GpuFrameInfo info = m.render(view, request, texture, nullptr);
    done();
    return info;
  } catch (...) {
    done();
    throw;
  }
}

GpuFrameInfo GpuRenderer::render(const View& view, const GpuEffectRequest& request, uint32_t texture, const GpuLayers& layers) {
  Impl& m = *impl_;
  if (m.source != Impl::Source::Layers) invalid(cat("render: this renderer takes ", m.sourceName(), ", not layers"));
  guarded([&] { cameraOf(view); });
  const size_t pixels = size_t(view.width) * size_t(view.height), slots = pixels * size_t(m.options.layers);
  const size_t slotBytes = bufferBytes(layers.slots, "layers.slots"), countBytes = bufferBytes(layers.counts, "layers.counts");
  if (slotBytes < slots * sizeof(GpuLayerSlot))
    invalid(cat("layers.slots ", layers.slots, ": ", slotBytes, " bytes hold ", slotBytes / sizeof(GpuLayerSlot), " slots, fewer than the ", slots,
                " of a ", view.width, "x", view.height, " view with k = ", m.options.layers));
  if (countBytes < pixels * 4)
    invalid(cat("layers.counts ", layers.counts, ": ", countBytes, " bytes hold ", countBytes / 4, " counts, fewer than the view's ", pixels, " pixels"));
  size_t materialBytes = 0;
  if (layers.materials != 0) {
    materialBytes = bufferBytes(layers.materials, "layers.materials");
    if (materialBytes < slots * 4)
      invalid(cat("layers.materials ", layers.materials, ": ", materialBytes, " bytes hold ", materialBytes / 4, " indices, fewer than the ", slots,
                  " slots"));
  }
  const int k = m.options.layers;
  const uint32_t materialCount = uint32_t(m.drawn.materials.size());
  return m.render(view, request, texture, [&](GpuCapture& capture, const Camera& camera) {
    const GpuBuffer materials = layers.materials ? GpuBuffer::borrowed(layers.materials, materialBytes) : GpuBuffer();
    capture.submitLayers(camera, k, GpuBuffer::borrowed(layers.slots, slotBytes), GpuBuffer::borrowed(layers.counts, countBytes),
                         layers.materials ? &materials : nullptr, materialCount);
  });
}

GpuFrameInfo GpuRenderer::render(const View& view, const GpuEffectRequest& request, uint32_t texture, const GpuGBuffer& gbuffer) {
  Impl& m = *impl_;
  if (m.source != Impl::Source::Layers || m.options.layers != 1)
    invalid(cat("render: a G-buffer is one layer; this renderer takes ", m.source == Impl::Source::Layers ? "k = " + std::to_string(m.options.layers) + " layers" : m.sourceName()));
  guarded([&] { cameraOf(view); });
  const auto check = [&](uint32_t id, const char* what, bool optional) {
    if (optional && id == 0) return;
    if (id == 0 || !glIsTexture(id)) invalid(cat(what, " ", id, ": not a texture of the current context"));
    GLint target = 0, width = 0, height = 0;
    glGetTextureParameteriv(id, GL_TEXTURE_TARGET, &target);
    if (target != GL_TEXTURE_2D) invalid(cat(what, " ", id, ": not a 2D texture"));
    glGetTextureLevelParameteriv(id, 0, GL_TEXTURE_WIDTH, &width);
    glGetTextureLevelParameteriv(id, 0, GL_TEXTURE_HEIGHT, &height);
    if (width != view.width || height != view.height)
      invalid(cat(what, " ", id, ": ", width, "x", height, " texels, not the ", view.width, "x", view.height, " view's"));
  };
  check(gbuffer.depth, "gbuffer.depth", false);
  check(gbuffer.normals, "gbuffer.normals", false);
  check(gbuffer.albedo, "gbuffer.albedo", true);
  GLint normalFormat = 0;
  glGetTextureLevelParameteriv(gbuffer.normals, 0, GL_TEXTURE_RED_TYPE, &normalFormat);
  return m.render(view, request, texture, [&](GpuCapture& capture, const Camera& camera) {
    const size_t pixels = size_t(camera.width()) * size_t(camera.height());
    if (m.gslots.bytes() != pixels * 16) m.gslots = GpuBuffer(pixels * 16), m.gcounts = GpuBuffer(pixels * 4);
    const GpuProgram& convert = m.gpu.computeProgram("layers_gbuffer.comp", shader_source::layers_gbuffer_comp);
    m.gslots.bindStorage(0), m.gcounts.bindStorage(1);
    glBindTextureUnit(0, gbuffer.depth);
    glBindTextureUnit(1, gbuffer.normals);
    glBindTextureUnit(2, gbuffer.albedo ? gbuffer.albedo : gbuffer.normals);
    for (GLuint unit = 0; unit < 3; ++unit) glBindSampler(unit, 0);
    convert.set("uWidth", camera.width());
    convert.set("uHeight", camera.height());
    convert.set("uNear", camera.near());
    convert.set("uFar", camera.far());
    convert.set("uThickness", 0.0f);
    convert.set("uThicknessPerDepth", m.frame.thicknessPerDepth);
    convert.set("uNormalsUnsigned", normalFormat == GL_UNSIGNED_NORMALIZED);
    convert.set("uHaveAlbedo", gbuffer.albedo != 0);
    convert.set("uDepth", 0);
    convert.set("uNormals", 1);
    convert.set("uAlbedo", 2);
    m.gpu.dispatch(convert, pixels);
    capture.submitLayers(camera, 1, m.gslots, m.gcounts, nullptr, 1);
  });
}

GpuFrameInfo GpuRenderer::Impl::render(const View& view, const GpuEffectRequest& request, uint32_t texture,
                                       const std::function<void(GpuCapture&, const Camera&)>& input) {
  const Camera camera = guarded([&] { return cameraOf(view); });
  EffectConfig ec;
  guarded([&] {
    ec.effect = parseEffect(request.effect);
    if (ec.effect == Effect::Warp) inputError("effect \"warp\": view synthesis is not in the GPU frame (use the CPU's lt::render)");
    ec.bounces = request.bounces;
    ec.aoSamples = request.aoSamples;
    ec.maxDistance = request.maxDistance;
    ec.seed = request.seed;
    ec.countRays = true;
    validateEffectConfig(ec);
  });
  // The texture, before any state changes.
  if (texture == 0 || !glIsTexture(texture)) invalid(cat("texture ", texture, ": not a texture of the current context"));
  GLint target = 0, width = 0, height = 0, format = 0;
  glGetTextureParameteriv(texture, GL_TEXTURE_TARGET, &target);
  if (target != GL_TEXTURE_2D) invalid(cat("texture ", texture, ": not a 2D texture"));
  glGetTextureLevelParameteriv(texture, 0, GL_TEXTURE_WIDTH, &width);
  glGetTextureLevelParameteriv(texture, 0, GL_TEXTURE_HEIGHT, &height);
  glGetTextureLevelParameteriv(texture, 0, GL_TEXTURE_INTERNAL_FORMAT, &format);
  if (width < view.width || height < view.height)
    invalid(cat("texture ", texture, ": ", width, "x", height, " texels, smaller than the ", view.width, "x", view.height, " view"));
  const GpuPicture picture = pictureFor(texture, format);

  const GpuStateGuard state;
  return guarded([&] {
    frame.camera = camera;
    frame.thicknessPerDepth = thicknessPerDepth(camera, thicknessPx);
    const auto makeFrame = [&] {
      if (frame.lights.empty()) {
        frame.lights = frame.scene.lights;  // the scene's, else one above this first view's eye
        if (frame.lights.empty()) frame.lights.push_back(defaultLight(camera));
      }
      resident = makeResidentFrame(gpu, options, frame, tracer, tracers, source == Source::Scene ? nullptr : &drawn);
      if (source == Source::Geometry) resident->setGeometryPass([this](const GpuCapture& capture) { captureGeometry(capture); });
    };
    if (!resident) makeFrame();
    // The caller's layers for this frame only: the pass refers to this call's arguments.
    struct Forget {
      std::unique_ptr<GpuFrame>& frame;
      ~Forget() {
        if (frame) frame->setInputLayers(nullptr);
      }
    } forget{resident};
    if (input) resident->setInputLayers(input);
    GpuEffectParams params = gpuEffectParams(frame, ec);
    params.excludeOriginTriangle = source != Source::Layers;
    GpuFrameResult r = resident->render(camera, layerConfig(options, frame), params, picture, false);
    uint64_t triangles = 0;
    if (source == Source::Geometry) {
      // The count, complete with the frame the one wait finished. More triangles than the
      // capacity: a capacity that holds them all, and the frame again.
      glGetQueryObjectui64v(primitives, GL_QUERY_RESULT, &triangles);
      if (triangles > drawn.triangles.size()) {
        if (triangles > kMaxTriangles) inputError("draw calls: ", triangles, " triangles exceed one GPU capture's ", kMaxTriangles);
        resize(std::max<size_t>(triangles, std::min<size_t>(2 * drawn.triangles.size(), kMaxTriangles)));
        makeFrame();
        r = resident->render(camera, layerConfig(options, frame), params, picture, false);
        r.attempts += 1;
      }
    }
    rendered = true;
    // The picture, packed in rows on the device, into the texture from a pixel-unpack buffer.
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, resident->picture().id());
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    glPixelStorei(GL_UNPACK_SKIP_ROWS, 0);
    glPixelStorei(GL_UNPACK_SKIP_PIXELS, 0);
    glPixelStorei(GL_UNPACK_IMAGE_HEIGHT, 0);
    glPixelStorei(GL_UNPACK_SKIP_IMAGES, 0);
    glTextureSubImage2D(texture, 0, 0, 0, view.width, view.height, GL_RGBA, picture == GpuPicture::Srgb8 ? GL_UNSIGNED_BYTE : GL_FLOAT,
                        nullptr);
    GpuFrameInfo info;
    info.fragments = r.fragments, info.rays = r.sums[0], info.hits = r.sums[1];
    info.iterationsMean = r.sums[0] ? double(r.sums[2]) / double(r.sums[0]) : 0.0;
    info.gpuMs = r.gpuMs(), info.attempts = r.attempts, info.triangles = triangles;
    return info;
  });
}

void GpuRenderer::trace(uint32_t rays, uint32_t hits, size_t count) const {
  const Impl& m = *impl_;
  if (!m.rendered) invalid("trace: no frame rendered yet (render one first: its layers are what the rays are traced through)");
  if (count == 0) return;
  const size_t rayBytes = bufferBytes(rays, "rays"), hitBytes = bufferBytes(hits, "hits");
  if (rayBytes < count * sizeof(GpuRayRecord))
    invalid(cat("rays ", rays, ": ", rayBytes, " bytes hold ", rayBytes / sizeof(GpuRayRecord), " rays, fewer than ", count));
  if (hitBytes < count * sizeof(GpuHitRecord))
    invalid(cat("hits ", hits, ": ", hitBytes, " bytes hold ", hitBytes / sizeof(GpuHitRecord), " answers, fewer than ", count));
  const GpuStateGuard state;
  guarded([&] { m.resident->trace(GpuBuffer::borrowed(rays, rayBytes), GpuBuffer::borrowed(hits, hitBytes), count); });
}

#else

struct GpuDevice::Impl {};
struct GpuRenderer::Impl {};

GpuDevice::GpuDevice() { throw std::runtime_error("layertrace was built without its GPU back end (LAYERTRACE_GPU)"); }
std::string GpuDevice::renderer() const { return {}; }
bool GpuDevice::software() const { return false; }
GpuRenderer::GpuRenderer(GpuDevice&, const TriangleScene&, const std::string&, const TracerParams&, int, float) {
  throw std::runtime_error("layertrace was built without its GPU back end (LAYERTRACE_GPU)");
}
GpuRenderer::~GpuRenderer() = default;
GpuRenderer::GpuRenderer(GpuDevice&, const TriangleScene&, const GpuGeometry&, const std::string&, const TracerParams&, int, float) {
  throw std::runtime_error("layertrace was built without its GPU back end (LAYERTRACE_GPU)");
}
GpuFrameInfo GpuRenderer::render(const View&, const GpuEffectRequest&, uint32_t) { return {}; }
GpuRenderer::GpuRenderer(GpuDevice&, const TriangleScene&, const GpuLayerFormat&, const std::string&, const TracerParams&) {
  throw std::runtime_error("layertrace was built without its GPU back end (LAYERTRACE_GPU)");
}
GpuFrameInfo GpuRenderer::render(const View&, const GpuEffectRequest&, uint32_t, const GpuDrawCalls&) { return {}; }
GpuFrameInfo GpuRenderer::render(const View&, const GpuEffectRequest&, uint32_t, const GpuLayers&) { return {}; }
GpuFrameInfo GpuRenderer::render(const View&, const GpuEffectRequest&, uint32_t, const GpuGBuffer&) { return {}; }
void GpuRenderer::trace(uint32_t, uint32_t, size_t) const {}

#endif

GpuDevice::~GpuDevice() = default;

}  // namespace lt
