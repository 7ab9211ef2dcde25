// HSSR exactness (seed 000 §4.3: τ affects speed, not results): for every ray, hssr returns the
// same hit as the exhaustive oracle (the same traversal with one level), for any τ, level count
// and n_up. Rays: mirror reflections from random covered pixels, and random directions.
#include <random>

#include <glm/geometric.hpp>

#include "layertrace/app/frame.h"
#include "layertrace/screen/hssr_tracer.h"
#include "layertrace/screen/interval_pyramid.h"
#include "test_util.h"

namespace lt {
namespace {

std::vector<ScreenRay> sampleRays(const Frame& f, size_t count, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> px(0, f.camera.width() - 1), py(0, f.camera.height() - 1);
  std::normal_distribution<float> g;
  std::vector<ScreenRay> rays;
  const float maxDist = f.scene.bounds().diagonal();
  while (rays.size() < count) {
    const int x = px(rng), y = py(rng);
    if (f.layers.countAt(x, y) == 0) continue;
    const FragmentNode& frag = f.layers.pixel(x, y)[0];
    ScreenRay r;
    r.origin = f.camera.rayThrough({x + 0.5f, y + 0.5f}) * frag.depth;
    const glm::vec3 n = decodeOctahedral(frag.normal);
    const glm::vec3 v = glm::normalize(r.origin);
    if (rays.size() % 2 == 0) {
      r.dir = glm::reflect(v, glm::dot(n, v) > 0.0f ? -n : n);
    } else {
      r.dir = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
    }
    r.maxDistance = maxDist;
    rays.push_back(r);
  }
  return rays;
}

void expectExact(const Frame& f, size_t count) {
  const uint64_t seed = test::testSeed();
  const std::vector<ScreenRay> rays = sampleRays(f, count, seed);
  const IntervalPyramid one = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{1, 25.0f});
  const HssrTracer oracle(f.camera, f.layers, one, HssrConfig{1, 1});
  std::vector<TraceHit> truth(rays.size());
  size_t hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    RayCounters c;
    truth[i] = oracle.trace(rays[i], c);
    hits += truth[i].hit;
  }
  EXPECT_GT(hits, rays.size() / 10) << "too few hits to mean anything";
  for (float tau : {1.0f, 5.0f, 25.0f, 128.0f})
    for (int levels : {3, 5, 8}) {
      const IntervalPyramid p = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{levels, tau});
      for (int nUp : {1, 2, 4}) {
        const HssrTracer hssr(f.camera, f.layers, p, HssrConfig{nUp, levels});
        size_t mismatches = 0, firstBad = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
          RayCounters c;
          const TraceHit h = hssr.trace(rays[i], c);
          const bool same = h.hit == truth[i].hit && (!h.hit || (h.x == truth[i].x && h.y == truth[i].y && h.layer == truth[i].layer));
          if (!same && mismatches++ == 0) firstBad = i;
        }
        EXPECT_EQ(mismatches, 0u) << "tau " << tau << " levels " << levels << " n_up " << nUp << " first ray " << firstBad
                                  << " seed " << seed;
      }
    }
}

TEST(Hssr, MatchesExhaustiveOracleOnDefaultScene) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 320, o.height = 180;
  expectExact(buildFrame(o), 20000);
}

TEST(Hssr, PyramidCoversEveryChildInterval) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 200, o.height = 120;
  const Frame f = buildFrame(o);
  for (float tau : {1.0f, 25.0f, 128.0f}) {
    const IntervalPyramid p = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{6, tau});
    for (int L = 1; L < 6; ++L) {
      const PyramidLevel& lvl = p.levels[size_t(L)];
      for (int y = 0; y < f.layers.height; ++y)
        for (int x = 0; x < f.layers.width; ++x) {
          const size_t cell = lvl.cellIndex(x >> L, y >> L);
          for (int i = 0; i < f.layers.countAt(x, y); ++i) {
            const FragmentNode& fr = f.layers.pixel(x, y)[i];
            bool covered = false;
            for (uint32_t j = lvl.offset[cell]; j < lvl.offset[cell + 1] && !covered; ++j)
              covered = lvl.intervals[j].front <= fr.depth && lvl.intervals[j].back >= fr.back();
            ASSERT_TRUE(covered) << "level " << L << " pixel " << x << "," << y << " layer " << i << " tau " << tau;
          }
        }
    }
  }
}

}  // namespace
}  // namespace lt
