#include "layertrace/gpu/gpu_ldc.h"

#include <cstring>
#include <vector>

#include <epoxy/gl.h>

#include "layertrace/gpu/shader_sources.h"
#include "layertrace/util/default_init.h"
#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"

namespace lt {

namespace {
static_assert(sizeof(FragmentNode) == 16 && sizeof(glm::vec2) == 8);
}  // namespace

GpuLdcTracer::GpuLdcTracer(GpuContext& gpu, const Camera& camera, const LayeredDepthCube& ldc) : gpu_(gpu), camera_(camera), ldc_(ldc) {
  size_t offsets = 0, samples = 0, blocks = 0;
  for (int a = 0; a < 3; ++a) {
    const LdcView& v = ldc.views[size_t(a)];
    offsetBase_[a] = int(offsets), sampleBase_[a] = int(samples), blockBase_[a] = int(blocks);
    offsets += v.offset.size(), samples += v.samples.size(), blocks += v.blockIntervals.size();
  }
  if (offsets > size_t(INT32_MAX) || samples >= size_t(INT32_MAX) || blocks > size_t(INT32_MAX))
    inputError("the layered depth cube: ", samples, " samples, ", offsets, " texels; the GPU's limit is ", INT32_MAX);
  std::vector<uint32_t> allOffsets;
  std::vector<FragmentNode> allSamples;
  std::vector<glm::vec2> allBlocks;
  std::vector<uint32_t> allTriangles;
  allOffsets.reserve(offsets), allSamples.reserve(samples), allBlocks.reserve(blocks), allTriangles.reserve(samples);
  for (const LdcView& v : ldc.views) {
    allOffsets.insert(allOffsets.end(), v.offset.begin(), v.offset.end());
    allSamples.insert(allSamples.end(), v.samples.begin(), v.samples.end());
    allTriangles.insert(allTriangles.end(), v.triangle.begin(), v.triangle.end());
    allBlocks.insert(allBlocks.end(), v.blockIntervals.begin(), v.blockIntervals.end());
  }
  gpu_.makeCurrent();
  offsets_ = GpuBuffer(std::max<size_t>(allOffsets.size(), 1) * sizeof(uint32_t), allOffsets.data());
  samples_ = GpuBuffer(std::max<size_t>(allSamples.size(), 1) * sizeof(FragmentNode), allSamples.data());
  blocks_ = GpuBuffer(std::max<size_t>(allBlocks.size(), 1) * sizeof(glm::vec2), allBlocks.data());
  sampleTriangles_ = GpuBuffer(std::max<size_t>(allTriangles.size(), 1) * sizeof(uint32_t), allTriangles.data());
  timer_ = std::make_unique<GpuTimer>();
}

GpuLdcTracer::~GpuLdcTracer() {
  gpu_.makeCurrent();  // the buffers go with the context current
}

size_t GpuLdcTracer::memoryBytes() const { return offsets_.bytes() + samples_.bytes() + blocks_.bytes() + sampleTriangles_.bytes(); }

void GpuLdcTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  march(rays, hits, counters, false);
}

void GpuLdcTracer::occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  march(rays, hits, counters, true);
}

void GpuLdcTracer::marchResident(const GpuBuffer& rays, const GpuBuffer& answers, size_t n, bool anyHit) const {
  if (n == 0) return;
  GpuDebugGroup group("ldc march");
  const GpuProgram& p = gpu_.computeProgram("ldc_march.comp", shader_source::ldc_march_comp);
  rays.bindStorage(0);
  answers.bindStorage(1);
  offsets_.bindStorage(2);
  samples_.bindStorage(3);
  blocks_.bindStorage(4);
  float views[3][16], far[3];
  int size[3][2], blocks[3][2];
  for (int a = 0; a < 3; ++a) {
    const LdcView& v = ldc_.views[size_t(a)];
    std::memcpy(views[a], &v.camera.view()[0][0], sizeof(views[a]));
    far[a] = v.camera.far();
    size[a][0] = v.width, size[a][1] = v.height;
    blocks[a][0] = v.blocksX, blocks[a][1] = v.blocksY;
  }
  p.set("uRayCount", int(n));
  p.setMatrix("uCameraInverse", &camera_.viewInverse()[0][0]);
  p.setMatrix("uView", &views[0][0], 3);
  p.setIvec2("uSize", &size[0][0], 3);
  p.setIvec2("uBlocks", &blocks[0][0], 3);
  p.set("uFar", far, 3);
  p.set("uOffsetBase", offsetBase_, 3);
  p.set("uSampleBase", sampleBase_, 3);
  p.set("uBlockBase", blockBase_, 3);
  p.set("uTexel", ldc_.texel);
  p.set("uEpsilon", ldc_.config.epsilon);
  p.set("uHitDistance", ldc_.config.hitDistance);
  p.set("uBlock", ldc_.config.block);
  p.set("uSlots", ldc_.config.blockIntervals);
  p.set("uAnyHit", int(anyHit));
  gpu_.dispatch(p, n);
}

void GpuLdcTracer::answerWave(const GpuEffectWave& w) const {
  if (w.n == 0) return;
  reserve(waveAnswers_, w.n * sizeof(GpuLdcAnswer));
  marchResident(w.rays, waveAnswers_, w.n, w.anyHit);
  GpuDebugGroup group("ldc surfaces");
  const GpuProgram& p = gpu_.computeProgram("ldc_surface.comp", shader_source::ldc_surface_comp);
  w.rays.bindStorage(0);
  waveAnswers_.bindStorage(1);
  samples_.bindStorage(2);
  sampleTriangles_.bindStorage(3);
  w.hits.bindStorage(4);
  w.records.bindStorage(5);
  float inverses[3][16];
  for (int a = 0; a < 3; ++a) std::memcpy(inverses[a], &ldc_.views[size_t(a)].camera.viewInverse()[0][0], sizeof(inverses[a]));
  p.set("uRayCount", int(w.n));
  p.setMatrix("uCameraView", &camera_.view()[0][0]);
  p.setMatrix("uViewInverse", &inverses[0][0], 3);
  gpu_.dispatch(p, w.n);
}

void GpuLdcTracer::march(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters, bool anyHit) const {
  if (rays.empty()) return;
  gpu_.makeCurrent();
  batch_.upload(rays);
  const size_t bytes = rays.size() * sizeof(GpuLdcAnswer);
  const GpuBuffer& out = batch_.answers(0, bytes);
  timer_->begin();
  marchResident(batch_.rays(), out, rays.size(), anyHit);
  timer_->end();
  PoolVector<GpuLdcAnswer> answers(rays.size());
  out.read(answers.data(), bytes);
  totalTraceMs_ += timer_->ms();
  glUseProgram(0);
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const GpuLdcAnswer& a = answers[i];
    TraceHit& hit = hits[i];
    hit = TraceHit{};
    if (a.hit()) {
      // LdcTracer::traceAny's answer from the hit sample.
      const LdcView& v = ldc_.views[a.view];
      const uint32_t sample = a.sample - uint32_t(sampleBase_[a.view]);
      const FragmentNode& s = v.samples[sample];
      const Ray& ray = rays[i];
      hit.hit = true;
      hit.point = ray.origin + ray.dir * a.t;
      hit.normal = camera_.dirToCamera(v.camera.dirToWorld(decodeOctahedral(s.normal)));
      hit.albedoSpec = s.albedoSpec;
      hit.triangle = v.triangle[sample];
      if (!camera_.pixelOf(hit.point, hit.x, hit.y)) hit.x = hit.y = -1;
    }
    if (!counters.empty()) a.addCounters(counters[i]);
  });
}

}  // namespace lt
