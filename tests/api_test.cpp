// The public API (api/layertrace.h): user buffers give the CLI path's answers bit for
// bit, rays in world space give the camera-space answers, every bad argument is named, and the
// classification is the evaluation's.
#include <cstring>
#include <stdexcept>

#include <glm/geometric.hpp>

#include "layertrace/api/layertrace.h"
#include "layertrace/app/commands.h"
#include "layertrace/eval/classify.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "test_util.h"

namespace lt {
namespace {

Frame defaultFrame() {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 160, o.height = 90;
  o.captureLists = true;  // the lists feed ScreenLayers::fromFragments below
  return buildFrame(o);
}

View viewOf(const Camera& c) {
  View v;
  v.eye = c.desc().eye, v.target = c.desc().target, v.up = c.desc().up, v.fovY = c.desc().fovY;
  v.near = c.near(), v.far = c.far();
  v.width = c.width(), v.height = c.height();
  return v;
}

/// The pipeline's k layers as the API's layer-major buffers.
struct UserLayers {
  std::vector<float> front, back;
  std::vector<glm::vec3> normals;
  std::vector<uint32_t> ids;
};
UserLayers userLayersOf(const LayerArrays& L) {
  const size_t pixels = size_t(L.width) * size_t(L.height), n = pixels * size_t(L.k);
  UserLayers u{std::vector<float>(n, std::numeric_limits<float>::infinity()), std::vector<float>(n, std::numeric_limits<float>::infinity()),
               std::vector<glm::vec3>(n, glm::vec3(0, 0, 1)), std::vector<uint32_t>(n, 0)};
  for (size_t p = 0; p < pixels; ++p)
    for (int l = 0; l < L.count[p]; ++l) {
      const FragmentNode& f = L.slots[p * size_t(L.k) + size_t(l)];
      const size_t i = size_t(l) * pixels + p;
      u.front[i] = f.depth, u.back[i] = f.back(), u.normals[i] = decodeOctahedral(f.normal);
      u.ids[i] = L.triangle[p * size_t(L.k) + size_t(l)];
    }
  return u;
}

/// Everything but the material (user layers carry none) bit for bit.
::testing::AssertionResult sameHit(const TraceHit& a, const TraceHit& b) {
  if (a.hit != b.hit) return ::testing::AssertionFailure() << "hit " << a.hit << " vs " << b.hit;
  if (!a.hit) return ::testing::AssertionSuccess();
  if (a.x != b.x || a.y != b.y || a.layer != b.layer || a.triangle != b.triangle || std::memcmp(&a.point, &b.point, sizeof a.point) != 0 ||
      std::memcmp(&a.normal, &b.normal, sizeof a.normal) != 0)
    return ::testing::AssertionFailure() << "pixel " << a.x << "," << a.y << " layer " << a.layer << " vs " << b.x << "," << b.y << " layer " << b.layer;
  return ::testing::AssertionSuccess();
}

// The layers our pipeline captured, handed to the API as user buffers (k layers,
// and as full fragment lists), give every screen tracer the CLI path's hits bit for bit.
TEST(Api, UserBuffersGiveTheCliPathsHitsBitForBit) {
  const Frame f = defaultFrame();
  const View view = viewOf(f.camera);
  const UserLayers u = userLayersOf(f.layers);
  const ScreenLayers fromLayers = ScreenLayers::fromLayers(view, f.layers.k, u.front, u.back, u.normals, u.ids);
  // The fragment lists as CSR arrays.
  std::vector<uint32_t> offsets{0};
  std::vector<float> depth;
  std::vector<glm::vec3> normals;
  std::vector<uint32_t> ids;
  for (size_t p = 0; p < f.lists.head.size(); ++p) {
    std::vector<uint32_t> chain;
    for (uint32_t n = f.lists.head[p]; n != kNullIndex; n = f.lists.nodes[n].next) chain.push_back(n);
    for (uint32_t n : chain) {
      depth.push_back(f.lists.nodes[n].depth);
      normals.push_back(decodeOctahedral(f.lists.nodes[n].normal));
      ids.push_back(f.lists.triangle[n]);
    }
    offsets.push_back(uint32_t(depth.size()));
  }
  const ScreenLayers fromFragments = ScreenLayers::fromFragments(view, offsets, depth, normals, ids, f.layers.k, kDefaultThicknessPx);
  EXPECT_EQ(fromLayers.layers(), f.layers.k);
  for (int y = 0; y < f.layers.height; ++y)
    for (int x = 0; x < f.layers.width; ++x) ASSERT_EQ(fromFragments.countAt(x, y), f.layers.countAt(x, y));
  const std::vector<Ray> rays = test::sampleRays(f, 4000, test::testSeed());
  for (const char* name : {"hssr", "hiz", "ssr", "ssr-layers", "quadtree"}) {
    SCOPED_TRACE(name);
    const BuiltTracer cli = buildTracer(name, f, TracerOptions{});
    std::vector<TraceHit> expected(rays.size()), a(rays.size()), b(rays.size());
    cli.tracer->traceBatch(rays, expected, {});
    ScreenTracer(fromLayers, name).trace(rays, a);
    ScreenTracer(fromFragments, name).trace(rays, b);
    size_t hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      ASSERT_TRUE(sameHit(a[i], expected[i])) << "k layers, ray " << i;
      ASSERT_TRUE(sameHit(b[i], expected[i])) << "fragments, ray " << i;
      hits += expected[i].hit;
    }
    EXPECT_GT(hits, rays.size() / 3);
  }
}

// World-space rays get the camera-space answers (points and normals in world space); any-hit
// queries agree with closest hits; classification is the evaluation's.
TEST(Api, WorldSpaceRaysAndClassificationAgreeWithTheCameraPath) {
  const Frame f = defaultFrame();
  const View view = viewOf(f.camera);
  const UserLayers u = userLayersOf(f.layers);
  const ScreenLayers layers = ScreenLayers::fromLayers(view, f.layers.k, u.front, u.back, u.normals, u.ids);
  const ScreenTracer hssr(layers);
  EXPECT_STREQ(hssr.name(), "hssr");
  // Random mirror and scattered rays (not the exact screen diagonals, which a rounded bit moves).
  const std::vector<Ray> rays = test::sampleRays(f, 2000, test::testSeed(), false);
  std::vector<Ray> world(rays);
  for (Ray& r : world) r.origin = cameraToWorld(view, r.origin), r.dir = glm::normalize(f.camera.dirToWorld(r.dir));
  std::vector<TraceHit> cam(rays.size()), wor(rays.size()), any(rays.size());
  hssr.trace(rays, cam);
  hssr.trace(world, wor, RaySpace::World);
  hssr.occluded(rays, any);
  // The round trip through world space rounds the rays' last bits: a ray that grazes a pixel
  // boundary may cross into the neighbour, so the answers agree on all but a few rays.
  size_t same = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    ASSERT_EQ(cam[i].hit, any[i].hit) << i;
    same += cam[i].hit == wor[i].hit &&
            (!cam[i].hit || glm::length(cameraToWorld(view, cam[i].point) - wor[i].point) <= 1e-3f * glm::length(cam[i].point - rays[i].origin));
  }
  EXPECT_GE(double(same), 0.98 * double(rays.size()));
  // The geometric side from the same triangles, and the strict classes.
  const TriangleScene scene(f.scene.positions, f.scene.triangles);
  EXPECT_EQ(scene.triangleCount(), f.scene.triangleCount());
  const MeshTracer embree(scene, view, "embree-robust");  // the ground truth, as compare's
  std::vector<TraceHit> truth(rays.size());
  embree.trace(rays, truth);
  // One name, one meaning: "embree" is the CLI's plain Embree, "embree-robust" the reference.
  std::vector<TraceHit> plain(rays.size());
  MeshTracer(scene, view, "embree").trace(rays, plain);
  const BuiltTracer cliEmbree = buildTracer("embree", f, TracerOptions{}), cliRobust = buildTracer("embree-robust", f, TracerOptions{});
  for (size_t i = 0; i < rays.size(); i += 37) {
    RayCounters c;
    const TraceHit a = cliEmbree.tracer->trace(rays[i], c), b = cliRobust.tracer->trace(rays[i], c);
    ASSERT_EQ(plain[i].hit, a.hit) << i;
    ASSERT_EQ(truth[i].hit, b.hit) << i;
    EXPECT_TRUE(!a.hit || plain[i].triangle == a.triangle) << i;
    EXPECT_TRUE(!b.hit || truth[i].triangle == b.triangle) << i;
  }
  const std::vector<uint8_t> classes = classifyHits(layers, rays, cam, truth);
  size_t correct = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    ASSERT_EQ(classes[i], uint8_t(classifyRay(rays[i], cam[i], truth[i], Query::Closest, f.camera, f.layers))) << i;
    correct += classes[i] == uint8_t(HitClass::CorrectHit);
  }
  EXPECT_GT(correct, rays.size() / 3);
  EXPECT_STREQ(hitClassName(HitClass::InfoMiss), "info_miss");
}

// A scene given as arrays: captureLayers stores what `layertrace render` stores, and render()
// makes the CLI's image (one light above the eye; the same tracer, effect and k).
TEST(Api, CaptureAndRenderOfUserTrianglesAreTheCliPaths) {
  const Frame f = defaultFrame();
  const View view = viewOf(f.camera);
  const TriangleScene scene(f.scene.positions, f.scene.triangles);
  const ScreenLayers captured = captureLayers(scene, view, f.layers.k);
  size_t stored = 0;
  for (int y = 0; y < f.layers.height; ++y)
    for (int x = 0; x < f.layers.width; ++x) {
      ASSERT_EQ(captured.countAt(x, y), f.layers.countAt(x, y)) << x << "," << y;
      stored += size_t(captured.countAt(x, y));
    }
  EXPECT_GT(stored, size_t(f.layers.width * f.layers.height));
  // Every surface half a mirror, so the reflection rays show in the image.
  const std::vector<uint32_t> material(f.scene.triangleCount(), 0);
  const std::vector<MeshMaterial> mirror{{glm::vec3(0.6f), 0.5f}};
  const TriangleScene mirrors(f.scene.positions, f.scene.triangles, material, mirror);
  auto meanAbsDiff = [](const RgbImage& a, const RgbImage& b) {
    double d = 0.0;
    for (size_t i = 0; i < a.rgb.size(); ++i) d += std::abs(a.rgb[i] - b.rgb[i]);
    return d / double(a.rgb.size());
  };
  RenderRequest r;
  r.view = view;
  // Shading the primary hits: HSSR's layers and Embree see the same surfaces.
  r.effect = "shade";
  const RgbImage shadeHssr = render(mirrors, r);
  r.tracer = "embree";
  const RgbImage shadeEmbree = render(mirrors, r);
  ASSERT_EQ(shadeHssr.rgb.size(), size_t(view.width * view.height * 3));
  double mean = 0.0;
  for (float v : shadeEmbree.rgb) mean += v / double(shadeEmbree.rgb.size());
  EXPECT_GT(mean, 0.02);  // lit
  EXPECT_LE(meanAbsDiff(shadeHssr, shadeEmbree), 1.0 / 255.0);
  // Reflections: HSSR misses what the layers do not hold, Embree does not.
  r.effect = "reflection";
  const RgbImage reflEmbree = render(mirrors, r);
  r.tracer = "hssr";
  const RgbImage reflHssr = render(mirrors, r);
  EXPECT_GT(meanAbsDiff(reflHssr, reflEmbree), 1.0 / 255.0);
}

/// Expects std::invalid_argument whose message names `what`.
template <class F>
void expectInvalid(const std::string& what, F&& f) {
  try {
    f();
    ADD_FAILURE() << "no exception for " << what;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  }
}

// Inputs are validated, and the exception names the argument.
TEST(Api, BadArgumentsAreNamed) {
  View v;
  v.width = 4, v.height = 2;
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> front(8, 2.0f), back(8, 2.5f);
  EXPECT_NO_THROW(ScreenLayers::fromLayers(v, 1, front, back));
  expectInvalid("front: 7 elements", [&] { ScreenLayers::fromLayers(v, 1, std::span(front).first(7), back); });
  expectInvalid("k 0", [&] { ScreenLayers::fromLayers(v, 0, front, back); });
  front[3] = nan;
  expectInvalid("front[3]", [&] { ScreenLayers::fromLayers(v, 1, front, back); });
  front[3] = 2.0f, back[5] = 1.0f;
  expectInvalid("back[5]", [&] { ScreenLayers::fromLayers(v, 1, front, back); });
  // Two layers: pixel 1's second layer in front of its first; pixel 2's second after an empty first.
  std::vector<float> f2(16, inf), b2(16, inf);
  f2[1] = 3.0f, b2[1] = 3.1f, f2[8 + 1] = 2.0f, b2[8 + 1] = 2.1f;
  expectInvalid("not sorted", [&] { ScreenLayers::fromLayers(v, 2, f2, b2); });
  f2[8 + 1] = inf, f2[8 + 2] = 2.0f, b2[8 + 2] = 2.1f;
  expectInvalid("follows an empty layer", [&] { ScreenLayers::fromLayers(v, 2, f2, b2); });
  View bad = v;
  bad.fovY = 180.0f;
  expectInvalid("view.fovY 180", [&] { ScreenLayers::fromDepthBuffer(bad, front); });
  bad = v, bad.far = bad.near;
  expectInvalid("view.far", [&] { ScreenLayers::fromDepthBuffer(bad, front); });
  expectInvalid("thicknessPx -1", [&] { ScreenLayers::fromDepthBuffer(v, front, {}, -1.0f); });
  std::vector<uint32_t> offsets{0, 1, 1, 1, 1, 1, 1, 0, 1};
  std::vector<float> depth{2.0f};
  expectInvalid("offsets[7]", [&] { ScreenLayers::fromFragments(v, offsets, depth); });
  const ScreenLayers layers = ScreenLayers::fromDepthBuffer(v, front);
  expectInvalid("not a screen tracer", [&] { ScreenTracer(layers, "embree"); });
  expectInvalid("countAt(4, 0)", [&] { (void)layers.countAt(4, 0); });
  const ScreenTracer tracer(layers);
  std::vector<Ray> rays(2);
  std::vector<TraceHit> hits(1);
  expectInvalid("hits: 1 elements for 2 rays", [&] { tracer.trace(rays, hits); });
  hits.resize(2);
  rays[1].dir = {0.0f, 0.0f, -2.0f};
  expectInvalid("rays[1]", [&] { tracer.trace(rays, hits); });
  const std::vector<glm::vec3> pos{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<glm::uvec3> tri{{0, 1, 3}};
  expectInvalid("triangles", [&] { TriangleScene(pos, tri); });
  const std::vector<glm::uvec3> ok{{0, 1, 2}};
  const std::vector<uint32_t> material{1};
  expectInvalid("materialOfTriangle[0] = 1", [&] { TriangleScene(pos, ok, material); });
  const TriangleScene scene(pos, ok);
  expectInvalid("not a geometric tracer", [&] { MeshTracer(scene, v, "hssr"); });
  RenderRequest r;
  r.view = v;
  r.tracer = "bvh";
  expectInvalid("tracer \"bvh\"", [&] { render(scene, r); });
  r.tracer = "hssr", r.effect = "glow";
  expectInvalid("glow", [&] { render(scene, r); });
}

// (a) One depth buffer: each surface is thicknessPx footprints thick; a ray along a pixel's view
// direction from in front of it hits it at its depth.
TEST(Api, DepthBufferOfAPlaneIsHitWhereItIs) {
  View v;
  v.width = 32, v.height = 24, v.fovY = 60.0f;
  std::vector<float> depth(size_t(v.width * v.height), 5.0f);
  depth[0] = std::numeric_limits<float>::infinity();
  const ScreenLayers layers = ScreenLayers::fromDepthBuffer(v, depth);
  EXPECT_EQ(layers.countAt(0, 0), 0);
  EXPECT_EQ(layers.countAt(5, 5), 1);
  const ScreenTracer tracer(layers);
  Ray r;
  r.dir = pixelDirection(v, 20.5f, 10.5f);
  r.startsOnSurface = false;
  TraceHit h;
  tracer.trace({&r, 1}, {&h, 1});
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(h.x, 20);
  EXPECT_EQ(h.y, 10);
  EXPECT_NEAR(-h.point.z, 5.0f, 0.05f);
}

// A scene file loads as the CLI loads it: its cameras, the CLI's default view with its clip
// planes, and a render of any effect with parameters and a preset that is the CLI's render.
TEST(Api, LoadedScenesRenderAsTheCli) {
  const TriangleScene scene = TriangleScene::load(test::sourceDir() + "/scenes/default.json");
  EXPECT_EQ(scene.cameraNames(), (std::vector<std::string>{"main", "low"}));
  const Frame f = buildFrame(test::defaultSceneOptions(96, 64));
  const View view = scene.view("", 96, 64);
  EXPECT_EQ(view.eye, f.camera.desc().eye);
  EXPECT_EQ(view.target, f.camera.desc().target);
  EXPECT_EQ(view.fovY, f.camera.desc().fovY);
  EXPECT_EQ(view.near, f.camera.near());
  EXPECT_EQ(view.far, f.camera.far());
  EXPECT_EQ(scene.triangleCount(), f.scene.triangleCount());
  for (const char* effect : {"ao", "reflection", "warp"}) {
    SCOPED_TRACE(effect);
    RenderRequest r;
    r.view = view;
    r.effect = effect;
    r.aoSamples = 2;
    r.params = TracerParams("paper").set("hssr-tau", "12");
    const glm::vec3 second = view.eye + glm::vec3(0.3f, 0.1f, 0.0f);
    if (std::string(effect) == "warp") r.warpEye = second;
    const RgbImage api = render(scene, r);
    RenderOptions o;
    o.run.frame = test::defaultSceneOptions(96, 64);
    o.tracer = "hssr";
    o.effect.effect = parseEffect(effect);
    o.effect.aoSamples = 2;
    o.effect.countRays = false;
    if (std::string(effect) == "warp") o.effect.warpEye = glm::dvec3(second);
    o.tracers = presetOptions("paper");
    o.tracers.preset = "paper";
    o.tracers.pyramid.tau = 12.0f;
    o.repeat = 1;
    o.run.quiet = true;
    const RenderOutput cli = renderFrame(o);
    ASSERT_EQ(api.rgb.size(), cli.result.image.data.size());
    size_t differ = 0;
    for (size_t i = 0; i < api.rgb.size(); ++i) differ += api.rgb[i] != cli.result.image.data[i];
    EXPECT_EQ(differ, 0u);
  }
  expectInvalid("camera \"nope\"", [&] { (void)scene.view("nope", 96, 64); });
  expectInvalid("missing.obj: file not found", [] { (void)TriangleScene::load("missing.obj"); });
}

// Parameters by name reach the tracers, with the CLI's checks and messages.
TEST(Api, TracerParametersByName) {
  for (const TracerParam& p : tracerParams()) EXPECT_EQ(TracerParams().get(p.flag + 2), paramValue(p, TracerOptions{})) << p.flag;
  EXPECT_NE(TracerParams("paper").get("hssr-levels"), TracerParams().get("hssr-levels"));  // the paper's level count
  EXPECT_EQ(TracerParams().set("hssr-tau", "25").get("hssr-tau"), "25");
  EXPECT_EQ(TracerParams::names().size(), tracerParams().size());
  expectInvalid("--hssr-tau many: not a number", [] { TracerParams().set("hssr-tau", "many"); });
  expectInvalid("parameter \"hssr-nope\": unknown", [] { TracerParams().set("hssr-nope", "1"); });
  expectInvalid("--preset fast: unknown (use tuned or paper)", [] { TracerParams p("fast"); });
  const Frame f = defaultFrame();
  const View view = viewOf(f.camera);
  const TriangleScene scene(f.scene.positions, f.scene.triangles);
  const ScreenLayers layers = captureLayers(scene, view, 4);
  const std::vector<Ray> rays = test::sampleRays(f, 4000, test::testSeed() + 71);
  std::vector<TraceHit> a(rays.size()), b(rays.size()), c(rays.size()), d(rays.size());
  ScreenTracer(layers, "hssr").trace(rays, a);
  ScreenTracer(layers, "hssr", TracerParams().set("hssr-levels", "1")).trace(rays, b);  // the exhaustive march
  ScreenTracer(layers, "ssr").trace(rays, c);
  ScreenTracer(layers, "ssr", TracerParams().set("ssr-stride", "8")).trace(rays, d);
  size_t hssrDiffer = 0, ssrDiffer = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    hssrDiffer += a[i].hit != b[i].hit || a[i].x != b[i].x || a[i].y != b[i].y || a[i].layer != b[i].layer;
    ssrDiffer += c[i].hit != d[i].hit || c[i].x != d[i].x || c[i].y != d[i].y;
  }
  EXPECT_EQ(hssrDiffer, 0u);
  EXPECT_GT(ssrDiffer, rays.size() / 100) << "a stride of 8 skips pixels";
}

}  // namespace
}  // namespace lt
