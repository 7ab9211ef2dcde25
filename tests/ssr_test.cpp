// Screen-space tracers on analytic scenes with known answers: a mirror floor in
// front of a wall, rays leaving the screen or passing behind the near plane, z-thickness,
// hidden surfaces, no false positives, and the share of hits the non-conservative DDA skips.
#include <cmath>
#include <cstdlib>
#include <random>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <tbb/global_control.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/scene/load.h"
#include "layertrace/hssr/hssr_tracer.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/ssr/ssr_tracer.h"
#include "test_util.h"

namespace lt {
namespace {

constexpr float kWallDistance = 10.0f;

using test::frameOf;

/// Floor y = -1 (material 0) and a 20 m wall z = -10 (material 1) seen from the origin, looking
/// down -z and tilted down by `tilt` (so that some reflections land above the screen).
Frame floorAndWall(int W, int H, int k = 4, float thickness = 0.1f, float tilt = 0.0f) {
  Scene s = makeQuad({-30, -1, -0.2f}, {0, 0, -kWallDistance + 0.2f}, {60, 0, 0});
  Scene wall = makeQuad({-30, -1, -kWallDistance}, {60, 0, 0}, {0, 20, 0});
  wall.materials[0].albedo = {0.8f, 0.1f, 0.1f};
  s.append(wall);
  s.finalize("floor-and-wall");
  CameraDesc cd = test::originCamera(60.0f, 0.05f, 100.0f);
  cd.target = {0.0f, -tilt, -1.0f};
  Frame f = frameOf(s, cd, W, H, k, thickness);
  f.lights.push_back({{0, 3, -5}, glm::vec3(10.0f)});
  return f;
}

Ray mirrorRayAt(const Frame& f, int x, int y) {
  const FragmentNode& fr = f.layers.pixel(x, y)[0];
  Ray r;
  r.origin = f.camera.rayThrough({x + 0.5f, y + 0.5f}) * fr.depth;
  const glm::vec3 v = glm::normalize(r.origin), n = decodeOctahedral(fr.normal);
  r.dir = glm::reflect(v, glm::dot(n, v) > 0.0f ? -n : n);
  r.maxDistance = 100.0f;
  return r;
}

struct Tracers {
  IntervalPyramid pyramid, one;
  std::unique_ptr<EmbreeScene> embree;
  std::vector<std::unique_ptr<Tracer>> all;
  explicit Tracers(const Frame& f) {
    pyramid = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{5, 25.0f});
    one = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{1, 25.0f});
    embree = std::make_unique<EmbreeScene>(f.scene);
    all.push_back(std::make_unique<SsrTracer>(f.camera, f.layers, SsrConfig{}));
    SsrConfig layered;
    layered.allLayers = true;
    all.push_back(std::make_unique<SsrTracer>(f.camera, f.layers, layered));
    all.push_back(std::make_unique<HssrTracer>(f.camera, f.layers, pyramid, HssrConfig{2, 5}));
    all.push_back(std::make_unique<HssrTracer>(f.camera, f.layers, one, HssrConfig{2, 1}));
    all.push_back(makeEmbreeTracer(f.scene, f.camera, *embree));
  }
};

TEST(ScreenTracers, MirrorFloorHitsTheAnalyticWallPixel) {
  const int W = 320, H = 180;
  const Frame f = floorAndWall(W, H, 4, 0.1f, 0.3f);
  const Tracers t(f);
  for (const auto& tracer : t.all) {
    int checkedHits = 0, checkedMisses = 0;
    for (int y = H / 2 + 2; y < H; y += 3)
      for (int x = 0; x < W; x += 3) {
        ASSERT_GT(f.layers.countAt(x, y), 0);
        if (std::abs(decodeOctahedral(f.layers.pixel(x, y)[0].normal).y) < 0.9f) continue;  // the wall, not the floor
        const Ray r = mirrorRayAt(f, x, y);
        // The reflected ray comes from the camera mirrored in the floor, (0, -2, 0) in world space.
        const glm::vec3 mirrored(0, -2, 0), p = f.camera.toWorld(r.origin);
        const glm::vec3 w = mirrored + (p - mirrored) * (-kWallDistance / p.z);
        const glm::vec3 wc = f.camera.toCamera(w);
        const glm::vec2 px = f.camera.project(wc);
        RayCounters c;
        const TraceHit h = tracer->trace(r, c);
        if (px.y > 1.0f && px.x > 1.0f && px.x < W - 1.0f) {
          ++checkedHits;
          ASSERT_TRUE(h.hit) << tracer->name() << " pixel " << x << "," << y << " expected " << px.x << "," << px.y;
          if (std::string(tracer->name()) == "embree") {
            ASSERT_NEAR(glm::length(h.point - wc), 0.0f, 1e-3f) << x << "," << y;
          } else {
            ASSERT_LE(std::abs(h.x - int(px.x)), 1) << tracer->name() << " from " << x << "," << y;
            ASSERT_LE(std::abs(h.y - int(px.y)), 1) << tracer->name() << " from " << x << "," << y;
          }
          EXPECT_NEAR(unpackAlbedo(h.albedoSpec).x, 0.8f, 0.01f);  // the wall's colour
          EXPECT_NEAR(f.camera.toWorld(h.point).z, -kWallDistance, 0.02f);
        } else if (px.y < -1.0f && std::string(tracer->name()) != "embree") {
          ++checkedMisses;  // the true hit is above the top of the screen: screen space cannot see it
          ASSERT_FALSE(h.hit) << tracer->name() << " pixel " << x << "," << y;
        }
      }
    EXPECT_GT(checkedHits, 500) << tracer->name();
    if (std::string(tracer->name()) != "embree") {
      EXPECT_GT(checkedMisses, 50) << tracer->name();
    }
  }
}

TEST(ScreenTracers, RaysTowardTheCameraPassBehindTheNearPlaneAndMiss) {
  const Frame f = floorAndWall(160, 90);
  const Tracers t(f);
  for (const auto& tracer : t.all)
    for (int x = 5; x < 160; x += 10) {
      Ray r;
      r.origin = f.camera.rayThrough({x + 0.5f, 10.5f}) * f.layers.pixel(x, 10)[0].depth;  // on the wall
      r.dir = glm::normalize(glm::vec3(0.05f, 0.02f, 1.0f));
      r.maxDistance = 100.0f;
      RayCounters c;
      EXPECT_FALSE(tracer->trace(r, c).hit) << tracer->name() << " x " << x;
    }
}

/// A thin occluder (z-thickness 0.1) at depth 5 in front of the wall, and rays from the floor
/// that cross its depth either inside its pixels (hit) or 0.5 behind it (miss).
TEST(ScreenTracers, ThicknessDecidesBetweenPassingBehindAndThrough) {
  Scene s = makeQuad({-30, -1, -0.2f}, {0, 0, -9.8f}, {60, 0, 0});
  Scene board = makeQuad({-1, -0.5f, -5.0f}, {2, 0, 0}, {0, 3, 0});  // faces the camera, depth 5
  board.materials[0].albedo = {0.1f, 0.1f, 0.9f};
  s.append(board);
  s.finalize("board");
  const Frame f = frameOf(s, test::originCamera(60.0f, 0.05f, 100.0f), 200, 120, 4);
  const Tracers t(f);
  const glm::vec3 start(0.0f, -1.0f, -2.0f);  // on the floor, in front of the board
  for (const auto& tracer : t.all) {
    if (std::string(tracer->name()) == "embree") continue;  // geometry has no thickness
    // Through: aim at the board's centre (depth 5 reached inside its pixels).
    Ray through{start, glm::normalize(glm::vec3(0.0f, 1.0f, -5.0f) - start), 100.0f};
    RayCounters c;
    const TraceHit h = tracer->trace(through, c);
    ASSERT_TRUE(h.hit) << tracer->name();
    EXPECT_NEAR(-h.point.z, 5.0f, 0.05f);
    // Behind: a ray that is beyond depth 5.5 whenever it is over the board's pixels. It rises
    // from the floor far behind the board: it passes the board's screen region at depths 6–9.
    Ray behind{glm::vec3(0.0f, -1.0f, -6.0f), glm::normalize(glm::vec3(0.2f, 1.0f, -0.4f)), 3.0f};
    EXPECT_FALSE(tracer->trace(behind, c).hit) << tracer->name();
  }
}

/// A surface hidden behind the front layer: only multi-layer tracers can find it.
TEST(ScreenTracers, LayersFindSurfacesHiddenBehindTheFrontLayer) {
  Scene s = makeQuad({-30, -1, -0.2f}, {0, 0, -19.8f}, {60, 0, 0});
  Scene front = makeQuad({-3, -1, -4.0f}, {6, 0, 0}, {0, 6, 0});   // occluder at depth 4
  Scene hidden = makeQuad({-2, -1, -8.0f}, {4, 0, 0}, {0, 4, 0});  // fully behind it at depth 8
  hidden.materials[0].albedo = {0.9f, 0.9f, 0.1f};
  s.append(front);
  s.append(hidden);
  s.finalize("hidden");
  const Frame f = frameOf(s, test::originCamera(60.0f, 0.05f, 100.0f), 200, 120, 4);
  const Tracers t(f);
  // From the floor between occluder and hidden quad (behind the occluder's depth), straight
  // at the hidden quad: every pixel it crosses shows the occluder in front.
  const glm::vec3 start(0.5f, -1.0f, -6.0f);
  const Ray r{start, glm::normalize(glm::vec3(0.0f, 1.0f, -8.0f) - start), 100.0f};
  for (const auto& tracer : t.all) {
    RayCounters c;
    const TraceHit h = tracer->trace(r, c);
    if (std::string(tracer->name()) == "ssr") {
      EXPECT_FALSE(h.hit && std::abs(-h.point.z - 8.0f) < 0.1f) << "the front layer cannot hold the hidden quad";
    } else {
      ASSERT_TRUE(h.hit) << tracer->name();
      EXPECT_NEAR(-h.point.z, 8.0f, 0.05f) << tracer->name();
      EXPECT_NEAR(unpackAlbedo(h.albedoSpec).z, 0.1f, 0.02f) << tracer->name();
    }
  }
}

std::vector<Ray> randomRays(const Frame& f, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> px(0, f.camera.width() - 1), py(0, f.camera.height() - 1);
  std::normal_distribution<float> g;
  std::vector<Ray> rays;
  while (rays.size() < n) {
    const int x = px(rng), y = py(rng);
    if (!f.layers.countAt(x, y)) continue;
    Ray r = mirrorRayAt(f, x, y);
    if (rays.size() % 2) r.dir = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
    r.maxDistance = f.scene.bounds().diagonal();
    rays.push_back(r);
  }
  return rays;
}

/// `n` rays, or a quarter of them in sanitized builds (they look for memory and thread errors, and
/// these single-threaded loops took a minute each under ThreadSanitizer).
size_t sanitizedRays(size_t n) { return std::getenv("LAYERTRACE_SANITIZED") ? n / 4 : n; }

/// Every hit ssr-layers reports is a real overlap: the ray's depth over the part of its 2D line
/// within one step of the hit pixel (half a stride plus half a pixel: a step's depth range spans
/// a stride along the major axis) overlaps the hit fragment's interval.
TEST(ScreenTracers, SsrLayersReportsNoFalsePositives) {
  LT_SKIP_SINGLE_THREADED_UNDER_TSAN();
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 320, o.height = 180;
  const Frame f = buildFrame(o);
  const uint64_t seed = test::testSeed();
  for (float stride : {1.0f, 3.0f}) {
    SsrConfig sc;
    sc.allLayers = true;
    sc.stride = stride;
    const SsrTracer ssr(f.camera, f.layers, sc);
    int hits = 0;
    for (const Ray& r : randomRays(f, sanitizedRays(20000), seed)) {
      RayCounters c;
      const TraceHit h = ssr.trace(r, c);
      if (!h.hit) continue;
      ++hits;
      const ScreenSegment seg = makeScreenSegment(f.camera, r);
      const glm::vec2 d = seg.p1 - seg.p0;
      // Parameter range of the line inside the hit pixel grown by half a pixel.
      float lo = 0.0f, hi = 1.0f;
      for (int a = 0; a < 2; ++a) {
        const float grow = 0.5f * stride + 0.5f;
        const float bmin = float(a ? h.y : h.x) - grow, bmax = float(a ? h.y : h.x) + 1.0f + grow;
        if (d[a] == 0.0f) continue;
        const float t0 = (bmin - seg.p0[a]) / d[a], t1 = (bmax - seg.p0[a]) / d[a];
        lo = std::max(lo, std::min(t0, t1)), hi = std::min(hi, std::max(t0, t1));
      }
      ASSERT_LE(lo, hi + 1e-6f) << "hit pixel not on the ray's line, seed " << seed;
      const float za = seg.depthAt(lo), zb = seg.depthAt(std::max(lo, hi));
      const FragmentNode& fr = f.layers.pixel(h.x, h.y)[h.layer];
      ASSERT_LE(fr.depth, std::max(za, zb) * (1 + 1e-5f)) << "stride " << stride << " seed " << seed;
      ASSERT_GE(fr.back(), std::min(za, zb) * (1 - 1e-5f)) << "stride " << stride << " seed " << seed;
    }
    EXPECT_GT(hits, int(sanitizedRays(20000) / 10));
  }
}

/// Hofmann et al. 2017, Figure 10: the non-conservative DDA of SSR skips hits the conservative one
/// finds. Measured and reported here (not hidden); bounded so a broken SSR would fail.
TEST(ScreenTracers, SsrSkipRateAgainstTheExhaustiveOracleIsMeasured) {
  LT_SKIP_SINGLE_THREADED_UNDER_TSAN();
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 320, o.height = 180;
  const Frame f = buildFrame(o);
  const IntervalPyramid one = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{1, 25.0f});
  const HssrTracer oracle(f.camera, f.layers, one, HssrConfig{1, 1});
  for (float stride : {1.0f, 4.0f}) {
    SsrConfig sc;
    sc.allLayers = true;
    sc.stride = stride;
    const SsrTracer ssr(f.camera, f.layers, sc);
    size_t oracleHits = 0, skipped = 0, differ = 0;
    for (const Ray& r : randomRays(f, sanitizedRays(20000), test::testSeed())) {
      RayCounters c;
      const TraceHit a = oracle.trace(r, c), b = ssr.trace(r, c);
      oracleHits += a.hit;
      skipped += a.hit && !b.hit;
      differ += a.hit && b.hit && (a.x != b.x || a.y != b.y || a.layer != b.layer);
    }
    const double skipRate = double(skipped) / double(oracleHits);
    std::printf("ssr-layers stride %g: %zu oracle hits, %.3f %% missed, %.3f %% another fragment\n", stride, oracleHits,
                100.0 * skipRate, 100.0 * double(differ) / double(oracleHits));
    RecordProperty(stride == 1.0f ? "skip_rate_stride1" : "skip_rate_stride4", std::to_string(skipRate));
    EXPECT_LT(skipRate, stride == 1.0f ? 0.05 : 0.25);
  }
}

}  // namespace
}  // namespace lt

#include "layertrace/eval/classify.h"

namespace lt {
namespace {

RayClass classifyWith(const Tracer& tracer, const Tracer& reference, const Frame& f, const Ray& r) {
  RayCounters c;
  return classifyRay(r, tracer.trace(r, c), reference.trace(r, c), Query::Closest, f.camera, f.layers);
}

// Each class constructed on purpose.
TEST(Classify, ReflectionOfSomethingOffScreenIsAnInformationMiss) {
  const Frame f = floorAndWall(320, 180, 4, 0.1f, 0.3f);
  const Tracers t(f);
  const Tracer& hssr = *t.all[2];
  const Tracer& embree = *t.all[4];
  int info = 0, correct = 0;
  for (int y = 100; y < 180; y += 4)
    for (int x = 20; x < 300; x += 20) {
      if (std::abs(decodeOctahedral(f.layers.pixel(x, y)[0].normal).y) < 0.9f) continue;
      const Ray r = mirrorRayAt(f, x, y);
      const RayClass c = classifyWith(hssr, embree, f, r);
      RayCounters rc;
      const TraceHit truth = embree.trace(r, rc);
      const glm::vec2 p = f.camera.project(truth.point);
      const bool outside = p.y < -2.0f || p.x < -2.0f || p.x > 322.0f;
      const bool inside = p.y > 2.0f && p.x > 2.0f && p.x < 318.0f;
      if (outside) {
        EXPECT_EQ(c, RayClass::InfoMiss) << x << "," << y;
        ++info;
      } else if (inside) {
        EXPECT_EQ(c, RayClass::CorrectHit) << x << "," << y << " truth at " << p.x << "," << p.y << " depth " << -truth.point.z;
        ++correct;
      }
    }
  EXPECT_GT(info, 20);
  EXPECT_GT(correct, 20);
}

Frame hiddenQuadFrame(int k) {
  Scene s = makeQuad({-30, -1, -0.2f}, {0, 0, -19.8f}, {60, 0, 0});
  s.append(makeQuad({-3, -1, -4.0f}, {6, 0, 0}, {0, 6, 0}));
  s.append(makeQuad({-2, -1, -8.0f}, {4, 0, 0}, {0, 4, 0}));
  s.finalize("hidden");
  const Frame f = frameOf(s, test::originCamera(60.0f, 0.05f, 100.0f), 200, 120, k);
  return f;
}

TEST(Classify, SurfaceBehindTheFrontLayerIsInformationMissWithOneLayerCorrectHitWithFour) {
  const glm::vec3 start(0.5f, -1.0f, -6.0f);
  const Ray r{start, glm::normalize(glm::vec3(0.0f, 1.0f, -8.0f) - start), 100.0f};
  for (int k : {1, 4}) {
    const Frame f = hiddenQuadFrame(k);
    const Tracers t(f);
    const RayClass c = classifyWith(*t.all[2], *t.all[4], f, r);
    EXPECT_EQ(c, k == 1 ? RayClass::InfoMiss : RayClass::CorrectHit) << "k " << k << ": " << rayClassName(c);
  }
}

TEST(Classify, LargeStrideSkippingAThinPoleIsAFalseMiss) {
  // A pole 0.05 wide (1.6 pixels: it covers two pixel centres) at depth 5; rays cross it.
  Scene s = makeQuad({-30, -1, -0.2f}, {0, 0, -19.8f}, {60, 0, 0});
  s.append(makeBox({-0.025f, -1.0f, -5.025f}, {0.025f, 3.0f, -4.975f}));
  s.finalize("pole");
  const Frame f = frameOf(s, test::originCamera(60.0f, 0.05f, 100.0f), 320, 180, 4);
  const Tracers t(f);
  SsrConfig wide;
  wide.allLayers = true;
  wide.stride = 8.0f;
  wide.refine = false;
  const SsrTracer ssr8(f.camera, f.layers, wide);
  int falseMisses = 0, hssrCorrect = 0, rays = 0;
  for (int i = 0; i < 16; ++i) {
    // Horizontal rays at the pole's depth, starting left of it at varying offsets.
    const glm::vec3 start(-1.5f - 0.013f * float(i), 0.5f, -5.0f);
    const Ray r{start, glm::vec3(1.0f, 0.0f, 0.0f), 10.0f};
    ++rays;
    hssrCorrect += classifyWith(*t.all[2], *t.all[4], f, r) == RayClass::CorrectHit;
    const RayClass c = classifyWith(ssr8, *t.all[4], f, r);
    EXPECT_TRUE(c == RayClass::FalseMiss || c == RayClass::CorrectHit) << rayClassName(c);
    falseMisses += c == RayClass::FalseMiss;
  }
  EXPECT_EQ(hssrCorrect, rays);  // the conservative DDA never skips the pole
  EXPECT_GT(falseMisses, rays / 2) << "stride 8 should step over a one-pixel pole most of the time";
}

}  // namespace
}  // namespace lt
