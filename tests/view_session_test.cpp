// The viewer's CPU side (app/view_session.h), headless: its full picture is `render`'s image bit
// for bit, a moving camera's picture has ¼ of the pixels, overlays come back with the right
// size and meaning, and a refused option becomes an error message instead of an exception.
#include "layertrace/app/view_session.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/eval/classify.h"
#include "test_util.h"
#include "layertrace/util/error.h"

namespace lt {
namespace {

RenderOptions defaultOptions() {
  RenderOptions o;
  o.run.frame.scenePath = test::sourceDir() + "/scenes/default.json";
  o.run.frame.width = 160, o.run.frame.height = 90;
  o.tracer = "hssr";
  o.effect.effect = Effect::Reflection;
  o.effect.bounces = 2;
  return o;
}

TEST(ViewSession, FullPictureIsRendersImage) {
  const RenderOptions o = defaultOptions();
  ViewSession session(o);
  const ViewResult v = session.render(session.initialRequest());
  ASSERT_TRUE(v.error.empty()) << v.error;
  // What runRender computes for the same options.
  const Frame f = buildFrame(o.run.frame);
  const BuiltTracer b = buildTracer(o.tracer, f, o.tracers);
  EffectConfig ec = o.effect;
  ec.seed = o.run.seed;
  const EffectResult r = renderEffect(f, *b.tracer, ec);
  ASSERT_EQ(v.traced.width, r.image.width);
  ASSERT_EQ(v.traced.height, r.image.height);
  EXPECT_EQ(v.traced.data, r.image.data);
  EXPECT_EQ(v.image.data, r.image.data);  // no overlay: the picture shown is the traced one
  EXPECT_EQ(v.rays, r.rays);
}

TEST(ViewSession, MovingCameraTracesAQuarterOfThePixelsAndTheNewCameraCounts) {
  ViewSession session(defaultOptions());
  ViewRequest q = session.initialRequest();
  q.scale = 2;
  const ViewResult moving = session.render(q);
  ASSERT_TRUE(moving.error.empty()) << moving.error;
  EXPECT_EQ(moving.image.width, 80);
  EXPECT_EQ(moving.image.height, 45);
  // Another camera gives another picture; going back gives the first one again (nothing of
  // the previous view leaks into the next).
  q.scale = 1;
  const ViewResult first = session.render(q);
  ViewRequest other = q;
  other.camera.eye += 0.3f * (other.camera.target - other.camera.eye);
  const ViewResult moved = session.render(other);
  const ViewResult again = session.render(q);
  EXPECT_NE(first.traced.data, moved.traced.data);
  EXPECT_EQ(first.traced.data, again.traced.data);
}

TEST(ViewSession, OverlaysAndGeometricTracers) {
  ViewSession session(defaultOptions());
  ViewRequest q = session.initialRequest();
  q.overlay = ViewOverlay::Classes;
  const ViewResult c = session.render(q);
  ASSERT_TRUE(c.classified);
  double sum = 0.0;
  for (double x : c.classFractions) sum += x;
  EXPECT_NEAR(sum, 1.0, 1e-9);
  EXPECT_GT(c.classFractions[size_t(RayClass::CorrectHit)], 0.3);
  EXPECT_NE(c.image.data, c.traced.data);
  // Embree against itself: every ray in a correct class.
  q.tracer = "embree";
  for (int repeat = 0; repeat < 2; ++repeat) {  // the second frame reuses the cached BVH
    const ViewResult e = session.render(q);
    ASSERT_TRUE(e.error.empty()) << e.error;
    EXPECT_NEAR(e.classFractions[size_t(RayClass::CorrectHit)] + e.classFractions[size_t(RayClass::CorrectMiss)], 1.0, 1e-3);
    EXPECT_EQ(session.cachedStructures(), 1u);
  }
  // The grid is built once per set of its own parameters; another method's parameter, or the
  // camera, does not rebuild it.
  q.tracer = "grid";
  q.overlay = ViewOverlay::None;
  ASSERT_TRUE(session.render(q).error.empty());
  EXPECT_EQ(session.cachedStructures(), 2u);
  q.tracers.pyramid.tau = 9.0f;
  q.camera.eye += 0.1f * (q.camera.target - q.camera.eye);
  ASSERT_TRUE(session.render(q).error.empty());
  EXPECT_EQ(session.cachedStructures(), 2u);
  q.tracers.grid.lambda1 *= 2.0f;
  ASSERT_TRUE(session.render(q).error.empty());
  EXPECT_EQ(session.cachedStructures(), 3u);
  q.tracer = "hssr";
  q.overlay = ViewOverlay::Iterations;
  const ViewResult it = session.render(q);
  EXPECT_EQ(it.image.width, 160);
  if (kCountersCompiled) {  // builds without counters report none
    EXPECT_GT(it.iterationsMean, 1.0);
  }
  q.overlay = ViewOverlay::Layer;
  q.layer = 1;
  const ViewResult l = session.render(q);
  EXPECT_EQ(l.image.width, 160);
  q.overlay = ViewOverlay::DepthComplexity;
  EXPECT_EQ(session.render(q).image.height, 90);
}

// --device gpu: the capture, the tracers with a GPU version and their effects run on the GPU; the pictures are
// the CPU session's (bit for bit on an IEEE device such as llvmpipe, as tests/gpu_test.cpp
// holds the GPU tracers to), and a tracer without a GPU version runs on the CPU over the GPU's
// capture.
TEST(ViewSession, GpuDeviceGivesTheCpuPictures) {
  if (std::getenv("LAYERTRACE_SANITIZED")) GTEST_SKIP() << "sanitized build: the GPU driver is not instrumented";
  RenderOptions cpuOptions = defaultOptions(), gpuOptions = defaultOptions();
  gpuOptions.run.device = "gpu";
  ViewSession cpu(cpuOptions), gpu(gpuOptions);
  const bool software = gpuStats(*openGpu())["software"].get<bool>();  // an IEEE device: exact
  for (const char* tracer : {"hssr", "ssr-layers", "quadtree", "ldc", "grid", "hybrid", "embree"}) {
    SCOPED_TRACE(tracer);
    ViewRequest q = cpu.initialRequest();
    q.tracer = tracer;
    const ViewResult a = cpu.render(q), b = gpu.render(q);
    ASSERT_TRUE(b.error.empty()) << b.error;
    // hssr, ssr-layers, quadtree, ldc and grid: resident frames; hybrid: traced on the GPU,
    // shaded on the CPU; embree: no GPU version, on the CPU.
    const std::string name = tracer;
    EXPECT_EQ(b.device, name == "embree" ? "cpu" : "gpu");
    EXPECT_EQ(a.device, "cpu");
    // The default effect (reflection) is generated and shaded on the GPU but with the hybrid.
    EXPECT_EQ(b.shading, name == "hybrid" || name == "embree" ? "cpu" : "gpu");
    ASSERT_EQ(a.traced.data.size(), b.traced.data.size());
    // The rays and their answers are the CPU's; the shading is GLSL's, whose pow is not libm's:
    // colours agree to 1e-4 relative, not to the bit.
    size_t differ = 0;
    float worst = 0.0f;
    for (size_t i = 0; i < a.traced.data.size(); ++i) {
      const float d = std::abs(a.traced.data[i] - b.traced.data[i]) / std::max(1.0f, std::abs(a.traced.data[i]));
      worst = std::max(worst, d);
      differ += d > 1e-4f;
    }
    RecordProperty(std::string(tracer) + "_largest_relative_difference", std::to_string(worst));
    EXPECT_LE(double(differ), software ? 0.0 : 1e-3 * double(a.traced.data.size()));
    EXPECT_EQ(gpu.frame().capturePipeline, "gpu-lists");
    // The panel's accounting of the GPU frame: the capture's draw, the passes' dispatches.
    EXPECT_GE(b.gpuFrame.value("draws", 0), 1);
    EXPECT_GE(b.gpuFrame.value("dispatches", 0), 3);
    EXPECT_TRUE(a.gpuFrame.is_null());
  }
  // HSSR's picture is one resident frame, kept while the tracer stays: the next one links,
  // allocates and uploads nothing and waits once.
  ViewRequest q = cpu.initialRequest();
  ASSERT_TRUE(gpu.render(q).error.empty());
  q.camera.eye.x += 0.05f;
  const ViewResult again = gpu.render(q);
  ASSERT_TRUE(again.error.empty()) << again.error;
  EXPECT_EQ(again.gpuFrame.value("program_links", 99), 0);
  EXPECT_EQ(again.gpuFrame.value("buffer_allocations", 99), 0);
  EXPECT_EQ(again.gpuFrame.value("host_waits", 99), 1);
  const ViewResult want = cpu.render(q);
  ASSERT_EQ(again.traced.data.size(), want.traced.data.size());
  size_t differ = 0;
  for (size_t i = 0; i < want.traced.data.size(); ++i)
    differ += std::abs(want.traced.data[i] - again.traced.data[i]) / std::max(1.0f, std::abs(want.traced.data[i])) > 1e-4f;
  EXPECT_LE(double(differ), software ? 0.0 : 1e-3 * double(want.traced.data.size()));
}

TEST(ViewSession, RefusedOptionsBecomeMessages) {
  ViewSession session(defaultOptions());
  ViewRequest q = session.initialRequest();
  q.layers = 0;
  const ViewResult bad = session.render(q);
  EXPECT_NE(bad.error.find("--layers"), std::string::npos) << bad.error;
  EXPECT_TRUE(bad.image.data.empty());
  q.layers = 4;
  q.tracers.pyramid.tau = -1.0f;
  EXPECT_NE(session.render(q).error.find("--hssr-tau"), std::string::npos);
  q.tracers.pyramid.tau = 25.0f;
  EXPECT_TRUE(session.render(q).error.empty());  // and the session still works
  EXPECT_THROW(parseViewOverlay("nope"), InputError);
  ViewOptions v;
  v.screenshot = "a.png";
  EXPECT_THROW(validateViewOptions(v), InputError);  // needs --frames
  v.frames = 2;
  v.screenshot = "a.jpg";
  EXPECT_THROW(validateViewOptions(v), InputError);
}

}  // namespace
}  // namespace lt
