// HSSR exactness (Hofmann et al. 2017, §4.3: τ affects speed, not results): for every ray, hssr
// returns the same hit as the exhaustive oracle (the same traversal with one level), for any τ,
// level count and n_up. Rays: mirror reflections from random covered pixels, and random directions.
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <random>
#include <set>

#include <tbb/parallel_for.h>

#include <glm/geometric.hpp>

#include "layertrace/pipeline/frame.h"
#include "layertrace/hssr/hssr_march.h"
#include "layertrace/hssr/hssr_march_lanes.h"
#include "layertrace/hssr/hssr_march_reference.h"
#include "layertrace/hssr/hssr_tracer.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/util/parallel.h"
#include "test_util.h"

namespace lt {
namespace {

void expectExact(const Frame& f, size_t count) {
  const uint64_t seed = test::testSeed();
  std::vector<Ray> rays = test::sampleRays(f, count, seed);
  const IntervalPyramid one = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{1, 25.0f});
  const HssrTracer oracle(f.camera, f.layers, one, HssrConfig{1, 1});
  auto traceAll = [&](const std::vector<Ray>& rs) {
    std::vector<TraceHit> out(rs.size());
    parallelFor(size_t(0), rs.size(), [&](size_t i) {
      RayCounters c;
      out[i] = oracle.trace(rs[i], c);
    });
    return out;
  };
  std::vector<TraceHit> truth = traceAll(rays);
  // Second bounces: mirror rays from the oracle's hits (origins on deeper layers, arbitrary
  // screen positions — what multi-bounce effects trace).
  std::vector<Ray> second;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (!truth[i].hit) continue;
    const glm::vec3 n = glm::dot(truth[i].normal, rays[i].dir) > 0.0f ? -truth[i].normal : truth[i].normal;
    second.push_back({truth[i].point, glm::normalize(glm::reflect(rays[i].dir, n)), rays[i].maxDistance});
  }
  const std::vector<TraceHit> secondTruth = traceAll(second);
  rays.insert(rays.end(), second.begin(), second.end());
  truth.insert(truth.end(), secondTruth.begin(), secondTruth.end());
  const size_t hits = size_t(std::count_if(truth.begin(), truth.end(), [](const TraceHit& h) { return h.hit; }));
  EXPECT_GT(hits, rays.size() / 10) << "too few hits to mean anything";
  for (float tau : {1.0f, 5.0f, 25.0f, 128.0f})
    for (int levels : {3, 5, 8}) {
      const IntervalPyramid p = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{levels, tau});
      for (int nUp : {1, 2, 4}) {
        const HssrTracer hssr(f.camera, f.layers, p, HssrConfig{nUp, levels});
        std::atomic<size_t> mismatches{0}, firstBad{rays.size()};
        parallelFor(size_t(0), rays.size(), [&](size_t i) {
          RayCounters c;
          const TraceHit h = hssr.trace(rays[i], c);
          const bool same = h.hit == truth[i].hit && (!h.hit || (h.x == truth[i].x && h.y == truth[i].y && h.layer == truth[i].layer));
          if (!same) {
            ++mismatches;
            size_t cur = firstBad.load();
            while (i < cur && !firstBad.compare_exchange_weak(cur, i)) {}
          }
        });
        EXPECT_EQ(mismatches.load(), 0u) << "tau " << tau << " levels " << levels << " n_up " << nUp << " first ray " << firstBad.load()
                                  << " seed " << seed;
      }
    }
}

/// The lane march (hssr_march_lanes.h: a ray per vector lane with lane refill), on every vector
/// target this CPU runs, against hssrMarch one ray at a time: the same pixel, interval and entry parameter bit for
/// bit, in batches of several sizes (a batch shorter than the lanes, the renderer's 256, all) —
/// and the same traversal: as many cells tested per ray (hits do not depend on the ascent and
/// descent rules, so a lane step that dropped one would pass the hit comparison).
void expectLanesEqualMarch(const Frame& f, const IntervalPyramid& p, int levels, AscentRule nUp, const std::vector<Ray>& rays,
                           bool allTargets = true) {
  const int W = f.camera.width(), H = f.camera.height();
  std::vector<ScreenSegment> segs(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) segs[i] = makeScreenSegment(f.camera, rays[i]);
  EXPECT_TRUE(hssrLanesAvailable(p, levels)) << "levels " << levels;
  // The one-ray march's answers and cells, once: the lanes of every target and batch size are
  // held to them.
  std::vector<MarchHit> one(segs.size());
  std::vector<uint32_t> oneCells(segs.size());
  size_t hits = 0;
  uint64_t cells = 0;
  for (size_t i = 0; i < segs.size(); ++i) {
    MarchCellCount c;
    one[i] = segs[i].valid ? hssrMarch(p, levels, nUp, segs[i], W, H, c) : MarchHit{};
    oneCells[i] = c.cells;
    hits += one[i].hit();
    cells += c.cells;
  }
  EXPECT_GT(hits, segs.size() / 10) << "too few hits to mean anything";
  EXPECT_GT(cells, 2 * segs.size()) << "too few cells per ray to mean anything";
  // (sanitized builds: the renderer's batch size only, a third of the time; the Release run
  // covers the short and the whole batch)
  std::vector<size_t> batches{size_t(5), size_t(256), segs.size()};
  if (std::getenv("LAYERTRACE_SANITIZED")) batches = {size_t(256)};
  test::forEachSimdTarget(
      [&](const SimdTarget&) {
        for (size_t batch : batches) {
          std::vector<MarchHit> lanes(segs.size());
          std::vector<uint32_t> laneCells(segs.size());
          for (size_t b = 0; b < segs.size(); b += batch) {
            const size_t n = std::min(batch, segs.size() - b);
            hssrMarchBatch(p, levels, nUp, std::span(segs).subspan(b, n), W, H, std::span(lanes).subspan(b, n),
                           std::span(laneCells).subspan(b, n));
          }
          size_t differ = 0, first = segs.size(), cellsDiffer = 0, firstCells = segs.size();
          for (size_t i = 0; i < segs.size(); ++i) {
            const MarchHit &a = one[i], &b = lanes[i];
            if (a.x != b.x || a.y != b.y || a.interval != b.interval || std::bit_cast<uint32_t>(a.s) != std::bit_cast<uint32_t>(b.s)) {
              ++differ;
              first = std::min(first, i);
            }
            if (oneCells[i] != laneCells[i]) ++cellsDiffer, firstCells = std::min(firstCells, i);
          }
          EXPECT_EQ(differ, 0u) << "levels " << levels << " n_up " << nUp.nUp << " parent ascent " << nUp.newParent << " batch "
                                << batch << " first ray " << first;
          EXPECT_EQ(cellsDiffer, 0u) << "cells tested: levels " << levels << " n_up " << nUp.nUp << " parent ascent "
                                     << nUp.newParent << " batch " << batch << " first ray " << firstCells;
        }
      },
      allTargets);
}

/// The fast march (incremental spans, κ-domain fixed-slot coarse cells, sentinels) against the
/// reference march it replaced: the same level-0 pixel, interval and entry parameter, bit for
/// bit, for the oracle (1 level) and the hierarchical march, on `rays` and their mirror bounces;
/// the paper's 6 levels (0–5), the default (PyramidConfig, 7) and the lanes' most (8); the paper's τ
/// (25) and the default (4).
void expectSameAsReference(const Frame& f, size_t count) {
  const uint64_t seed = test::testSeed() + 7;
  std::vector<Ray> rays = test::sampleRays(f, count, seed);
  const int W = f.camera.width(), H = f.camera.height();
  std::vector<std::pair<float, int>> configs;  // (τ, levels)
  for (float tau : std::set<float>{25.0f, PyramidConfig{}.tau})
    for (int levels : std::set<int>{1, 3, 6, PyramidConfig{}.levels, 8}) configs.emplace_back(tau, levels);
  for (const auto& [tau, levels] : configs) {
    const IntervalPyramid p = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{levels, tau});
    // Does any coarse cell hold more intervals than its fixed slots (merged there, CoarseCell)?
    bool slotsMerged = false;
    for (int L = 1; L < p.levelCount(); ++L)
      for (size_t i = 0; i + 1 < p.levels[size_t(L)].offset.size(); ++i)
        slotsMerged = slotsMerged || p.levels[size_t(L)].offset[i + 1] - p.levels[size_t(L)].offset[i] > uint32_t(CoarseCell::kSlots);
    // (the paper's pure n_up rule with the paper's τ; on the real scenes, whose rays are many,
    // with the paper's 6 levels only)
    std::vector<AscentRule> rules{AscentRule(1), AscentRule(2)};
    if (tau == 25.0f && (count <= 40000 || levels == 6)) rules.emplace_back(2, false);
    for (AscentRule rule : rules) {
      std::atomic<size_t> mismatches{0}, firstBad{rays.size()}, hits{0}, cellsDiffer{0};
      parallelFor(size_t(0), rays.size(), [&](size_t i) {
        const ScreenSegment seg = makeScreenSegment(f.camera, rays[i]);
        if (!seg.valid) return;
        MarchCellCount c, cr;
        const MarchHit a = hssrMarch(p, levels, rule, seg, W, H, c), b = hssrMarchReference(p, levels, rule.nUp, seg, W, H, cr);
        hits += a.hit();
        cellsDiffer += c.cells != cr.cells;
        if (a.x != b.x || a.y != b.y || a.interval != b.interval || std::bit_cast<uint32_t>(a.s) != std::bit_cast<uint32_t>(b.s)) {
          ++mismatches;
          size_t cur = firstBad.load();
          while (i < cur && !firstBad.compare_exchange_weak(cur, i)) {}
        }
      });
      EXPECT_GT(hits.load(), rays.size() / 10) << "too few hits to mean anything";
      EXPECT_EQ(mismatches.load(), 0u) << "tau " << tau << " levels " << levels << " n_up " << rule.nUp << " parent ascent "
                                       << rule.newParent << " first ray " << firstBad.load() << " seed " << seed;
      // The paper's pure n_up rule is the reference march's traversal: the same cells, but for
      // a coarse overlap test on the border — the fast march tests in inverse depth, the
      // reference in depth, and the two round apart (3 of 40,000 rays at τ = 25, 5 levels) — and
      // for coarse cells whose intervals were merged into their fixed slots (a coarse test can
      // then overlap where the CSR list's gap would not, and the march descends once more).
      if (!rule.newParent && levels > 1) {
        EXPECT_LE(cellsDiffer.load(), rays.size() / (slotsMerged ? 200 : 2000)) << "tau " << tau << " levels " << levels;
      }
      if (rule.newParent && rule.nUp > 1 && levels > 2) {
        EXPECT_GT(cellsDiffer.load(), 0u) << "the new-parent ascent changed no traversal";
      }
      // (the real scenes' many rays: every vector target at the default τ and levels, the best
      // and the scalar one elsewhere; the default scene: every target everywhere)
      expectLanesEqualMarch(f, p, levels, rule, rays, count <= 40000 || (tau == PyramidConfig{}.tau && levels == PyramidConfig{}.levels));
    }
    // The uncounted batch runs the lanes on this CPU's best vector target: the same hits as the
    // one-ray path.
    const HssrTracer t(f.camera, f.layers, p, HssrConfig{2, levels});
    std::vector<TraceHit> batch(rays.size());
    t.traceBatch(rays, batch, {});
    size_t differ = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      RayCounters c;
      const TraceHit one = t.trace(rays[i], c);
      differ += one.hit != batch[i].hit || one.x != batch[i].x || one.y != batch[i].y || one.layer != batch[i].layer;
    }
    EXPECT_EQ(differ, 0u) << "tau " << tau << " levels " << levels;
  }
}

TEST(Hssr, FastMarchEqualsReferenceMarch) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 317, o.height = 179;  // partial cells on every pyramid level
  // (sanitized builds look for memory and thread errors, not rare rays: a quarter of them)
  expectSameAsReference(buildFrame(o), std::getenv("LAYERTRACE_SANITIZED") ? 10000 : 40000);
}

/// The lanes over pyramids of fewer layers (k = 1 is the hybrid's known-space pyramid: one
/// [u, ∞) interval per pixel), where a pixel's record is shorter than a coarse cell's.
TEST(Hssr, LanesEqualMarchForFewerLayers) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 317, o.height = 179;
  const Frame f = buildFrame(o);
  const std::vector<Ray> rays = test::sampleRays(f, test::sanitizedCount(20000), test::testSeed() + 11);
  for (int k : {1, 2, 3})
    for (int levels : {1, 5}) {
      const IntervalPyramid p = buildIntervalPyramid(makeIntervalLayers(f.layers, k), f.camera, PyramidConfig{levels, 25.0f});
      ASSERT_EQ(p.base->k, k);
      expectLanesEqualMarch(f, p, levels, 2, rays);
    }
}

/// Axis-parallel segments (rows and columns: a level camera's reflections off walls parallel
/// to its axis and off a level floor — 6 % of am_thornish's reflection rays) through the lanes,
/// which substitute p0 and invD on the flat axis instead of special-casing it: bit for bit
/// hssrMarch, with p0 on pixel centres, on integer boundaries (where a careless substitution
/// would form 0 · ∞) and anywhere between, from surfaces and from outside, both directions, and
/// rows/columns near the view's borders and on every pyramid level's partial cells.
TEST(Hssr, LanesEqualMarchOnAxisParallelSegments) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 317, o.height = 179;
  const Frame f = buildFrame(o);
  const int W = f.camera.width(), H = f.camera.height();
  std::mt19937 rng(uint32_t(test::testSeed() + 13));
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  // k = 1/z between the nearest and farthest stored depths, so the segments pass through layers.
  float zMin = 1e30f, zMax = 0.0f;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int l = 0; l < f.layers.countAt(x, y); ++l) {
        const float z = f.layers.pixel(x, y)[l].depth;
        zMin = std::min(zMin, z), zMax = std::max(zMax, z);
      }
  ASSERT_LT(zMin, zMax);
  auto coord = [&](int extent) {
    const float v = unit(rng) * float(extent);
    switch (rng() % 4) {
      case 0: return std::floor(v) + 0.5f;  // a pixel centre
      case 1: return std::floor(v);         // a pixel boundary
      case 2: return float(rng() % 4 == 0 ? 0 : extent) - 0.25f * unit(rng);  // at a border
      default: return v;
    }
  };
  std::vector<ScreenSegment> segs;
  for (int i = 0; i < 40000; ++i) {
    ScreenSegment s;
    s.valid = true;
    s.clippedStart = rng() % 3 == 0;
    s.p0 = {coord(W), coord(H)};
    s.p1 = s.p0;
    if (i % 2)
      s.p1.x = unit(rng) * float(W);
    else
      s.p1.y = unit(rng) * float(H);
    if (s.p1 == s.p0) continue;
    s.k0 = 1.0f / (zMin + unit(rng) * (zMax - zMin)), s.k1 = 1.0f / (zMin + unit(rng) * (zMax - zMin));
    segs.push_back(s);
  }
  for (int levels : {1, 3, PyramidConfig{}.levels, 8}) {
    const IntervalPyramid p = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{levels, PyramidConfig{}.tau});
    for (AscentRule nUp : {AscentRule(1), AscentRule(2), AscentRule(2, false)}) {
      std::vector<MarchHit> lanes(segs.size());
      std::vector<uint32_t> laneCells(segs.size());
      hssrMarchBatch(p, levels, nUp, segs, W, H, lanes, laneCells);
      size_t differ = 0, first = segs.size(), hits = 0, cellsDiffer = 0;
      for (size_t i = 0; i < segs.size(); ++i) {
        MarchCellCount c;
        const MarchHit a = hssrMarch(p, levels, nUp, segs[i], W, H, c), b = lanes[i];
        hits += a.hit();
        if (a.x != b.x || a.y != b.y || a.interval != b.interval || std::bit_cast<uint32_t>(a.s) != std::bit_cast<uint32_t>(b.s))
          ++differ, first = std::min(first, i);
        cellsDiffer += c.cells != laneCells[i];
      }
      EXPECT_GT(hits, segs.size() / 10) << "too few hits to mean anything";
      EXPECT_EQ(differ, 0u) << "levels " << levels << " n_up " << nUp.nUp << " parent ascent " << nUp.newParent << " first segment "
                            << first << " of " << segs.size();
      EXPECT_EQ(cellsDiffer, 0u) << "cells tested: levels " << levels << " n_up " << nUp.nUp << " parent ascent " << nUp.newParent;
    }
  }
}

/// Rays as long as the API's default (1e30): their far depth 1/k can round to +∞ (k − k₀
/// cancels to 0), and the level-0 test must still stop at the empty slots' {+∞, +∞} sentinel.
/// The march over k slots (scalar and lanes) answers as the reference march over each pixel's
/// count, on every level count.
TEST(Hssr, VeryLongRaysStopAtTheEmptySlots) {
  const Frame f = buildFrame(test::defaultSceneOptions(160, 90));
  const int W = f.camera.width(), H = f.camera.height();
  std::vector<Ray> rays = test::sampleRays(f, test::sanitizedCount(20000), test::testSeed() + 17);
  std::vector<ScreenSegment> segs;
  size_t infinite = 0;
  for (Ray& r : rays) {
    r.maxDistance = 1e30f;
    const ScreenSegment seg = makeScreenSegment(f.camera, r);
    if (!seg.valid) continue;
    infinite += std::isinf(1.0f / (seg.k0 + (seg.k1 - seg.k0)));
    segs.push_back(seg);
  }
  ASSERT_GT(infinite, 10u) << "no segment reaches an infinite depth: the case is not exercised";
  for (int levels : {1, 5}) {
    const IntervalPyramid p = buildIntervalPyramid(f.layers, f.camera, PyramidConfig{levels, 25.0f});
    std::vector<MarchHit> lanes(segs.size());
    std::vector<uint32_t> laneCells(segs.size());
    hssrMarchBatch(p, levels, AscentRule(2), segs, W, H, lanes, laneCells);
    size_t differ = 0, lanesDiffer = 0, hits = 0;
    for (size_t i = 0; i < segs.size(); ++i) {
      MarchCellCount c, cr;
      const MarchHit a = hssrMarch(p, levels, AscentRule(2), segs[i], W, H, c), b = hssrMarchReference(p, levels, 2, segs[i], W, H, cr);
      hits += b.hit();
      differ += a.x != b.x || a.y != b.y || a.interval != b.interval;
      lanesDiffer += a.x != lanes[i].x || a.y != lanes[i].y || a.interval != lanes[i].interval;
    }
    EXPECT_GT(hits, segs.size() / 10);
    EXPECT_EQ(differ, 0u) << "levels " << levels;
    EXPECT_EQ(lanesDiffer, 0u) << "levels " << levels;
  }
}

TEST(Hssr, MatchesExhaustiveOracleOnDefaultScene) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 320, o.height = 180;
  expectExact(buildFrame(o), 20000);
}

// ≥ 100 000 rays per real scene (half mirror reflections, half random directions)
// at 1280×720, for τ ∈ {1, 5, 25, 128}, levels ∈ {1 (the oracle), 3, 5, 8}, n_up ∈ {1, 2, 4}.
class RealSceneHssr : public ::testing::TestWithParam<std::pair<const char*, const char*>> {};

TEST_P(RealSceneHssr, MatchesExhaustiveOracle) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  const FrameOptions o = test::realSceneOptions(GetParam().first, GetParam().second);
  const Frame f = buildFrame(o);
  expectExact(f, 100000);
  expectSameAsReference(f, 100000);
}

INSTANTIATE_TEST_SUITE_P(Scenes, RealSceneHssr,
                         ::testing::Values(std::make_pair("fzk-haus.json", "interior"), std::make_pair("am-thornish.json", "hall"),
                                           std::make_pair("engine.json", "interior")),
                         [](const auto& p) { return test::sceneCaseName(p.param.first); });

TEST(Hssr, MatchesExhaustiveOracleAtOddResolutionsAndTopDownView) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 317, o.height = 179;  // partial cells on every pyramid level
  o.eye = glm::vec3(0.1f, 2.9f, -0.4f), o.target = glm::vec3(0.1f, 0.0f, -0.4f);  // straight down: up falls back
  expectExact(buildFrame(o), 10000);
}

TEST(Hssr, MatchesExhaustiveOracleWithAdaptiveThickness) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 320, o.height = 180;
  o.adaptiveThickness = true;
  o.layers = 2;
  expectExact(buildFrame(o), 10000);
}

/// The pyramid covers: every level-0 interval lies inside one interval of the cell above it, on
/// every level (so by induction every level's intervals are covered by every coarser level).
void expectCovered(const Frame& f) {
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
      // Sorted by front within each cell (the traversal's early exit relies on it).
      for (size_t c = 0; c + 1 < lvl.offset.size(); ++c)
        for (uint32_t j = lvl.offset[c] + 1; j < lvl.offset[c + 1]; ++j)
          ASSERT_LE(lvl.intervals[j - 1].front, lvl.intervals[j].front);
    }
  }
}

TEST(Hssr, PyramidCoversEveryChildInterval) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 200, o.height = 120;
  expectCovered(buildFrame(o));
}

TEST_P(RealSceneHssr, PyramidCoversEveryChildInterval) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  const FrameOptions o = test::realSceneOptions(GetParam().first, GetParam().second);
  expectCovered(buildFrame(o));
}

}  // namespace
}  // namespace lt
