#include "layertrace/gpu/gpu_screen_tracer.h"

#include <algorithm>
#include <string>

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


constexpr size_t kGroupSize = 64;  ///< local_size_x of the march shaders
constexpr const char* kNoCounters = "#define LT_NO_COUNTERS 1\n";  ///< the timed variant (screen_common.glsl writeHit)

/// The define of hssr_march.comp's in-warp reloading (§5.3) for the subgroup extension `gpu`
/// has, or empty. Choice: ARB_shader_ballot first (with group_vote and the 64-bit integers its
/// ballots need), as it is the variant tested on llvmpipe; KHR_shader_subgroup where it is the
/// only one, if compute shaders have its ballot and vote features.
std::string_view subgroupDefine(const GpuContext& gpu) {
  if (gpu.hasExtension("GL_ARB_shader_ballot") && gpu.hasExtension("GL_ARB_shader_group_vote") && gpu.hasExtension("GL_ARB_gpu_shader_int64"))
    return "#define LT_SUBGROUP_ARB 1\n";
  if (gpu.hasExtension("GL_KHR_shader_subgroup")) {
    gpu.makeCurrent();
    GLint stages = 0, features = 0;
    glGetIntegerv(GL_SUBGROUP_SUPPORTED_STAGES_KHR, &stages);
    glGetIntegerv(GL_SUBGROUP_SUPPORTED_FEATURES_KHR, &features);
    const GLint needed = GL_SUBGROUP_FEATURE_BASIC_BIT_KHR | GL_SUBGROUP_FEATURE_VOTE_BIT_KHR | GL_SUBGROUP_FEATURE_BALLOT_BIT_KHR;
    if ((stages & GL_COMPUTE_SHADER_BIT) && (features & needed) == needed) return "#define LT_SUBGROUP_KHR 1\n";
  }
  return {};
}

}  // namespace

GpuScreenTracer::GpuScreenTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const IntervalLayers& level0,
                                 const PyramidConfig& pyramid, const HssrConfig& config)
    : gpu_(gpu), camera_(camera), layers_(&layers), hssr_(config), pyramidConfig_(pyramid) {
  validateHssrConfig(config);
  gpu_.makeCurrent();
  program_ = &gpu_.computeProgram("hssr_march.comp", shader_source::hssr_march_comp);
  timedProgram_ = &gpu_.computeProgram("hssr_march.comp", shader_source::hssr_march_comp, kNoCounters);
  subgroupDefine_ = subgroupDefine(gpu_);
  upload(level0);
  pyramid_ = std::make_unique<GpuPyramid>();
  buildPyramidOnGpu(gpu, *level0_, *counts_, camera.width(), camera.height(), level0.k, camera, pyramid, *pyramid_);
  name_ = std::max(1, std::min(config.maxLevels, pyramid_->levels)) == 1 ? "exhaustive" : config.name;
  persistent_ = config.rayReloading;
  timer_ = std::make_unique<GpuTimer>();
}

GpuScreenTracer::GpuScreenTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const SsrConfig& config)
    : gpu_(gpu), camera_(camera), layers_(&layers), name_(config.allLayers ? "ssr-layers" : "ssr"), ssr_(config), isSsr_(true) {
  validateSsrConfig(config);
  gpu_.makeCurrent();
  program_ = &gpu_.computeProgram("ssr_march.comp", shader_source::ssr_march_comp);
  timedProgram_ = &gpu_.computeProgram("ssr_march.comp", shader_source::ssr_march_comp, kNoCounters);
  upload(makeIntervalLayers(layers, config.allLayers ? layers.k : 1));
  timer_ = std::make_unique<GpuTimer>();
}

GpuScreenTracer::GpuScreenTracer(GpuContext& gpu, const SsrConfig& config)
    : gpu_(gpu), name_(config.allLayers ? "ssr-layers" : "ssr"), ssr_(config), isSsr_(true) {
  validateSsrConfig(config);
  gpu_.makeCurrent();
  program_ = &gpu_.computeProgram("ssr_march.comp", shader_source::ssr_march_comp);
  timedProgram_ = &gpu_.computeProgram("ssr_march.comp", shader_source::ssr_march_comp, kNoCounters);
  if (!config.allLayers) maxIntervals_ = 1;
  timer_ = std::make_unique<GpuTimer>();
}

GpuScreenTracer::GpuScreenTracer(GpuContext& gpu, const PyramidConfig& pyramid, const HssrConfig& config)
    : gpu_(gpu), hssr_(config), pyramidConfig_(pyramid) {
  validateHssrConfig(config);
  gpu_.makeCurrent();
  program_ = &gpu_.computeProgram("hssr_march.comp", shader_source::hssr_march_comp);
  timedProgram_ = &gpu_.computeProgram("hssr_march.comp", shader_source::hssr_march_comp, kNoCounters);
  subgroupDefine_ = subgroupDefine(gpu_);
  name_ = std::max(1, std::min(config.maxLevels, pyramid.levels)) == 1 ? "exhaustive" : config.name;
  persistent_ = config.rayReloading;
  pyramid_ = std::make_unique<GpuPyramid>();
  timer_ = std::make_unique<GpuTimer>();
}

void GpuScreenTracer::rebuild(const Camera& camera, const GpuBuffer& level0, const GpuBuffer& counts, int k) {
  camera_ = camera;
  level0_ = &level0;
  counts_ = &counts;
  k_ = k;
  if (pyramid_) buildPyramidResident(gpu_, level0, counts, camera.width(), camera.height(), k, camera, pyramidConfig_, *pyramid_);
}

GpuScreenTracer::~GpuScreenTracer() {
  gpu_.makeCurrent();  // the buffers go with the context current
}

void GpuScreenTracer::upload(const IntervalLayers& level0) {
  static_assert(sizeof(Interval) == 8);
  ownLevel0_ = GpuBuffer(level0.slots.size() * sizeof(Interval), level0.slots.data());
  const std::vector<uint32_t> counts(level0.count.begin(), level0.count.end());
  ownCounts_ = GpuBuffer(counts.size() * sizeof(uint32_t), counts.data());
  k_ = level0.k;
}

void GpuScreenTracer::setUniforms(const GpuProgram& p, size_t n, bool persistent) const {
  p.set("uRayCount", int(n));
  p.set("uWidth", camera_.width());
  p.set("uHeight", camera_.height());
  p.set("uK", k_);
  p.set("uNear", camera_.near());
  p.set("uOrtho", camera_.orthographic());
  p.set("uFocal", camera_.focal());
  if (isSsr_) {
    p.set("uMaxIntervals", maxIntervals_);
    p.set("uStride", ssr_.stride);
    p.set("uJitter", ssr_.jitter);
    p.set("uMaxSteps", ssrMaxSteps(ssr_, camera_.width(), camera_.height()));
    p.set("uRefine", ssr_.refine);
    return;
  }
  p.set("uLevels", std::max(1, std::min(hssr_.maxLevels, pyramid_->levels)));
  p.set("uNUp", hssr_.nUp);
  p.set("uParentAscent", hssr_.parentAscent);
  p.set("uLevelWidth", pyramid_->width.data(), GpuPyramid::kMaxLevels);
  p.set("uLevelHeight", pyramid_->height.data(), GpuPyramid::kMaxLevels);
  p.set("uLevelOffset", pyramid_->cellBase.data(), GpuPyramid::kMaxLevels);
  p.set("uPersistent", persistent);
}

uint32_t GpuScreenTracer::persistentGroups(size_t n) {
  constexpr size_t kRaysPerInvocation = 8;
  const size_t groups = (n + kGroupSize - 1) / kGroupSize;
  return uint32_t(std::min(groups, std::max(size_t(kPersistentGroups), (groups + kRaysPerInvocation - 1) / kRaysPerInvocation)));
}

const char* GpuScreenTracer::subgroupExtension(const GpuContext& gpu) {
  const std::string_view d = subgroupDefine(gpu);
  return d.empty() ? "none" : d.find("ARB") != std::string_view::npos ? "GL_ARB_shader_ballot" : "GL_KHR_shader_subgroup";
}

bool GpuScreenTracer::setSubgroupReloading(bool on) {
  subgroupOff_ = !on;
  return subgroupReloading() == on;
}

const GpuProgram& GpuScreenTracer::marchProgram(bool counters, bool subgroup) const {
  if (!subgroup) return counters ? *program_ : *timedProgram_;
  const GpuProgram*& p = reloadPrograms_[counters ? 1 : 0];
  if (!p) {
    const std::string defines = std::string(counters ? "" : kNoCounters) + std::string(subgroupDefine_);
    p = &gpu_.computeProgram("hssr_march.comp", shader_source::hssr_march_comp, defines);
  }
  return *p;
}

size_t GpuScreenTracer::memoryBytes() const {
  return level0_->bytes() + counts_->bytes() + (pyramid_ ? pyramid_->memoryBytes() : 0);
}

void GpuScreenTracer::march(std::span<const Ray> rays, std::vector<GpuMarchHit>& out) const {
  out.resize(rays.size());  // every entry is written below
  lastTraceMs_ = 0.0;
  if (rays.empty()) return;
  gpu_.makeCurrent();
  batch_.upload(rays);
  const size_t hitBytes = rays.size() * sizeof(GpuMarchRecord);
  const GpuBuffer& hits = batch_.answers(0, hitBytes);
  timer_->begin();
  marchResident(batch_.rays(), hits, rays.size());
  timer_->end();
  PoolVector<GpuMarchRecord> answers(rays.size());
  hits.read(answers.data(), hitBytes);
  lastTraceMs_ = timer_->ms();
  totalTraceMs_ += lastTraceMs_;
  glUseProgram(0);
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const GpuMarchRecord& a = answers[i];
    GpuMarchHit& h = out[i];
    h.counters = RayCounters{};
    h.x = a.x, h.y = a.y, h.layer = a.layer;
    addCounters(a, h.counters);
  });
}

void GpuScreenTracer::marchResident(const GpuBuffer& rays, const GpuBuffer& hits, size_t n, const GpuBuffer* groups, bool counters) const {
  if (n == 0) return;
  GpuDebugGroup group(isSsr_ ? "ssr march" : "hssr march");
  rays.bindStorage(0);
  hits.bindStorage(1);
  level0_->bindStorage(2);
  counts_->bindStorage(3);
  if (pyramid_) pyramid_->cells.bindStorage(4);
  const bool persistent = persistent_ && pyramid_;  // a march over a pyramid: hssr, hiz, exhaustive
  const GpuProgram& program = marchProgram(counters, persistent && subgroupReloading());
  setUniforms(program, n, persistent);
  if (persistent) {
    if (!queue_.id()) queue_ = GpuBuffer(sizeof(uint32_t));
    queue_.fill(0u);
    queue_.bindStorage(5);
  }
  if (groups) {
    gpu_.dispatchIndirect(program, *groups, persistent ? kPersistentArgs : 0);
  } else if (persistent) {
    // Enough groups to fill a large GPU several times over; each invocation then loops.
    gpu_.dispatchGroups(program, persistentGroups(n));
  } else {
    gpu_.dispatch(program, n);
  }
}

void GpuScreenTracer::marchResidentWithParams(const GpuBuffer& rays, const GpuBuffer& hits, const GpuBuffer& params, size_t n) const {
  LT_CHECK(pyramid_ != nullptr, name_);
  if (n == 0) return;
  GpuDebugGroup group("hssr march");
  if (!paramsProgram_) paramsProgram_ = &gpu_.computeProgram("hssr_march.comp", shader_source::hssr_march_comp, "#define LT_HIT_PARAM 1\n");
  rays.bindStorage(0);
  hits.bindStorage(1);
  level0_->bindStorage(2);
  counts_->bindStorage(3);
  pyramid_->cells.bindStorage(4);
  params.bindStorage(6);
  setUniforms(*paramsProgram_, n, false);
  gpu_.dispatch(*paramsProgram_, n);
}

void GpuScreenTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  LT_CHECK(layers_ != nullptr, name_);  // a resident tracer has no CPU layers to answer from: march()
  thread_local std::vector<GpuMarchHit> reused;  // from batch to batch
  std::vector<GpuMarchHit>& marched = reused;     // (the workers below read this thread's)
  march(rays, marched);
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const GpuMarchHit& m = marched[i];
    hits[i] = m.hit() ? fragmentHit(camera_, *layers_, m.x, m.y, m.layer) : TraceHit{};
    if (counters.empty()) return;
    counters[i] += m.counters;
  });
}

}  // namespace lt
