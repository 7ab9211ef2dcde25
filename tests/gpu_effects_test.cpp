// The effects on the GPU (gpu/gpu_effects.h: ray generation, the origin rule and shading as
// compute passes around a GPU tracer's march) against render/effects.cpp with the CPU tracer:
// the same rays, the same answers, the same counters and the same image.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/render/effects.h"
#include "layertrace/scene/surface.h"
#include "test_util.h"

#if LAYERTRACE_HAS_GPU
#include "layertrace/eval/verify_layers.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_effects.h"
#include "layertrace/gpu/gpu_screen_tracer.h"
#endif

namespace lt {
namespace {

#if LAYERTRACE_HAS_GPU

class GpuEffect : public test::GpuSuite {};

struct ImageAgreement {
  size_t pixels = 0, differ = 0;
  float maxDiff = 0.0f;
};

/// Pixels whose colour differs by more than `tolerance` relative (to max(1, |value|)).
ImageAgreement compareImages(const Image& a, const Image& b, float tolerance) {
  ImageAgreement r;
  for (int y = 0; y < a.height; ++y)
    for (int x = 0; x < a.width; ++x) {
      ++r.pixels;
      float worst = 0.0f;
      for (int c = 0; c < 3; ++c) {
        const float u = a.at(x, y)[c], v = b.at(x, y)[c];
        worst = std::max(worst, std::abs(u - v) / std::max(1.0f, std::abs(u)));
      }
      r.maxDiff = std::max(r.maxDiff, worst);
      r.differ += worst > tolerance;
    }
  return r;
}

/// Renders `ec` with the CPU tracer `name` (the reference path) and on the GPU with its GPU
/// version, rays generated and shaded on the device, and checks that both agree.
void expectSameEffect(GpuContext& gpu, const Frame& f, const std::string& name, const EffectConfig& ec) {
  SCOPED_TRACE(name + " " + effectName(ec.effect));
  const BuiltTracer cpu = buildTracer(name, f, TracerOptions{});
  const BuiltTracer onGpu = buildGpuTracer(name, f, TracerOptions{}, gpu);
  const EffectResult want = renderEffect(f, *cpu.tracer, ec);
  EffectConfig device = ec;
  device.wholeWaves = device.shadeOnDevice = true;
  const EffectResult got = renderEffect(f, *onGpu.tracer, device);
  ASSERT_TRUE(got.onDevice);
  // Enough rays for the comparison to mean something (refraction: the glass sphere's pixels).
  if (ec.effect != Effect::Shade) {
    ASSERT_GT(want.rays, ec.effect == Effect::Refraction ? size_t(1000) : size_t(f.camera.width()) * size_t(f.camera.height()) / 4);
  }
  // Counters. On llvmpipe the rays are the CPU's to the bit (IEEE arithmetic, `precise` in the
  // CPU's order, the same splitmix64 stream), so every ray meets the same fragment with the same
  // iterations; except AO's directions, which take GLSL's sin and cos (not libm's: a few ulp).
  // Such a ray may take one more or one fewer cell: measured on FZK-Haus's interior at 640×360
  // with 24 samples, 1 iteration in 75,322,467 over 5,529,600 rays, every answer the same. A GPU
  // with approximate division and square root (GLSL allows 2.5 ulp) may also send a grazing ray
  // to a neighbouring pixel: 0.1 % of the rays.
  const bool exact = gpu.software() && ec.effect != Effect::AO;
  const double share = exact ? 0.0 : gpu.software() ? 1e-4 : 1e-3;
  const double slack = share * double(want.rays);
  EXPECT_NEAR(double(got.rays), double(want.rays), slack);
  EXPECT_NEAR(double(got.hits), double(want.hits), slack);
  EXPECT_NEAR(double(got.bentRays), double(want.bentRays), slack);
  EXPECT_NEAR(double(got.iterationSum), double(want.iterationSum), share * double(want.iterationSum));
  EXPECT_NEAR(double(got.intervalSum), double(want.intervalSum), share * double(want.intervalSum));
  EXPECT_EQ(got.giveUps, want.giveUps);
  ASSERT_EQ(got.holes.size(), want.holes.size());
  if (exact) {
    EXPECT_TRUE(got.holes == want.holes);
    EXPECT_EQ(got.iterationsP99, want.iterationsP99);
    for (int l = 0; l < RayCounters::kLevels; ++l) EXPECT_EQ(got.levelIterations[l], want.levelIterations[l]) << "level " << l;
    EXPECT_EQ(got.planeNodeSum, want.planeNodeSum);
    EXPECT_EQ(got.boxNodeSum, want.boxNodeSum);
    EXPECT_EQ(got.occlusionSum, want.occlusionSum);
  }
  // Colours: GLSL's pow is not libm's (a few ulp), so the shaded colour differs in its last
  // bits; a pixel whose ray changed answer differs by a whole surface (AO: by one sample).
  const ImageAgreement image = compareImages(want.image, got.image, 1e-4f);
  const ImageAgreement traced = compareImages(want.traced, got.traced, 1e-4f);
  const size_t allowed = size_t(std::ceil(share * double(want.rays)));
  EXPECT_LE(image.differ, allowed) << "largest relative difference " << image.maxDiff;
  EXPECT_LE(traced.differ, allowed) << "largest relative difference " << traced.maxDiff;
}

Frame defaultFrame(int W, int H) { return buildFrame(test::defaultSceneOptions(W, H)); }

TEST_F(GpuEffect, EveryEffectOfEveryGpuTracerEqualsTheCpu) {
  // Odd sizes: tiles cut by the frame's edge.
  Frame f = defaultFrame(203, 117);
  // A second light behind the first: shadow rays per pixel with slots left empty.
  f.lights.push_back({f.camera.desc().eye + glm::vec3(0.0f, 3.0f, -2.0f), glm::vec3(4.0f)});
  for (const char* name : {"ssr", "ssr-layers", "hiz", "hssr", "quadtree", "ldc", "grid"}) {
    EffectConfig ec;
    ec.effect = Effect::Reflection;
    ec.bounces = 3;
    expectSameEffect(*gpu_, f, name, ec);
  }
  for (Effect effect : {Effect::Shade, Effect::AO, Effect::Shadow, Effect::Refraction, Effect::Warp}) {
    EffectConfig ec;
    ec.effect = effect;
    ec.aoSamples = 5;
    ec.seed = test::testSeed();
    // View synthesis: a second eye beside the first (scene coordinates), some of its rays
    // through disocclusions.
    ec.warpEye = f.scene.toWorld(f.camera.desc().eye + glm::vec3(0.4f, 0.1f, 0.0f));
    expectSameEffect(*gpu_, f, "hssr", ec);
  }
  // The tracers that answer with the surface they met (the quad-tree: the hit fragment at its
  // exact plane point; the cube: its sample), every effect with rays.
  for (const char* name : {"quadtree", "ldc", "grid"})
    for (Effect effect : {Effect::AO, Effect::Shadow, Effect::Refraction, Effect::Warp}) {
      EffectConfig ec;
      ec.effect = effect;
      ec.aoSamples = 3;
      ec.seed = test::testSeed();
      ec.warpEye = f.scene.toWorld(f.camera.desc().eye + glm::vec3(0.4f, 0.1f, 0.0f));
      expectSameEffect(*gpu_, f, name, ec);
    }
  // The glass sphere's refraction through every tracer.
  EffectConfig refraction;
  refraction.effect = Effect::Refraction;
  expectSameEffect(*gpu_, f, "ssr-layers", refraction);
}

TEST_F(GpuEffect, OriginRuleAndBentRaysAlongASmoothWall) {
  // Most reflections along the wall are first answered by the wall they leave (the origin
  // rule's continuations), or leave below it (mirrored or bent): both rules on the device.
  const Frame f = test::frameOf(test::smoothRoom(), test::originCamera(60.0f, 0.05f, 50.0f), 160, 90, 4, 0.05f);
  for (bool mirror : {true, false}) {
    EffectConfig ec;
    ec.effect = Effect::Reflection;
    ec.bounces = 2;
    ec.mirrorBelowSurface = mirror;
    expectSameEffect(*gpu_, f, "hssr", ec);
    ec.effect = Effect::AO;
    expectSameEffect(*gpu_, f, "ssr-layers", ec);
  }
}

// A frame in chunks of one 8×8 tile each gives the picture and the counters of one chunk.
TEST_F(GpuEffect, ChunksGiveTheWholeFramesAnswers) {
  const Frame f = defaultFrame(75, 41);
  const BuiltTracer b = buildGpuTracer("hssr", f, TracerOptions{}, *gpu_);
  const auto& tracer = dynamic_cast<const GpuScreenTracer&>(*b.tracer);
  const GpuEffects effects(*gpu_, f.scene, f.camera, f.layers, f.lights);
  for (GpuEffectKind kind : {GpuEffectKind::Reflection, GpuEffectKind::AO}) {
    GpuEffectParams p;
    p.kind = kind;
    p.bounces = 2;
    p.aoSamples = 3;
    const GpuEffectOutput whole = effects.run(tracer, p);
    p.chunkBytes = 1;  // one tile a chunk
    const GpuEffectOutput tiles = effects.run(tracer, p);
    ASSERT_EQ(whole.image.size(), size_t(75 * 41));
    EXPECT_TRUE(whole.image == tiles.image && whole.traced == tiles.traced);
    EXPECT_EQ(std::memcmp(whole.tally.data(), tiles.tally.data(), whole.tally.size() * sizeof(GpuPixelTally)), 0);
    EXPECT_EQ(whole.histogram, tiles.histogram);
    uint64_t rays = 0;
    for (const GpuPixelTally& t : whole.tally) rays += t.rays;
    EXPECT_GT(rays, 75u * 41u / 2);
  }
}

// A tracer keeps the passes' uploads for its frame (GpuScreenTracer::effects) and makes them
// again when the frame's lights change: the second render sees the new light.
TEST_F(GpuEffect, TheTracersUploadsFollowTheFramesLights) {
  Frame f = defaultFrame(96, 54);
  const BuiltTracer b = buildGpuTracer("hssr", f, TracerOptions{}, *gpu_);
  EffectConfig ec;
  ec.effect = Effect::Shadow;
  ec.wholeWaves = ec.shadeOnDevice = true;
  const EffectResult before = renderEffect(f, *b.tracer, ec);
  EXPECT_EQ(compareImages(before.image, renderEffect(f, *b.tracer, ec).image, 0.0f).differ, 0u);  // kept, the same
  f.lights.push_back({f.camera.desc().eye + glm::vec3(0.0f, 1.0f, 0.0f), glm::vec3(3.0f)});
  const EffectResult after = renderEffect(f, *b.tracer, ec);
  ASSERT_TRUE(after.onDevice);
  EXPECT_GT(after.rays, before.rays);  // a ray to the new light from the pixels it faces
  const BuiltTracer fresh = buildGpuTracer("hssr", f, TracerOptions{}, *gpu_);
  const EffectResult want = renderEffect(f, *fresh.tracer, ec);
  EXPECT_EQ(after.rays, want.rays);
  EXPECT_EQ(compareImages(want.image, after.image, 0.0f).differ, 0u);
}

// --hssr-ray-reloading (Hofmann et al. 2017, §5.3) changes the schedule, not the answers.
TEST_F(GpuEffect, RayReloadingGivesTheSameImage) {
  const Frame f = defaultFrame(160, 90);
  const BuiltTracer b = buildGpuTracer("hssr", f, TracerOptions{}, *gpu_);
  TracerOptions reloading;
  reloading.hssr.rayReloading = true;
  const BuiltTracer r = buildGpuTracer("hssr", f, reloading, *gpu_);
  EXPECT_FALSE(dynamic_cast<const GpuScreenTracer&>(*b.tracer).persistentThreads());
  ASSERT_TRUE(dynamic_cast<const GpuScreenTracer&>(*r.tracer).persistentThreads());
  EffectConfig ec;
  ec.effect = Effect::Reflection;
  ec.bounces = 2;
  ec.wholeWaves = ec.shadeOnDevice = true;
  const EffectResult plain = renderEffect(f, *b.tracer, ec);
  const EffectResult reloaded = renderEffect(f, *r.tracer, ec);
  EXPECT_EQ(compareImages(plain.image, reloaded.image, 0.0f).differ, 0u);
  EXPECT_EQ(plain.iterationSum, reloaded.iterationSum);
}

TEST_F(GpuEffect, MoreLightsThanTheShadersHoldShadeOnTheCpu) {
  // What the passes do not render runs as before: rays generated on the CPU, traced in whole
  // waves on the GPU, the same image as without shadeOnDevice.
  Frame f = defaultFrame(96, 64);
  while (f.lights.size() <= size_t(GpuEffects::kMaxLights)) f.lights.push_back({glm::vec3(0.0f, 2.0f, float(f.lights.size())), glm::vec3(0.5f)});
  const BuiltTracer b = buildGpuTracer("hssr", f, TracerOptions{}, *gpu_);
  EffectConfig ec;
  ec.effect = Effect::Shadow;
  ec.wholeWaves = true;
  const EffectResult cpuShaded = renderEffect(f, *b.tracer, ec);
  ec.shadeOnDevice = true;
  const EffectResult r = renderEffect(f, *b.tracer, ec);
  EXPECT_FALSE(r.onDevice);
  EXPECT_EQ(compareImages(cpuShaded.image, r.image, 0.0f).differ, 0u);
  EXPECT_EQ(r.rays, cpuShaded.rays);
}

// A fetched real scene, textured, end to end on the GPU (real label: `make test` fetches the
// scenes first): the GPU's capture holds the CPU's fragments, and every GPU tracer's reflections,
// generated and shaded on the GPU over those layers, are the CPU's.
class GpuRealScene : public GpuEffect {};

TEST_F(GpuRealScene, CaptureTracersAndEffectsEqualTheCpu) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  FrameOptions o = test::realSceneOptions("am-thornish.json", "hall");
  o.width = 320, o.height = 180;
  const Frame f = buildFrame(o);
  Frame onGpu;
  loadFrameScene(o, onGpu);
  rasterizeFrameOnGpu(*gpu_, o, "lists", onGpu);
  EXPECT_EQ(onGpu.lists.generated, f.lists.generated) << "every fragment, counted exactly";
  // The residue: pixels where two triangles' surfaces lie within 1e-5 relative depth of each
  // other (the map's overlapping brushes), so that a last-bit difference of the interpolated
  // depth (the GL pipeline transforms the vertices itself) decides which of them a layer keeps.
  // Measured on llvmpipe: 5 of 230,400 pixel-layers, each two surfaces 1e-5 apart.
  const LayerAgreement capture = compareLayerArrays(onGpu.layers, f.layers, 1e-5f);
  EXPECT_GE(capture.matchFraction(), 0.9999);
  EXPECT_EQ(capture.countsDiffer, 0u);
  for (const char* name : {"ssr", "ssr-layers", "hiz", "hssr", "quadtree", "ldc"}) {
    EffectConfig ec;
    ec.effect = Effect::Reflection;
    ec.bounces = 2;
    expectSameEffect(*gpu_, f, name, ec);
  }
  EffectConfig ao;
  ao.effect = Effect::AO;
  ao.aoSamples = 2;
  expectSameEffect(*gpu_, f, "hssr", ao);
}

// The grid's hits shaded on the device: the textured duck seen in the mirror floor (its texels
// sampled at the hit's footprint, shaders/geometry_hit.comp) and its AO.
TEST_F(GpuRealScene, GridShadesTexturedHitsAsTheCpu) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  FrameOptions o = test::realSceneOptions("duck.json", "front");
  o.width = 240, o.height = 160;
  const Frame f = buildFrame(o);
  ASSERT_TRUE(std::any_of(f.scene.materials.begin(), f.scene.materials.end(),
                          [&](const Material& m) { return surfaceFlags(f.scene, m) & kSurfaceSampled; }))
      << "the duck is textured";
  for (Effect effect : {Effect::Reflection, Effect::AO, Effect::Shadow}) {
    EffectConfig ec;
    ec.effect = effect;
    ec.bounces = 2;
    ec.aoSamples = 2;
    expectSameEffect(*gpu_, f, "grid", ec);
  }
}

#endif  // LAYERTRACE_HAS_GPU

}  // namespace
}  // namespace lt
