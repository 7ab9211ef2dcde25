// The public GPU API (api/gpu.h): the GPU back end's resident frame (gpu/gpu_frame.h) in the
// caller's context, its picture copied into the caller's texture on the device, its tracer
// marching the caller's ray buffer. Every call checks its arguments before it touches OpenGL and
// runs under a GpuStateGuard, so the caller's state is as it was when the call returns or throws.
#include "layertrace/api/gpu.h"

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
  GpuContext& gpu;
  FrameOptions options;
  std::string tracer;
  TracerOptions tracers;
  float thicknessPx = 0.0f;
  Frame frame;  ///< the scene (a copy), the lights, the last view's camera and z-thickness
  std::unique_ptr<GpuFrame> resident;  ///< made on the first render (its lights follow that view)
  bool rendered = false;
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

}  // namespace

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
  if (!isResidentTracer(tracer)) invalid(cat("tracer \"", tracer, "\": the GPU frame traces with hssr, hiz or exhaustive"));
  if (layers < 1 || layers > 16) invalid(cat("layers ", layers, ": must be between 1 and 16"));
  if (!(thicknessPx > 0.0f) || !std::isfinite(thicknessPx)) invalid(cat("thicknessPx ", thicknessPx, ": must be positive"));
  guarded([&] { validateTracerOptions(impl_->tracers); });
  impl_->options.layers = layers;
  impl_->frame.scene = scene.impl().scene;
}

GpuRenderer::~GpuRenderer() = default;

GpuFrameInfo GpuRenderer::render(const View& view, const GpuEffectRequest& request, uint32_t texture) {
  Impl& m = *impl_;
  Frame& frame = m.frame;
  const Camera camera = cameraOf(view);
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
    frame.thicknessPerDepth = thicknessPerDepth(camera, m.thicknessPx);
    if (!m.resident) {
      frame.lights = frame.scene.lights;  // the scene's, else one above this first view's eye
      if (frame.lights.empty()) frame.lights.push_back(defaultLight(camera));
      m.resident = makeResidentFrame(m.gpu, m.options, frame, m.tracer, m.tracers);
    }
    const GpuFrameResult r = m.resident->render(camera, layerConfig(m.options, frame), gpuEffectParams(frame, ec), picture, false);
    m.rendered = true;
    // The picture, packed in rows on the device, into the texture from a pixel-unpack buffer.
    glBindBuffer(GL_PIXEL_UNPACK_BUFFER, m.resident->picture().id());
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
    info.gpuMs = r.gpuMs(), info.attempts = r.attempts;
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
GpuFrameInfo GpuRenderer::render(const View&, const GpuEffectRequest&, uint32_t) { return {}; }
void GpuRenderer::trace(uint32_t, uint32_t, size_t) const {}

#endif

GpuDevice::~GpuDevice() = default;

}  // namespace lt
