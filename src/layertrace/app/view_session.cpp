#include "layertrace/app/view_session.h"

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <sstream>

#include "layertrace/eval/classify.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/render/frame_sequence.h"
#include "layertrace/util/error.h"
#if LAYERTRACE_HAS_GPU
#include "layertrace/gpu/gpu_frame.h"
#include "layertrace/render/gpu_effect_params.h"
#endif

namespace lt {

namespace {

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// View-independent structures (Embree's BVH, the grid, the layered depth cube) depend on the
/// scene and their own parameters only: the viewer builds each once per parameter set. The key
/// names the tracer and the values of every parameter group its registry entry reads.
std::string structureKey(const TracerEntry& entry, const TracerOptions& o) {
  std::string key = entry.info.name;
  for (const TracerParam& p : tracerParams())
    if (entry.reads(p)) key += ' ' + paramValue(p, o);
  return key;
}

}  // namespace

struct ViewCache {
  std::map<std::string, BuiltTracer> geometric;
  std::unique_ptr<BuiltTracer> reference;
  /// --device gpu, a tracer of the resident frame and the plain picture: the frame stays on the
  /// device (gpu/gpu_frame.h) and is made again only when `residentKey` (the tracer, its
  /// parameters and the capture's) changes.
#if LAYERTRACE_HAS_GPU
  std::unique_ptr<GpuFrame> resident;
#endif
  std::string residentKey;
};

ViewOverlay parseViewOverlay(const std::string& name) {
  for (int i = 0; i < 5; ++i)
    if (name == kViewOverlayOptions[i]) return ViewOverlay(i);
  inputError("--overlay ", name, ": unknown (use image, classes, iterations, layer, complexity)");
}

void validateViewOptions(const ViewOptions& o) {
  parseViewOverlay(o.overlay);
  if (o.frames < 0 || o.frames > 100000) inputError("--frames ", o.frames, ": must be between 0 and 100000");
  for (const auto& [opt, path] : {std::pair{"-o ", &o.screenshot}, std::pair{"--screenshot-ui ", &o.screenshotUi}}) {
    if (path->empty()) continue;
    if (o.frames == 0) inputError(opt, *path, ": needs --frames N (scripted mode)");
    if (std::filesystem::path(*path).extension() != ".png") inputError(opt, *path, ": must be a .png file");
  }
  const RenderOptions& r = o.render;
  if (!isKnownTracer(r.tracer)) inputError("--tracer ", r.tracer, ": unknown (use ", tracerNames(), ")");
}

ViewSession::~ViewSession() { closeGpu(); }

void ViewSession::closeGpu() {
#if LAYERTRACE_HAS_GPU
  if (gpu_ && cache_->resident) {
    makeGpuCurrent(*gpu_);  // its buffers go with the context current
    cache_->resident.reset();
    releaseGpu(*gpu_);
  }
#endif
  gpu_.reset();
}

ViewSession::ViewSession(const RenderOptions& options) : options_(options), cache_(std::make_unique<ViewCache>()) {
  validateTracerOptions(options.tracers);
  validateEffectConfig(options.effect);
  if (!isKnownTracer(options.tracer)) inputError("--tracer ", options.tracer, ": unknown (use ", tracerNames(), ")");
  if (options.run.device == "gpu") {
    gpu_ = openGpu();  // before the scene: a machine without one is told at once
    releaseGpu(*gpu_);  // render() makes it current on the thread that renders (the viewer's worker)
  }
  loadFrameScene(options.run.frame, frame_);
  initial_.camera = frame_.camera.desc();
  initial_.width = options.run.frame.width;
  initial_.height = options.run.frame.height;
  initial_.tracer = options.tracer;
  initial_.effect = options.effect;
  initial_.effect.seed = options.run.seed;
  initial_.effect.progress = false;
  initial_.tracers = options.tracers;
  initial_.layers = options.run.frame.layers;
  initial_.thicknessPx = options.run.frame.thicknessPx.value_or(kDefaultThicknessPx);
}

size_t ViewSession::cachedStructures() const { return cache_->geometric.size(); }

std::string ViewSession::presentOnGpu(void* eglDisplay, void* eglContext) {
  if (!gpu_) return "not --device gpu";
#if LAYERTRACE_HAS_GPU
  LT_CHECK(!cache_->resident, "presentOnGpu after the first frame");
#endif
  try {
    gpu_ = openGpuSharing(eglDisplay, eglContext);
  } catch (const InputError& e) {
    return e.what();
  }
  sharedGpu_ = true;
  return {};
}

ViewResult ViewSession::render(const ViewRequest& q) {
  ViewResult out;
  out.scale = std::max(1, q.scale);
  const auto t0 = std::chrono::steady_clock::now();
  try {
    validateTracerOptions(q.tracers);
    validateEffectConfig(q.effect);
    FrameOptions fo = options_.run.frame;
    fo.width = std::max(1, q.width / out.scale);
    fo.height = std::max(1, q.height / out.scale);
    fo.layers = q.layers;
    if (!options_.run.frame.thickness) fo.thicknessPx = q.thicknessPx;
    prepareCapture(q.tracer, q.tracers, fo);  // into memory reused frame to frame
    validateFrameOptions(fo);
    setFrameView(fo, q.camera, frame_);
    const nlohmann::json activityBefore = gpu_ ? gpuActivityReading() : nlohmann::json();
    EffectConfig ec = q.effect;
    ec.progress = false;
#if LAYERTRACE_HAS_GPU
    if (gpu_ && q.overlay == ViewOverlay::None && rendersResident(q.tracer, frame_, ec)) {
      // One resident frame: capture to picture on the device and one wait.
      makeGpuCurrent(*gpu_);
      ViewCache& cache = *cache_;
      const TracerEntry* entry = findTracer(q.tracer);
      const std::string key = cat(structureKey(*entry, q.tracers), " k", fo.layers, " peel", fo.depthPeeling, " pool", fo.pool, " front",
                                  fo.frontFacesOnly);
      if (!cache.resident || key != cache.residentKey) {
        cache.resident.reset();
        cache.resident = makeResidentFrame(*gpu_, fo, frame_, q.tracer, q.tracers);
        cache.residentKey = key;
      }
      ec.countRays = true;
      // On the GPU the picture stays there as the sRGB codes the window shows; read back, it
      // is the linear RGBA32F (the values the downloaded path gives, to the bit).
      const bool stay = sharedGpu_ && q.pictureOnGpu;
      const GpuFrameResult r = cache.resident->render(frame_.camera, layerConfig(fo, frame_), gpuEffectParams(frame_, ec),
                                                      stay ? GpuPicture::Srgb8 : GpuPicture::Float32, !stay);
      frame_.capturePipeline = fo.depthPeeling ? "gpu-peel" : "gpu-lists";
      if (stay) {
        out.gpuPicture = cache.resident->picture().id();
        out.pictureWidth = frame_.camera.width(), out.pictureHeight = frame_.camera.height();
      } else {
        out.image = Image(frame_.camera.width(), frame_.camera.height());
        for (size_t i = 0; i < r.float32.size(); ++i)
          for (int c = 0; c < 3; ++c) out.image.data[3 * i + size_t(c)] = r.float32[i][c];
        out.traced = out.image;
      }
      out.captureMs = r.captureMs + r.layersMs;
      out.structureMs = r.pyramidMs;
      out.traceMs = r.traceMs;
      out.shadeMs = r.shadeMs;
      out.rays = r.sums[0];
      out.iterationsMean = r.sums[0] ? double(r.sums[2]) / double(r.sums[0]) : 0.0;
      out.device = out.shading = "gpu";
      out.gpuFrame = gpuActivityReading();
      for (auto& [name, value] : out.gpuFrame.items()) value = value.get<uint64_t>() - activityBefore.value(name, uint64_t(0));
      releaseGpu(*gpu_);  // the frame is kept: whichever thread renders next, or destroys it, takes the context
      out.totalMs = msSince(t0);
      return out;
    }
#endif
    if (gpu_) {
      makeGpuCurrent(*gpu_);
      rasterizeFrameOnGpu(*gpu_, fo, "lists", frame_);
    } else {
      rasterizeFrame(fo, frame_);
    }
    out.captureMs = frame_.rasterMs + frame_.sortMs;

    ViewCache& cache = *cache_;
    const TracerEntry* entry = findTracer(q.tracer);
    if (!entry) inputError("--tracer ", q.tracer, ": unknown (use ", tracerNames(), ")");
    // Screen-space tracers and the hybrid depend on this frame's layers: built every frame.
    const bool viewIndependent = entry->info.kind == TracerKind::Geometric || entry->info.kind == TracerKind::ViewIndependent;
    BuiltTracer fresh;
    const BuiltTracer* built = nullptr;
    const auto ts = std::chrono::steady_clock::now();
    const bool onGpu = gpu_ && hasGpuTracer(q.tracer);
    if (onGpu) {
      fresh = buildGpuTracer(q.tracer, frame_, q.tracers, *gpu_);
      built = &fresh;
    } else if (!viewIndependent) {
      fresh = entry->build(frame_, q.tracers);
      built = &fresh;
    } else {
      const std::string key = structureKey(*entry, q.tracers);
      auto it = cache.geometric.find(key);
      if (it == cache.geometric.end()) it = cache.geometric.emplace(key, entry->build(frame_, q.tracers)).first;
      built = &it->second;
    }
    out.structureMs = msSince(ts);

    std::unique_ptr<ClassifyObserver> classes;
    if (q.overlay == ViewOverlay::Classes) {
      if (!cache.reference) cache.reference = std::make_unique<BuiltTracer>(buildReference(frame_));
      classes = std::make_unique<ClassifyObserver>(*cache.reference->tracer, frame_.camera, frame_.layers);
    }
    ec.countRays = q.overlay == ViewOverlay::Iterations;  // the heat map needs the counters
    ec.wholeWaves = onGpu;  // one dispatch per wave
    ec.shadeOnDevice = onGpu;
    out.device = onGpu ? "gpu" : "cpu";
    EffectResult r = renderEffect(frame_, *built->tracer, ec, classes.get());
    out.traceMs = r.traceMs;
    out.shadeMs = r.shadeMs;
    out.shading = r.onDevice ? "gpu" : "cpu";
    out.rays = r.rays;
    out.iterationsMean = r.rays ? double(r.iterationSum) / double(r.rays) : 0.0;
    switch (q.overlay) {
      case ViewOverlay::None: out.image = r.image; break;
      case ViewOverlay::Classes: {
        out.image = classes->classImage();
        const auto counts = classes->counts();
        uint64_t total = 0;
        for (uint64_t c : counts) total += c;
        for (int i = 0; i < kRayClasses; ++i) out.classFractions[size_t(i)] = total ? double(counts[size_t(i)]) / double(total) : 0.0;
        out.classified = true;
        break;
      }
      case ViewOverlay::Iterations: out.image = iterationHeat(r); break;
      case ViewOverlay::Layer: out.image = layerAlbedo(frame_.layers, std::clamp(q.layer, 0, frame_.layers.k - 1)); break;
      case ViewOverlay::DepthComplexity:
        out.image = depthComplexityImages(frame_.camera.width(), frame_.camera.height(), frame_.lists.complexity).heat;
        break;
    }
    out.traced = std::move(r.image);
    if (gpu_) {
      out.gpuFrame = gpuActivityReading();
      for (auto& [key, value] : out.gpuFrame.items()) value = value.get<uint64_t>() - activityBefore.value(key, uint64_t(0));
    }
  } catch (const InputError& e) {
    out = ViewResult{};
    out.scale = std::max(1, q.scale);
    out.error = e.what();
  }
  if (gpu_) releaseGpu(*gpu_);  // (after this frame's GPU objects went) for whichever thread comes next
  out.totalMs = msSince(t0);
  return out;
}

}  // namespace lt
