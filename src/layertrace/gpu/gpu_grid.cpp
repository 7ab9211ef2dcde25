#include "layertrace/gpu/gpu_grid.h"

#include <algorithm>
#include <atomic>
#include <vector>

#include <epoxy/gl.h>

#include "layertrace/gpu/gpu_scene_tables.h"
#include "layertrace/gpu/shader_sources.h"
#include "layertrace/raster/fragment.h"
#include "layertrace/util/default_init.h"
#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"

namespace lt {

namespace {
/// shaders/grid_march.comp's query and answer, std430.
struct QueryRecord {
  float origin[3], tnear;
  float dir[3], tfar;
};
struct AnswerRecord {
  float t;
  uint32_t triangle, steps, tests;
  float ng[3];
  uint32_t flags;  ///< 1: a step cap ended the walk; 2: undecided (an alpha-tested candidate)
};
static_assert(sizeof(QueryRecord) == 32 && sizeof(AnswerRecord) == 32);
constexpr uint32_t kMiss = 0xFFFFFFFFu;
}  // namespace

GpuGridTracer::GpuGridTracer(GpuContext& gpu, const Scene& scene, const Camera& camera, const IrregularGrid& grid)
    : gpu_(gpu), hits_(scene, camera), cpu_(&grid), layout_(GpuGridLayout::of(grid)) {
  const IrregularGrid::Packed p = grid.packed();
  if (p.walk.size() / 4 > size_t(UINT32_MAX) - 64 || p.leaves.size() > size_t(UINT32_MAX))
    inputError("the irregular grid: ", p.walk.size(), " bytes of cells exceed the GPU traversal's 32-bit word index");
  gpu_.makeCurrent();
  ownTopCells_ = GpuBuffer(std::max<size_t>(p.topCells.size(), 16), p.topCells.data());
  ownLeaves_ = GpuBuffer(std::max<size_t>(p.leaves.size_bytes(), 16), p.leaves.data());
  ownWalk_ = GpuBuffer(std::max<size_t>(p.walk.size(), 16), p.walk.data());
  if (grid.hasCutOuts()) markCutOuts(scene);
  timer_ = std::make_unique<GpuTimer>();
}

GpuGridTracer::GpuGridTracer(GpuContext& gpu, const Scene& scene, const Camera& camera, std::unique_ptr<GpuGridBuild> built,
                             const IrregularGrid* cutOuts)
    : gpu_(gpu), hits_(scene, camera), cpu_(cutOuts), built_(std::move(built)), layout_(built_->layout()) {
  if (scene.anyCutOut() && !cpu_) inputError("the grid built on the GPU: the scene's alpha-tested triangles need a CPU grid beside it");
  if (built_->walk().bytes() / 4 > size_t(UINT32_MAX) - 64)
    inputError("the irregular grid: ", built_->walk().bytes(), " bytes of cells exceed the GPU traversal's 32-bit word index");
  topCells_ = &built_->topCells(), leaves_ = &built_->leaves(), walk_ = &built_->walk();
  gpu_.makeCurrent();
  if (scene.anyCutOut()) markCutOuts(scene);
  timer_ = std::make_unique<GpuTimer>();
}

/// What answerWave reads of the scene, and its per-ray buffers (kept from wave to wave).
struct GpuGridTracer::EffectTables {
  /// `shared`: the scene's tables already on the device (else uploaded here).
  EffectTables(GpuContext& gpu, const Scene& scene, const GpuSceneTables* shared) {
    if (!shared) own = std::make_unique<GpuSceneTables>(gpu, scene);
    tables = shared ? shared : own.get();
    std::vector<uint32_t> words(scene.triMaterial.begin(), scene.triMaterial.end());
    for (const Material& m : scene.materials) words.push_back(packAlbedoSpec(m.albedo, m.specular));
    materials = GpuBuffer(std::max<size_t>(words.size(), 1) * sizeof(uint32_t), words.data());
  }
  std::unique_ptr<GpuSceneTables> own;
  const GpuSceneTables* tables = nullptr;
  GpuBuffer materials;  ///< shaders/geometry_hit.comp Materials: per triangle its material, then per material its packed colour
  GpuBuffer queries, answers;
};

void GpuGridTracer::shareSceneTables(const GpuSceneTables* tables) {
  LT_CHECK(!tables || &tables->scene == &hits_.scene(), "the tables of the grid's own scene");
  sharedTables_ = tables;
  effectTables_.reset();  // (made again on the next wave, with the shared tables or its own)
}

void GpuGridTracer::setEffectCamera(const Camera& camera) {
  frameCamera_ = camera;
  hits_.setCamera(frameCamera_);
}

bool GpuGridTracer::effectsOnDevice() const {
  if (!effectsOnDevice_) effectsOnDevice_ = !cutOuts_.id() && GpuSceneTables::limit(gpu_, hits_.scene()).empty();
  return *effectsOnDevice_;
}

void GpuGridTracer::answerWave(const GpuEffectWave& w) const {
  LT_CHECK(effectsOnDevice(), "grid effect waves with alpha-tested triangles");
  if (w.n == 0) return;
  const Scene& scene = hits_.scene();
  const Camera& camera = hits_.camera();
  if (!effectTables_) effectTables_ = std::make_unique<EffectTables>(gpu_, scene, sharedTables_);
  EffectTables& e = *effectTables_;
  reserve(e.queries, w.n * sizeof(QueryRecord));
  reserve(e.answers, w.n * sizeof(AnswerRecord));
  {
    GpuDebugGroup group("grid queries");
    const GpuProgram& p = gpu_.computeProgram("grid_queries.comp", shader_source::grid_queries_comp);
    w.rays.bindStorage(0);
    e.queries.bindStorage(1);
    p.set("uRayCount", int(w.n));
    p.setMatrix("uViewInverse", &camera.viewInverse()[0][0]);
    p.set("uOffsetUnit", GeometricHits::offsetUnit(scene));
    gpu_.dispatch(p, w.n);
  }
  walkResident(e.queries, e.answers, w.n, w.anyHit);
  GpuDebugGroup group("grid hit surfaces");
  const GpuProgram& p = gpu_.computeProgram("geometry_hit.comp", shader_source::geometry_hit_comp);
  w.rays.bindStorage(0);
  e.answers.bindStorage(1);
  w.hits.bindStorage(2);
  w.records.bindStorage(3);
  e.tables->positions.bindStorage(4);
  e.tables->normals.bindStorage(5);
  e.tables->indices.bindStorage(6);
  e.materials.bindStorage(7);
  e.tables->bindSurface(p);
  p.set("uRayCount", int(w.n));
  p.setMatrix("uView", &camera.view()[0][0]);
  p.setMatrix("uViewInverse", &camera.viewInverse()[0][0]);
  p.set("uMaterialTable", uint32_t(scene.triMaterial.size()));
  p.set("uAnyHit", int(w.anyHit));
  p.set("uNear", camera.near());
  p.set("uOrtho", camera.orthographic());
  p.set("uPixelScale", camera.pixelFootprint(1.0f));
  gpu_.dispatch(p, w.n);
}

void GpuGridTracer::markCutOuts(const Scene& scene) {
  std::vector<uint32_t> bits((scene.triangleCount() + 31) / 32, 0u);
  for (uint32_t t = 0; t < scene.triangleCount(); ++t)
    if (scene.cutOut(t)) bits[t / 32] |= 1u << (t % 32);
  cutOuts_ = GpuBuffer(std::max<size_t>(bits.size() * sizeof(uint32_t), 16), bits.data());
}

GpuGridTracer::~GpuGridTracer() {
  gpu_.makeCurrent();  // the buffers go with the context current
}

size_t GpuGridTracer::memoryBytes() const { return topCells_->bytes() + leaves_->bytes() + walk_->bytes(); }

void GpuGridTracer::queryRays(std::span<const Ray> rays, std::span<const float> from, bool anyHit, std::span<GeoHit> hits,
                              std::span<RayCounters> counters) const {
  // World-space queries from each ray's segment start, as GeometricTracer::query makes them.
  const Camera& cam = hits_.camera();
  PoolVector<IrregularGrid::Query> queries(rays.size());
  parallelFor(size_t(0), rays.size(), [&](size_t i) {
    const Ray& r = rays[i];
    const glm::vec3 o = cam.toWorld(r.origin);
    queries[i] = {o, cam.dirToWorld(r.dir), segmentStart(startOf(from, i), hits_.originOffset(r), o), r.maxDistance};
  });
  const bool counted = !counters.empty() && kCountersCompiled;
  PoolVector<TraversalCounts> counts(counted ? rays.size() : 0);
  query(queries, anyHit, hits, counts);
  if (!counted) return;
  for (size_t i = 0; i < rays.size(); ++i) {
    counters[i].addIterations(std::max(counts[i].steps, 1u));
    if (counts[i].giveUps) counters[i].giveUp();
  }
}

void GpuGridTracer::query(std::span<const IrregularGrid::Query> queries, bool anyHit, std::span<GeoHit> hits,
                          std::span<TraversalCounts> counts) const {
  lastTraceMs_ = 0.0;
  if (queries.empty()) return;
  gpu_.makeCurrent();
  PoolVector<QueryRecord> records(queries.size());
  parallelFor(size_t(0), queries.size(), [&](size_t i) {
    const IrregularGrid::Query& q = queries[i];
    records[i] = {{q.origin.x, q.origin.y, q.origin.z}, q.tnear, {q.dir.x, q.dir.y, q.dir.z}, q.tfar};
  });
  const size_t queryBytes = records.size() * sizeof(QueryRecord), answerBytes = queries.size() * sizeof(AnswerRecord);
  // (the batch's ray buffer is for camera-space rays: the world-space queries go in answer slot
  // 1, the answers in slot 0)
  const GpuBuffer& in = batch_.answers(1, queryBytes);
  const GpuBuffer& out = batch_.answers(0, answerBytes);
  in.write(records.data(), queryBytes);
  timer_->begin();
  walkResident(in, out, queries.size(), anyHit);
  timer_->end();
  PoolVector<AnswerRecord> answers(queries.size());
  out.read(answers.data(), answerBytes);
  lastTraceMs_ = timer_->ms();
  totalTraceMs_ += lastTraceMs_;
  glUseProgram(0);
  std::atomic<uint64_t> undecided{0};
  parallelFor(size_t(0), queries.size(), [&](size_t i) {
    const AnswerRecord& a = answers[i];
    TraversalCounts n{a.steps, a.tests, a.flags & 1u};
    GeoHit g;
    if (a.flags & 2u) {
      // A candidate on an alpha-tested triangle: the CPU grid answers the query (its one-ray
      // traversal, the same walk with the texture test).
      const IrregularGrid::Query& q = queries[i];
      n = {};
      if (anyHit) g.triangle = cpu_->occluded(q.origin, q.dir, q.tnear, q.tfar, &n) ? 0u : kMiss;
      else g = cpu_->intersect(q.origin, q.dir, q.tnear, q.tfar, &n);
      undecided.fetch_add(1, std::memory_order_relaxed);
    } else if (a.triangle != kMiss) {
      g.t = a.t, g.triangle = a.triangle, g.ng = {a.ng[0], a.ng[1], a.ng[2]};
    }
    hits[i] = g;
    if (!counts.empty()) counts[i] = n;
  });
  cpuAnswered_ += undecided.load();
}

void GpuGridTracer::walkResident(const GpuBuffer& queries, const GpuBuffer& answers, size_t n, bool anyHit) const {
  if (n == 0) return;
  GpuDebugGroup group("grid march");
  const GpuProgram& prog = gpu_.computeProgram("grid_march.comp", shader_source::grid_march_comp);
  queries.bindStorage(0);
  answers.bindStorage(1);
  topCells_->bindStorage(2);
  leaves_->bindStorage(3);
  walk_->bindStorage(4);
  if (cutOuts_.id()) cutOuts_.bindStorage(5);
  const GpuGridLayout& L = layout_;
  prog.set("uQueryCount", int(n));
  prog.setVec3("uLo", &L.lo.x);
  prog.setVec3("uHi", &L.hi.x);
  prog.setVec3("uVoxel", &L.voxel.x);
  prog.setVec3("uInvVoxel", &L.invVoxel.x);
  prog.setIvec3("uTop", L.top);
  prog.setIvec3("uVirt", L.virt);
  prog.set("uDepth", L.depth);
  prog.set("uAnyHit", int(anyHit));
  prog.set("uCutOuts", int(cutOuts_.id() != 0));
  gpu_.dispatch(prog, n);
}

void GpuGridTracer::traceBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  PoolVector<GeoHit> g(rays.size());
  queryRays(rays, {}, false, g, counters);
  parallelFor(size_t(0), rays.size(), [&](size_t i) { hits[i] = hits_.makeHit(rays[i], g[i]); });
}

void GpuGridTracer::occludedBatch(std::span<const Ray> rays, std::span<TraceHit> hits, std::span<RayCounters> counters) const {
  PoolVector<GeoHit> g(rays.size());
  queryRays(rays, {}, true, g, counters);
  for (size_t i = 0; i < rays.size(); ++i) hits[i] = GeometricHits::occludedHit(g[i].hit());
}

void GpuGridTracer::intersectSegments(std::span<const Ray> rays, std::span<const float> from, std::span<GeoHit> hits,
                                      std::span<RayCounters> counters) const {
  queryRays(rays, from, false, hits, counters);
}

void GpuGridTracer::occludedSegments(std::span<const Ray> rays, std::span<const float> from, std::span<uint8_t> blocked,
                                     std::span<RayCounters> counters) const {
  PoolVector<GeoHit> g(rays.size());
  queryRays(rays, from, true, g, counters);
  for (size_t i = 0; i < rays.size(); ++i) blocked[i] = g[i].hit() ? 1 : 0;
}

}  // namespace lt
