// The seeds' other methods on the GPU against their CPU twins: the quad-tree of Widmer et al.
// 2015 built on the device (node for node the CPU's build) and traced there; the layered depth
// cube of Bürger et al. 2007 and the irregular grid of Pérard-Gayot et al. 2017 traced there;
// and the hybrid with both halves there: ray for ray the CPU's answers (hit, exact point, normal,
// material and every counter). The CPU tracers are the reference (tested against Embree and the
// exhaustive march in their own suites).
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/render/frame_sequence.h"
#include "layertrace/util/error.h"
#include "test_util.h"

#if LAYERTRACE_HAS_GPU
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_frame.h"
#include "layertrace/gpu/gpu_grid.h"
#include "layertrace/gpu/gpu_grid_build.h"
#include "layertrace/gpu/gpu_hybrid.h"
#include "layertrace/gpu/gpu_quadtree.h"
#endif

namespace lt {
namespace {

#if LAYERTRACE_HAS_GPU

class GpuMethods : public test::GpuSuite {
 protected:
  /// Answers that may differ out of n: none on llvmpipe (IEEE arithmetic in the CPU's order);
  /// the documented 0.1 % on a GPU whose division is approximate.
  static size_t allowed(size_t n) { return gpu_->software() ? 0 : n / 1000; }
};

struct NodeAgreement {
  size_t nodes = 0, differ = 0;
};

/// The GPU's quad-tree of `f`'s layers against the CPU's, node for node (all 16 bytes).
NodeAgreement compareQuadtrees(GpuContext& gpu, const Frame& f, const QuadtreeConfig& config) {
  const Quadtree cpu = buildQuadtree(f.layers, f.camera, config);
  const GpuQuadtreeTracer onGpu(gpu, f.camera, f.layers, config);
  const std::vector<QuadNode> nodes = onGpu.readNodes();
  const Quadtree& summary = onGpu.summary();
  EXPECT_EQ(summary.depthScale, cpu.depthScale);
  EXPECT_EQ(summary.levelCount(), cpu.levelCount());
  EXPECT_EQ(summary.kindCounts, cpu.kindCounts);
  NodeAgreement a;
  a.nodes = cpu.nodes.size();
  EXPECT_EQ(nodes.size(), cpu.nodes.size());
  for (size_t i = 0; i < std::min(nodes.size(), cpu.nodes.size()); ++i)
    if (std::memcmp(&nodes[i], &cpu.nodes[i], sizeof(QuadNode)) != 0) {
      if (a.differ++ < 5 && gpu.software())
        ADD_FAILURE() << "node " << i << ": CPU {" << cpu.nodes[i].a << ", " << cpu.nodes[i].b << ", " << cpu.nodes[i].c << ", "
                      << cpu.nodes[i].flags << "}, GPU {" << nodes[i].a << ", " << nodes[i].b << ", " << nodes[i].c << ", "
                      << nodes[i].flags << "}";
    }
  return a;
}

struct RayAgreement {
  size_t rays = 0, differ = 0, cpuHits = 0;
};

/// `rays` through the CPU tracer `name` (one by one, counted: the reference path) and its GPU
/// version (one batch), as closest-hit and, with `anyHit`, also as any-hit queries: the hit, its
/// point, normal, material and triangle bit for bit, and every counter (summed over the queries).
RayAgreement compareAnswers(GpuContext& gpu, const std::string& name, const Tracer& cpu, const Tracer& onGpu, const std::vector<Ray>& rays,
                            bool anyHit = false) {
  RayAgreement a;
  for (const Query q : {Query::Closest, Query::Any}) {
    if (q == Query::Any && !anyHit) break;
    SCOPED_TRACE(q == Query::Any ? "any hit" : "closest hit");
    std::vector<TraceHit> hits(rays.size());
    std::vector<RayCounters> counters(rays.size());
    onGpu.batch(q, rays, hits, counters);
    a.rays += rays.size();
    for (size_t i = 0; i < rays.size(); ++i) {
      RayCounters c;
      TraceHit h;
      cpu.batch(q, std::span<const Ray>(&rays[i], 1), std::span<TraceHit>(&h, 1), std::span<RayCounters>(&c, 1));
      const TraceHit& g = hits[i];
      const RayCounters& gc = counters[i];
      a.cpuHits += h.hit;
      const bool sameHit = h.hit == g.hit && h.x == g.x && h.y == g.y && h.layer == g.layer && h.triangle == g.triangle &&
                           h.albedoSpec == g.albedoSpec && std::memcmp(&h.point, &g.point, sizeof(h.point)) == 0 &&
                           std::memcmp(&h.normal, &g.normal, sizeof(h.normal)) == 0;
      const bool sameCounters = std::memcmp(&c, &gc, sizeof(RayCounters)) == 0;
      if (!sameHit || !sameCounters) {
        if (a.differ++ < 5 && gpu.software())
          ADD_FAILURE() << name << " ray " << i << ": CPU " << h.hit << " (" << h.x << ", " << h.y << ", " << h.layer << ") it "
                        << c.iterations << ", GPU " << g.hit << " (" << g.x << ", " << g.y << ", " << g.layer << ") it " << gc.iterations
                        << (sameHit ? " (counters differ)" : "");
      }
    }
  }
  return a;
}

RayAgreement compareRays(GpuContext& gpu, const Frame& f, const std::string& name, const TracerOptions& options,
                         const std::vector<Ray>& rays, bool anyHit = false) {
  const BuiltTracer cpu = buildTracer(name, f, options);
  const BuiltTracer onGpu = buildGpuTracer(name, f, options, gpu);
  return compareAnswers(gpu, name, *cpu.tracer, *onGpu.tracer, rays, anyHit);
}

/// `rays` through the CPU tracer `name` and through the resident GPU frame of the same view
/// (its own capture, layer arrays and pyramid on the device: `compare --device gpu`).
RayAgreement compareResident(GpuContext& gpu, const FrameOptions& fo, const Frame& f, const std::string& name, const std::vector<Ray>& rays) {
  const BuiltTracer cpu = buildTracer(name, f, TracerOptions{});
  const std::unique_ptr<GpuFrame> resident = makeResidentFrame(gpu, fo, f, name, TracerOptions{});
  resident->build(f.camera, layerConfig(fo, f));
  const GpuFrameTracer onGpu(*resident, name.c_str());
  return compareAnswers(gpu, name, *cpu.tracer, onGpu, rays);
}

Frame defaultFrame(int W, int H) { return buildFrame(test::defaultSceneOptions(W, H)); }

/// A view through the alpha-tested grate of test::writeGrateObj (written into `dir`).
Frame grateFrame(const test::TempDir& dir, int W, int H) {
  FrameOptions o;
  o.scenePath = test::writeGrateObj(dir);
  o.eye = glm::dvec3(0.35, 0.45, 1.5), o.target = glm::dvec3(0.0, 0.2, -3.0);
  o.width = W, o.height = H;
  return buildFrame(o);
}

/// A ray from the eye through every pixel centre (free rays: nothing is skipped at their start).
std::vector<Ray> eyeRays(const Frame& f) {
  std::vector<Ray> rays;
  for (int y = 0; y < f.camera.height(); ++y)
    for (int x = 0; x < f.camera.width(); ++x)
      rays.push_back(test::freeRay(f.camera.rayOrigin({float(x) + 0.5f, float(y) + 0.5f}),
                                   glm::normalize(f.camera.rayThrough({float(x) + 0.5f, float(y) + 0.5f})), 100.0f));
  return rays;
}

/// Rays from outside the view toward it (view synthesis), `count` of them.
std::vector<Ray> raysFromOutside(const Frame& f, int count) {
  std::vector<Ray> rays;
  const float d = f.scene.bounds().diagonal();
  for (int i = 0; i < count; ++i) {
    const glm::vec3 eye(0.2f * d * float(i % 7 - 3) / 3.0f, 0.1f * d, 0.6f * d);
    const glm::vec3 target = f.camera.rayThrough({float(i % f.camera.width()) + 0.5f, float(i % f.camera.height()) + 0.5f}) * (0.5f * d);
    rays.push_back(test::freeRay(eye, glm::normalize(target - eye), 2.0f * d));
  }
  return rays;
}

TEST_F(GpuMethods, QuadtreeBuildEqualsTheCpusNodeForNode) {
  // Odd sizes: nodes past the image on every level.
  const Frame f = defaultFrame(317, 179);
  QuadtreeConfig printed;
  printed.printedLine8 = printed.printedLine10 = true;
  QuadtreeConfig fixedScale;
  fixedScale.depthScale = 0.37f, fixedScale.gammaNorm = 1e-2f, fixedScale.gammaDist = 1e-3f;  // more proxy planes
  const QuadtreeConfig configs[] = {QuadtreeConfig{}, presetOptions("paper").quadtree, printed, fixedScale};
  for (const QuadtreeConfig& config : configs) {
    const NodeAgreement a = compareQuadtrees(*gpu_, f, config);
    EXPECT_LE(a.differ, allowed(a.nodes));
  }
  // The comparison can fail: other rules give other nodes.
  const GpuQuadtreeTracer plain(*gpu_, f.camera, f.layers, QuadtreeConfig{}), other(*gpu_, f.camera, f.layers, printed);
  const std::vector<QuadNode> a = plain.readNodes(), b = other.readNodes();
  EXPECT_NE(std::memcmp(a.data(), b.data(), a.size() * sizeof(QuadNode)), 0);
  // Proxy planes above level 0 exist, so Algorithm 2's merge is exercised, not only its boxes.
  uint64_t merged = 0;
  for (size_t l = 1; l < plain.summary().kindCounts.size(); ++l) merged += plain.summary().kindCounts[l][QuadNode::Plane];
  EXPECT_GT(merged, 0u);
}

TEST_F(GpuMethods, QuadtreeAnswersAsTheCpuRayForRay) {
  const Frame f = defaultFrame(317, 179);
  const std::vector<Ray> rays = test::sampleRays(f, 20000, test::testSeed() + 61);
  TracerOptions rootStart;
  rootStart.quadtree.rootStart = true;
  rootStart.quadtree.backfaceHits = false;
  for (const TracerOptions& o : {TracerOptions{}, presetOptions("paper"), rootStart}) {
    const RayAgreement a = compareRays(*gpu_, f, "quadtree", o, rays);
    EXPECT_LE(a.differ, allowed(a.rays));
    EXPECT_GT(a.cpuHits, a.rays / 10) << "the rays must hit something for the comparison to mean anything";
  }
  // View synthesis: rays entering the view from outside, and an orthographic camera.
  const std::vector<Ray> outside = raysFromOutside(f, 3000);
  EXPECT_LE(compareRays(*gpu_, f, "quadtree", TracerOptions{}, outside).differ, allowed(outside.size()));
  CameraDesc desc = f.camera.desc();
  desc.orthoHeight = 0.8f * f.scene.bounds().diagonal();
  const Frame of = test::frameOf(f.scene, desc, 160, 100);
  const std::vector<Ray> orays = test::sampleRays(of, 6000, test::testSeed() + 62);
  const RayAgreement ortho = compareRays(*gpu_, of, "quadtree", TracerOptions{}, orays);
  EXPECT_LE(ortho.differ, allowed(ortho.rays));
  EXPECT_GT(ortho.cpuHits, 0u);
}

TEST_F(GpuMethods, LdcAnswersAsTheCpuRayForRay) {
  const Frame f = defaultFrame(200, 120);
  const std::vector<Ray> rays = test::sampleRays(f, 5000, test::testSeed() + 64);
  TracerOptions coarse;  // a coarser cube, one interval per block (§1.3 as published), a wider patch
  coarse.ldc.resolution = 160, coarse.ldc.blockIntervals = 1, coarse.ldc.epsilon = 0.5f, coarse.ldc.block = 4;
  for (const TracerOptions& o : {TracerOptions{}, presetOptions("paper"), coarse}) {
    const RayAgreement a = compareRays(*gpu_, f, "ldc", o, rays, true);
    EXPECT_LE(a.differ, allowed(a.rays));
    EXPECT_GT(a.cpuHits, a.rays / 10) << "the rays must hit something for the comparison to mean anything";
  }
  // The cube answers rays from anywhere: from outside the view too.
  const std::vector<Ray> outside = raysFromOutside(f, 3000);
  EXPECT_LE(compareRays(*gpu_, f, "ldc", TracerOptions{}, outside).differ, allowed(outside.size()));
  // The comparison can fail: another cube gives other answers to the same rays.
  const BuiltTracer a = buildGpuTracer("ldc", f, TracerOptions{}, *gpu_), b = buildGpuTracer("ldc", f, coarse, *gpu_);
  std::vector<TraceHit> ha(rays.size()), hb(rays.size());
  a.tracer->traceBatch(rays, ha, {});
  b.tracer->traceBatch(rays, hb, {});
  size_t differ = 0;
  for (size_t i = 0; i < rays.size(); ++i) differ += std::memcmp(&ha[i].point, &hb[i].point, sizeof(ha[i].point)) != 0;
  EXPECT_GT(differ, 0u);
}

TEST_F(GpuMethods, GridAnswersAsTheCpuGridRayForRay) {
  const Frame f = defaultFrame(200, 120);
  const std::vector<Ray> rays = test::sampleRays(f, 8000, test::testSeed() + 65);
  for (const TracerOptions& o : {TracerOptions{}, presetOptions("paper")}) {
    const RayAgreement a = compareRays(*gpu_, f, "grid", o, rays, true);
    EXPECT_LE(a.differ, allowed(a.rays));
    EXPECT_GT(a.cpuHits, a.rays / 2);
  }
  const std::vector<Ray> outside = raysFromOutside(f, 3000);
  EXPECT_LE(compareRays(*gpu_, f, "grid", TracerOptions{}, outside, true).differ, allowed(2 * outside.size()));
  // Segments from a point along each ray (the hybrid's geometric queries): the CPU grid's hits.
  const BuiltTracer cpu = buildTracer("grid", f, TracerOptions{}), onGpu = buildGpuTracer("grid", f, TracerOptions{}, *gpu_);
  std::vector<float> from(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) from[i] = float(i % 5) * 0.05f * rays[i].maxDistance;
  std::vector<GeoHit> want(rays.size()), got(rays.size());
  std::vector<uint8_t> wantBlocked(rays.size()), gotBlocked(rays.size());
  const auto& cpuGeo = dynamic_cast<const GeoHitQueries&>(*cpu.tracer);
  const auto& gpuGeo = dynamic_cast<const GeoHitQueries&>(*onGpu.tracer);
  cpuGeo.intersectSegments(rays, from, want, {});
  gpuGeo.intersectSegments(rays, from, got, {});
  cpuGeo.occludedSegments(rays, from, wantBlocked, {});
  gpuGeo.occludedSegments(rays, from, gotBlocked, {});
  size_t differ = 0, hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    hits += want[i].hit();
    differ += want[i].triangle != got[i].triangle || std::memcmp(&want[i].t, &got[i].t, sizeof(float)) != 0 ||
              std::memcmp(&want[i].ng, &got[i].ng, sizeof(want[i].ng)) != 0 || wantBlocked[i] != gotBlocked[i];
  }
  EXPECT_LE(differ, allowed(rays.size()));
  EXPECT_GT(hits, rays.size() / 4);
}

// Alpha-tested triangles: a ray whose walk meets one as a candidate is answered by the CPU grid
// (the GPU reads no texture), so the answers are the CPU grid's through the grate's holes too.
TEST_F(GpuMethods, GridAnswersThroughAlphaTestedTrianglesAsTheCpu) {
  test::TempDir dir;
  const Frame f = grateFrame(dir, 96, 72);
  const std::vector<Ray> rays = eyeRays(f);
  const RayAgreement a = compareRays(*gpu_, f, "grid", TracerOptions{}, rays, true);
  EXPECT_LE(a.differ, allowed(a.rays));
  const BuiltTracer onGpu = buildGpuTracer("grid", f, TracerOptions{}, *gpu_);
  std::vector<TraceHit> hits(rays.size());
  onGpu.tracer->traceBatch(rays, hits, {});
  EXPECT_GT(dynamic_cast<const GpuGridTracer&>(*onGpu.tracer).cpuAnswered(), 0u) << "the grate was met";
}

/// The GPU's grid build against the CPU's with merging and expansion off (what the GPU builds):
/// the packed structure byte for byte — top cells, the voxel map's leaves, every cell record and
/// triangle block — and the layout the traversal reads. Returns whether all of it is equal.
bool gpuGridEqualsTheCpus(GpuContext& gpu, const Scene& scene, const GridConfig& config) {
  const IrregularGrid cpu(scene, config);
  const GpuGridBuild onGpu(gpu, scene, config);
  const IrregularGrid::Packed p = cpu.packed();
  EXPECT_EQ(onGpu.cellsInitial(), cpu.stats().cellsInitial);
  EXPECT_EQ(onGpu.cells(), cpu.cells().size());
  EXPECT_EQ(onGpu.refs(), cpu.refs().size());
  EXPECT_EQ(onGpu.expandedFaces(), cpu.stats().expandedFaces);
  if (config.merge) {
    EXPECT_LT(onGpu.cells(), onGpu.cellsInitial()) << "merged";
  }
  const GpuGridLayout want = GpuGridLayout::of(cpu), got = onGpu.layout();
  EXPECT_EQ(std::memcmp(&want, &got, sizeof want), 0) << "the layout (box, voxel, resolutions, depth)";
  auto same = [](const GpuBuffer& b, const void* data, size_t bytes, const char* what) {
    EXPECT_GE(b.bytes(), bytes) << what;
    if (b.bytes() < bytes) return false;
    std::vector<unsigned char> read(bytes);
    if (bytes) b.read(read.data(), bytes);
    const bool equal = bytes == 0 || std::memcmp(read.data(), data, bytes) == 0;
    EXPECT_TRUE(equal) << what;
    return equal;
  };
  gpu.makeCurrent();
  const bool top = same(onGpu.topCells(), p.topCells.data(), p.topCells.size(), "top cells");
  const bool leaves = same(onGpu.leaves(), p.leaves.data(), p.leaves.size_bytes(), "leaves");
  const bool walk = same(onGpu.walk(), p.walk.data(), p.walk.size(), "cell records and triangle blocks");
  return top && leaves && walk && onGpu.cells() == cpu.cells().size();
}

// Pérard-Gayot et al. 2017, all four steps and the packing on the GPU: the CPU's cells,
// references and packed bytes, for the default configuration (merging, three passes of partial
// expansion), the paper's depth rule, whole-neighbour expansion, a shallow cap, one expansion
// pass, and the initial grid alone.
TEST_F(GpuMethods, GridBuiltOnTheGpuEqualsTheCpusByteForByte) {
  if (!gpu_->software()) GTEST_SKIP() << "an IEEE device only (the division of a GPU may round its own way)";
  const Frame f = defaultFrame(64, 36);
  GridConfig oneDepth, whole, shallow, onePass, initial;
  oneDepth.oneDepthPerCell = true;
  whole.partialExpansion = false;
  shallow.maxDepth = 1, shallow.lambda1 = 0.05f;
  onePass.expansionPasses = 1;
  initial.merge = false, initial.expansionPasses = 0;
  for (const auto& [c, what] : {std::pair{GridConfig{}, "default"}, {oneDepth, "one depth per cell"}, {whole, "whole neighbours"},
                                {shallow, "depth cap 1"}, {onePass, "one expansion pass"}, {initial, "no merging, no expansion"}})
    EXPECT_TRUE(gpuGridEqualsTheCpus(*gpu_, f.scene, c)) << what;
}

// The grid built on the GPU (--grid-gpu-build) walks as its CPU twin: the same answers and
// counters, through alpha-tested triangles too, where the CPU grid beside it decides.
TEST_F(GpuMethods, GridBuiltOnTheGpuAnswersAsItsCpuTwinRayForRay) {
  TracerOptions o;
  o.grid.gpuBuild = true;
  const Frame f = defaultFrame(160, 90);
  const std::vector<Ray> rays = test::sampleRays(f, 6000, test::testSeed() + 68);
  const RayAgreement a = compareRays(*gpu_, f, "grid", o, rays, true);
  EXPECT_LE(a.differ, allowed(a.rays));
  EXPECT_GT(a.cpuHits, a.rays / 2);
  test::TempDir dir;
  const Frame grate = grateFrame(dir, 64, 48);
  const std::vector<Ray> through = eyeRays(grate);
  EXPECT_LE(compareRays(*gpu_, grate, "grid", o, through, true).differ, allowed(2 * through.size())) << "the grate";
  const BuiltTracer onGpu = buildGpuTracer("grid", grate, o, *gpu_);
  ASSERT_NE(dynamic_cast<const GpuGridTracer&>(*onGpu.tracer).gpuBuild(), nullptr);
  std::vector<TraceHit> hits(through.size());
  onGpu.tracer->traceBatch(through, hits, {});
  EXPECT_GT(dynamic_cast<const GpuGridTracer&>(*onGpu.tracer).cpuAnswered(), 0u) << "the grate was met";
}

// The resident frame's own capture, layer arrays and pyramid answer the CPU's rays as the CPU
// tracers do over the CPU's capture: the fragment, its point, normal, material and triangle, and
// every counter (compare --device gpu asks the frame this way).
TEST_F(GpuMethods, TheResidentFrameAnswersAsTheCpuRayForRay) {
  const FrameOptions fo = test::defaultSceneOptions(203, 117);
  const Frame f = buildFrame(fo);
  const std::vector<Ray> rays = test::sampleRays(f, 8000, test::testSeed() + 67);
  for (const char* name : {"hssr", "hiz", "ssr", "ssr-layers"}) {
    SCOPED_TRACE(name);
    const RayAgreement a = compareResident(*gpu_, fo, f, name, rays);
    EXPECT_LE(a.differ, allowed(a.rays));
    EXPECT_GT(a.cpuHits, a.rays / 4);
  }
}

/// The hybrid `screen` with both halves on the GPU (its decisions there too with hssr and hiz)
/// against the CPU hybrid whose geometric half is the grid, closest and any hits: the same
/// decisions over the same answers, ray for ray, counters and statistics included.
void expectHybridAsTheCpus(GpuContext& gpu, const Frame& f, const std::string& screen, const std::vector<Ray>& rays, size_t allowed,
                           double minHits) {
  SCOPED_TRACE(screen);
  TracerOptions cpuOptions;
  cpuOptions.hybrid.screen = screen, cpuOptions.hybrid.geo = "grid";
  TracerOptions gpuOptions = cpuOptions;
  gpuOptions.hybrid.geo = "embree";  // ignored on the GPU: its geometric half is the grid
  const BuiltTracer cpu = buildTracer("hybrid", f, cpuOptions), onGpu = buildGpuTracer("hybrid", f, gpuOptions, gpu);
  const auto* decidedOnGpu = dynamic_cast<const GpuHybridTracer*>(onGpu.tracer.get());
  EXPECT_NE(decidedOnGpu, nullptr) << "decisions on the GPU";
  auto& cpuHybrid = dynamic_cast<HybridTracer&>(*cpu.tracer);
  auto& gpuHybrid = dynamic_cast<HybridTracer&>(*onGpu.tracer);
  for (const Query q : {Query::Closest, Query::Any}) {
    SCOPED_TRACE(q == Query::Any ? "any hit" : "closest hit");
    cpuHybrid.resetStats();
    gpuHybrid.resetStats();
    {
      std::vector<TraceHit> want(rays.size()), got(rays.size());
      std::vector<RayCounters> wantC(rays.size()), gotC(rays.size());
      cpu.tracer->query(q, rays, want, wantC);
      onGpu.tracer->query(q, rays, got, gotC);
      size_t differ = 0, hits = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        hits += want[i].hit;
        const bool sameHit = want[i].hit == got[i].hit && want[i].triangle == got[i].triangle &&
                             std::memcmp(&want[i].point, &got[i].point, sizeof(want[i].point)) == 0 &&
                             std::memcmp(&want[i].normal, &got[i].normal, sizeof(want[i].normal)) == 0;
        const bool sameCounters = std::memcmp(&wantC[i], &gotC[i], sizeof(RayCounters)) == 0;
        if ((!sameHit || !sameCounters) && differ++ < 3 && gpu.software())
          ADD_FAILURE() << "ray " << i << (sameHit ? ": counters differ" : ": hits differ") << ", hit " << want[i].hit << " / " << got[i].hit
                        << ", triangle " << want[i].triangle << " / " << got[i].triangle << ", iterations " << wantC[i].iterations << " / "
                        << gotC[i].iterations << ", intervals " << wantC[i].intervals << " / " << gotC[i].intervals << ", fragments "
                        << wantC[i].fragments << " / " << gotC[i].fragments << ", give-ups " << wantC[i].giveUps << " / " << gotC[i].giveUps;
      }
      EXPECT_LE(differ, allowed);
      EXPECT_GT(double(hits), minHits * double(rays.size()));
    }
    // Who answered: the same screen hits, certain misses, windows, rejections and remainders.
    const HybridStats a = cpuHybrid.stats(), b = gpuHybrid.stats();
    EXPECT_EQ(a.rays, b.rays);
    if (allowed == 0) {
      EXPECT_EQ(a.screenHits, b.screenHits);
      EXPECT_EQ(a.certainMisses, b.certainMisses);
      EXPECT_EQ(a.geoRays, b.geoRays);
      EXPECT_EQ(a.windowQueries, b.windowQueries);
      EXPECT_EQ(a.rejectedHits, b.rejectedHits);
      EXPECT_NEAR(a.geoLengthSum, b.geoLengthSum, 1e-9 * double(rays.size()));
    }
    EXPECT_GT(double(a.screenHits), 0.5 * minHits * double(a.rays));
    if (decidedOnGpu) {
      EXPECT_GT(decidedOnGpu->gpuDecided(), 0u);
    }
  }
}

TEST_F(GpuMethods, HybridAnswersAsTheCpuHybridRayForRay) {
  const Frame f = defaultFrame(200, 120);
  const std::vector<Ray> rays = test::sampleRays(f, 8000, test::testSeed() + 66);
  for (const char* screen : {"hssr", "hiz", "quadtree", "ldc"})
    expectHybridAsTheCpus(*gpu_, f, screen, rays, allowed(rays.size()), 0.5);
}

// A fetched real scene (real label: `make test` fetches the scenes first).
class GpuMethodsRealScene : public GpuMethods {};

TEST_F(GpuMethodsRealScene, EveryGpuTracerOnAFetchedSceneEqualsTheCpu) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  FrameOptions o = test::realSceneOptions("am-thornish.json", "hall");
  o.width = 240, o.height = 136;
  const Frame f = buildFrame(o);
  const NodeAgreement nodes = compareQuadtrees(*gpu_, f, QuadtreeConfig{});
  EXPECT_LE(nodes.differ, allowed(nodes.nodes));
  if (gpu_->software()) {  // (elsewhere the division may round its own way: the walks are checked)
    EXPECT_TRUE(gpuGridEqualsTheCpus(*gpu_, f.scene, GridConfig{})) << "the grid built on the GPU";
  }
  const std::vector<Ray> rays = test::sampleRays(f, 12000, test::testSeed() + 63);
  for (const char* name : {"quadtree", "ldc", "grid"}) {
    const RayAgreement a = compareRays(*gpu_, f, name, TracerOptions{}, rays);
    EXPECT_LE(a.differ, allowed(a.rays)) << name;
    EXPECT_GT(a.cpuHits, a.rays / 10) << name;
  }
  expectHybridAsTheCpus(*gpu_, f, "hssr", rays, allowed(rays.size()), 0.1);
  // The resident frame's own capture: its textures (a 256 × 640 one, whose mip levels are not
  // all powers of two, read at negative coordinates) give the CPU's colours too.
  for (const char* name : {"hssr", "ssr-layers"}) {
    const RayAgreement a = compareResident(*gpu_, o, f, name, rays);
    EXPECT_LE(a.differ, allowed(a.rays)) << name;
    EXPECT_GT(a.cpuHits, a.rays / 10) << name;
  }
}

#endif  // LAYERTRACE_HAS_GPU

}  // namespace
}  // namespace lt
