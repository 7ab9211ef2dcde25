#include "layertrace/gpu/gpu_quadtree.h"

#include <algorithm>
#include <cmath>

#include <epoxy/gl.h>
#include <glm/trigonometric.hpp>

#include "layertrace/gpu/shader_sources.h"
#include "layertrace/screen/fragment_hit.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/util/default_init.h"
#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"

namespace lt {

static_assert(sizeof(QuadNode) == 16);

GpuQuadtreeTracer::GpuQuadtreeTracer(GpuContext& gpu, const Camera& camera, const LayerArrays& layers, const QuadtreeConfig& config)
    : gpu_(gpu), camera_(camera), layers_(&layers) {
  validateQuadtreeConfig(config);
  summary_.config = config;
  shape(layers.width, layers.height, layers.k);
  gpu_.makeCurrent();
  // Each slot's depth (k per pixel) and the counts: what Algorithm 1 reads.
  PoolVector<float> depths(layers.slots.size());
  parallelFor(size_t(0), depths.size(), [&](size_t i) { depths[i] = layers.slots[i].depth; });
  const std::vector<uint32_t> counts(layers.count.begin(), layers.count.end());
  depths_ = GpuBuffer(std::max<size_t>(depths.size(), 1) * sizeof(float), depths.data());
  counts_ = GpuBuffer(std::max<size_t>(counts.size(), 1) * sizeof(uint32_t), counts.data());
  build(depths_, counts_, false);
}

GpuQuadtreeTracer::GpuQuadtreeTracer(GpuContext& gpu, const QuadtreeConfig& config) : gpu_(gpu) {
  validateQuadtreeConfig(config);
  summary_.config = config;
}

void GpuQuadtreeTracer::rebuild(const Camera& camera, const GpuBuffer& level0, const GpuBuffer& counts, int k) {
  LT_CHECK(layers_ == nullptr, "a quad-tree of the CPU's layers");
  camera_ = camera;
  if (camera.width() != summary_.width || camera.height() != summary_.height || k != summary_.k) shape(camera.width(), camera.height(), k);
  summaryRead_ = false;
  build(level0, counts, true);
}

void GpuQuadtreeTracer::shape(int width, int height, int k) {
  Quadtree& t = summary_;
  t.width = width, t.height = height, t.k = k;
  t.levels.clear();
  t.nodesPerLayer = 0;
  for (int w = t.width, h = t.height;; w = (w + 1) / 2, h = (h + 1) / 2) {  // as buildQuadtree
    t.levels.push_back({w, h, t.nodesPerLayer});
    t.nodesPerLayer += size_t(w) * size_t(h);
    if (w == 1 && h == 1) break;
  }
  if (t.levelCount() > kMaxLevels) inputError("the quad-tree of ", t.width, "x", t.height, ": ", t.levelCount(), " levels, the GPU's limit is ", kMaxLevels);
  const size_t nodes = t.nodesPerLayer * size_t(t.k);
  if (nodes > size_t(INT32_MAX)) inputError("the quad-tree of ", t.width, "x", t.height, " with k = ", t.k, ": ", nodes, " nodes, the GPU's limit is ", INT32_MAX);
  gpu_.makeCurrent();
  nodes_ = GpuBuffer(std::max<size_t>(nodes, 1) * sizeof(QuadNode));
  scale_ = GpuBuffer(sizeof(float));
  nodeSums_ = GpuBuffer(6 * sizeof(uint32_t));
  kinds_ = GpuBuffer(size_t(t.levelCount()) * 3 * sizeof(uint32_t));
  if (!timer_) timer_ = std::make_unique<GpuTimer>();
}

void GpuQuadtreeTracer::build(const GpuBuffer& depths, const GpuBuffer& counts, bool level0) {
  const Quadtree& t = summary_;
  const QuadtreeConfig& config = t.config;
  GpuDebugGroup group("quadtree build");
  // With `level0`, the depths are a resident frame's level 0 ([depth, back] a slot).
  const char* variant = level0 ? "#define LT_LEVEL0 1\n" : "";
  const size_t pixels = size_t(t.width) * size_t(t.height);
  kinds_.fill(0u);
  timer_->begin();
  depths.bindStorage(0);
  counts.bindStorage(1);
  nodes_.bindStorage(2);
  scale_.bindStorage(3);
  kinds_.bindStorage(4);
  {
    GpuDebugGroup scaleGroup("quadtree depth scale");
    const GpuProgram& p = gpu_.computeProgram("quadtree_scale.comp", shader_source::quadtree_scale_comp, variant);
    p.set("uPixels", int(pixels));
    p.set("uStride", int(std::max<size_t>(1, pixels / 65536)));  // as defaultDepthScale
    p.set("uK", t.k);
    p.set("uFocal", camera_.focal());
    p.set("uGrazing", std::tan(glm::radians(85.0f)));
    p.set("uFixedScale", config.depthScale);
    gpu_.dispatchGroups(p, 1);
  }
  const GpuProgram& build = gpu_.computeProgram("quadtree_build.comp", shader_source::quadtree_build_comp, variant);
  setLevels(build);
  build.set("uK", t.k);
  build.set("uLambdaH", config.lambdaH);
  build.set("uLambdaD", config.lambdaD);
  build.set("uGammaNorm", config.gammaNorm);
  build.set("uGammaDist", config.gammaDist);
  build.set("uPrintedLine8", int(config.printedLine8));
  build.set("uPrintedLine10", int(config.printedLine10));
  for (int l = 0; l < t.levelCount(); ++l) {
    GpuDebugGroup levelGroup(l == 0 ? "quadtree leaves" : "quadtree merge");
    build.set("uLevel", l);
    const QuadtreeLevel& lv = t.levels[size_t(l)];
    gpu_.dispatch(build, size_t(lv.width) * size_t(lv.height) * size_t(t.k));
  }
  timer_->end();
  glUseProgram(0);
}

GpuQuadtreeTracer::~GpuQuadtreeTracer() {
  gpu_.makeCurrent();  // the buffers go with the context current
}

void GpuQuadtreeTracer::setLevels(const GpuProgram& p) const {
  const Quadtree& t = summary_;
  int width[kMaxLevels] = {}, height[kMaxLevels] = {}, offset[kMaxLevels] = {};
  for (int l = 0; l < t.levelCount(); ++l) {
    width[l] = t.levels[size_t(l)].width;
    height[l] = t.levels[size_t(l)].height;
    offset[l] = int(t.levels[size_t(l)].offset);
  }
  p.set("uLevelCount", t.levelCount());
  p.set("uLevelWidth", width, kMaxLevels);
  p.set("uLevelHeight", height, kMaxLevels);
  p.set("uLevelOffset", offset, kMaxLevels);
  p.set("uNodesPerLayer", int(t.nodesPerLayer));
}

const Quadtree& GpuQuadtreeTracer::summary() const {
  if (!summaryRead_) {
    gpu_.makeCurrent();
    scale_.read(&summary_.depthScale, sizeof(float));
    std::vector<uint32_t> kinds(size_t(summary_.levelCount()) * 3);
    kinds_.read(kinds.data(), kinds.size() * sizeof(uint32_t));
    summary_.kindCounts.assign(summary_.levels.size(), {0, 0, 0});
    for (size_t l = 0; l < summary_.levels.size(); ++l)
      for (size_t k = 0; k < 3; ++k) summary_.kindCounts[l][k] = kinds[l * 3 + k];
    summary_.buildMs = timer_->ms();
    summaryRead_ = true;
  }
  return summary_;
}

std::vector<QuadNode> GpuQuadtreeTracer::readNodes() const {
  gpu_.makeCurrent();
  std::vector<QuadNode> nodes(summary_.nodesPerLayer * size_t(summary_.k));
  nodes_.read(nodes.data(), nodes.size() * sizeof(QuadNode));
  return nodes;
}

size_t GpuQuadtreeTracer::memoryBytes() const { return nodes_.bytes() + depths_.bytes() + counts_.bytes(); }

void GpuQuadtreeTracer::marchResident(const GpuBuffer& rays, const GpuBuffer& hits, const GpuBuffer& extra, size_t n, bool counters) const {
  if (n == 0) return;
  GpuDebugGroup group("quadtree march");
  const GpuProgram& p = counters ? gpu_.computeProgram("quadtree_march.comp", shader_source::quadtree_march_comp)
                                 : gpu_.computeProgram("quadtree_march.comp", shader_source::quadtree_march_comp, "#define LT_NO_COUNTERS 1\n");
  rays.bindStorage(0);
  hits.bindStorage(1);
  nodes_.bindStorage(4);
  scale_.bindStorage(5);
  extra.bindStorage(6);
  setLevels(p);
  p.set("uRayCount", int(n));
  p.set("uWidth", camera_.width());
  p.set("uHeight", camera_.height());
  p.set("uK", summary_.k);
  p.set("uNear", camera_.near());
  p.set("uOrtho", camera_.orthographic());
  p.set("uFocal", camera_.focal());
  p.set("uRootStart", int(summary_.config.rootStart));
  p.set("uBackfaceHits", int(summary_.config.backfaceHits));
  gpu_.dispatch(p, n);
}

void GpuQuadtreeTracer::answerWave(const GpuEffectWave& w) const {
  if (w.n == 0) return;
  reserve(waveExtra_, w.n * sizeof(GpuQuadtreeExtra));
  marchResident(w.rays, w.hits, waveExtra_, w.n, w.counters);
  GpuDebugGroup group("quadtree hit points");
  const GpuProgram& p = gpu_.computeProgram("quadtree_point.comp", shader_source::quadtree_point_comp);
  w.rays.bindStorage(0);
  w.hits.bindStorage(1);
  waveExtra_.bindStorage(2);
  scale_.bindStorage(3);
  w.records.bindStorage(4);
  nodeSums_.bindStorage(5);
  p.set("uRayCount", int(w.n));
  p.set("uWidth", camera_.width());
  p.set("uHeight", camera_.height());
  p.set("uNear", camera_.near());
  p.set("uOrtho", camera_.orthographic());
  p.set("uFocal", camera_.focal());
  p.set("uPixelScale", camera_.pixelFootprint(1.0f));
  gpu_.dispatch(p, w.n);
}

void GpuQuadtreeTracer::beginEffect() const {
  gpu_.makeCurrent();
  nodeSums_.fill(0u);
}

GpuTracerSums GpuQuadtreeTracer::effectSums() const {
  gpu_.makeCurrent();
  uint32_t words[6];
  nodeSums_.read(words, sizeof(words));
  auto word64 = [&](int i) { return uint64_t(words[2 * i]) | uint64_t(words[2 * i + 1]) << 32; };
  return GpuTracerSums{word64(0), word64(1), word64(2)};
}

void GpuQuadtreeTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  LT_CHECK(layers_ != nullptr, "a resident quad-tree has no CPU layers to answer from");
  if (rays.empty()) return;
  const float scale = summary().depthScale;
  gpu_.makeCurrent();
  batch_.upload(rays);
  const size_t hitBytes = rays.size() * sizeof(GpuMarchRecord), extraBytes = rays.size() * sizeof(GpuQuadtreeExtra);
  const GpuBuffer& hitsOut = batch_.answers(0, hitBytes);
  const GpuBuffer& extraOut = batch_.answers(1, extraBytes);
  const bool counted = !counters.empty();
  timer_->begin();
  marchResident(batch_.rays(), hitsOut, extraOut, rays.size(), counted);
  timer_->end();
  PoolVector<GpuMarchRecord> answers(rays.size());
  PoolVector<GpuQuadtreeExtra> extra(rays.size());
  hitsOut.read(answers.data(), hitBytes);
  extraOut.read(extra.data(), extraBytes);
  totalTraceMs_ += timer_->ms();
  glUseProgram(0);
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const GpuMarchRecord& a = answers[i];
    if (a.layer < 0) {
      hits[i] = TraceHit{};
    } else {
      LT_CHECK(layers_->countAt(a.x, a.y) > a.layer, "quadtree plane over an empty pixel ", a.x, ",", a.y);
      hits[i] = fragmentHit(camera_, *layers_, a.x, a.y, a.layer);
      // The exact ray–plane point, as QuadtreeTracer::traceImpl computes it from the same
      // segment (the GPU's segment is the CPU's, bit for bit).
      const ScreenSegment seg = makeScreenSegment(camera_, rays[i]);
      const float s = extra[i].s;
      const glm::vec2 at = seg.p0 + s * (seg.p1 - seg.p0);
      const float w = scale * seg.k0 + s * (scale * (seg.k1 - seg.k0));
      hits[i].point = camera_.rayThrough(at) * (scale / w);
    }
    if (counted) extra[i].addCounters(a, counters[i]);
  });
}

}  // namespace lt
