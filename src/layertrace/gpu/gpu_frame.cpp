#include "layertrace/gpu/gpu_frame.h"

#include <algorithm>
#include <array>
#include <bit>
#include <initializer_list>

#include <epoxy/gl.h>
#include <glm/gtc/type_ptr.hpp>

#include "layertrace/gpu/shader_sources.h"
#include "layertrace/hssr/hssr_method.h"
#include "layertrace/raster/fragment.h"
#include "layertrace/util/default_init.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"
#include "layertrace/util/parallel.h"

namespace lt {

namespace {

/// status_ words: the fragments generated, the depth complexity's maximum, the fragments kept
/// in the layers, the pyramid's
/// per-level totals, the effect's sums and percentile (gpu_effects.h kSumsWords).
constexpr size_t kFragmentsWord = 0, kComplexityWord = 1, kKeptWord = 2, kLevelsWord = 3, kSumsWord = kLevelsWord + GpuPyramid::kStatusWords,
                 kStatusWords = kSumsWord + kSumsWords;
/// With the quad-tree, its six node-counter words follow (read only then).
constexpr size_t kNodeSumsWord = kStatusWords, kNodeSumsWords = 6;

enum Stage { kCapture, kLayers, kPyramid, kStages };

}  // namespace

GpuFrame::GpuFrame(GpuContext& gpu, const Scene& scene, std::span<const PointLight> lights, const GpuFrameConfig& config)
    : gpu_(gpu), scene_(scene), lights_(lights.begin(), lights.end()), config_(config) {
  if (config.capture.keepLists) inputError("a resident GPU frame keeps no fragment lists (layers --verify reads them)");
  validateHssrConfig(config.march);
  LT_CHECK(lights.size() <= size_t(GpuEffects::kMaxLights), lights.size());
  LT_CHECK(!config.sceneTracer || config.sceneTracer->effectsOnDevice(), "a tracer of the scene that answers on the device");
}

void GpuFrame::create() {
  const Scene& scene = scene_;
  capture_ = std::make_unique<GpuCapture>(gpu_, scene);
  if (config_.quadtree) {
    quadtree_ = std::make_unique<GpuQuadtreeTracer>(gpu_, *config_.quadtree);
  } else if (!config_.sceneTracer) {
    tracer_ = config_.ssr ? std::make_unique<GpuScreenTracer>(gpu_, config_.ssrMarch)
                          : std::make_unique<GpuScreenTracer>(gpu_, config_.pyramid, config_.march);
    if (persistent_) tracer_->setPersistentThreads(*persistent_);
  }
  effects_ = std::make_unique<GpuEffects>(gpu_, scene, lights_);
  if (config_.sceneTracer) config_.sceneTracer->shareSceneTables(&capture_->sceneTables());
  layersPass_ = &gpu_.computeProgram("frame_layers.comp", shader_source::frame_layers_comp);
  trianglesPass_ = &gpu_.computeProgram("frame_triangles.comp", shader_source::frame_triangles_comp);
  picturePass_ = &gpu_.computeProgram("frame_picture.comp", shader_source::frame_picture_comp);
  gatherPass_ = &gpu_.computeProgram("frame_gather.comp", shader_source::frame_gather_comp);
  timer_ = std::make_unique<GpuTimer>();
  std::vector<glm::vec4> materials;
  for (const Material& m : scene.materials) materials.emplace_back(m.mirror, m.shininess, m.transmission, m.ior);
  if (materials.empty()) materials.emplace_back(0.0f);
  materials_ = GpuBuffer(materials.size() * sizeof(glm::vec4), materials.data());
  triangles_ = GpuBuffer((scene.triangles.size() + 1) * 32);
  status_ = GpuBuffer((kStatusWords + kNodeSumsWords) * sizeof(uint32_t));
  reduced_ = GpuBuffer(2 * sizeof(uint32_t));
}

GpuFrame::~GpuFrame() {
  gpu_.makeCurrent();
  if (config_.sceneTracer && capture_) config_.sceneTracer->shareSceneTables(nullptr);  // (the capture's go)
  effects_.reset(), tracer_.reset(), quadtree_.reset(), capture_.reset();  // before the buffers they read
}

size_t GpuFrame::memoryBytes() const {
  if (!capture_) return 0;
  size_t bytes = capture_->memoryBytes() + effects_->memoryBytes() + materials_.bytes() + level0_.bytes() + status_.bytes() + reduced_.bytes() +
                 picture_.bytes();
  if (tracer_ && tracer_->pyramid()) bytes += tracer_->pyramid()->memoryBytes();
  if (quadtree_) bytes += quadtree_->memoryBytes();
  return bytes;  // (effects_ counts fragments_ and triangles_)
}

const GpuEffectTracer& GpuFrame::effectTracer() const {
  if (tracer_) return *tracer_;
  if (quadtree_) return *quadtree_;
  return *config_.sceneTracer;
}

const GpuScreenTracer& GpuFrame::ownMarch() const {
  LT_CHECK(tracer_ != nullptr, "a frame traced by a tracer of the scene has no march of its own");
  return *tracer_;
}

void GpuFrame::submit(const Camera& camera, const GpuEffectParams* effect, GpuPicture picture, GpuFrameResult& out) {
  const int W = camera.width(), H = camera.height(), k = config_.capture.layers.k;
  const size_t pixels = size_t(W) * size_t(H), slots = pixels * size_t(k);
  timeline_.begin(kCapture);
  if (geometryPass_) {
    GpuDebugGroup group("geometry");
    geometryPass_(*capture_);
  }
  if (inputLayers_) inputLayers_(*capture_, camera);
  else capture_->submit(camera, config_.capture);
  timeline_.end(kCapture);

  {
    GpuDebugGroup group("layers");
    timeline_.begin(kLayers);
    if (level0_.bytes() != std::max<size_t>(slots * 8, 16)) {
      level0_ = GpuBuffer(slots * 8);
      fragments_ = GpuBuffer(slots * 16);
    }
    reduced_.fill(0u);
    capture_->slots().bindStorage(0), capture_->counts().bindStorage(1), capture_->slotTriangle().bindStorage(2);
    level0_.bindStorage(3), fragments_.bindStorage(4), capture_->complexity().bindStorage(5), reduced_.bindStorage(6);
    layersPass_->set("uPixels", int(pixels));
    layersPass_->set("uK", k);
    gpu_.dispatch(*layersPass_, pixels);
    // The effect passes' per-triangle records for this view.
    trianglesPass_->set("uTriangleCount", int(scene_.triangles.size()));
    trianglesPass_->setMatrix("uView", glm::value_ptr(camera.view()));
    capture_->bindScene(0, 1, 2);
    materials_.bindStorage(3), triangles_.bindStorage(4);
    gpu_.dispatch(*trianglesPass_, scene_.triangles.size() + 1);
    timeline_.end(kLayers);
  }

  timeline_.begin(kPyramid);
  if (tracer_) tracer_->rebuild(camera, level0_, capture_->counts(), k);
  else if (quadtree_) quadtree_->rebuild(camera, level0_, capture_->counts(), k);
  else config_.sceneTracer->setEffectCamera(camera);
  timeline_.end(kPyramid);

  effects_->setFrame(camera, fragments_, triangles_, k);
  if (effect) {
    GpuEffectReadback readback{};
    readback.image = picture == GpuPicture::Linear;
    readback.tally = readback.histogram = readback.sums = false;
    const GpuEffectOutput eo = effects_->run(effectTracer(), *effect, readback);
    if (readback.image) {
      out.image = eo.image;
      out.traceMs = eo.traceMs, out.shadeMs = eo.shadeMs;
    }
  }
  if (effect && (picture == GpuPicture::Srgb8 || picture == GpuPicture::Float32)) {
    // Packed in rows on the device; read with the counters, after the frame's one wait.
    GpuDebugGroup group("picture");
    const bool srgb = picture == GpuPicture::Srgb8;
    const size_t bytes = pixels * (srgb ? 4 : 16);
    if (picture_.bytes() < bytes) picture_ = GpuBuffer(bytes);
    effects_->picture().bindStorage(0), picture_.bindStorage(srgb ? 1 : 2);
    picturePass_->set("uWidth", W);
    picturePass_->set("uHeight", H);
    picturePass_->set("uFormat", srgb ? 0 : 1);
    if (srgb) {
      static const std::array<float, 255> thresholds = srgb8Thresholds();
      glProgramUniform1fv(picturePass_->id(), glGetUniformLocation(picturePass_->id(), "uThresholds"), 255, thresholds.data());
    }
    gpu_.dispatch(*picturePass_, pixels);
  }

  // The frame's counters into one block, read with one wait.
  GpuDebugGroup group("counters");
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT | GL_SHADER_STORAGE_BARRIER_BIT);
  glCopyNamedBufferSubData(capture_->counter().id(), status_.id(), 0, kFragmentsWord * 4, 4);
  static_assert(kKeptWord == kComplexityWord + 1);
  glCopyNamedBufferSubData(reduced_.id(), status_.id(), 0, kComplexityWord * 4, 8);
  if (tracer_ && tracer_->pyramid())
    glCopyNamedBufferSubData(tracer_->pyramid()->status.id(), status_.id(), 0, kLevelsWord * 4, GpuPyramid::kStatusWords * 4);
  else
    glClearNamedBufferSubData(status_.id(), GL_R32UI, kLevelsWord * 4, GpuPyramid::kStatusWords * 4, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
  if (effect) glCopyNamedBufferSubData(effects_->sums().id(), status_.id(), 0, kSumsWord * 4, kSumsWords * 4);
  else glClearNamedBufferSubData(status_.id(), GL_R32UI, kSumsWord * 4, kSumsWords * 4, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
  if (quadtree_ && effect)
    glCopyNamedBufferSubData(quadtree_->effectSumsBuffer().id(), status_.id(), 0, kNodeSumsWord * 4, kNodeSumsWords * 4);
  else if (quadtree_)
    glClearNamedBufferSubData(status_.id(), GL_R32UI, kNodeSumsWord * 4, kNodeSumsWords * 4, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
}

GpuFrameResult GpuFrame::render(const Camera& camera, const LayerConfig& layers, const GpuEffectParams& effect, GpuPicture picture,
                                bool readPicture) {
  return run(camera, layers, &effect, picture, readPicture);
}

GpuFrameResult GpuFrame::build(const Camera& camera, const LayerConfig& layers) {
  return run(camera, layers, nullptr, GpuPicture::None, false);
}

GpuFrameResult GpuFrame::run(const Camera& camera, const LayerConfig& layers, const GpuEffectParams* effect, GpuPicture picture,
                             bool readPicture) {
  LT_CHECK(layers.k == config_.capture.layers.k, layers.k, config_.capture.layers.k);
  config_.capture.layers = layers;
  camera_ = camera;
  gpu_.makeCurrent();
  GpuDebugGroup frame("frame");
  if (!capture_) create();
  GpuFrameResult out;
  for (out.attempts = 1;; ++out.attempts) {
    submit(camera, effect, picture, out);
    uint32_t status[kStatusWords + kNodeSumsWords] = {};
    status_.read(status, (kStatusWords + (quadtree_ ? kNodeSumsWords : 0)) * sizeof(uint32_t));
    // The GPU times, read after the frame's one wait (they wait no more).
    const std::vector<double> ms = timeline_.collect(kStages);
    out.captureMs = ms[kCapture], out.layersMs = ms[kLayers], out.pyramidMs = ms[kPyramid];
    out.rasterMs = capture_->setupMs() + capture_->rasterMs(), out.sortMs = capture_->sortMs();
    if (effect && picture != GpuPicture::Linear) effects_->collectTimes(out.traceMs, out.shadeMs);
    out.fragments = status[kFragmentsWord];
    bool again = false;
    if (config_.capture.method == GpuCaptureMethod::Lists && out.fragments > capture_->poolCapacity()) {
      if (!config_.capture.growOnOverflow)
        inputError("--pool ", config_.capture.poolCapacity, ": fragment pool overflow: ", out.fragments, " fragments generated, ",
                   capture_->poolCapacity(), " stored, ", out.fragments - capture_->poolCapacity(), " lost (use --pool ", out.fragments,
                   " or more, or 0 for automatic)");
      if (out.attempts == 1) out.overflowLost = out.fragments - capture_->poolCapacity();
      capture_->growPool(std::max<uint64_t>(out.fragments, 2 * capture_->poolCapacity()));
      again = true;
    }
    if (tracer_ && tracer_->pyramid() && !tracer_->pyramid()->fits(status + kLevelsWord)) again = true;
    if (again) {
      LT_CHECK(out.attempts < 4, out.attempts, out.fragments);
      continue;
    }
    const size_t pixels = size_t(camera.width()) * size_t(camera.height());
    if (readPicture && picture == GpuPicture::Srgb8) out.srgb8.resize(pixels), picture_.read(out.srgb8.data(), pixels * 4);
    if (readPicture && picture == GpuPicture::Float32) out.float32.resize(pixels), picture_.read(out.float32.data(), pixels * 16);
    out.levelIntervals.assign(status + kLevelsWord, status + kLevelsWord + (tracer_ && tracer_->pyramid() ? tracer_->pyramid()->levels : 1));
    const auto word64 = [&](size_t w) { return uint64_t(status[w]) | uint64_t(status[w + 1]) << 32; };
    for (size_t i = 0; i < 16; ++i) out.sums[i] = word64(kSumsWord + 2 * i);
    out.tracerSums = {word64(kNodeSumsWord), word64(kNodeSumsWord + 2), word64(kNodeSumsWord + 4)};
    out.iterationsP99 = effect && effect->countRays ? status[kSumsWord + kPercentileWord] : 0;
    out.maxComplexity = status[kComplexityWord];
    out.levelIntervals[0] = status[kKeptWord];
    out.poolCapacity = capture_->poolCapacity();
    return out;
  }
}

void GpuFrame::retrace(const GpuEffectParams& effect, double& traceMs, double& shadeMs) {
  LT_CHECK(capture_ != nullptr);
  gpu_.makeCurrent();
  GpuDebugGroup frame("effect again");
  GpuEffectReadback readback{};
  readback.image = readback.tally = readback.histogram = false;
  readback.sums = true;  // the one wait, after which the timer queries are read
  const GpuEffectOutput eo = effects_->run(effectTracer(), effect, readback);
  traceMs = eo.traceMs, shadeMs = eo.shadeMs;
}

void GpuFrame::trace(const GpuBuffer& rays, const GpuBuffer& hits, size_t n) const {
  LT_CHECK(capture_ != nullptr);
  gpu_.makeCurrent();
  GpuDebugGroup group("trace");
  ownMarch().marchResident(rays, hits, n, nullptr, true);
}

double GpuFrame::march(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  LT_CHECK(capture_ != nullptr && hits.size() == rays.size());
  if (rays.empty()) return 0.0;
  gpu_.makeCurrent();
  GpuDebugGroup group("march");
  batch_.upload(rays);
  const size_t n = rays.size();
  const GpuBuffer& answers = batch_.answers(0, n * sizeof(GpuMarchRecord));
  const GpuBuffer& gathered = batch_.answers(1, n * sizeof(glm::uvec4));
  timer_->begin();
  ownMarch().marchResident(batch_.rays(), answers, n, nullptr, !counters.empty());
  timer_->end();
  answers.bindStorage(0), fragments_.bindStorage(1), gathered.bindStorage(2);
  gatherPass_->set("uCount", int(n));
  gatherPass_->set("uWidth", camera_.width());
  gatherPass_->set("uK", config_.capture.layers.k);
  gpu_.dispatch(*gatherPass_, n);
  PoolVector<GpuMarchRecord> marched(n);
  PoolVector<glm::uvec4> stored(n);
  answers.read(marched.data(), n * sizeof(GpuMarchRecord));
  gathered.read(stored.data(), n * sizeof(glm::uvec4));
  glUseProgram(0);
  parallelFor(size_t(0), n, [&](size_t i) {
    const GpuMarchRecord& a = marched[i];
    TraceHit& h = hits[i];
    h = TraceHit{};
    if (a.layer >= 0) {
      const glm::uvec4& f = stored[i];  // as fragmentHit reads the CPU's layers
      h.hit = true;
      h.x = a.x, h.y = a.y, h.layer = a.layer;
      h.point = camera_.rayThrough({float(a.x) + 0.5f, float(a.y) + 0.5f}) * std::bit_cast<float>(f.x);
      h.normal = decodeOctahedral(f.y);
      h.albedoSpec = f.z;
      h.triangle = f.w;
    }
    if (!counters.empty()) addCounters(a, counters[i]);
  });
  return timer_->ms();
}

void GpuFrameTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  totalTraceMs_ += frame_.march(rays, hits, counters);
}

void GpuFrame::setPersistentThreads(bool on) {
  persistent_ = on;
  if (tracer_) tracer_->setPersistentThreads(on);
}

size_t GpuFrame::captureBytes() const { return capture_ ? capture_->memoryBytes() : 0; }
size_t GpuFrame::effectBytes() const { return effects_ ? effects_->memoryBytes() : 0; }

size_t GpuFrame::hierarchyBytes() const {
  if (!capture_) return 0;
  return level0_.bytes() + capture_->counts().bytes() + (tracer_ && tracer_->pyramid() ? tracer_->pyramid()->memoryBytes() : 0) +
         (quadtree_ ? quadtree_->memoryBytes() : 0);
}

}  // namespace lt
