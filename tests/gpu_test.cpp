// The GPU back end against the CPU path: the same rays from the same layers give the same hit
// fragment (pixel and layer, or a miss) and the same per-ray counters on both devices. The CPU
// tracers are the reference (they are tested against the exhaustive march and both oracles).
// These run under any OpenGL 4.5 driver; CI has Mesa's llvmpipe.
#include <algorithm>
#include <array>
#include <bit>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/util/error.h"
#include "test_util.h"

#if LAYERTRACE_HAS_GPU
#include "layertrace/eval/verify_layers.h"
#include "layertrace/gpu/gpu_capture.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_pyramid.h"
#include "layertrace/gpu/gpu_screen_tracer.h"
#endif

namespace lt {
namespace {

#if LAYERTRACE_HAS_GPU

class Gpu : public test::GpuSuite {
 protected:
  /// Answers that may differ out of n: none on llvmpipe (IEEE arithmetic in the shaders' order,
  /// `precise` everywhere: the CPU's bits); on a GPU whose division and reciprocal are approximate
  /// (GLSL allows 2.5 ulp), a ray that passes a pixel corner or grazes an interval's end within
  /// that rounding may take the other side: at most 0.1 %.
  static size_t allowed(size_t n) { return gpu_->software() ? 0 : n / 1000; }
};

struct Agreement {
  size_t rays = 0, hitsDiffer = 0, countersDiffer = 0, cpuHits = 0;
};

/// Traces `rays` with the registry's CPU tracer `name` (counted, one by one: the reference
/// path) and its GPU version, and compares answer by answer.
Agreement compareDevices(GpuContext& gpu, const Frame& f, const std::string& name, const TracerOptions& options,
                         const std::vector<Ray>& rays) {
  const BuiltTracer cpu = buildTracer(name, f, options);
  const BuiltTracer onGpu = buildGpuTracer(name, f, options, gpu);
  const auto& g = dynamic_cast<const GpuScreenTracer&>(*onGpu.tracer);
  std::vector<GpuMarchHit> marched;
  g.march(rays, marched);
  Agreement a;
  a.rays = rays.size();
  for (size_t i = 0; i < rays.size(); ++i) {
    RayCounters c;
    const TraceHit h = cpu.tracer->trace(rays[i], c);
    const GpuMarchHit& m = marched[i];
    a.cpuHits += h.hit;
    const bool same = h.hit ? m.hit() && m.x == h.x && m.y == h.y && m.layer == h.layer : !m.hit();
    if (!same) {
      if (a.hitsDiffer++ < 5 && gpu.software())
        ADD_FAILURE() << name << " ray " << i << ": CPU " << h.hit << " (" << h.x << ", " << h.y << ", " << h.layer << "), GPU ("
                      << m.x << ", " << m.y << ", " << m.layer << ")";
      continue;
    }
    bool levels = true;
    for (int l = 0; l < RayCounters::kLevels; ++l) levels = levels && c.levelIterations[l] == m.counters.levelIterations[l];
    if (c.iterations != m.counters.iterations || c.intervals != m.counters.intervals || c.pixels != m.counters.pixels ||
        c.giveUps != m.counters.giveUps || c.fragments != m.counters.fragments || !levels)
      ++a.countersDiffer;
  }
  return a;
}

Frame defaultFrame(int W, int H) { return buildFrame(test::defaultSceneOptions(W, H)); }

TEST_F(Gpu, EveryGpuTracerAnswersAsTheCpuOnTheDefaultScene) {
  // Odd sizes: partial cells on every pyramid level.
  const Frame f = defaultFrame(317, 179);
  const std::vector<Ray> rays = test::sampleRays(f, 20000, test::testSeed() + 21);
  for (const char* name : {"ssr", "ssr-layers", "hiz", "hssr"}) {
    const Agreement a = compareDevices(*gpu_, f, name, TracerOptions{}, rays);
    EXPECT_LE(a.hitsDiffer, allowed(a.rays)) << name;
    EXPECT_LE(a.countersDiffer, allowed(a.rays)) << name;
    EXPECT_GT(a.cpuHits, a.rays / 10) << name << ": the rays must hit something for the comparison to mean anything";
  }
}

TEST_F(Gpu, ParametersReachTheShaders) {
  const Frame f = defaultFrame(160, 90);
  const std::vector<Ray> rays = test::sampleRays(f, 8000, test::testSeed() + 22);
  TracerOptions o;
  // SSR with a stride (and the binary refinement), jitter and a step cap that stops rays early.
  o.ssr.stride = 3.0f, o.ssr.jitter = 0.5f, o.ssr.maxSteps = 12;
  // HSSR over 3 levels with τ = 25 and n_up = 1.
  o.pyramid.levels = 3, o.pyramid.tau = 25.0f, o.hssr.nUp = 1;
  for (const char* name : {"ssr", "ssr-layers", "hssr"}) {
    const Agreement a = compareDevices(*gpu_, f, name, o, rays);
    EXPECT_LE(a.hitsDiffer, allowed(a.rays)) << name;
    EXPECT_LE(a.countersDiffer, allowed(a.rays)) << name;
  }
  // The paper's preset: HSSR's pure n_up ascent (the cells counted differ from the default's).
  const TracerOptions paper = presetOptions("paper");
  ASSERT_FALSE(paper.hssr.parentAscent);
  for (const char* name : {"ssr", "hssr"}) {
    const Agreement a = compareDevices(*gpu_, f, name, paper, rays);
    EXPECT_LE(a.hitsDiffer, allowed(a.rays)) << name << " (paper preset)";
    EXPECT_LE(a.countersDiffer, allowed(a.rays)) << name << " (paper preset)";
  }
  // The same rays give other answers with other parameters: the comparison can fail.
  const BuiltTracer capped = buildGpuTracer("ssr", f, o, *gpu_), plain = buildGpuTracer("ssr", f, TracerOptions{}, *gpu_);
  std::vector<GpuMarchHit> a, b;
  dynamic_cast<const GpuScreenTracer&>(*capped.tracer).march(rays, a);
  dynamic_cast<const GpuScreenTracer&>(*plain.tracer).march(rays, b);
  size_t differ = 0;
  for (size_t i = 0; i < rays.size(); ++i) differ += a[i].layer != b[i].layer || a[i].x != b[i].x;
  EXPECT_GT(differ, 0u);
}

TEST_F(Gpu, RaysFromOutsideTheViewAndAnOrthographicCamera) {
  // View synthesis: rays from another eye, entering the view from outside (no origin pixel).
  const Frame f = defaultFrame(200, 120);
  std::mt19937 rng(uint32_t(test::testSeed() + 23));
  std::normal_distribution<float> g;
  std::vector<Ray> rays;
  const float d = f.scene.bounds().diagonal();
  for (int i = 0; i < 4000; ++i) {
    const glm::vec3 eye = glm::vec3(g(rng), g(rng), g(rng) + 0.5f) * 0.3f * d;
    const glm::vec3 target = f.camera.rayThrough({float(i % 200) + 0.5f, float(i % 120) + 0.5f}) * (0.5f * d);
    rays.push_back(test::freeRay(eye, glm::normalize(target - eye), 2.0f * d));
  }
  for (const char* name : {"ssr-layers", "hiz", "hssr"}) EXPECT_LE(compareDevices(*gpu_, f, name, TracerOptions{}, rays).hitsDiffer, allowed(rays.size())) << name;

  Frame ortho = buildFrame(test::defaultSceneOptions(160, 100));
  CameraDesc desc = ortho.camera.desc();
  desc.orthoHeight = 0.8f * d;
  const Frame of = test::frameOf(ortho.scene, desc, 160, 100);
  const std::vector<Ray> orays = test::sampleRays(of, 6000, test::testSeed() + 24);
  for (const char* name : {"ssr", "hssr"}) {
    const Agreement a = compareDevices(*gpu_, of, name, TracerOptions{}, orays);
    EXPECT_LE(a.hitsDiffer, allowed(orays.size())) << name;
    EXPECT_GT(a.cpuHits, 0u) << name;
  }
}

TEST_F(Gpu, TracersWithoutAGpuVersionAreRefusedByName) {
  const Frame f = defaultFrame(64, 36);
  for (const char* name : {"embree", "embree-robust"}) {
    EXPECT_FALSE(hasGpuTracer(name));
    try {
      buildGpuTracer(name, f, TracerOptions{}, *gpu_);
      ADD_FAILURE() << name << " was built";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
}

/// The GPU's capture of `o`'s view with `method` against the CPU's (same options).
LayerAgreement compareCaptures(GpuContext& gpu, const FrameOptions& o, const std::string& method, uint64_t* gpuFragments = nullptr) {
  const Frame cpu = buildFrame(o);
  Frame onGpu;
  loadFrameScene(o, onGpu);
  rasterizeFrameOnGpu(gpu, o, method, onGpu);
  if (gpuFragments) *gpuFragments = onGpu.lists.generated;
  EXPECT_EQ(onGpu.lists.generated, cpu.lists.generated) << method << ": every fragment, counted exactly";
  EXPECT_EQ(onGpu.lists.complexity, cpu.lists.complexity) << method;
  return compareLayerArrays(onGpu.layers, cpu.layers, 1e-5f);
}

FrameOptions defaultView(int W, int H) { return test::defaultSceneOptions(W, H); }

// The same fragments in the same slots (triangle, depth within 1e-5 relative) as the CPU
// capture. Both evaluate the pixel-centre ray against the triangle's plane; what may differ is
// the coverage of a pixel centre within rounding of an edge (the GPU transforms the vertices
// itself, and its rasterizer's tie rule is the driver's). On the default scene nothing differs.
TEST_F(Gpu, CaptureEqualsTheCpuCapture) {
  for (const char* method : {"lists", "peel"}) {
    FrameOptions o = defaultView(317, 179);
    o.layers = 3;
    const LayerAgreement a = compareCaptures(*gpu_, o, method);
    EXPECT_GE(a.matchFraction(), 0.9999) << method;
    // Mesa's llvmpipe computes IEEE floats in the shaders' order: the same bits as the CPU. A
    // GPU's division may be approximate (2.5 ulp in GLSL): the depths then agree within 1e-5.
    if (gpu_->software()) {
      EXPECT_EQ(a.sameBits, a.filled) << method;
    }
    EXPECT_GT(a.pixelLayers, 0u);
  }
  // Front faces only, and an orthographic camera.
  FrameOptions o = defaultView(160, 100);
  o.frontFacesOnly = true;
  EXPECT_GE(compareCaptures(*gpu_, o, "lists").matchFraction(), 0.9999);
  EXPECT_GE(compareCaptures(*gpu_, o, "peel").matchFraction(), 0.9999);
}

/// A view through the textured, cut-out grate of test::writeGrateObj (written into `dir`).
FrameOptions grateView(const test::TempDir& dir, int width, int height, int layers) {
  FrameOptions o;
  o.scenePath = test::writeGrateObj(dir);
  o.eye = glm::dvec3(0.35, 0.45, 1.5), o.target = glm::dvec3(0.0, 0.2, -3.0), o.fov = 55.0f;
  o.width = width, o.height = height, o.layers = layers;
  return o;
}

// Textures and alpha cut-outs: the GPU captures discard exactly the CPU's fragments (the same
// texel decides, from the same barycentrics) and sample the same colours, to the last bit on
// llvmpipe and within one unit of it elsewhere (the GPU's log2 and square root round their way).
TEST_F(Gpu, CutOutGrateEqualsTheCpuCapture) {
  test::TempDir dir;
  const FrameOptions o = grateView(dir, 160, 120, 3);
  for (const char* method : {"lists", "peel"}) {
    uint64_t gpuFragments = 0;
    const LayerAgreement a = compareCaptures(*gpu_, o, method, &gpuFragments);
    EXPECT_EQ(a.matchFraction(), 1.0) << method;
    EXPECT_GT(a.filled, uint64_t(o.width * o.height));
    if (gpu_->software()) {
      EXPECT_EQ(a.sameBits, a.filled) << method;
    }
  }
  // The same view with the grate solid has more fragments: the test sees the holes.
  Frame solid;
  FrameOptions off = o;
  off.textures = false;
  loadFrameScene(off, solid);
  rasterizeFrameOnGpu(*gpu_, off, "lists", solid);
  Frame cut;
  loadFrameScene(o, cut);
  rasterizeFrameOnGpu(*gpu_, o, "lists", cut);
  EXPECT_GT(solid.lists.generated, cut.lists.generated + uint64_t(o.width * o.height / 20));
}

// A texture whose side is no power of two, read across its edges (bilinear taps at −1) and
// through its holes: the wrapped texels are the CPU's (GLSL leaves % undefined for negative
// operands; llvmpipe computes −1 % 12 as 3).
TEST_F(Gpu, TexturesOfAnySideWrapAsOnTheCpu) {
  test::TempDir dir;
  FrameOptions o = grateView(dir, 96, 72, 2);
  o.scenePath = test::writeGrateObj(dir, 12);
  const LayerAgreement a = compareCaptures(*gpu_, o, "lists");
  EXPECT_EQ(a.matchFraction(), 1.0);
  EXPECT_GT(a.filled, uint64_t(o.width * o.height));
  if (gpu_->software()) {
    EXPECT_EQ(a.sameBits, a.filled);
  }
}

/// Every fragment of pixel `p`'s list: (depth bits, triangle, normal, albedo and specular),
/// sorted (the GPU links a pixel's fragments in atomic order).
std::vector<std::array<uint32_t, 4>> listOf(const FragmentLists& l, size_t p) {
  std::vector<std::array<uint32_t, 4>> out;
  for (uint32_t i = l.head[p]; i != kNullIndex; i = l.nodes[i].next)
    out.push_back({std::bit_cast<uint32_t>(l.nodes[i].depth), l.triangle[i], l.nodes[i].normal, l.nodes[i].albedoSpec});
  std::sort(out.begin(), out.end());
  return out;
}

// The pool holds thin nodes (depth, next, triangle); the lists that `layers --verify` reads are
// expanded to whole nodes by a pass of their own. They hold every fragment with the CPU's
// normal and textured colour (bits on llvmpipe; elsewhere the same fragments).
TEST_F(Gpu, ListsForVerificationHoldEveryFragmentAsTheCpu) {
  test::TempDir dir;
  FrameOptions o = grateView(dir, 96, 72, 2);
  o.captureLists = true;
  const Frame cpu = buildFrame(o);
  Frame onGpu;
  loadFrameScene(o, onGpu);
  rasterizeFrameOnGpu(*gpu_, o, "lists", onGpu);
  ASSERT_EQ(onGpu.lists.head.size(), cpu.lists.head.size());
  ASSERT_EQ(onGpu.lists.nodes.size(), cpu.lists.nodes.size());
  size_t differ = 0, fragments = 0, textured = 0;
  for (size_t p = 0; p < cpu.lists.head.size(); ++p) {
    const auto a = listOf(onGpu.lists, p), b = listOf(cpu.lists, p);
    fragments += b.size();
    for (const auto& f : b) textured += f[3] != b.front()[3];
    if (a.size() != b.size()) {
      ++differ;
      continue;
    }
    for (size_t i = 0; i < a.size(); ++i) {
      const bool same = gpu_->software() ? a[i] == b[i] : a[i][1] == b[i][1];
      differ += !same;
    }
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(fragments, size_t(o.width * o.height));
  EXPECT_GT(textured, 0u) << "the view shows textured fragments of more than one colour";
}

TEST_F(Gpu, CaptureKeepsTheSortRulesOfTheCpu) {
  // Adaptive thickness and the minimum separation read whole lists.
  FrameOptions o = defaultView(200, 120);
  o.adaptiveThickness = true;
  o.layers = 2;
  EXPECT_GE(compareCaptures(*gpu_, o, "lists").matchFraction(), 0.9999);
  o.adaptiveThickness = false;
  o.minSeparation = 0.05f;
  EXPECT_GE(compareCaptures(*gpu_, o, "lists").matchFraction(), 0.9999);
  EXPECT_GE(compareCaptures(*gpu_, o, "peel").matchFraction(), 0.9999);
  // Depth peeling cannot grow intervals over fragments it never kept.
  o.minSeparation = 0.0f, o.adaptiveThickness = true;
  Frame f;
  loadFrameScene(o, f);
  EXPECT_THROW(rasterizeFrameOnGpu(*gpu_, o, "peel", f), InputError);
}

TEST_F(Gpu, CapturePoolOverflowIsCountedExactlyAndGrows) {
  FrameOptions o = defaultView(160, 90);
  uint64_t total = 0;
  compareCaptures(*gpu_, o, "lists", &total);
  ASSERT_GT(total, 100u);
  // A fixed pool too small by one: refused with the exact counts.
  o.pool = total - 1;
  Frame f;
  loadFrameScene(o, f);
  try {
    rasterizeFrameOnGpu(*gpu_, o, "lists", f);
    ADD_FAILURE() << "no overflow reported";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(std::to_string(total) + " fragments generated, " + std::to_string(total - 1) + " stored, 1 lost"), std::string::npos) << m;
  }
  // Exactly enough: no loss.
  o.pool = total;
  rasterizeFrameOnGpu(*gpu_, o, "lists", f);
  EXPECT_EQ(f.lists.generated, total);
  EXPECT_EQ(f.raster.passes, 1);
}

TEST_F(Gpu, CapturedLayersTracedOnTheGpuAnswerAsTheCpuCapture) {
  // The whole GPU path (capture, then the tracers) against the whole CPU path.
  const FrameOptions o = defaultView(200, 120);
  const Frame cpu = buildFrame(o);
  Frame onGpu;
  loadFrameScene(o, onGpu);
  rasterizeFrameOnGpu(*gpu_, o, "lists", onGpu);
  const std::vector<Ray> rays = test::sampleRays(cpu, 5000, test::testSeed() + 25);
  const BuiltTracer a = buildTracer("hssr", cpu, TracerOptions{}), b = buildGpuTracer("hssr", onGpu, TracerOptions{}, *gpu_);
  size_t same = 0;
  for (const Ray& r : rays) {
    RayCounters c;
    const TraceHit x = a.tracer->trace(r, c), y = b.tracer->trace(r, c);
    same += x.hit == y.hit && x.x == y.x && x.y == y.y && x.layer == y.layer;
  }
  EXPECT_GE(same, rays.size() - allowed(rays.size()));
}

TEST_F(Gpu, HssrEqualsTheOneLevelMarchOnTheGpu) {
  const Frame f = defaultFrame(257, 143);
  const std::vector<Ray> rays = test::sampleRays(f, 10000, test::testSeed() + 26);
  TracerOptions one;
  one.pyramid.levels = 1;
  const BuiltTracer hssr = buildGpuTracer("hssr", f, TracerOptions{}, *gpu_), exhaustive = buildGpuTracer("hssr", f, one, *gpu_);
  EXPECT_STREQ(exhaustive.tracer->name(), "exhaustive");
  std::vector<GpuMarchHit> a, b;
  dynamic_cast<const GpuScreenTracer&>(*hssr.tracer).march(rays, a);
  dynamic_cast<const GpuScreenTracer&>(*exhaustive.tracer).march(rays, b);
  size_t differ = 0, fewerSteps = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    differ += a[i].x != b[i].x || a[i].y != b[i].y || a[i].layer != b[i].layer;
    fewerSteps += a[i].counters.iterations < b[i].counters.iterations;
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_GT(fewerSteps, rays.size() / 4) << "the hierarchy must skip something";
}

// Hofmann et al. 2017, §5.3: ray reloading changes the schedule, never an answer or a counter,
// both as published (subgroups step their lanes' rays a cell at a time and reload lane by lane,
// where the driver has subgroup operations: llvmpipe has GL_ARB_shader_ballot) and with the
// work-group batches of drivers without them. The schedule depends on the threads' timing, so
// each runs several times.
TEST_F(Gpu, RayReloadingAnswersAsThePlainMarch) {
  const Frame f = defaultFrame(257, 143);
  const std::vector<Ray> rays = test::sampleRays(f, 30000, test::testSeed() + 27);
  const BuiltTracer hssr = buildGpuTracer("hssr", f, TracerOptions{}, *gpu_);
  auto& t = dynamic_cast<GpuScreenTracer&>(*hssr.tracer);
  std::vector<GpuMarchHit> plain, reloaded;
  t.march(rays, plain);
  const std::vector<Ray> reversed(rays.rbegin(), rays.rend());
  if (gpu_->hasExtension("GL_ARB_shader_ballot") && gpu_->hasExtension("GL_ARB_shader_group_vote")) {
    EXPECT_TRUE(t.subgroupReloading());  // llvmpipe: the subgroup schedule is the one tested
  }
  for (const bool subgroup : {true, false}) {
    if (subgroup && !t.subgroupReloading()) continue;
    ASSERT_TRUE(t.setSubgroupReloading(subgroup));
    for (int run = 0; run < 3; ++run) {
      SCOPED_TRACE((subgroup ? "subgroup, run " : "work group, run ") + std::to_string(run));
      // Other answers in the tracer's buffers first, so that a ray left unanswered shows.
      ASSERT_TRUE(setGpuPersistentThreads(t, false));
      t.march(reversed, reloaded);
      ASSERT_TRUE(setGpuPersistentThreads(t, true));
      t.march(rays, reloaded);
      size_t differ = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        const GpuMarchHit &a = plain[i], &b = reloaded[i];
        differ += a.x != b.x || a.y != b.y || a.layer != b.layer || a.counters.iterations != b.counters.iterations ||
                  a.counters.intervals != b.counters.intervals || a.counters.pixels != b.counters.pixels || a.counters.giveUps != b.counters.giveUps ||
                  !std::equal(std::begin(a.counters.levelIterations), std::end(a.counters.levelIterations), std::begin(b.counters.levelIterations));
      }
      EXPECT_EQ(differ, 0u);
    }
  }
}

// The pyramid built on the GPU equals the CPU's bit for bit on an IEEE device (llvmpipe): the
// CSR lists of every level and the κ cells the march reads, for τ from 1 to ∞ (Hi-Z) and at odd
// sizes (partial cells on every level).
TEST_F(Gpu, PyramidBuiltOnTheGpuEqualsTheCpuPyramid) {
  const Frame f = defaultFrame(317, 179);
  const IntervalLayers level0 = makeIntervalLayers(f.layers, f.layers.k);
  const GpuBuffer l0(level0.slots.size() * sizeof(Interval), level0.slots.data());
  const std::vector<uint32_t> counts(level0.count.begin(), level0.count.end());
  const GpuBuffer c(counts.size() * 4, counts.data());
  for (const float tau : {1.0f, 4.0f, 25.0f, std::numeric_limits<float>::infinity()}) {
    const PyramidConfig config{7, tau};
    const IntervalPyramid cpu = buildIntervalPyramid(f.layers, f.camera, config);
    GpuPyramid g;
    buildPyramidOnGpu(*gpu_, l0, c, f.camera.width(), f.camera.height(), level0.k, f.camera, config, g);
    const IntervalPyramid gpu = downloadPyramid(g);
    ASSERT_EQ(gpu.levelCount(), cpu.levelCount());
    size_t cellsDiffer = 0, listsDiffer = 0, merged = 0;
    for (int L = 1; L < cpu.levelCount(); ++L) {
      const PyramidLevel &a = cpu.levels[size_t(L)], &b = gpu.levels[size_t(L)];
      ASSERT_EQ(a.width, b.width);
      ASSERT_EQ(a.offset, b.offset) << "level " << L << " tau " << tau;
      for (size_t i = 0; i < a.intervals.size(); ++i)
        listsDiffer += std::memcmp(&a.intervals[i], &b.intervals[i], sizeof(Interval)) != 0;
      for (size_t i = 0; i < a.cells.size(); ++i) {
        if (std::memcmp(&a.cells[i], &b.cells[i], sizeof(CoarseCell)) != 0 && cellsDiffer++ < 3)
          ADD_FAILURE() << "level " << L << " cell " << i << " tau " << tau;
        merged += a.offset[i + 1] - a.offset[i] > uint32_t(CoarseCell::kSlots);
      }
    }
    if (gpu_->software()) {
      EXPECT_EQ(listsDiffer, 0u) << tau;
      EXPECT_EQ(cellsDiffer, 0u) << tau;
    }
    if (tau == 1.0f) {
      EXPECT_GT(merged, 0u) << "some cells must hold more than four intervals, or the slot merge goes untested";
    }
  }
}

#endif

}  // namespace
}  // namespace lt
