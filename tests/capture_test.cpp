// The tile-local capture gives the k-layer arrays of the reference pipeline
// (rasterize into lists, then sort and truncate) bit for bit, for any tile size and thread count,
// and reuses its memory from frame to frame.
#include <algorithm>
#include <bit>
#include <limits>
#include <cstring>
#include <random>

#include <tbb/global_control.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/raster/capture.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/raster/rasterizer.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/hssr/interval_pyramid_lanes.h"
#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"
#include "test_util.h"

namespace lt {
namespace {

/// Random triangles in front of (and some through) the near plane, every third one duplicated
/// with another material: identical vertices give identical depths, so the order of equal depths
/// decides which material a slot holds.
Scene tieSoup(uint64_t seed) {
  Scene s;
  s.materials = {Material{"red", {0.9f, 0.1f, 0.1f}}, Material{"green", {0.1f, 0.9f, 0.1f}}, Material{"blue", {0.1f, 0.1f, 0.9f}}};
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), d(0.5f, 30.0f);
  for (int i = 0; i < 400; ++i) {
    const float z = -d(rng), r = 0.2f * -z;
    glm::vec3 v[3];
    for (glm::vec3& p : v) p = {u(rng) * 3.0f * r, u(rng) * 2.0f * r, z + u(rng) * 4.0f};
    test::addTriangle(s, v[0], v[1], v[2], uint32_t(i % 3));
    if (i % 3 == 0) test::addTriangle(s, v[0], v[1], v[2], 1 + uint32_t(i / 3) % 2);
  }
  for (size_t n = 0; n < s.normals.size(); ++n) s.normals[n] = glm::normalize(glm::vec3(u(rng), u(rng), 1.0f));
  s.finalize("tie-soup");
  return s;
}

struct Captured {
  LayerArrays layers;
  std::vector<uint32_t> complexity;
  uint64_t generated = 0;
};

Captured reference(const Scene& s, const Camera& cam, const RasterConfig& rc, const LayerConfig& lc) {
  const FragmentLists lists = rasterize(s, cam, rc);
  return {sortAndTruncate(lists, lc), lists.complexity, lists.generated};
}

Captured tiled(const Scene& s, const Camera& cam, const RasterConfig& rc, const LayerConfig& lc) {
  Captured c;
  LayerCapture capture;
  CaptureStats st;
  capture.capture(s, cam, rc, lc, c.layers, c.complexity, &st);
  c.generated = st.generated;
  return c;
}

/// Depth peeling; `generated` per geometry pass (every pass rasterizes the whole view).
Captured peeled(const Scene& s, const Camera& cam, const RasterConfig& rc, const LayerConfig& lc) {
  Captured c;
  LayerCapture capture;
  CaptureStats st;
  capture.capturePeeled(s, cam, rc, lc, c.layers, c.complexity, &st);
  EXPECT_EQ(st.generated % uint64_t(lc.k), 0u);
  c.generated = st.generated / uint64_t(lc.k);
  return c;
}

::testing::AssertionResult sameBytes(const Captured& a, const Captured& b) {
  if (a.layers.width != b.layers.width || a.layers.height != b.layers.height || a.layers.k != b.layers.k)
    return ::testing::AssertionFailure() << "sizes differ";
  if (a.generated != b.generated) return ::testing::AssertionFailure() << "generated " << a.generated << " vs " << b.generated;
  if (a.complexity != b.complexity) return ::testing::AssertionFailure() << "depth complexity differs";
  if (a.layers.count != b.layers.count) return ::testing::AssertionFailure() << "layer counts differ";
  if (a.layers.triangle != b.layers.triangle) return ::testing::AssertionFailure() << "slot triangles differ";
  for (size_t i = 0; i < a.layers.slots.size(); ++i)
    if (std::memcmp(&a.layers.slots[i], &b.layers.slots[i], sizeof(FragmentNode)) != 0)
      return ::testing::AssertionFailure() << "slot " << i << " (pixel " << i / size_t(a.layers.k) << ") differs: depth "
                                           << a.layers.slots[i].depth << " vs " << b.layers.slots[i].depth;
  return ::testing::AssertionSuccess();
}

/// Kept slots of one pixel with equal depths (the ties the order rule decides).
size_t tiedSlots(const LayerArrays& L) {
  size_t ties = 0;
  for (size_t p = 0; p < L.count.size(); ++p)
    for (int i = 1; i < L.count[p]; ++i) ties += L.slots[p * size_t(L.k) + size_t(i)].depth == L.slots[p * size_t(L.k) + size_t(i) - 1].depth;
  return ties;
}

TEST(Capture, TileLocalEqualsListPipelineBitForBit) {
  const Scene s = tieSoup(test::testSeed());
  CameraDesc ortho = test::originCamera(60.0f, 0.3f, 40.0f);
  ortho.orthoHeight = 12.0f;
  const CameraDesc views[] = {test::originCamera(60.0f, 0.3f, 40.0f), ortho};
  size_t ties = 0;
  for (const CameraDesc& view : views)
    for (bool front : {false, true})
      for (int k : {1, 3, 4, 16})
        for (float perDepth : {0.0f, 0.01f}) {
          const Camera cam(view, 203, 117);  // not a multiple of any tile size
          RasterConfig rc;
          rc.frontFacesOnly = front;
          const LayerConfig lc{k, 0.05f, 0.0f, false, perDepth};
          const Captured ref = reference(s, cam, rc, lc);
          ASSERT_GT(ref.generated, 10000u);
          ties += tiedSlots(ref.layers);
          for (int tileSize : {8, 32, 45}) {
            if (test::sanitized() && tileSize == 32) continue;  // (8 and 45 cover full and partial tiles)
            rc.tileSize = tileSize;
            EXPECT_TRUE(sameBytes(tiled(s, cam, rc, lc), ref))
                << "ortho " << (view.orthoHeight > 0) << " front-only " << front << " k " << k << " tile " << tileSize;
          }
        }
  EXPECT_GT(ties, 1000u) << "the scene should make the order of equal depths matter";
}

// Depth peeling (k geometry passes, nothing stored) gives the lists' k layers bit for bit: the
// same fragments in the same slots, equal depths in the lists' order, and with a minimum
// separation the layers sortAndTruncate keeps.
TEST(Capture, DepthPeelingEqualsTheListsBitForBit) {
  const Scene s = tieSoup(test::testSeed() + 2);
  CameraDesc ortho = test::originCamera(60.0f, 0.3f, 40.0f);
  ortho.orthoHeight = 12.0f;
  size_t ties = 0;
  for (const CameraDesc& view : {test::originCamera(60.0f, 0.3f, 40.0f), ortho})
    for (bool front : {false, true})
      for (int k : {1, 3, 8})
        for (float minSeparation : {0.0f, 0.5f}) {
          if (test::sanitized() && k == 3) continue;
          const Camera cam(view, 203, 117);
          RasterConfig rc;
          rc.frontFacesOnly = front;
          rc.tileSize = 45;
          const LayerConfig lc{k, 0.05f, minSeparation, false, 0.01f};
          const Captured ref = reference(s, cam, rc, lc);
          ties += tiedSlots(ref.layers);
          EXPECT_TRUE(sameBytes(peeled(s, cam, rc, lc), ref))
              << "ortho " << (view.orthoHeight > 0) << " front-only " << front << " k " << k << " separation " << minSeparation;
        }
  EXPECT_GT(ties, 1000u) << "the scene should make the order of equal depths matter";
  // Adaptive thickness grows intervals over fragments peeling never keeps.
  LayerArrays layers;
  std::vector<uint32_t> complexity;
  EXPECT_THROW(LayerCapture().capturePeeled(s, Camera(ortho, 64, 48), RasterConfig{}, LayerConfig{4, 0.05f, 0.0f, true}, layers, complexity),
               InputError);
}

// With lists asked for, the same pass writes them in exact-size storage; every
// pixel's list equals the reference pool's (same fragments, same order), and the k layers are
// unchanged.
TEST(Capture, ListsFromTheTilePassEqualTheReferenceLists) {
  const Scene s = tieSoup(test::testSeed() + 4);
  CameraDesc ortho = test::originCamera(60.0f, 0.3f, 40.0f);
  ortho.orthoHeight = 12.0f;
  LayerCapture capture;
  for (const CameraDesc& view : {test::originCamera(60.0f, 0.3f, 40.0f), ortho})
    for (int tileSize : {16, 32}) {
      const Camera cam(view, 203, 117);
      RasterConfig rc;
      rc.tileSize = tileSize;
      const LayerConfig lc{3, 0.05f};
      const FragmentLists want = rasterize(s, cam, rc);
      LayerArrays layers;
      FragmentLists lists;
      capture.captureWithLists(s, cam, rc, lc, layers, lists);
      EXPECT_EQ(lists.generated, want.generated);
      EXPECT_EQ(lists.nodes.size(), want.generated) << "exact-size storage, not a pool";
      EXPECT_TRUE(lists.complexity == want.complexity);
      EXPECT_TRUE(test::sameListContents(lists, want)) << "ortho " << (view.orthoHeight > 0) << " tile " << tileSize;
      EXPECT_TRUE(sameBytes(Captured{layers, lists.complexity, lists.generated}, Captured{sortAndTruncate(want, lc), want.complexity, want.generated}));
    }
}

TEST(Capture, OneAndTwoThreadsGiveTheSameBytes) {
  const Scene s = tieSoup(test::testSeed() + 1);
  const Camera cam(test::originCamera(60.0f, 0.3f, 40.0f), 320, 180);
  const LayerConfig lc{4, 0.05f};
  Captured one, two;
  {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 1);
    one = tiled(s, cam, RasterConfig{}, lc);
  }
  {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, 2);
    two = tiled(s, cam, RasterConfig{}, lc);
  }
  EXPECT_TRUE(sameBytes(one, two));
}

// The second frame of the same size writes into the memory of the first.
TEST(Capture, ASecondFrameReusesEveryBuffer) {
  const Scene s = tieSoup(test::testSeed() + 2);
  CameraDesc view = test::originCamera(60.0f, 0.3f, 40.0f);
  const LayerConfig lc{4, 0.05f};
  LayerCapture capture;
  LayerArrays layers;
  std::vector<uint32_t> complexity;
  capture.capture(s, Camera(view, 160, 90), RasterConfig{}, lc, layers, complexity);
  const void* slots = layers.slots.data();
  const void* counts = layers.count.data();
  const void* tris = layers.triangle.data();
  const void* dc = complexity.data();
  const size_t scratch = capture.scratchBytes();
  ASSERT_GT(scratch, 0u);
  view.eye = {0.3f, -0.2f, 0.5f};  // another view of the same scene
  const Camera moved(view, 160, 90);
  capture.capture(s, moved, RasterConfig{}, lc, layers, complexity);
  EXPECT_EQ(layers.slots.data(), slots);
  EXPECT_EQ(layers.count.data(), counts);
  EXPECT_EQ(layers.triangle.data(), tris);
  EXPECT_EQ(complexity.data(), dc);
  EXPECT_EQ(capture.scratchBytes(), scratch);
  // And the reused buffers hold the new view's answer, nothing of the old one.
  Captured ref = reference(s, moved, RasterConfig{}, lc);
  ref.generated = 0;
  EXPECT_TRUE(sameBytes(Captured{layers, complexity, 0}, ref));
}

::testing::AssertionResult samePyramid(const IntervalPyramid& a, const IntervalPyramid& b) {
  auto bytesEqual = [](const auto& x, const auto& y) {
    return x.size() == y.size() && (x.empty() || std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) == 0);
  };
  if (!bytesEqual(a.base->slots, b.base->slots) || a.base->count != b.base->count) return ::testing::AssertionFailure() << "level 0 differs";
  if (a.levels.size() != b.levels.size()) return ::testing::AssertionFailure() << "level counts differ";
  for (size_t L = 1; L < a.levels.size(); ++L)
    if (a.levels[L].offset != b.levels[L].offset || !bytesEqual(a.levels[L].intervals, b.levels[L].intervals) ||
        !bytesEqual(a.levels[L].cells, b.levels[L].cells))
      return ::testing::AssertionFailure() << "level " << L << " differs";
  return ::testing::AssertionSuccess();
}

// The pyramid too: rebuilt for the next view into the same memory, it equals a fresh build.
TEST(Capture, APyramidRebuiltInPlaceEqualsAFreshOne) {
  const Scene s = tieSoup(test::testSeed() + 3);
  CameraDesc view = test::originCamera(60.0f, 0.3f, 40.0f);
  const LayerConfig lc{4, 0.05f};
  const PyramidConfig pc{5, 25.0f};
  LayerCapture capture;
  LayerArrays layers;
  std::vector<uint32_t> complexity;
  const Camera first(view, 203, 117);
  capture.capture(s, first, RasterConfig{}, lc, layers, complexity);
  IntervalPyramid reused;
  buildIntervalPyramid(layers, first, pc, reused);
  const void* base = reused.base->slots.data();
  const void* cells = reused.levels[1].cells.data();
  view.eye = {-0.4f, 0.1f, 0.2f};
  const Camera second(view, 203, 117);
  capture.capture(s, second, RasterConfig{}, lc, layers, complexity);
  buildIntervalPyramid(layers, second, pc, reused);
  EXPECT_EQ(reused.base->slots.data(), base);
  EXPECT_EQ(reused.levels[1].cells.data(), cells);
  EXPECT_TRUE(samePyramid(reused, buildIntervalPyramid(layers, second, pc)));
  EXPECT_FALSE(samePyramid(reused, buildIntervalPyramid(layers, first, PyramidConfig{5, 5.0f}))) << "the comparison must be able to fail";
}

// The pyramid's level 0 that the capture writes tile by tile is the one makeIntervalLayers
// builds from the finished k layers, in every pipeline (with adaptive thickness it is rebuilt
// after the whole-list sort).
TEST(Capture, LevelZeroFromTheTilesEqualsOneFromTheLayers) {
  const Scene s = tieSoup(test::testSeed() + 5);
  for (int variant = 0; variant < 4; ++variant) {
    Frame f;
    f.scene = s;
    f.camera = Camera(test::originCamera(60.0f, 0.3f, 40.0f), 203, 117);
    f.thickness = 0.05f;
    FrameOptions o;
    o.width = 203, o.height = 117, o.thickness = 0.05f;
    o.captureLists = variant == 1;
    o.adaptiveThickness = variant == 2;
    o.referenceCapture = variant == 3;
    rasterizeFrame(o, f);
    ASSERT_TRUE(f.level0()) << variant;
    const IntervalLayers want = makeIntervalLayers(f.layers, f.layers.k);
    EXPECT_EQ(f.level0()->count, want.count) << f.capturePipeline;
    ASSERT_EQ(f.level0()->slots.size(), want.slots.size());
    EXPECT_EQ(std::memcmp(f.level0()->slots.data(), want.slots.data(), want.slots.size() * sizeof(Interval)), 0) << f.capturePipeline;
  }
}

/// Hofmann et al. 2017, §4.3, written as plainly as possible: per cell, gather the 2×2 children's
/// intervals, stable-sort them by front, merge greedily within τ.
std::vector<std::vector<std::vector<Interval>>> plainPyramid(const IntervalLayers& base, const Camera& camera, const PyramidConfig& c) {
  std::vector<std::vector<std::vector<Interval>>> levels(size_t(c.levels));
  int w = base.width, h = base.height;
  levels[0].resize(size_t(w) * size_t(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) levels[0][size_t(y) * size_t(w) + size_t(x)].assign(base.pixel(x, y), base.pixel(x, y) + base.countAt(x, y));
  for (int L = 1; L < c.levels; ++L) {
    const int cw = (w + 1) / 2, ch = (h + 1) / 2;
    const float tau = c.tau * camera.pixelFootprint(1.0f) * float(1 << L);
    levels[size_t(L)].resize(size_t(cw) * size_t(ch));
    for (int y = 0; y < ch; ++y)
      for (int x = 0; x < cw; ++x) {
        std::vector<Interval> kids;
        for (int cy = 2 * y; cy < std::min(2 * y + 2, h); ++cy)
          for (int cx = 2 * x; cx < std::min(2 * x + 2, w); ++cx) {
            const auto& k = levels[size_t(L - 1)][size_t(cy) * size_t(w) + size_t(cx)];
            kids.insert(kids.end(), k.begin(), k.end());
          }
        std::stable_sort(kids.begin(), kids.end(), [](const Interval& a, const Interval& b) { return a.front < b.front; });
        auto& out = levels[size_t(L)][size_t(y) * size_t(cw) + size_t(x)];
        for (size_t i = 0; i < kids.size();) {
          Interval cur = kids[i++];
          while (i < kids.size() && (kids[i].front <= cur.front + tau * cur.front || kids[i].front <= cur.back)) cur.back = std::max(cur.back, kids[i++].back);
          out.push_back(cur);
        }
      }
    w = cw, h = ch;
  }
  return levels;
}

/// A cell's n intervals at `got` against the plain merge's, bit for bit.
::testing::AssertionResult sameCell(const std::vector<Interval>& want, const Interval* got, size_t n) {
  if (n != want.size()) return ::testing::AssertionFailure() << n << " intervals, the plain merge has " << want.size();
  if (n > 0 && std::memcmp(want.data(), got, n * sizeof(Interval)) != 0) return ::testing::AssertionFailure() << "different intervals";
  return ::testing::AssertionSuccess();
}

/// Every cell of a built level against the plain merge's cells; counts cells of several intervals.
::testing::AssertionResult levelEqualsPlain(const PyramidLevel& lvl, const std::vector<std::vector<Interval>>& want, size_t& multi) {
  if (want.size() != size_t(lvl.width) * size_t(lvl.height)) return ::testing::AssertionFailure() << "cell counts differ";
  for (size_t c = 0; c < want.size(); ++c) {
    const ::testing::AssertionResult r = sameCell(want[c], lvl.intervals.data() + lvl.offset[c], lvl.offset[c + 1] - lvl.offset[c]);
    if (!r) return ::testing::AssertionFailure() << "cell " << c << ": " << r.message();
    multi += want[c].size() > 1;
  }
  return ::testing::AssertionSuccess();
}

// The pyramid build (in-place, fixed-array gathering, insertion sort) equals the plain merge on
// every cell of every level, bit for bit.
TEST(Capture, PyramidEqualsThePlainMerge) {
  const Scene s = tieSoup(test::testSeed() + 6);
  for (int k : {1, 2, 3, 4, 16}) {
    const Camera cam(test::originCamera(60.0f, 0.3f, 40.0f), 203, 117);
    LayerCapture capture;
    LayerArrays layers;
    std::vector<uint32_t> complexity;
    capture.capture(s, cam, RasterConfig{}, LayerConfig{k, 0.05f, 0.0f, false, 0.002f}, layers, complexity);
    for (float tau : {2.0f, 25.0f}) {
      const PyramidConfig pc{6, tau};
      const IntervalPyramid p = buildIntervalPyramid(layers, cam, pc);
      const auto want = plainPyramid(*p.base, cam, pc);
      size_t cells = 0, multi = 0;
      for (int L = 1; L < pc.levels; ++L) {
        ASSERT_TRUE(levelEqualsPlain(p.levels[size_t(L)], want[size_t(L)], multi)) << "k " << k << " tau " << tau << " level " << L;
        cells += want[size_t(L)].size();
      }
      EXPECT_GT(multi, cells / 20) << "cells with several intervals make the merge matter";
    }
  }
}

/// Level 0 of k = 4 built to stress the level-1 merge: fronts from a few values (ties inside a
/// pixel and across children), backs short, long (overlapping the next fronts) or +∞, 0–4
/// intervals per pixel, sorted by front.
IntervalLayers stressLevel0(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  IntervalLayers b;
  b.width = width, b.height = height, b.k = 4;
  b.slots.resize(size_t(width) * size_t(height) * 4);
  b.count.resize(size_t(width) * size_t(height));
  constexpr float inf = std::numeric_limits<float>::infinity();
  for (size_t p = 0; p < b.count.size(); ++p) {
    const int n = int(rng() % 5);
    std::vector<Interval> iv;
    for (int i = 0; i < n; ++i) {
      const float front = 1.0f + float(rng() % 12) * (rng() % 2 ? 0.01f : 0.5f);
      const uint32_t kind = rng() % 8;
      const float back = kind == 0 ? inf : kind == 1 ? front + 3.0f : kind == 2 ? front : front + 0.002f * float(rng() % 10);
      iv.push_back({front, back});
    }
    std::stable_sort(iv.begin(), iv.end(), [](const Interval& a, const Interval& c) { return a.front < c.front; });
    for (int i = 0; i < 4; ++i) b.slots[p * 4 + size_t(i)] = i < n ? iv[size_t(i)] : Interval{inf, inf};
    b.count[p] = uint8_t(n);
  }
  return b;
}

// The merge in vector lanes (sixteen cells per call), on every vector target this CPU runs,
// equals the plain merge on every cell of every level, on level 0s made to stress it (ties,
// overlaps, +∞ backs, empty pixels), for τ from 0.001 to ∞; so do the pyramids built around it
// (edge cells one at a time, odd sizes).
TEST(Capture, MergeLanesEqualThePlainMerge) {
  const Camera cam(test::originCamera(60.0f, 0.3f, 40.0f), 261, 37);  // level 1: 131 cells, 8 lane groups + 3 cells; odd rows
  size_t groups[4] = {}, refused = 0;
  test::forEachSimdTarget([&](const SimdTarget&) {
  for (uint32_t seed = 0; seed < 4; ++seed) {
    const IntervalLayers base = stressLevel0(cam.width(), cam.height(), test::testSeed() + seed);
    for (float tau : {0.001f, 2.0f, 25.0f, 3000.0f, std::numeric_limits<float>::infinity()}) {
      const PyramidConfig pc{4, tau};
      const auto want = plainPyramid(base, cam, pc);
      const IntervalPyramid p = buildIntervalPyramid(base, cam, pc);
      size_t multi = 0;
      for (int L = 1; L < pc.levels; ++L) {
        const PyramidLevel& lvl = p.levels[size_t(L)];
        ASSERT_TRUE(levelEqualsPlain(lvl, want[size_t(L)], multi)) << "tau " << tau << " level " << L;
        if (!mergeLanesAvailable(p, L)) continue;
        // The lanes called directly, on every group of sixteen cells they take.
        const float tauPerDepth = tau * cam.pixelFootprint(1.0f) * float(1 << L);
        const PyramidLevel& child = p.levels[size_t(L - 1)];
        for (int y = 0; 2 * y + 2 <= child.height; ++y)
          for (int x0 = 0; 2 * x0 + 32 <= child.width; x0 += 16) {
            std::vector<Interval> got{{-1.0f, -1.0f}};  // appended after what is there
            uint32_t counts[16];
            if (!mergeCellsLanes(p, L, x0, y, tauPerDepth, got, counts)) {
              ASSERT_GE(L, 2);
              ASSERT_EQ(got.size(), 1u) << "refused: nothing written";
              ++refused;
              continue;
            }
            ++groups[L];
            size_t at = 1;
            for (int j = 0; j < 16; ++j) {
              ASSERT_LE(at + counts[j], got.size());
              ASSERT_TRUE(sameCell(want[size_t(L)][size_t(y) * size_t(lvl.width) + size_t(x0 + j)], &got[at], counts[j]))
                  << "tau " << tau << " level " << L << " cell " << x0 + j << ", " << y;
              at += counts[j];
            }
            ASSERT_EQ(at, got.size());
            ASSERT_EQ(got[0].front, -1.0f);
          }
      }
      if (tau == 2.0f) {
        EXPECT_GT(multi, 100u) << "cells of several intervals make the sweep matter";
      }
    }
  }
  });
  // A level 0 with nothing stored: every level above is empty (the lanes read no interval).
  IntervalLayers empty = stressLevel0(cam.width(), cam.height(), test::testSeed());
  std::fill(empty.count.begin(), empty.count.end(), uint8_t(0));
  const IntervalPyramid none = buildIntervalPyramid(std::move(empty), cam, PyramidConfig{4, 25.0f});
  for (int L = 1; L < 4; ++L) EXPECT_TRUE(none.levels[size_t(L)].intervals.empty()) << L;
  EXPECT_GT(groups[1], 100u);
  EXPECT_GT(groups[2], 10u);
  EXPECT_GT(groups[3], 1u);
  EXPECT_GT(refused, 0u) << "children of more than four intervals are left to the one-cell merge";
}


// Levels 1… merged tile by tile (PyramidTileBuilder: tiles in any order, concurrently) equal
// the global build over the same level 0, for tile sizes holding whole cells of every level
// (32), of some levels (8: levels above 3 are built globally by finish) and of none (45); at
// odd image sizes, so that edge tiles and edge cells are partial.
TEST(Capture, APyramidBuiltPerTileEqualsTheGlobalBuild) {
  const Scene s = tieSoup(test::testSeed() + 8);
  const Camera cam(test::originCamera(60.0f, 0.3f, 40.0f), 203, 117);
  for (int k : {1, 4}) {
    LayerCapture capture;
    LayerArrays layers;
    std::vector<uint32_t> complexity;
    capture.capture(s, cam, RasterConfig{}, LayerConfig{k, 0.05f}, layers, complexity);
    const auto level0 = std::make_shared<IntervalLayers>(makeIntervalLayers(layers, k));
    for (int tileSize : {32, 8, 45})
      for (int levels : {1, 2, 5, 8})
        for (float tau : {2.0f, 25.0f}) {
          const PyramidConfig pc{levels, tau};
          PyramidTileBuilder builder;
          IntervalPyramid tiled;
          builder.begin(level0, cam, pc, tileSize, tiled);
          EXPECT_EQ(builder.tileLevels(), std::min(levels - 1, tileSize == 32 ? 5 : tileSize == 8 ? 3 : 0));
          const int tx = (cam.width() + tileSize - 1) / tileSize, ty = (cam.height() + tileSize - 1) / tileSize;
          parallelFor(0, tx * ty, [&](int t) {
            const int i = tx * ty - 1 - t;  // last tile first: no order is assumed
            const int x0 = (i % tx) * tileSize, y0 = (i / tx) * tileSize;
            builder.tile(x0, y0, std::min(x0 + tileSize, cam.width()) - 1, std::min(y0 + tileSize, cam.height()) - 1);
          });
          builder.finish(2);
          IntervalPyramid global;
          buildIntervalPyramid(level0, cam, pc, global);
          EXPECT_TRUE(samePyramid(tiled, global)) << "k " << k << " tile " << tileSize << " levels " << levels << " tau " << tau;
          if (levels == 5 && tau == 25.0f) {
            IntervalPyramid other;
            buildIntervalPyramid(level0, cam, PyramidConfig{levels, 2.0f}, other);
            EXPECT_FALSE(samePyramid(tiled, other)) << "the comparison must be able to fail";
          }
        }
  }
}

// Through the frame: the capture builds the pyramid FrameOptions::pyramid asks for — after the
// pass or per tile — an hssr tracer of that configuration uses it (one of another configuration
// builds its own), and the next view reuses its memory.
TEST(Capture, TheFramesPyramidIsBuiltByTheCaptureAndReused) {
  for (bool perTile : {false, true}) {
    Frame f;
    f.scene = tieSoup(test::testSeed() + 9);
    CameraDesc view = test::originCamera(60.0f, 0.3f, 40.0f);
    f.camera = Camera(view, 203, 117);
    f.thickness = 0.05f;
    FrameOptions o;
    o.width = 203, o.height = 117, o.thickness = 0.05f;
    o.pyramid = PyramidConfig{};  // (the tracers' default: the held tracer below takes it)
    o.pyramidPerTile = perTile;
    rasterizeFrame(o, f);
    ASSERT_TRUE(f.pyramid);
    EXPECT_TRUE(samePyramid(*f.pyramid, buildIntervalPyramid(f.layers, f.camera, *o.pyramid))) << perTile;
    EXPECT_EQ(f.pyramidFor(*o.pyramid), f.pyramid);
    EXPECT_EQ(f.pyramidFor(PyramidConfig{o.pyramid->levels, 10.0f}), nullptr);
    EXPECT_EQ(f.pyramidFor(PyramidConfig{o.pyramid->levels - 1, 25.0f}), nullptr);
    TracerOptions to;
    to.pyramid = *o.pyramid;
    EXPECT_EQ(buildTracer("hssr", f, to).pyramid, f.pyramid);
    to.pyramid.tau = 10.0f;
    EXPECT_NE(buildTracer("hssr", f, to).pyramid, f.pyramid);
    const void* cells = f.pyramid->levels[1].cells.data();
    const void* intervals = f.level0()->slots.data();
    view.eye = {-0.4f, 0.1f, 0.2f};
    f.camera = Camera(view, 203, 117);
    rasterizeFrame(o, f);
    EXPECT_EQ(f.pyramid->levels[1].cells.data(), cells) << perTile;
    EXPECT_EQ(f.level0()->slots.data(), intervals) << perTile;
    EXPECT_TRUE(samePyramid(*f.pyramid, buildIntervalPyramid(f.layers, f.camera, *o.pyramid))) << perTile;
    // A tracer still holding the pyramid keeps it: the next capture builds another.
    const BuiltTracer held = buildTracer("hssr", f, TracerOptions{});
    const std::shared_ptr<IntervalPyramid> before = f.pyramid;
    rasterizeFrame(o, f);
    EXPECT_NE(f.pyramid, before);
    EXPECT_EQ(held.pyramid, before);
    // Whole-list rules rewrite the layers after the pass: the pyramid follows them.
    o.adaptiveThickness = true;
    rasterizeFrame(o, f);
    ASSERT_TRUE(f.pyramid);
    EXPECT_TRUE(samePyramid(*f.pyramid, buildIntervalPyramid(f.layers, f.camera, *o.pyramid))) << perTile;
    // The reference pipeline too.
    o.adaptiveThickness = false, o.referenceCapture = true;
    rasterizeFrame(o, f);
    ASSERT_TRUE(f.pyramid);
    EXPECT_TRUE(samePyramid(*f.pyramid, buildIntervalPyramid(f.layers, f.camera, *o.pyramid))) << perTile;
    o.pyramid.reset();
    rasterizeFrame(o, f);
    EXPECT_EQ(f.pyramid, nullptr);
  }
}

// The prefix sums that place list nodes and pyramid intervals run in parallel blocks: they equal
// the serial loop for any length (block edges included), in place or not, capped or not.
TEST(Capture, ParallelPrefixSumEqualsTheSerialOne) {
  std::mt19937_64 rng(test::testSeed() + 10);
  for (size_t n : {size_t(0), size_t(1), size_t(65535), size_t(65536), size_t(65537), size_t(300001)})
    for (uint64_t cap : {uint64_t(0xFFFFFFFFu), uint64_t(1000000)}) {
      std::vector<uint32_t> in(n);
      for (uint32_t& v : in) v = uint32_t(rng() % 40);
      std::vector<uint32_t> want(n);
      uint64_t total = 0;
      for (size_t i = 0; i < n; ++i) want[i] = uint32_t(std::min(total, cap)), total += in[i];
      std::vector<uint32_t> out(n, 7);
      EXPECT_EQ(parallelExclusiveScan(in.data(), out.data(), n, cap), total) << n;
      EXPECT_EQ(out, want) << n << " cap " << cap;
      EXPECT_EQ(parallelExclusiveScan(in.data(), in.data(), n, cap), total) << n;  // in place
      EXPECT_EQ(in, want) << n << " cap " << cap << " in place";
      if (n == 300001) {
        EXPECT_GT(total, uint64_t(1000000)) << "the 1 000 000 cap must be reached to be tested";
      }
    }
}

TEST(Capture, OptionsThatNeedWholeListsAreRefused) {
  const Scene s = tieSoup(1);
  const Camera cam(test::originCamera(), 32, 32);
  LayerCapture capture;
  LayerArrays layers;
  std::vector<uint32_t> complexity;
  EXPECT_THROW(capture.capture(s, cam, RasterConfig{}, LayerConfig{4, 0.1f, 0.2f}, layers, complexity), InputError);
  EXPECT_THROW(capture.capture(s, cam, RasterConfig{}, LayerConfig{4, 0.1f, 0.0f, true}, layers, complexity), InputError);
  EXPECT_THROW(capture.capture(s, cam, RasterConfig{}, LayerConfig{17, 0.1f}, layers, complexity), InputError);
}

}  // namespace
}  // namespace lt
