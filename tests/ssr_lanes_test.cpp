// The SSR march of McGuire and Mara 2014 in vector lanes, on every vector target this CPU runs
// (ssr/ssr_march_lanes.h), against the
// one-ray march it must equal bit for bit: the same pixel, interval and sample parameter for every
// ray, over the front layer (ssr) and all k ≤ 4 layers (ssr-layers), strides 1 and 3, with jitter,
// with a step cap that ends marches early, in batches shorter than the lanes, of the renderer's
// 256, and all at once; and the tracers' uncounted batches against their one-ray answers.
#include <bit>
#include <cstdio>

#include <gtest/gtest.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/ssr/ssr_march_lanes.h"
#include "layertrace/ssr/ssr_tracer.h"
#include "test_util.h"

namespace lt {
namespace {

void expectLanesEqualMarch(const Frame& f, const std::vector<Ray>& rays) {
  const int W = f.camera.width(), H = f.camera.height();
  struct Case {
    int k;
    float stride, jitter;
    int maxSteps;
  };
  for (const Case& c : {Case{1, 1.0f, 0.0f, 10000}, Case{f.layers.k, 1.0f, 0.0f, 10000}, Case{2, 3.0f, 0.37f, 10000},
                        Case{3, 1.0f, 0.0f, 7}, Case{f.layers.k, 2.5f, 0.9f, 40}}) {
    const IntervalLayers depth = makeIntervalLayers(f.layers, c.k);
    EXPECT_TRUE(ssrLanesAvailable(depth)) << "k " << c.k;
    std::vector<SsrStart> starts(rays.size());
    for (size_t i = 0; i < rays.size(); ++i) starts[i] = SsrStart(makeScreenSegment(f.camera, rays[i]), c.stride, c.jitter);
    std::vector<SsrSample> one(rays.size());
    size_t hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      NoCounters none;
      one[i] = ssrMarch(depth, starts[i], c.maxSteps, W, H, none);
      hits += one[i].hit();
    }
    EXPECT_GT(hits, rays.size() / 20) << "too few hits to mean anything (k " << c.k << " stride " << c.stride << ")";
    test::forEachSimdTarget([&](const SimdTarget&) {
    for (size_t batch : {size_t(5), size_t(256), rays.size()}) {
      std::vector<SsrSample> lanes(rays.size());
      for (size_t b = 0; b < rays.size(); b += batch) {
        const size_t n = std::min(batch, rays.size() - b);
        ssrMarchBatch(depth, std::span(starts).subspan(b, n), c.maxSteps, W, H, std::span(lanes).subspan(b, n));
      }
      size_t differ = 0, first = rays.size();
      for (size_t i = 0; i < rays.size(); ++i) {
        const SsrSample &a = one[i], &l = lanes[i];
        if (a.x != l.x || a.y != l.y || a.layer != l.layer || std::bit_cast<uint32_t>(a.s) != std::bit_cast<uint32_t>(l.s)) {
          ++differ;
          first = std::min(first, i);
        }
      }
      EXPECT_EQ(differ, 0u) << "k " << c.k << " stride " << c.stride << " max steps " << c.maxSteps << " batch " << batch
                            << " first ray " << first;
    }
    });
  }
  // The tracers: uncounted batches (the lanes, then refinement and the fragment) against one
  // ray at a time with counters (ssrMarch itself).
  for (bool allLayers : {false, true})
    for (float stride : {1.0f, 4.0f}) {
      SsrConfig sc;
      sc.allLayers = allLayers;
      sc.stride = stride;
      const SsrTracer t(f.camera, f.layers, sc);
      std::vector<TraceHit> batch(rays.size());
      for (size_t b = 0; b < rays.size(); b += 256) {
        const size_t n = std::min<size_t>(256, rays.size() - b);
        t.traceBatch(std::span(rays).subspan(b, n), std::span(batch).subspan(b, n), {});
      }
      size_t differ = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        RayCounters rc;
        const TraceHit h = t.trace(rays[i], rc);
        differ += h.hit != batch[i].hit || h.x != batch[i].x || h.y != batch[i].y || h.layer != batch[i].layer ||
                  std::bit_cast<uint32_t>(h.point.z) != std::bit_cast<uint32_t>(batch[i].point.z);
      }
      EXPECT_EQ(differ, 0u) << t.name() << " stride " << stride;
    }
}

TEST(SsrLanes, EqualTheOneRayMarch) {
  LT_SKIP_SINGLE_THREADED_UNDER_TSAN();
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 317, o.height = 179;
  const Frame f = buildFrame(o);
  expectLanesEqualMarch(f, test::sampleRays(f, test::sanitizedCount(20000), test::testSeed() + 23));
}

class RealSceneSsrLanes : public ::testing::TestWithParam<std::pair<const char*, const char*>> {};

TEST_P(RealSceneSsrLanes, EqualTheOneRayMarch) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  const Frame f = buildFrame(test::realSceneOptions(GetParam().first, GetParam().second));
  expectLanesEqualMarch(f, test::sampleRays(f, 30000, test::testSeed() + 29));
}

INSTANTIATE_TEST_SUITE_P(Scenes, RealSceneSsrLanes,
                         ::testing::Values(std::make_pair("fzk-haus.json", "interior"), std::make_pair("am-thornish.json", "hall"),
                                           std::make_pair("engine.json", "interior")),
                         [](const auto& p) { return test::sceneCaseName(p.param.first); });

}  // namespace
}  // namespace lt
