// The resident GPU frame (gpu/gpu_frame.h) against the GPU path it replaces — capture on the
// GPU, layers downloaded, tracer and effect passes built over them — bit for bit; and its
// accounting: the frames after the first link, allocate and upload nothing beyond the
// parameters, and wait for the GPU once.
#include <cstdlib>
#include <limits>
#include <cstring>
#include <functional>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/render/frame_sequence.h"
#include "layertrace/util/error.h"
#include "layertrace/hiz/hiz_pyramid.h"
#include "test_util.h"

#if LAYERTRACE_HAS_GPU
#include "layertrace/gpu/gpu_capture.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_frame.h"
#include "layertrace/gpu/gpu_quadtree.h"
#include "layertrace/render/gpu_effect_params.h"
#include "layertrace/screen/interval_layers.h"
#endif

namespace lt {
namespace {

using test::defaultSceneOptions;

TEST(FrameSequence, OrbitStartsAtTheCameraAndKeepsItsDistanceAndHeight) {
  CameraDesc d;
  d.eye = {3.0f, 2.0f, 4.0f};
  d.target = {1.0f, 0.5f, -1.0f};
  for (int i = 0; i < 8; ++i) {
    const CameraDesc o = orbitCamera(d, i, 45.0f);
    EXPECT_NEAR(glm::length(o.eye - o.target), glm::length(d.eye - d.target), 1e-4f);
    EXPECT_NEAR(o.eye.y, d.eye.y, 1e-4f);
    EXPECT_EQ(o.target, d.target);
    if (i == 0) EXPECT_EQ(o.eye, d.eye);
    else EXPECT_GT(glm::length(o.eye - d.eye), 0.1f);
  }
  // Half a turn: the eye opposite the start about the target's vertical.
  const CameraDesc h = orbitCamera(d, 4, 45.0f);
  EXPECT_NEAR(h.eye.x - d.target.x, -(d.eye.x - d.target.x), 1e-4f);
  EXPECT_NEAR(h.eye.z - d.target.z, -(d.eye.z - d.target.z), 1e-4f);
}

/// `frames` frames of the default scene's reflections at W × H on `gpu` (null: the CPU).
std::vector<FrameSample> defaultSceneFrames(int W, int H, int frames, GpuContext* gpu, std::function<void(int, const Image&)> onImage = {},
                                            const std::string& tracer = "hssr") {
  const FrameOptions fo = defaultSceneOptions(W, H);
  Frame frame;
  loadFrameScene(fo, frame);
  FrameSequenceConfig c;
  c.frames = frames;
  c.tracer = tracer;
  c.onImage = std::move(onImage);
  return runFrameSequence(fo, frame, c, gpu);
}

TEST(FrameSequence, CpuFramesFollowTheOrbitAndCountTheirRays) {
  int images = 0;
  const std::vector<FrameSample> s =
      defaultSceneFrames(96, 64, 3, nullptr, [&](int, const Image& img) { images += img.width == 96 && img.height == 64; });
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(images, 3);
  for (const FrameSample& f : s) EXPECT_GT(f.rays, 96u * 64u / 4);
  EXPECT_NE(s[0].hits, s[1].hits);  // another view, other answers
  const nlohmann::json summary = frameSummary(s);
  EXPECT_EQ(summary["frames"], 3);
  EXPECT_EQ(summary["rays"].get<uint64_t>(), (s[1].rays + s[2].rays) / 2);
}

#if LAYERTRACE_HAS_GPU

class GpuFrameTest : public test::GpuSuite {};

struct Reference {
  GpuEffectOutput out;
  uint64_t fragments = 0;
};

/// The path the resident frame replaces: the GPU capture downloaded, the GPU tracer and the
/// effect passes built over the downloaded layers.
Reference downloadedPath(GpuContext& gpu, const FrameOptions& fo, Frame& frame, const GpuFrameConfig& fc, const GpuEffectParams& p) {
  GpuCaptureResult cap;
  captureOnGpu(gpu, frame.scene, frame.camera, fc.capture, cap);
  const IntervalLayers level0 = makeIntervalLayers(cap.layers, cap.layers.k);
  GpuScreenTracer tracer(gpu, frame.camera, cap.layers, level0, fc.pyramid, fc.march);
  GpuEffects effects(gpu, frame.scene, frame.camera, cap.layers, frame.lights);
  GpuEffectReadback all;
  all.sums = true;
  (void)fo;
  return {effects.run(tracer, p, all), cap.generated};
}

GpuFrameConfig hssrConfig(const FrameOptions& fo, const Frame& frame) {
  GpuFrameConfig fc;
  fc.capture.layers = layerConfig(fo, frame);
  return fc;
}

void expectSameFrame(const GpuFrameResult& got, const Reference& want, size_t pixels) {
  EXPECT_EQ(got.fragments, want.fragments);
  for (size_t i = 0; i < 16; ++i) EXPECT_EQ(got.sums[i], want.out.sums[i]) << "sum " << i;
  ASSERT_EQ(got.image.size(), pixels);
  ASSERT_EQ(want.out.image.size(), pixels);
  size_t differ = 0;
  for (size_t q = 0; q < pixels; ++q) differ += std::memcmp(&got.image[q], &want.out.image[q], sizeof(glm::vec3)) != 0;
  EXPECT_EQ(differ, 0u);
}

TEST_F(GpuFrameTest, ResidentFramesEqualTheDownloadedPathBitForBit) {
  const int W = 203, H = 117;  // partial tiles
  FrameOptions fo = defaultSceneOptions(W, H);
  Frame frame;
  loadFrameScene(fo, frame);
  const CameraDesc start = frame.camera.desc();
  EffectConfig ec;
  ec.bounces = 3;
  GpuFrameConfig fc = hssrConfig(fo, frame);
  GpuFrame resident(*gpu_, frame.scene, frame.lights, fc);
  // Three views and the first again: the kept buffers carry nothing from one frame to the next.
  for (int i : {0, 3, 5, 0}) {
    SCOPED_TRACE(i);
    setFrameView(fo, orbitCamera(start, i, 45.0f), frame);
    const GpuEffectParams p = gpuEffectParams(frame, ec);
    const GpuFrameResult got = resident.render(frame.camera, layerConfig(fo, frame), p, GpuPicture::Linear);
    const Reference want = downloadedPath(*gpu_, fo, frame, fc, p);
    ASSERT_GT(want.out.sums[0], uint64_t(W * H / 4));
    expectSameFrame(got, want, size_t(W) * size_t(H));
  }
}

TEST_F(GpuFrameTest, EveryEffectAndTheHiZMarchAndRayReloadingEqualTheDownloadedPath) {
  const int W = 96, H = 64;
  FrameOptions fo = defaultSceneOptions(W, H);
  Frame frame;
  loadFrameScene(fo, frame);
  setFrameView(fo, orbitCamera(frame.camera.desc(), 1), frame);
  struct Case {
    Effect effect;
    bool hiz, reloading;
  };
  for (const Case c : {Case{Effect::AO, false, false}, Case{Effect::Shadow, false, true}, Case{Effect::Refraction, true, false},
                       Case{Effect::Reflection, true, true}, Case{Effect::Shade, false, false}}) {
    SCOPED_TRACE(std::string(effectName(c.effect)) + (c.hiz ? " hiz" : " hssr") + (c.reloading ? " reloading" : ""));
    EffectConfig ec;
    ec.effect = c.effect;
    ec.bounces = 2;
    GpuFrameConfig fc = hssrConfig(fo, frame);
    if (c.hiz) {
      fc.march = hizConfig(fc.pyramid.levels);
      fc.pyramid.tau = std::numeric_limits<float>::infinity();
    }
    fc.march.rayReloading = c.reloading;
    GpuFrame resident(*gpu_, frame.scene, frame.lights, fc);
    const GpuEffectParams p = gpuEffectParams(frame, ec);
    const GpuFrameResult got = resident.render(frame.camera, layerConfig(fo, frame), p, GpuPicture::Linear);
    expectSameFrame(got, downloadedPath(*gpu_, fo, frame, fc, p), size_t(W) * size_t(H));
  }
}

// The timed runs' counter-free marches (LT_NO_COUNTERS) answer as the counted ones.
TEST_F(GpuFrameTest, TheCounterFreeMarchesGiveTheSameAnswers) {
  const int W = 96, H = 64;
  FrameOptions fo = defaultSceneOptions(W, H);
  Frame frame;
  loadFrameScene(fo, frame);
  for (const bool hiz : {false, true}) {
    SCOPED_TRACE(hiz ? "hiz" : "hssr");
    GpuFrameConfig fc = hssrConfig(fo, frame);
    if (hiz) fc.march = hizConfig(fc.pyramid.levels), fc.pyramid.tau = std::numeric_limits<float>::infinity();
    GpuFrame resident(*gpu_, frame.scene, frame.lights, fc);
    EffectConfig ec;
    ec.bounces = 2;
    const GpuFrameResult counted = resident.render(frame.camera, layerConfig(fo, frame), gpuEffectParams(frame, ec), GpuPicture::Linear);
    ec.countRays = false;
    const GpuFrameResult timed = resident.render(frame.camera, layerConfig(fo, frame), gpuEffectParams(frame, ec), GpuPicture::Linear);
    EXPECT_GT(counted.sums[2], 0u);  // iterations
    EXPECT_EQ(timed.sums[2], 0u);
    EXPECT_EQ(timed.sums[0], counted.sums[0]);
    EXPECT_EQ(timed.sums[1], counted.sums[1]);
    ASSERT_EQ(timed.image.size(), counted.image.size());
    EXPECT_EQ(std::memcmp(timed.image.data(), counted.image.data(), counted.image.size() * sizeof(glm::vec3)), 0);
  }
}

// The picture packed on the device: RGBA32F is the linear picture to the bit, and RGBA8 holds
// the PNG writer's sRGB codes of it to the bit (encode8), at a size with partial tiles.
TEST_F(GpuFrameTest, PackedPicturesAreTheLinearPictureEncodedAsTheCpuEncodesIt) {
  const int W = 101, H = 59;
  FrameOptions fo = defaultSceneOptions(W, H);
  Frame frame;
  loadFrameScene(fo, frame);
  EffectConfig ec;
  ec.bounces = 2;
  GpuFrame resident(*gpu_, frame.scene, frame.lights, hssrConfig(fo, frame));
  const GpuEffectParams p = gpuEffectParams(frame, ec);
  const GpuFrameResult linear = resident.render(frame.camera, layerConfig(fo, frame), p, GpuPicture::Linear);
  const GpuFrameResult srgb = resident.render(frame.camera, layerConfig(fo, frame), p, GpuPicture::Srgb8);
  const GpuFrameResult f32 = resident.render(frame.camera, layerConfig(fo, frame), p, GpuPicture::Float32);
  ASSERT_EQ(linear.image.size(), size_t(W * H));
  ASSERT_EQ(srgb.srgb8.size(), size_t(W * H));
  ASSERT_EQ(f32.float32.size(), size_t(W * H));
  EXPECT_TRUE(srgb.image.empty());
  Image img(W, H);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) img.set(x, y, linear.image[size_t(y) * W + size_t(x)]);
  std::vector<uint8_t> want;
  encode8(img, true, 3, want);
  size_t differ = 0, notFloat = 0, distinct = 0;
  for (size_t i = 0; i < size_t(W * H); ++i) {
    for (size_t c = 0; c < 3; ++c) differ += uint8_t(srgb.srgb8[i] >> (8 * c)) != want[3 * i + c];
    differ += (srgb.srgb8[i] >> 24) != 255u;
    notFloat += std::memcmp(&f32.float32[i], &linear.image[i], sizeof(glm::vec3)) != 0;
    distinct += i > 0 && want[3 * i] != want[3 * i - 3];
  }
  EXPECT_EQ(differ, 0u);
  EXPECT_EQ(notFloat, 0u);
  EXPECT_GT(distinct, size_t(W * H / 20)) << "a picture with detail";
  EXPECT_EQ(srgb.sums, linear.sums);  // the same frame
}

TEST_F(GpuFrameTest, AnOverflowingPoolGrowsAndTheFrameRunsAgainWithTheSameAnswers) {
  const int W = 96, H = 64;
  FrameOptions fo = defaultSceneOptions(W, H);
  Frame frame;
  loadFrameScene(fo, frame);
  EffectConfig ec;
  GpuFrameConfig fc = hssrConfig(fo, frame);
  GpuFrame plain(*gpu_, frame.scene, frame.lights, fc);
  const GpuEffectParams p = gpuEffectParams(frame, ec);
  const GpuFrameResult want = plain.render(frame.camera, layerConfig(fo, frame), p, GpuPicture::Linear);
  fc.capture.poolCapacity = 100;  // far fewer than the frame's fragments
  GpuFrame small(*gpu_, frame.scene, frame.lights, fc);
  const GpuFrameResult got = small.render(frame.camera, layerConfig(fo, frame), p, GpuPicture::Linear);
  EXPECT_GE(got.attempts, 2);
  EXPECT_EQ(got.fragments, want.fragments);
  EXPECT_GT(got.fragments, 100u);
  EXPECT_EQ(got.sums, want.sums);
  EXPECT_EQ(got.image.size(), want.image.size());
  EXPECT_EQ(std::memcmp(got.image.data(), want.image.data(), want.image.size() * sizeof(glm::vec3)), 0);
  // Without growing, the overflow is an input error with the exact counts.
  fc.capture.growOnOverflow = false;
  GpuFrame fixed(*gpu_, frame.scene, frame.lights, fc);
  try {
    fixed.render(frame.camera, layerConfig(fo, frame), p, GpuPicture::None);
    FAIL() << "no overflow error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(std::to_string(want.fragments) + " fragments generated, 100 stored"), std::string::npos) << e.what();
  }
}

// The quad-tree (built on the device from each frame's level 0), the layered depth cube and the
// irregular grid (their structures of the scene built once beside the frame) trace the resident
// frame: every view's picture and counters are those of the downloaded path with a tracer built
// for that view (reflections; AO, whose rays are any-hit walks), and a frame after the first
// allocates, links and uploads nothing.
TEST_F(GpuFrameTest, TheQuadtreeAndTheTracersOfTheSceneTraceResidentFramesAsTheDownloadedPath) {
  const int W = 131, H = 75;
  FrameOptions fo = defaultSceneOptions(W, H);
  Frame frame;
  loadFrameScene(fo, frame);
  const CameraDesc start = frame.camera.desc();
  for (const std::string name : {"quadtree", "ldc", "grid"}) {
    SCOPED_TRACE(name);
    GpuFrameConfig fc = hssrConfig(fo, frame);
    BuiltTracer built;
    if (name == "quadtree") {
      fc.quadtree = QuadtreeConfig{};
    } else {
      built = buildGpuTracer(name, frame, TracerOptions{}, *gpu_);
      fc.sceneTracer = dynamic_cast<GpuEffectTracer*>(built.tracer.get());
      ASSERT_TRUE(fc.sceneTracer && fc.sceneTracer->effectsOnDevice());
    }
    GpuFrame resident(*gpu_, frame.scene, frame.lights, fc);
    for (const Effect effect : {Effect::Reflection, Effect::AO}) {
      EffectConfig ec;
      ec.effect = effect;
      ec.bounces = 2;
      ec.aoSamples = 2;
      for (int i : {0, 1}) {
        SCOPED_TRACE(i);
        setFrameView(fo, orbitCamera(start, i, 45.0f), frame);
        const GpuEffectParams p = gpuEffectParams(frame, ec);
        const GpuActivity before = gpuActivity();
        const GpuFrameResult got = resident.render(frame.camera, layerConfig(fo, frame), p, GpuPicture::Linear);
        const GpuActivity a = gpuActivity() - before;
        if (i == 1) {  // (not the first frame: that one uploads the scene and links the programs)
          EXPECT_EQ(a.programLinks, 0u);
          EXPECT_EQ(a.bufferAllocations, 0u);
          EXPECT_LE(a.uploadBytes, 64u * 1024u);
        }
        // (a tracer built for this view: the resident ones follow the views by rebuild and
        // setEffectCamera)
        GpuCaptureResult cap;
        captureOnGpu(*gpu_, frame.scene, frame.camera, fc.capture, cap);
        std::unique_ptr<GpuQuadtreeTracer> tree;
        BuiltTracer fresh;
        if (name == "quadtree") tree = std::make_unique<GpuQuadtreeTracer>(*gpu_, frame.camera, cap.layers, QuadtreeConfig{});
        else fresh = buildGpuTracer(name, frame, TracerOptions{}, *gpu_);
        const GpuEffectTracer& tracer = tree ? *tree : dynamic_cast<const GpuEffectTracer&>(*fresh.tracer);
        GpuEffects effects(*gpu_, frame.scene, frame.camera, cap.layers, frame.lights);
        GpuEffectReadback all;
        all.sums = true;
        const Reference want{effects.run(tracer, p, all), cap.generated};
        ASSERT_GT(want.out.sums[0], uint64_t(W * H / 4));
        expectSameFrame(got, want, size_t(W) * size_t(H));
        const GpuTracerSums nodes = tracer.effectSums();
        EXPECT_EQ(got.tracerSums.planeNodes, nodes.planeNodes);
        EXPECT_EQ(got.tracerSums.boxNodes, nodes.boxNodes);
        EXPECT_EQ(got.tracerSums.occlusions, nodes.occlusions);
        if (tree) {
          EXPECT_GT(nodes.planeNodes, 0u);
        }
      }
    }
  }
}

TEST_F(GpuFrameTest, TheFramesAfterTheFirstLinkAllocateAndUploadNothingAndWaitOnce) {
  // The quad-tree and the tracers of the scene too (the quad-tree's block adds its six node-counter
  // words).
  for (const std::string tracer : {"quadtree", "ldc", "grid"}) {
    SCOPED_TRACE(tracer);
    const std::vector<FrameSample> s = defaultSceneFrames(160, 90, 3, gpu_.get(), {}, tracer);
    ASSERT_EQ(s.size(), 3u);
    for (size_t i = 1; i < s.size(); ++i) {
      EXPECT_EQ(s[i].programLinks, 0u);
      EXPECT_EQ(s[i].bufferAllocations, 0u);
      EXPECT_LE(s[i].uploadBytes, 64u * 1024u);
      EXPECT_EQ(s[i].hostWaits, 1u);
      EXPECT_EQ(s[i].downloadBytes, tracer == "quadtree" ? 236u : 212u);
      EXPECT_GT(s[i].rays, 160u * 90u / 4);
    }
  }
  const std::vector<FrameSample> s = defaultSceneFrames(160, 90, 4, gpu_.get());
  ASSERT_EQ(s.size(), 4u);
  EXPECT_GT(s[0].bufferAllocations, 0u);  // the first frame uploads the scene and allocates
  EXPECT_GT(s[0].uploadBytes, 64u * 1024u);
  for (size_t i = 1; i < s.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(s[i].programLinks, 0u);
    EXPECT_EQ(s[i].bufferAllocations, 0u);
    EXPECT_LE(s[i].uploadBytes, 64u * 1024u);
    EXPECT_EQ(s[i].hostWaits, 1u);
    // the counters' block: fragments, complexity maximum, kept fragments, 16 level totals, 16 64-bit
    // sums, the percentile and a spare word
    EXPECT_EQ(s[i].downloadBytes, 212u);
    EXPECT_EQ(s[i].draws, 1u);
    EXPECT_EQ(s[i].attempts, 1);
    EXPECT_GT(s[i].rays, 160u * 90u / 4);
  }
}

#endif

}  // namespace
}  // namespace lt
