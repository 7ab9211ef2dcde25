#include "layertrace/render/frame_sequence.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>

#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/util/error.h"
#include "layertrace/util/timing.h"
#if LAYERTRACE_HAS_GPU
#include "layertrace/gpu/gpu_frame.h"
#include "layertrace/hiz/hiz_pyramid.h"
#include "layertrace/render/gpu_effect_params.h"
#endif

namespace lt {

namespace {

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// Frame i's view: the orbit's camera at the options' size, with the frame's z-thickness.
void viewFrame(const FrameOptions& options, const CameraDesc& start, int i, Frame& frame) {
  setFrameView(options, orbitCamera(start, i), frame);
}

std::vector<FrameSample> runOnCpu(const FrameOptions& options, Frame& frame, const FrameSequenceConfig& c) {
  std::vector<FrameSample> out;
  const CameraDesc start = frame.camera.desc();
  EffectConfig ec = c.effect;
  ec.progress = false;
  for (int i = 0; i < c.frames; ++i) {
    FrameSample s;
    s.frame = i;
    const auto t0 = std::chrono::steady_clock::now();
    viewFrame(options, start, i, frame);
    rasterizeFrame(options, frame);
    s.captureMs = frame.rasterMs + frame.sortMs;
    const BuiltTracer b = buildTracer(c.tracer, frame, c.tracers);
    s.pyramidMs = b.buildMs;
    const EffectResult r = renderEffect(frame, *b.tracer, ec);
    s.wallMs = msSince(t0);
    s.traceMs = r.traceMs, s.shadeMs = r.shadeMs;
    s.rays = r.rays, s.hits = r.hits, s.fragments = frame.lists.generated;
    if (c.onImage) c.onImage(i, r.image);
    out.push_back(s);
  }
  return out;
}

#if LAYERTRACE_HAS_GPU
/// The tracers of hasResidentFrame, for messages.
constexpr const char* kResidentTracers = "hssr, hiz, exhaustive, ssr, ssr-layers, quadtree, ldc or grid";

Image imageOf(const Camera& camera, const std::vector<glm::vec3>& rows) {
  Image img(camera.width(), camera.height());
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) img.set(x, y, rows[size_t(y) * size_t(img.width) + size_t(x)]);
  return img;
}

/// The resident frame's configuration for the tracer `name` (hasResidentFrame).
GpuFrameConfig residentConfig(const FrameOptions& options, const std::string& name, const TracerOptions& to) {
  GpuFrameConfig fc;
  fc.capture.method = options.depthPeeling ? GpuCaptureMethod::Peel : GpuCaptureMethod::Lists;
  fc.capture.poolCapacity = options.pool;
  fc.capture.growOnOverflow = options.pool == 0;
  fc.capture.frontFacesOnly = options.frontFacesOnly;
  if (isResidentSceneTracer(name)) return fc;  // (its structure: attachSceneTracer)
  if (name == "quadtree") {
    fc.quadtree = to.quadtree;
    return fc;
  }
  if (name == "ssr" || name == "ssr-layers") {
    fc.ssr = true;
    fc.ssrMarch = to.ssr;
    fc.ssrMarch.allLayers = name == "ssr-layers";
    return fc;
  }
  const bool hiz = name == "hiz";
  fc.march = hiz ? hizConfig(to.pyramid.levels) : to.hssr;
  fc.march.maxLevels = name == "exhaustive" ? 1 : to.pyramid.levels;
  fc.pyramid = hiz ? PyramidConfig{to.pyramid.levels, std::numeric_limits<float>::infinity()} : to.pyramid;
  if (name == "exhaustive") fc.pyramid.levels = 1;
  return fc;
}

/// The structure of the scene tracer `name` (isResidentSceneTracer), built by the CPU and
/// uploaded once, as the tracer of `fc`'s effect waves.
BuiltTracer attachSceneTracer(GpuContext& gpu, const Frame& frame, const std::string& name, const TracerOptions& tracers, GpuFrameConfig& fc) {
  BuiltTracer b = buildGpuTracer(name, frame, tracers, gpu);
  fc.sceneTracer = dynamic_cast<GpuEffectTracer*>(b.tracer.get());
  LT_CHECK(fc.sceneTracer && fc.sceneTracer->effectsOnDevice(), name);
  return b;
}

std::vector<FrameSample> runOnGpu(const FrameOptions& options, Frame& frame, const FrameSequenceConfig& c, GpuContext& gpu) {
  const std::string& name = c.tracer;
  if (!hasResidentFrame(name)) inputError("--tracer ", name, ": the resident GPU frame traces with ", kResidentTracers, " (bench --experiment frame --device gpu)");
  EffectConfig ec = c.effect;
  ec.progress = false;
  const CameraDesc start = frame.camera.desc();
  std::unique_ptr<GpuFrame> resident;
  std::vector<FrameSample> out;
  for (int i = 0; i < c.frames; ++i) {
    FrameSample s;
    s.frame = i;
    const GpuActivity before = gpuActivity();
    const auto t0 = std::chrono::steady_clock::now();
    viewFrame(options, start, i, frame);
    const LayerConfig layers = layerConfig(options, frame);
    // The first frame uploads the scene (and a tracer's structure of the scene) and links the
    // programs: it is counted with them.
    if (!resident) resident = makeResidentFrame(gpu, options, frame, name, c.tracers);
    const GpuFrameResult r = resident->render(frame.camera, layers, gpuEffectParams(frame, ec), c.onImage ? GpuPicture::Linear : GpuPicture::None);
    s.wallMs = msSince(t0);
    const GpuActivity a = gpuActivity() - before;
    s.gpuMs = r.gpuMs();
    s.captureMs = r.captureMs + r.layersMs, s.pyramidMs = r.pyramidMs, s.traceMs = r.traceMs, s.shadeMs = r.shadeMs;
    s.uploadBytes = a.uploadBytes, s.downloadBytes = a.downloadBytes, s.hostWaits = a.hostWaits, s.programLinks = a.programLinks;
    s.bufferAllocations = a.bufferAllocations, s.dispatches = a.dispatches, s.draws = a.draws;
    s.rays = r.sums[0], s.hits = r.sums[1], s.fragments = r.fragments, s.attempts = r.attempts;
    if (c.onImage) c.onImage(i, imageOf(frame.camera, r.image));
    out.push_back(s);
  }
  return out;
}
#endif

}  // namespace

bool isGpuFrameTracer(const std::string& name) {
  return name == "hssr" || name == "hiz" || name == "exhaustive" || name == "ssr" || name == "ssr-layers";
}

bool isResidentSceneTracer(const std::string& tracer) { return tracer == "ldc" || tracer == "grid"; }

bool hasResidentFrame(const std::string& tracer) { return isGpuFrameTracer(tracer) || tracer == "quadtree" || isResidentSceneTracer(tracer); }

bool rendersResident(const std::string& tracer, const Frame& frame, const EffectConfig& effect) {
#if LAYERTRACE_HAS_GPU
  // (the grid's hits on alpha-tested triangles need the CPU grid's texel test: GpuGridTracer)
  return hasResidentFrame(tracer) && !(tracer == "grid" && frame.scene.anyCutOut()) && GpuEffects::supports(int(frame.lights.size())) &&
         effect.effect != Effect::Warp;
#else
  (void)tracer, (void)frame, (void)effect;
  return false;
#endif
}

std::unique_ptr<GpuFrame> makeResidentFrame(GpuContext& gpu, const FrameOptions& options, const Frame& frame, const std::string& tracer,
                                            const TracerOptions& tracers, const Scene* geometry) {
#if LAYERTRACE_HAS_GPU
  if (!hasResidentFrame(tracer)) inputError("tracer \"", tracer, "\": the resident GPU frame traces with ", kResidentTracers);
  const bool sceneTracer = isResidentSceneTracer(tracer);
  if (sceneTracer && geometry)
    inputError("tracer \"", tracer, "\": its structure is built from the scene, not from a caller's draw calls (use a screen tracer)");
  if (tracer == "grid" && frame.scene.anyCutOut())
    inputError("--tracer grid: the scene's alpha-tested triangles need the CPU grid's texel test, which the resident GPU frame "
               "does not run (render --device gpu shades them on the CPU)");
  if (!GpuEffects::supports(int(frame.lights.size())))
    inputError("--device gpu: ", frame.lights.size(), " lights, more than the GPU frame's ", GpuEffects::kMaxLights);
  validateTracerOptions(tracers);
  GpuFrameConfig fc = residentConfig(options, tracer, tracers);
  fc.capture.layers = layerConfig(options, frame);
  if (sceneTracer) fc.sceneTracerOwner = std::make_shared<BuiltTracer>(attachSceneTracer(gpu, frame, tracer, tracers, fc));
  return std::make_unique<GpuFrame>(gpu, geometry ? *geometry : frame.scene, frame.lights, fc);
#else
  (void)gpu, (void)options, (void)frame, (void)tracer, (void)tracers, (void)geometry;
  openGpu();  // throws: this build has no GPU back end
  throw InternalError("no GPU back end in this build");
#endif
}

ResidentRender renderResident(const FrameOptions& options, Frame& frame, const std::string& tracer, const TracerOptions& tracers,
                              const EffectConfig& effect, int repeat, bool srgb8, GpuContext& gpu) {
  LT_CHECK(rendersResident(tracer, frame, effect), tracer);
  if (repeat < 1) inputError("--repeat ", repeat, ": must be at least 1");
  ResidentRender out;
#if LAYERTRACE_HAS_GPU
  validateTracerOptions(tracers);
  GpuFrameConfig fc = residentConfig(options, tracer, tracers);
  fc.capture.layers = layerConfig(options, frame);
  const nlohmann::json before = gpuActivityReading();
  const auto t0 = std::chrono::steady_clock::now();
  // (a tracer of the scene: its structure's build and upload are counted with the frame)
  if (isResidentSceneTracer(tracer)) out.structure = attachSceneTracer(gpu, frame, tracer, tracers, fc);
  GpuFrame resident(gpu, frame.scene, frame.lights, fc);
  const GpuEffectParams params = gpuEffectParams(frame, effect);
  const GpuFrameResult r = resident.render(frame.camera, fc.capture.layers, params, srgb8 ? GpuPicture::Srgb8 : GpuPicture::Float32);
  out.frameAccount = gpuFrameStats(before, gpuActivityReading(), msSince(t0), r.gpuMs());
  if (const GpuQuadtreeTracer* q = resident.quadtree()) {
    // The tree's statistics (its node kinds and depth scale: read after the frame's account)
    BuiltTracer b;
    b.quadtree = std::make_unique<Quadtree>(q->summary());
    b.buildMs = b.quadtree->buildMs;
    b.memoryBytes = q->memoryBytes();
    out.structure = std::move(b);
  }
  EffectResult& e = out.effect;
  if (srgb8) {
    out.srgb8.resize(r.srgb8.size() * 3);
    for (size_t i = 0; i < r.srgb8.size(); ++i)
      for (size_t c = 0; c < 3; ++c) out.srgb8[3 * i + c] = uint8_t(r.srgb8[i] >> (8 * c));
  } else {
    e.image = Image(frame.camera.width(), frame.camera.height());
    for (size_t i = 0; i < r.float32.size(); ++i) e.image.set(int(i % size_t(e.image.width)), int(i / size_t(e.image.width)), glm::vec3(r.float32[i]));
  }
  e.rays = r.sums[0], e.hits = r.sums[1], e.iterationSum = r.sums[2], e.intervalSum = r.sums[3], e.pixelSum = r.sums[4];
  e.giveUps = r.sums[5], e.bentRays = r.sums[6];
  for (int l = 0; l < RayCounters::kLevels; ++l) e.levelIterations[l] = r.sums[8 + size_t(l)];
  e.iterationsP99 = r.iterationsP99;
  e.planeNodeSum = r.tracerSums.planeNodes, e.boxNodeSum = r.tracerSums.boxNodes, e.occlusionSum = r.tracerSums.occlusions;
  e.onDevice = true;
  e.traceMs = r.traceMs, e.shadeMs = r.shadeMs;
  e.deviceBytes = resident.effectBytes();
  out.captureBytes = resident.captureBytes();
  out.fragments = r.fragments, out.poolCapacity = r.poolCapacity, out.overflowLost = r.overflowLost, out.maxComplexity = r.maxComplexity;
  out.levelIntervals.assign(r.levelIntervals.begin(), r.levelIntervals.end());
  out.rasterMs = r.rasterMs, out.sortMs = r.sortMs, out.layersMs = r.layersMs, out.pyramidMs = r.pyramidMs;
  out.hierarchyBytes = resident.hierarchyBytes();
  out.attempts = r.attempts;
  // The timed repeats: the effect again over the same layers, without counters (as measureTrace).
  GpuEffectParams timed = params;
  timed.countRays = false;
  std::vector<double> trace, shade;
  for (int i = 0; i < repeat; ++i) {
    double t = 0.0, sh = 0.0;
    resident.retrace(timed, t, sh);
    trace.push_back(t), shade.push_back(sh);
  }
  out.timedTraceMs = median(std::move(trace)), out.timedShadeMs = median(std::move(shade));
#else
  (void)options, (void)frame, (void)tracers, (void)srgb8, (void)gpu;
#endif
  return out;
}

ResidentStages measureResidentStages(const FrameOptions& options, Frame& frame, const std::string& tracer, const TracerOptions& tracers,
                                     const EffectConfig& effect, int repeat, GpuContext& gpu) {
  if (repeat < 1) inputError("--repeat ", repeat, ": must be at least 1");
  ResidentStages out;
#if LAYERTRACE_HAS_GPU
  const std::unique_ptr<GpuFrame> resident = makeResidentFrame(gpu, options, frame, tracer, tracers);
  const LayerConfig layers = layerConfig(options, frame);
  const GpuEffectParams counted = gpuEffectParams(frame, effect);
  // The first frame uploads the scene and is counted; the timed ones read no counter.
  const GpuFrameResult c = resident->render(frame.camera, layers, counted, GpuPicture::None);
  out.iterationsMean = c.sums[0] ? double(c.sums[2]) / double(c.sums[0]) : 0.0;
  GpuEffectParams timed = counted;
  timed.countRays = false;
  std::vector<double> raster, sort, arrays, pyramid, trace, shade;
  for (int i = 0; i < repeat; ++i) {
    const GpuFrameResult r = resident->render(frame.camera, layers, timed, GpuPicture::None);
    raster.push_back(r.rasterMs), sort.push_back(r.sortMs), arrays.push_back(r.layersMs);
    pyramid.push_back(r.pyramidMs), trace.push_back(r.traceMs), shade.push_back(r.shadeMs);
  }
  out.rasterMs = median(raster), out.sortMs = median(sort), out.layersMs = median(arrays);
  out.pyramidMs = median(pyramid), out.traceMs = median(trace), out.shadeMs = median(shade);
  out.memoryBytes = resident->captureBytes() + resident->hierarchyBytes();
  out.effectBytes = resident->effectBytes();
#else
  (void)options, (void)frame, (void)tracer, (void)tracers, (void)effect, (void)gpu;
  openGpu();  // throws: this build has no GPU back end
#endif
  return out;
}

ResidentCapture measureResidentCapture(const FrameOptions& options, Frame& frame, int repeat, GpuContext& gpu) {
  if (repeat < 1) inputError("--repeat ", repeat, ": must be at least 1");
  ResidentCapture out;
#if LAYERTRACE_HAS_GPU
  const std::unique_ptr<GpuFrame> resident = makeResidentFrame(gpu, options, frame, "hssr", TracerOptions{});
  const LayerConfig layers = layerConfig(options, frame);
  resident->build(frame.camera, layers);  // warm-up: the scene's upload
  std::vector<double> raster, sort;
  for (int i = 0; i < repeat; ++i) {
    const GpuFrameResult r = resident->build(frame.camera, layers);
    raster.push_back(r.rasterMs), sort.push_back(r.sortMs);
    out.fragments = r.fragments;
  }
  out.rasterMs = median(std::move(raster)), out.sortMs = median(std::move(sort));
  out.bytes = resident->captureBytes();
#else
  (void)options, (void)frame, (void)gpu;
  openGpu();  // throws: this build has no GPU back end
#endif
  return out;
}

CameraDesc orbitCamera(const CameraDesc& desc, int i, float degrees) {
  CameraDesc d = desc;
  if (i == 0) return d;
  const glm::vec3 up = glm::length(desc.up) > 0.0f ? glm::normalize(desc.up) : glm::vec3(0.0f, 1.0f, 0.0f);
  const glm::vec3 offset = desc.eye - desc.target;
  const glm::vec3 along = up * glm::dot(offset, up), across = offset - along;
  const glm::vec3 side = glm::cross(up, across);
  const float angle = glm::radians(degrees * float(i));
  d.eye = desc.target + along + across * std::cos(angle) + side * std::sin(angle);
  return d;
}

std::vector<FrameSample> runFrameSequence(const FrameOptions& options, Frame& frame, const FrameSequenceConfig& config, GpuContext* gpu) {
  if (config.frames < 1) inputError("--frames ", config.frames, ": must be at least 1");
  validateEffectConfig(config.effect);
#if LAYERTRACE_HAS_GPU
  if (gpu) return runOnGpu(options, frame, config, *gpu);
#else
  if (gpu) openGpu();
#endif
  return runOnCpu(options, frame, config);
}

nlohmann::json frameSampleJson(const FrameSample& s) {
  return {{"frame", s.frame},
          {"wall_ms", s.wallMs},
          {"gpu_ms", s.gpuMs},
          {"capture_ms", s.captureMs},
          {"pyramid_ms", s.pyramidMs},
          {"trace_ms", s.traceMs},
          {"shade_ms", s.shadeMs},
          {"upload_bytes", s.uploadBytes},
          {"download_bytes", s.downloadBytes},
          {"host_waits", s.hostWaits},
          {"program_links", s.programLinks},
          {"buffer_allocations", s.bufferAllocations},
          {"dispatches", s.dispatches},
          {"draws", s.draws},
          {"rays", s.rays},
          {"hits", s.hits},
          {"fragments", s.fragments},
          {"attempts", s.attempts}};
}

nlohmann::json frameSummary(const std::vector<FrameSample>& samples) {
  nlohmann::json summary = {{"frames", samples.size()}};
  if (samples.empty()) return summary;
  // The steady state: the frames after the first (which uploads, links and allocates).
  const size_t first = samples.size() > 1 ? 1 : 0;
  std::vector<nlohmann::json> rows;
  for (size_t i = first; i < samples.size(); ++i) rows.push_back(frameSampleJson(samples[i]));
  for (const auto& [key, value] : rows.front().items()) {
    if (key == "frame") continue;
    std::vector<double> v;
    for (const nlohmann::json& r : rows) v.push_back(r[key].get<double>());
    const double m = median(v);
    if (value.is_number_integer() || value.is_number_unsigned()) summary[key] = uint64_t(std::llround(m));
    else summary[key] = m;
  }
  return summary;
}

}  // namespace lt
