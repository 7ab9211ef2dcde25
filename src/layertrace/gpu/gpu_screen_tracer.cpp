#include "layertrace/gpu/gpu_screen_tracer.h"

#include <algorithm>

#include <epoxy/gl.h>

#include "layertrace/hssr/hssr_method.h"
#include "layertrace/screen/fragment_hit.h"
#include "layertrace/screen/interval_layers.h"
#include "layertrace/ssr/ssr_method.h"
#include "layertrace/util/default_init.h"
#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"
#include "layertrace/gpu/shader_sources.h"

namespace lt {

namespace {

/// shaders/screen_common.glsl GpuRay and GpuHit, std430.
struct RayRecord {
  float origin[3], maxDistance;
  float dir[3], startsOnSurface;
};
struct HitRecord {
  int32_t x, y, layer;
  uint32_t iterations, intervals, pixels, giveUps, pad;
  uint32_t levelIterations[8];
};
static_assert(sizeof(RayRecord) == 32 && sizeof(HitRecord) == 64);
static_assert(RayCounters::kLevels == 8, "the shaders count 8 levels");

/// Persistent threads: work groups launched (16 per multiprocessor of a 132-SM GPU; choice: the
/// queue balances the load, so more groups than the GPU holds at once only add idle launches).
constexpr size_t kPersistentGroups = 2112;
constexpr size_t kGroupSize = 64;  ///< local_size_x of the march shaders

}  // namespace

GpuScreenTracer::GpuScreenTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const IntervalLayers& level0,
                                 const PyramidConfig& pyramid, const HssrConfig& config)
    : gpu_(gpu), camera_(camera), layers_(layers) {
  validateHssrConfig(config);
  gpu_.makeCurrent();
  program_ = gpu_.computeProgram("hssr_march.comp", shader_source::hssr_march_comp);
  upload(level0);
  pyramid_ = std::make_unique<GpuPyramid>();
  buildPyramidOnGpu(gpu, level0_, counts_, camera.width(), camera.height(), level0.k, camera, pyramid, *pyramid_);
  const int levels = std::max(1, std::min(config.maxLevels, pyramid_->levels));
  name_ = levels == 1 ? "exhaustive" : config.name;
  program_.set("uLevels", levels);
  program_.set("uNUp", config.nUp);
  program_.set("uParentAscent", config.parentAscent);
  persistent_ = config.rayReloading;
  program_.set("uLevelWidth", pyramid_->width.data(), GpuPyramid::kMaxLevels);
  program_.set("uLevelHeight", pyramid_->height.data(), GpuPyramid::kMaxLevels);
  program_.set("uLevelOffset", pyramid_->cellBase.data(), GpuPyramid::kMaxLevels);
  timer_ = std::make_unique<GpuTimer>();
}

GpuScreenTracer::GpuScreenTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const SsrConfig& config)
    : gpu_(gpu), camera_(camera), layers_(layers), name_(config.allLayers ? "ssr-layers" : "ssr") {
  validateSsrConfig(config);
  gpu_.makeCurrent();
  program_ = gpu_.computeProgram("ssr_march.comp", shader_source::ssr_march_comp);
  upload(makeIntervalLayers(layers, config.allLayers ? layers.k : 1));
  program_.set("uStride", config.stride);
  program_.set("uJitter", config.jitter);
  program_.set("uMaxSteps", ssrMaxSteps(config, camera.width(), camera.height()));
  program_.set("uRefine", config.refine);
  timer_ = std::make_unique<GpuTimer>();
}

GpuScreenTracer::~GpuScreenTracer() {
  gpu_.makeCurrent();  // the buffers and the program go with the context current
}

void GpuScreenTracer::upload(const IntervalLayers& level0) {
  static_assert(sizeof(Interval) == 8);
  level0_ = GpuBuffer(level0.slots.size() * sizeof(Interval), level0.slots.data());
  const std::vector<uint32_t> counts(level0.count.begin(), level0.count.end());
  counts_ = GpuBuffer(counts.size() * sizeof(uint32_t), counts.data());
  program_.set("uWidth", camera_.width());
  program_.set("uHeight", camera_.height());
  program_.set("uK", level0.k);
  program_.set("uNear", camera_.near());
  program_.set("uOrtho", camera_.orthographic());
  program_.set("uFocal", camera_.focal());
}

size_t GpuScreenTracer::memoryBytes() const {
  return level0_.bytes() + counts_.bytes() + (pyramid_ ? pyramid_->memoryBytes() : 0);
}

void GpuScreenTracer::march(std::span<const Ray> rays, std::vector<GpuMarchHit>& out) const {
  out.resize(rays.size());  // every entry is written below
  lastTraceMs_ = 0.0;
  if (rays.empty()) return;
  gpu_.makeCurrent();
  PoolVector<RayRecord> records(rays.size());
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const Ray& r = rays[i];
    records[i] = {{r.origin.x, r.origin.y, r.origin.z}, r.maxDistance, {r.dir.x, r.dir.y, r.dir.z}, r.startsOnSurface ? 1.0f : 0.0f};
  });
  const size_t rayBytes = records.size() * sizeof(RayRecord), hitBytes = rays.size() * sizeof(HitRecord);
  if (rays_.bytes() < rayBytes) rays_ = GpuBuffer(std::max(rayBytes, 2 * rays_.bytes()));
  if (hits_.bytes() < hitBytes) hits_ = GpuBuffer(std::max(hitBytes, 2 * hits_.bytes()));
  rays_.write(records.data(), rayBytes);
  timer_->begin();
  marchResident(rays_, hits_, rays.size());
  timer_->end();
  PoolVector<HitRecord> answers(rays.size());
  hits_.read(answers.data(), hitBytes);
  lastTraceMs_ = timer_->ms();
  totalTraceMs_ += lastTraceMs_;
  glUseProgram(0);
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const HitRecord& a = answers[i];
    GpuMarchHit& h = out[i];
    h.counters = RayCounters{};
    h.x = a.x, h.y = a.y, h.layer = a.layer;
    h.counters.iterations = a.iterations;
    h.counters.intervals = a.intervals;
    h.counters.pixels = a.pixels;
    h.counters.giveUps = a.giveUps;
    std::copy(std::begin(a.levelIterations), std::end(a.levelIterations), h.counters.levelIterations);
  });
}

void GpuScreenTracer::marchResident(const GpuBuffer& rays, const GpuBuffer& hits, size_t n) const {
  if (n == 0) return;
  rays.bindStorage(0);
  hits.bindStorage(1);
  level0_.bindStorage(2);
  counts_.bindStorage(3);
  if (pyramid_) pyramid_->cells.bindStorage(4);
  program_.set("uRayCount", int(n));
  const bool persistent = persistent_ && pyramid_;  // a march over a pyramid: hssr, hiz, exhaustive
  program_.set("uPersistent", persistent);
  if (persistent) {
    const uint32_t zero = 0;
    if (!queue_.id()) queue_ = GpuBuffer(sizeof zero);
    queue_.write(&zero, sizeof zero);
    queue_.bindStorage(5);
    // Enough groups to fill a large GPU several times over; each invocation then loops.
    glUseProgram(program_.id());
    glDispatchCompute(GLuint(std::min((n + kGroupSize - 1) / kGroupSize, kPersistentGroups)), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
  } else {
    gpu_.dispatch(program_, n);
  }
}

const GpuEffects& GpuScreenTracer::effects(const Scene& scene, std::span<const PointLight> lights) const {
  auto same = [](const PointLight& a, const PointLight& b) { return a.position == b.position && a.intensity == b.intensity; };
  if (!effects_ || effectsScene_ != &scene || !std::equal(lights.begin(), lights.end(), effectsLights_.begin(), effectsLights_.end(), same)) {
    effects_.reset();  // (its buffers go before the new ones are made)
    effects_ = std::make_unique<GpuEffects>(gpu_, scene, camera_, layers_, lights);
    effectsScene_ = &scene;
    effectsLights_.assign(lights.begin(), lights.end());
  }
  return *effects_;
}

TraceHit GpuScreenTracer::trace(const Ray& ray, RayCounters& counters) const {
  TraceHit hit;
  traceBatch(std::span<const Ray>(&ray, 1), std::span<TraceHit>(&hit, 1), std::span<RayCounters>(&counters, 1));
  return hit;
}

void GpuScreenTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  thread_local std::vector<GpuMarchHit> reused;  // from batch to batch
  std::vector<GpuMarchHit>& marched = reused;     // (the workers below read this thread's)
  march(rays, marched);
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const GpuMarchHit& m = marched[i];
    hits[i] = m.hit() ? fragmentHit(camera_, layers_, m.x, m.y, m.layer) : TraceHit{};
    if (counters.empty()) return;
    RayCounters& c = counters[i];
    c.iterations += m.counters.iterations, c.intervals += m.counters.intervals, c.pixels += m.counters.pixels;
    c.giveUps += m.counters.giveUps;
    for (int l = 0; l < RayCounters::kLevels; ++l) c.levelIterations[l] += m.counters.levelIterations[l];
  });
}

}  // namespace lt
