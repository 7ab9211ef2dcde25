#include "layertrace/gpu/gpu_hybrid.h"

#include <algorithm>
#include <cstring>
#include <limits>
#include <vector>

#include <epoxy/gl.h>

#include "layertrace/gpu/shader_sources.h"
#include "layertrace/util/default_init.h"
#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"

namespace lt {

namespace {

/// shaders/hybrid_common.glsl HybridState, std430.
struct StateRecord {
  float origin[4], dir[4], best[4];
  float span;
  uint32_t bestTriangle, flags, geoIterations;
};
static_assert(sizeof(StateRecord) == 64);

/// shaders/hybrid_resolve.comp's answer, std430.
struct AnswerRecord {
  float t;
  uint32_t triangle, flags, geoIterations;
  float ng[3];
  uint32_t unused0;
  float from, end;
  uint32_t unused1[2];
};
static_assert(sizeof(AnswerRecord) == 48);

/// shaders/hybrid_common.glsl kFlag* (of them, what the host reads).
constexpr uint32_t kOriginWindow = 2u, kHitWindow = 4u, kRemainder = 8u, kUndecided = 16u, kRejected = 32u,
                   kWindowHit = 64u, kKnownMarch = 128u;
constexpr uint32_t kMiss = 0xFFFFFFFFu;
/// grid_march.comp's query and answer: two vec4 / uvec4 each.
constexpr size_t kQueryBytes = 32, kWalkAnswerBytes = 32;
/// Timeline stages, as HybridStats times them: the screen march and the decisions, the windows,
/// the remainders.
enum Stage { kScreen = 0, kWindows = 1, kRemainders = 2, kStages = 3 };

}  // namespace

bool GpuHybridTracer::canRunOnGpu(const Tracer& screen, const KnownSpace& known) {
  if (dynamic_cast<const GpuLdcTracer*>(&screen) || dynamic_cast<const GpuQuadtreeTracer*>(&screen)) return true;
  const auto* s = dynamic_cast<const GpuScreenTracer*>(&screen);
  return s && s->pyramid() && !known.marchesUnknownDepths();
}

GpuHybridTracer::GpuHybridTracer(GpuContext& gpu, const Scene& scene, const Camera& camera, const LayerArrays& layers,
                                 const KnownSpace& known, const Tracer& screen, const GpuGridTracer& grid, float worldMargin,
                                 bool uncertainEmptySpace)
    : HybridTracer(scene, camera, layers, known, screen, grid, worldMargin, uncertainEmptySpace),
      gpu_(gpu),
      scene_(scene),
      pyramidScreen_(dynamic_cast<const GpuScreenTracer*>(&screen)),
      quadtreeScreen_(dynamic_cast<const GpuQuadtreeTracer*>(&screen)),
      ldcScreen_(dynamic_cast<const GpuLdcTracer*>(&screen)),
      grid_(grid) {
  LT_CHECK(canRunOnGpu(screen, known), "the GPU hybrid needs a pyramid march with the frustum rules, the quad-tree or the cube");
  LT_CHECK((ldcScreen_ != nullptr) == (worldMargin > 0.0f), "a world-space screen half is the layered depth cube");
  if (scene.positions.size() * 3 > size_t(UINT32_MAX) || scene.triangles.size() * 3 > size_t(UINT32_MAX) ||
      layers.triangle.size() > size_t(UINT32_MAX))
    inputError("the hybrid on the GPU: ", scene.triangles.size(), " triangles exceed its 32-bit indices");
  gpu_.makeCurrent();
  std::vector<uint32_t> counts(layers.count.begin(), layers.count.end());
  layerTriangles_ = GpuBuffer(std::max<size_t>(layers.triangle.size() * sizeof(uint32_t), 16), layers.triangle.data());
  layerCounts_ = GpuBuffer(std::max<size_t>(counts.size() * sizeof(uint32_t), 16), counts.data());
  positions_ = GpuBuffer(std::max<size_t>(scene.positions.size() * sizeof(glm::vec3), 16), scene.positions.data());
  triangles_ = GpuBuffer(std::max<size_t>(scene.triangles.size() * sizeof(glm::uvec3), 16), scene.triangles.data());
  if (known.marchesUnknownDepths() && !ldcScreen_) {
    // Rule 3: KnownSpace's march, HSSR with n_up = 1 over its pyramid of [u, ∞) (τ = ∞), the
    // pyramid built on the GPU from the same level 0.
    const IntervalPyramid& p = known.pyramid();
    HssrConfig march;
    march.nUp = 1, march.maxLevels = p.levelCount(), march.parentAscent = true;
    knownMarch_ = std::make_unique<GpuScreenTracer>(gpu, camera, layers, *p.base,
                                                    PyramidConfig{p.levelCount(), std::numeric_limits<float>::infinity()}, march);
  }
  static_assert(sizeof(glm::vec3) == 12 && sizeof(glm::uvec3) == 12, "tightly packed triples");
}

GpuHybridTracer::~GpuHybridTracer() {
  gpu_.makeCurrent();  // the buffers go with the context current
}

size_t GpuHybridTracer::memoryBytes() const {
  return layerTriangles_.bytes() + layerCounts_.bytes() + positions_.bytes() + triangles_.bytes() + screenRays_.bytes() +
         screenHits_.bytes() + states_.bytes() + windows_.bytes() + windowAnswers_.bytes() + remainders_.bytes() +
         remainderAnswers_.bytes() + answers_.bytes() + knownHits_.bytes() + knownParams_.bytes() + screenExtra_.bytes() +
         (knownMarch_ ? knownMarch_->memoryBytes() : 0);
}

double GpuHybridTracer::totalTraceMs() const {
  const double screen = ldcScreen_        ? ldcScreen_->totalTraceMs()
                        : quadtreeScreen_ ? quadtreeScreen_->totalTraceMs()
                                          : pyramidScreen_->totalTraceMs();
  return totalTraceMs_ + screen + grid_.totalTraceMs();
}

TraceHit GpuHybridTracer::trace(const Ray& ray, RayCounters& counters) const {
  TraceHit h;
  runOnGpu(Query::Closest, std::span<const Ray>(&ray, 1), std::span<TraceHit>(&h, 1), std::span<RayCounters>(&counters, 1));
  return h;
}

void GpuHybridTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  runOnGpu(Query::Closest, rays, hits, counters);
}

void GpuHybridTracer::occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  runOnGpu(Query::Any, rays, hits, counters);
}

void GpuHybridTracer::setCamera(const GpuProgram& p) const {
  const Camera& c = camera();
  p.set("uWidth", c.width());
  p.set("uHeight", c.height());
  p.set("uNear", c.near());
  p.set("uOrtho", int(c.orthographic()));
  p.set("uFocal", c.focal());
  p.set("uPixelScale", c.pixelFootprint(1.0f));
  p.set("uWorldMargin", worldMargin());
  p.set("uUncertain", int(uncertainEmptySpace()));
}

void GpuHybridTracer::runOnGpu(Query q, std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  const size_t n = rays.size();
  if (n == 0) return;
  if (!kCountersCompiled) counters = {};
  const bool any = q == Query::Any;
  gpu_.makeCurrent();
  {
    GpuDebugGroup group("hybrid");
    batch_.upload(rays);
    reserve(screenRays_, n * 32);
    const size_t screenRecord = ldcScreen_ ? sizeof(GpuLdcAnswer) : sizeof(GpuMarchRecord);
    reserve(screenHits_, n * screenRecord);
    reserve(states_, n * sizeof(StateRecord));
    reserve(windows_, 2 * n * kQueryBytes);
    reserve(windowAnswers_, 2 * n * kWalkAnswerBytes);
    reserve(remainders_, n * kQueryBytes);
    reserve(remainderAnswers_, n * kWalkAnswerBytes);
    reserve(answers_, n * sizeof(AnswerRecord));

    timeline_.begin(kScreen);
    if (knownMarch_) {
      reserve(knownHits_, n * sizeof(GpuMarchRecord));
      reserve(knownParams_, n * sizeof(float));
      knownMarch_->marchResidentWithParams(batch_.rays(), knownHits_, knownParams_, n);
    }
    const GpuProgram& prepare = gpu_.computeProgram("hybrid_prepare.comp", shader_source::hybrid_prepare_comp);
    batch_.rays().bindStorage(0);
    screenRays_.bindStorage(1);
    states_.bindStorage(2);
    if (knownMarch_) knownHits_.bindStorage(3), knownParams_.bindStorage(4);
    prepare.set("uKnownMarch", int(knownMarch_ != nullptr));
    setCamera(prepare);
    prepare.set("uRayCount", int(n));
    prepare.setMatrix("uViewInverse", &camera().viewInverse()[0][0]);
    prepare.set("uOffsetUnit", offsetUnit());
    prepare.set("uFarLimit", known().farLimit());
    gpu_.dispatch(prepare, n);
    if (ldcScreen_) {
      ldcScreen_->marchResident(screenRays_, screenHits_, n, any);
    } else if (quadtreeScreen_) {
      reserve(screenExtra_, n * sizeof(GpuQuadtreeExtra));
      quadtreeScreen_->marchResident(screenRays_, screenHits_, screenExtra_, n, !counters.empty());
    } else {
      pyramidScreen_->marchResident(screenRays_, screenHits_, n, nullptr, !counters.empty());
    }
    const GpuProgram& check = gpu_.computeProgram("hybrid_check.comp", shader_source::hybrid_check_comp);
    batch_.rays().bindStorage(0);
    screenHits_.bindStorage(1);
    states_.bindStorage(2);
    windows_.bindStorage(3);
    layerTriangles_.bindStorage(4);
    layerCounts_.bindStorage(5);
    positions_.bindStorage(6);
    triangles_.bindStorage(7);
    setCamera(check);
    check.set("uRayCount", int(n));
    check.set("uK", layers().k);
    check.set("uTriangleCount", uint32_t(scene_.triangleCount()));
    gpu_.dispatch(check, n);
    timeline_.end(kScreen);

    timeline_.begin(kWindows);
    grid_.walkResident(windows_, windowAnswers_, 2 * n, any);
    timeline_.end(kWindows);

    timeline_.begin(kScreen);
    const GpuProgram& combine = gpu_.computeProgram("hybrid_combine.comp", shader_source::hybrid_combine_comp);
    batch_.rays().bindStorage(0);
    states_.bindStorage(1);
    windowAnswers_.bindStorage(2);
    remainders_.bindStorage(3);
    setCamera(combine);
    combine.set("uRayCount", int(n));
    combine.set("uAnyHit", int(any));
    gpu_.dispatch(combine, n);
    timeline_.end(kScreen);

    timeline_.begin(kRemainders);
    grid_.walkResident(remainders_, remainderAnswers_, n, any);
    timeline_.end(kRemainders);

    timeline_.begin(kScreen);
    const GpuProgram& resolve = gpu_.computeProgram("hybrid_resolve.comp", shader_source::hybrid_resolve_comp);
    states_.bindStorage(0);
    remainderAnswers_.bindStorage(1);
    answers_.bindStorage(2);
    resolve.set("uRayCount", int(n));
    resolve.set("uAnyHit", int(any));
    gpu_.dispatch(resolve, n);
    timeline_.end(kScreen);
  }
  PoolVector<AnswerRecord> answers(n);
  answers_.read(answers.data(), n * sizeof(AnswerRecord));
  // The counters of the marches, where asked: the screen march's, the quad-tree's extra ones,
  // rule 3's.
  const bool counted = !counters.empty();
  PoolVector<GpuMarchRecord> marched(counted && !ldcScreen_ ? n : 0), known(counted && knownMarch_ ? n : 0);
  PoolVector<GpuLdcAnswer> marchedLdc(counted && ldcScreen_ ? n : 0);
  PoolVector<GpuQuadtreeExtra> extra(counted && quadtreeScreen_ ? n : 0);
  if (!marched.empty()) screenHits_.read(marched.data(), n * sizeof(GpuMarchRecord));
  if (!marchedLdc.empty()) screenHits_.read(marchedLdc.data(), n * sizeof(GpuLdcAnswer));
  if (!extra.empty()) screenExtra_.read(extra.data(), n * sizeof(GpuQuadtreeExtra));
  if (!known.empty()) knownHits_.read(known.data(), n * sizeof(GpuMarchRecord));
  const std::vector<double> ms = timeline_.collect(kStages);
  glUseProgram(0);
  totalTraceMs_ += ms[kScreen] + ms[kWindows] + ms[kRemainders];

  // The answers, the counters and the statistics as HybridTracer::run gives them.
  HybridStats sums;
  sums.screenMs = ms[kScreen], sums.windowMs = ms[kWindows], sums.geoMs = ms[kRemainders];
  std::vector<uint32_t> onCpu;
  for (size_t i = 0; i < n; ++i) {
    const AnswerRecord& a = answers[i];
    if (a.flags & kUndecided) {
      onCpu.push_back(uint32_t(i));
      continue;
    }
    const Ray& r = rays[i];
    ++sums.rays;
    sums.windowQueries += ((a.flags & kOriginWindow) ? 1 : 0) + ((a.flags & kHitWindow) ? 1 : 0);
    sums.rejectedHits += (a.flags & kRejected) ? 1 : 0;
    if (a.flags & kRemainder) {
      ++sums.geoRays;
      const float inScene = lengthInScene(camera().toWorld(r.origin), camera().dirToWorld(r.dir), r.maxDistance);
      sums.geoLengthSum += inScene > a.from ? double(std::min(a.end, inScene) - a.from) / double(inScene) : 0.0;
    } else if (a.flags & kWindowHit) {
      ++sums.screenHits;
    } else {
      ++sums.certainMisses;
    }
    if (!counters.empty()) {
      if (ldcScreen_) marchedLdc[i].addCounters(counters[i]);
      else if (quadtreeScreen_) extra[i].addCounters(marched[i], counters[i]);
      else addCounters(marched[i], counters[i]);
      if (a.flags & kKnownMarch) addCounters(known[i], counters[i]);
      counters[i].addIterations(a.geoIterations);
      counters[i].giveUps += (a.flags >> 8) & 0xFFu;
    }
  }
  parallelFor(size_t(0), n, [&](size_t i) {
    const AnswerRecord& a = answers[i];
    if (a.flags & kUndecided) return;
    if (a.triangle == kMiss) hits[i] = TraceHit{};
    else if (any) hits[i] = GeometricHits::occludedHit(true);
    else hits[i] = geometricHits().makeHit(rays[i], GeoHit{a.t, a.triangle, {a.ng[0], a.ng[1], a.ng[2]}});
  });
  addStats(sums);
  gpuDecided_ += sums.rays;
  if (onCpu.empty()) return;
  // An alpha-tested candidate: the CPU's decisions, its grid settling the candidate.
  std::vector<Ray> again(onCpu.size());
  std::vector<TraceHit> answered(onCpu.size());
  std::vector<RayCounters> againCounters(counters.empty() ? 0 : onCpu.size());
  for (size_t j = 0; j < onCpu.size(); ++j) again[j] = rays[onCpu[j]];
  if (any) HybridTracer::occludedBatch(again, answered, againCounters);
  else HybridTracer::traceBatch(again, answered, againCounters);
  for (size_t j = 0; j < onCpu.size(); ++j) {
    hits[onCpu[j]] = answered[j];
    if (!counters.empty()) counters[onCpu[j]] += againCounters[j];
  }
  cpuDecided_ += onCpu.size();
}

}  // namespace lt
