#include "layertrace/gpu/gpu_screen_tracer.h"

#include <algorithm>
#include <array>

#include <epoxy/gl.h>

#include "layertrace/screen/fragment_hit.h"
#include "layertrace/screen/interval_layers.h"
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

constexpr int kGroupSize = 64;           ///< local_size_x of the march shaders
constexpr int kMaxGroups = 65535;        ///< the dispatch size every OpenGL 4.5 driver allows
constexpr int kMaxLevels = 16;           ///< uLevelWidth[16] in hssr_march.comp
/// Persistent threads: work groups launched (16 per multiprocessor of a 132-SM GPU; choice: the
/// queue balances the load, so more groups than the GPU holds at once only add idle launches).
constexpr size_t kPersistentGroups = 2112;

void setInt(uint32_t program, const char* name, int v) { glProgramUniform1i(program, glGetUniformLocation(program, name), v); }
void setFloat(uint32_t program, const char* name, float v) { glProgramUniform1f(program, glGetUniformLocation(program, name), v); }

}  // namespace

GpuScreenTracer::GpuScreenTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const IntervalPyramid& pyramid,
                                 const HssrConfig& config)
    : gpu_(gpu), camera_(camera), layers_(layers) {
  if (config.nUp < 1) inputError("--n-up ", config.nUp, ": must be >= 1");
  const int levels = std::max(1, std::min({config.maxLevels, pyramid.levelCount(), kMaxLevels}));
  name_ = levels == 1 ? "exhaustive" : config.name;
  gpu_.makeCurrent();
  program_ = gpu_.computeProgram("hssr_march.comp", shader_source::hssr_march_comp);
  upload(*pyramid.base);
  // Levels 1… one after the other, each cell as CoarseCell's two float[4] (κ fronts, κ backs).
  std::array<int, kMaxLevels> width{}, height{}, offset{};
  width[0] = camera.width(), height[0] = camera.height();
  std::vector<CoarseCell> cells;
  for (int L = 1; L < levels; ++L) {
    const PyramidLevel& lvl = pyramid.levels[size_t(L)];
    width[size_t(L)] = lvl.width, height[size_t(L)] = lvl.height, offset[size_t(L)] = int(cells.size());
    cells.insert(cells.end(), lvl.cells.begin(), lvl.cells.end());
  }
  static_assert(sizeof(CoarseCell) == 32);
  cells_ = GpuBuffer(cells.size() * sizeof(CoarseCell), cells.data());
  setMarchUniforms(levels, config.nUp, width.data(), height.data(), offset.data());
  timer_ = std::make_unique<GpuTimer>();
}

GpuScreenTracer::GpuScreenTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const IntervalLayers& level0,
                                 const PyramidConfig& pyramid, const HssrConfig& config)
    : gpu_(gpu), camera_(camera), layers_(layers) {
  if (config.nUp < 1) inputError("--n-up ", config.nUp, ": must be >= 1");
  gpu_.makeCurrent();
  program_ = gpu_.computeProgram("hssr_march.comp", shader_source::hssr_march_comp);
  upload(level0);
  pyramid_ = std::make_unique<GpuPyramid>();
  buildPyramidOnGpu(gpu, level0_, counts_, camera.width(), camera.height(), level0.k, camera, pyramid, *pyramid_);
  const int levels = std::max(1, std::min(config.maxLevels, pyramid_->levels));
  name_ = levels == 1 ? "exhaustive" : config.name;
  setMarchUniforms(levels, config.nUp, pyramid_->width.data(), pyramid_->height.data(), pyramid_->cellBase.data());
  timer_ = std::make_unique<GpuTimer>();
}

void GpuScreenTracer::setMarchUniforms(int levels, int nUp, const int* width, const int* height, const int* offset) {
  setInt(program_, "uLevels", levels);
  setInt(program_, "uNUp", nUp);
  glProgramUniform1iv(program_, glGetUniformLocation(program_, "uLevelWidth"), kMaxLevels, width);
  glProgramUniform1iv(program_, glGetUniformLocation(program_, "uLevelHeight"), kMaxLevels, height);
  glProgramUniform1iv(program_, glGetUniformLocation(program_, "uLevelOffset"), kMaxLevels, offset);
}

GpuScreenTracer::GpuScreenTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const SsrConfig& config)
    : gpu_(gpu), camera_(camera), layers_(layers), name_(config.allLayers ? "ssr-layers" : "ssr") {
  // The CPU tracer's checks and its step limit (ssr/ssr_tracer.cpp).
  if (!(config.stride >= 1.0f)) inputError("--stride ", config.stride, ": must be >= 1");
  if (!(config.jitter >= 0.0f && config.jitter <= 1.0f)) inputError("--jitter ", config.jitter, ": must be in [0, 1]");
  if (config.maxSteps < 0) inputError("--max-steps ", config.maxSteps, ": must be >= 0");
  const int maxSteps =
      config.maxSteps > 0 ? config.maxSteps : int(float(std::max(camera.width(), camera.height())) / config.stride) + 2;
  gpu_.makeCurrent();
  program_ = gpu_.computeProgram("ssr_march.comp", shader_source::ssr_march_comp);
  upload(makeIntervalLayers(layers, config.allLayers ? layers.k : 1));
  setFloat(program_, "uStride", config.stride);
  setFloat(program_, "uJitter", config.jitter);
  setInt(program_, "uMaxSteps", maxSteps);
  setInt(program_, "uRefine", config.refine ? 1 : 0);
  timer_ = std::make_unique<GpuTimer>();
}

GpuScreenTracer::~GpuScreenTracer() {
  gpu_.makeCurrent();
  timer_.reset();
  if (program_) glDeleteProgram(program_);
}

void GpuScreenTracer::upload(const IntervalLayers& level0) {
  k_ = level0.k;
  static_assert(sizeof(Interval) == 8);
  level0_ = GpuBuffer(level0.slots.size() * sizeof(Interval), level0.slots.data());
  const std::vector<uint32_t> counts(level0.count.begin(), level0.count.end());
  counts_ = GpuBuffer(counts.size() * sizeof(uint32_t), counts.data());
  setInt(program_, "uWidth", camera_.width());
  setInt(program_, "uHeight", camera_.height());
  setInt(program_, "uK", k_);
  setFloat(program_, "uNear", camera_.near());
  setInt(program_, "uOrtho", camera_.orthographic() ? 1 : 0);
  setFloat(program_, "uFocal", camera_.focal());
}

size_t GpuScreenTracer::memoryBytes() const {
  return level0_.bytes() + counts_.bytes() + cells_.bytes() + (pyramid_ ? pyramid_->memoryBytes() : 0);
}

void GpuScreenTracer::march(std::span<const Ray> rays, std::vector<GpuMarchHit>& out) const {
  out.assign(rays.size(), GpuMarchHit{});
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
  rays_.bindStorage(0);
  hits_.bindStorage(1);
  level0_.bindStorage(2);
  counts_.bindStorage(3);
  if (pyramid_) pyramid_->cells.bindStorage(4);
  else if (cells_.id()) cells_.bindStorage(4);
  glUseProgram(program_);
  setInt(program_, "uRayCount", int(rays.size()));
  const bool persistent = persistent_ && (pyramid_ || cells_.id());  // a march over a pyramid: hssr, hiz, exhaustive
  setInt(program_, "uPersistent", persistent ? 1 : 0);
  if (persistent) {
    const uint32_t zero = 0;
    if (!queue_.id()) queue_ = GpuBuffer(sizeof zero);
    queue_.write(&zero, sizeof zero);
    queue_.bindStorage(5);
  }
  timer_->begin();
  constexpr size_t perDispatch = size_t(kGroupSize) * size_t(kMaxGroups);
  if (persistent) {
    // Enough groups to fill a large GPU several times over; each invocation then loops.
    glDispatchCompute(GLuint(std::min<size_t>((rays.size() + kGroupSize - 1) / kGroupSize, kPersistentGroups)), 1, 1);
  } else {
    for (size_t first = 0; first < rays.size(); first += perDispatch) {
      setInt(program_, "uRayOffset", int(first));
      const size_t n = std::min(perDispatch, rays.size() - first);
      glDispatchCompute(GLuint((n + kGroupSize - 1) / kGroupSize), 1, 1);
    }
  }
  timer_->end();
  PoolVector<HitRecord> answers(rays.size());
  hits_.read(answers.data(), hitBytes);
  lastTraceMs_ = timer_->ms();
  totalTraceMs_ += lastTraceMs_;
  glUseProgram(0);
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const HitRecord& a = answers[i];
    GpuMarchHit& h = out[i];
    h.x = a.x, h.y = a.y, h.layer = a.layer;
    h.counters.iterations = a.iterations;
    h.counters.intervals = a.intervals;
    h.counters.pixels = a.pixels;
    h.counters.giveUps = a.giveUps;
    std::copy(std::begin(a.levelIterations), std::end(a.levelIterations), h.counters.levelIterations);
  });
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
