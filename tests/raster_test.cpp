// Rasterizer, fragment encoding, sort/truncate and overflow: each against a known answer.
#include <algorithm>
#include <cmath>
#include <random>

#include <glm/geometric.hpp>
#include <tbb/global_control.h>

#include "layertrace/raster/fragment.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/raster/rasterizer.h"
#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"
#include <glm/trigonometric.hpp>
#include "test_util.h"

namespace lt {
namespace {

using test::addTriangle;
using test::originCamera;

glm::vec3 randomUnit(std::mt19937_64& rng) {
  std::normal_distribution<float> n;
  glm::vec3 v;
  do v = {n(rng), n(rng), n(rng)};
  while (glm::length(v) < 1e-3f);
  return glm::normalize(v);
}

TEST(Fragment, OctahedralRoundTripErrorBound) {
  std::mt19937_64 rng(test::testSeed());
  float worst = 0.0f;
  for (int i = 0; i < 200000; ++i) {
    glm::vec3 n = randomUnit(rng);
    if (i < 6) n = glm::vec3(0.0f), n[i % 3] = (i < 3 ? 1.0f : -1.0f);  // the axes exactly
    const glm::vec3 d = decodeOctahedral(encodeOctahedral(n));
    const glm::dvec3 a(n), b(d);
    worst = std::max(worst, float(std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b))));
  }
  // 2 × 16-bit snorm: a quantisation step of 1/32767 moves the normal by at most ~1.5 steps.
  EXPECT_LT(worst, 1e-4f) << "seed " << test::testSeed();
}

// The inline rounding of the octahedral encoder is std::lround's: every half, its neighbours
// one ulp either side, and random values over the snorm16 range.
TEST(Fragment, InlineRoundingIsLround) {
  std::mt19937_64 rng(test::testSeed());
  std::uniform_real_distribution<float> u(-32767.0f, 32767.0f);
  auto check = [](float v) { ASSERT_EQ(roundHalfAway(v), std::lround(v)) << v; };
  for (int i = -32767; i < 32767; ++i) {
    const float half = float(i) + 0.5f;
    check(half), check(std::nextafter(half, 0.0f)), check(std::nextafter(half, 1e9f)), check(std::nextafter(half, -1e9f));
    check(float(i)), check(-0.0f);
  }
  for (int i = 0; i < 2000000; ++i) check(u(rng) * (i % 2 ? 1.0f : 1e-4f));
}

TEST(Fragment, AlbedoSpecularPackingRoundTrip) {
  std::mt19937_64 rng(test::testSeed());
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int i = 0; i < 10000; ++i) {
    const glm::vec3 a(u(rng), u(rng), u(rng));
    const float s = u(rng);
    const uint32_t p = packAlbedoSpec(a, s);
    const glm::vec3 back = unpackAlbedo(p);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(back[c], a[c], 0.5f / 255.0f * 2.4f * std::max(0.05f, std::pow(a[c], 1.0f / 1.7f)) + 1e-3f);
    EXPECT_NEAR(unpackSpecular(p), s, 0.5f / 255.0f + 1e-6f);
  }
  EXPECT_EQ(sizeof(FragmentNode), 16u);
}

/// Pixels whose centre lies strictly inside the triangle by at least `margin` pixels.
bool strictlyInside(glm::vec2 p, glm::vec2 a, glm::vec2 b, glm::vec2 c, float margin) {
  auto edge = [&](glm::vec2 u, glm::vec2 v) {
    const glm::vec2 d = v - u;
    return (d.x * (p.y - u.y) - d.y * (p.x - u.x)) / glm::length(d);
  };
  const float e0 = edge(a, b), e1 = edge(b, c), e2 = edge(c, a);
  return (e0 > margin && e1 > margin && e2 > margin) || (e0 < -margin && e1 < -margin && e2 < -margin);
}

TEST(Rasterizer, SharedEdgeCoversEveryPixelExactlyOnce) {
  std::mt19937_64 rng(test::testSeed());
  const int W = 96, H = 64;
  const Camera cam(originCamera(), W, H);
  std::uniform_real_distribution<float> px(-20.0f, float(W) + 20.0f), py(-20.0f, float(H) + 20.0f), dz(2.0f, 9.0f);
  int checkedInside = 0;
  for (int trial = 0; trial < 400; ++trial) {
    // Four screen points; the shared edge a–c; b and d on opposite sides of it.
    glm::vec2 s[4];
    for (auto& p : s) p = {px(rng), py(rng)};
    if (trial % 4 == 0) s[2] = {std::floor(s[2].x) + 0.5f, std::floor(s[2].y) + 0.5f};  // vertices on pixel centres
    if (trial % 8 == 1) s[2].y = s[0].y;                                               // horizontal shared edge
    if (trial % 8 == 3) s[2].x = s[0].x;                                               // vertical shared edge
    auto side = [&](glm::vec2 p) { const glm::vec2 d = s[2] - s[0]; return d.x * (p.y - s[0].y) - d.y * (p.x - s[0].x); };
    if (side(s[1]) * side(s[3]) >= 0.0f) continue;
    Scene scene;
    glm::vec3 v[4];
    for (int i = 0; i < 4; ++i) v[i] = cam.rayThrough(s[i]) * dz(rng);  // random depths: the quad is not planar
    addTriangle(scene, v[0], v[1], v[2]);
    addTriangle(scene, v[0], v[2], v[3]);
    scene.finalize("pair");
    const FragmentLists lists = rasterize(scene, cam);
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        const uint32_t n = lists.complexity[lists.pixelIndex(x, y)];
        ASSERT_LE(n, 1u) << "pixel " << x << "," << y << " covered twice, trial " << trial << " seed " << test::testSeed();
        const glm::vec2 c(float(x) + 0.5f, float(y) + 0.5f);
        const bool inside = strictlyInside(c, s[0], s[1], s[2], 0.01f) || strictlyInside(c, s[0], s[2], s[3], 0.01f) ||
                            (std::abs(side(c)) / glm::length(s[2] - s[0]) < 1e-3f && false);
        if (inside) {
          ++checkedInside;
          ASSERT_EQ(n, 1u) << "pixel " << x << "," << y << " inside but not covered, trial " << trial;
        }
      }
    // Pixels on the shared edge's line (inside the quad) must be covered by exactly one triangle:
    // the union's coverage equals the coverage of the quad as a whole.
    Scene single;
    addTriangle(single, v[0], v[1], v[2]);
    single.finalize("one");
    const FragmentLists one = rasterize(single, cam);
    Scene other;
    addTriangle(other, v[0], v[2], v[3]);
    other.finalize("two");
    const FragmentLists two = rasterize(other, cam);
    for (size_t p = 0; p < lists.complexity.size(); ++p)
      ASSERT_EQ(lists.complexity[p], one.complexity[p] + two.complexity[p]);
  }
  EXPECT_GT(checkedInside, 10000);
}

TEST(Rasterizer, DepthMatchesAnalyticPlane) {
  std::mt19937_64 rng(test::testSeed());
  const int W = 160, H = 90;
  const Camera cam(originCamera(70.0f, 0.05f, 200.0f), W, H);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), d(1.0f, 50.0f);
  size_t fragments = 0;
  for (int trial = 0; trial < 50; ++trial) {
    Scene scene;
    const glm::vec3 a(u(rng) * 30, u(rng) * 20, -d(rng)), b(u(rng) * 30, u(rng) * 20, -d(rng)), c(u(rng) * 30, u(rng) * 20, -d(rng));
    addTriangle(scene, a, b, c);
    scene.finalize("plane");
    const FragmentLists lists = rasterize(scene, cam);
    const glm::dvec3 n = glm::cross(glm::dvec3(b) - glm::dvec3(a), glm::dvec3(c) - glm::dvec3(a));
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x)
        for (uint32_t i = lists.head[lists.pixelIndex(x, y)]; i != kNullIndex; i = lists.nodes[i].next) {
          const glm::dvec3 dir((x + 0.5 - W * 0.5) / (H * 0.5 / std::tan(glm::radians(35.0))),
                               -(y + 0.5 - H * 0.5) / (H * 0.5 / std::tan(glm::radians(35.0))), -1.0);
          const double t = glm::dot(n, glm::dvec3(a)) / glm::dot(n, dir);
          if (std::abs(glm::dot(glm::normalize(n), glm::normalize(dir))) < 0.05) continue;  // grazing: ill-conditioned
          ASSERT_NEAR(lists.nodes[i].depth, t, 2e-5 * t) << "trial " << trial << " pixel " << x << "," << y;
          ++fragments;
        }
  }
  EXPECT_GT(fragments, 1000u);
}

TEST(Rasterizer, NearPlaneClippingKeepsOnlyFragmentsInFront) {
  const Camera cam(originCamera(60.0f, 1.0f, 100.0f), 64, 64);
  Scene scene;  // a floor-like triangle reaching behind the camera
  addTriangle(scene, {-5, -1, 5}, {5, -1, 5}, {0, -1, -40});
  scene.finalize("through-near");
  const FragmentLists lists = rasterize(scene, cam);
  ASSERT_GT(lists.generated, 100u);
  for (uint32_t h : lists.head)
    for (uint32_t i = h; i != kNullIndex; i = lists.nodes[i].next) ASSERT_GE(lists.nodes[i].depth, cam.near());
}

// --front-faces-only: a closed box (outward, counter-clockwise faces) shows one front face per
// covered pixel and loses only its back faces.
TEST(Rasterizer, FrontFacesOnlyKeepsTheFacesTowardTheCamera) {
  Scene scene = makeBox({-1, -1, -5}, {1, 1, -3});
  scene.finalize("box");
  const Camera cam(originCamera(), 64, 48);
  RasterConfig front;
  front.frontFacesOnly = true;
  const FragmentLists all = rasterize(scene, cam), culled = rasterize(scene, cam, front);
  uint64_t covered = 0;
  for (size_t p = 0; p < all.complexity.size(); ++p) {
    ASSERT_EQ(all.complexity[p], 2 * culled.complexity[p]) << "pixel " << p;
    ASSERT_LE(culled.complexity[p], 1u);
    covered += culled.complexity[p];
    if (culled.complexity[p] == 0) continue;
    // The kept fragment is the nearer of the two.
    float nearest = INFINITY;
    for (uint32_t i = all.head[p]; i != kNullIndex; i = all.nodes[i].next) nearest = std::min(nearest, all.nodes[i].depth);
    ASSERT_EQ(culled.nodes[culled.head[p]].depth, nearest) << "pixel " << p;
  }
  EXPECT_GT(covered, 100u);
}

TEST(Rasterizer, ResultIndependentOfThreadCount) {
  Scene scene;
  std::mt19937_64 rng(test::testSeed());
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  for (int i = 0; i < 3000; ++i) {
    const glm::vec3 c(u(rng) * 4, u(rng) * 3, -6 + u(rng) * 3);
    addTriangle(scene, c, c + glm::vec3(u(rng), u(rng), u(rng)) * 0.6f, c + glm::vec3(u(rng), u(rng), u(rng)) * 0.6f);
  }
  scene.finalize("soup");
  const Camera cam(originCamera(), 200, 120);
  auto layersWith = [&](int threads) {
    tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(threads));
    return sortAndTruncate(rasterize(scene, cam), LayerConfig{8, 0.01f, 0.0f});
  };
  const LayerArrays a = layersWith(1), b = layersWith(2);
  ASSERT_EQ(a.count, b.count);
  ASSERT_EQ(a.triangle, b.triangle);
  for (size_t i = 0; i < a.slots.size(); ++i) ASSERT_EQ(a.slots[i].depth, b.slots[i].depth);
}

/// Hand-built lists: pixel p holds the given depths in list order.
FragmentLists makeLists(const std::vector<std::vector<float>>& pixels) {
  FragmentLists l;
  l.width = int(pixels.size());
  l.height = 1;
  l.head.assign(pixels.size(), kNullIndex);
  l.complexity.assign(pixels.size(), 0);
  for (size_t p = 0; p < pixels.size(); ++p)
    for (auto it = pixels[p].rbegin(); it != pixels[p].rend(); ++it) {  // prepend in reverse: list order = given order
      const auto idx = uint32_t(l.nodes.size());
      l.nodes.push_back(FragmentNode{*it, 0u, 0u, l.head[p]});
      l.triangle.push_back(idx);
      l.head[p] = idx;
      ++l.complexity[p];
    }
  l.generated = l.stored = l.nodes.size();
  return l;
}

TEST(SortTruncate, KeepsTheKFrontMostInOrder) {
  std::mt19937_64 rng(test::testSeed());
  std::uniform_real_distribution<float> u(0.1f, 100.0f);
  std::uniform_int_distribution<int> len(0, 40);
  std::vector<std::vector<float>> pixels(500);
  for (auto& p : pixels) {
    p.resize(size_t(len(rng)));
    for (float& d : p) d = u(rng);
  }
  const FragmentLists lists = makeLists(pixels);
  for (int k : {1, 2, 4, 7, 16}) {
    const LayerArrays L = sortAndTruncate(lists, LayerConfig{k, 0.25f, 0.0f});
    for (size_t p = 0; p < pixels.size(); ++p) {
      std::vector<float> expect = pixels[p];
      std::sort(expect.begin(), expect.end());
      expect.resize(std::min(expect.size(), size_t(k)));
      ASSERT_EQ(L.count[p], expect.size());
      for (size_t i = 0; i < expect.size(); ++i) {
        ASSERT_EQ(L.slots[p * size_t(k) + i].depth, expect[i]) << "k " << k << " pixel " << p;
        ASSERT_EQ(L.slots[p * size_t(k) + i].thickness(), 0.25f);
      }
    }
  }
}

TEST(SortTruncate, MinimumSeparationSkipsCloseFragments) {
  const FragmentLists lists = makeLists({{5.0f, 1.0f, 1.05f, 1.2f, 3.0f, 3.4f, 9.0f}});
  const LayerArrays L = sortAndTruncate(lists, LayerConfig{4, 0.1f, 0.5f});
  ASSERT_EQ(L.count[0], 4);
  const float expect[4] = {1.0f, 3.0f, 5.0f, 9.0f};  // 1.05, 1.2 within 0.5 of 1.0; 3.4 within 0.5 of 3.0
  for (int i = 0; i < 4; ++i) EXPECT_EQ(L.slots[size_t(i)].depth, expect[i]);
}

TEST(SortTruncate, AdaptiveThicknessMergesOverlappingFragments) {
  // Thickness 0.5, k = 3: 1.0, 1.3 and 1.7 chain into one interval [1.0, 2.2]; 3.0 and 3.2
  // into [3.0, 3.7]; 5.0 takes the last layer; 9.0 and 12.0 are dropped.
  const FragmentLists lists = makeLists({{9.0f, 1.3f, 3.2f, 1.0f, 5.0f, 1.7f, 3.0f, 12.0f}});
  LayerConfig c{3, 0.5f, 0.0f};
  c.adaptiveThickness = true;
  const LayerArrays L = sortAndTruncate(lists, c);
  ASSERT_EQ(L.count[0], 3);
  EXPECT_EQ(L.slots[0].depth, 1.0f);
  EXPECT_NEAR(L.slots[0].back(), 2.2f, 1e-6f);
  EXPECT_EQ(L.slots[1].depth, 3.0f);
  EXPECT_NEAR(L.slots[1].back(), 3.7f, 1e-6f);
  EXPECT_EQ(L.slots[2].depth, 5.0f);
  EXPECT_NEAR(L.slots[2].back(), 5.5f, 1e-6f);
  // Without merging the same k = 3 stops at 1.7.
  const LayerArrays plain = sortAndTruncate(lists, LayerConfig{3, 0.5f, 0.0f});
  EXPECT_EQ(plain.slots[2].depth, 1.7f);
}

TEST(SortTruncate, RejectsInvalidK) {
  const FragmentLists lists = makeLists({{1.0f}});
  EXPECT_THROW(sortAndTruncate(lists, LayerConfig{0, 0.1f, 0.0f}), InputError);
  EXPECT_THROW(sortAndTruncate(lists, LayerConfig{17, 0.1f, 0.0f}), InputError);
  EXPECT_THROW(sortAndTruncate(lists, LayerConfig{4, 0.0f, 0.0f}), InputError);
}

TEST(Rasterizer, OverflowIsCountedExactlyAndGrowingRecoversEverything) {
  Scene scene;  // 20 full-screen layers
  for (int i = 0; i < 20; ++i) {
    const float z = -2.0f - float(i);
    addTriangle(scene, {-100, -100, z}, {100, -100, z}, {0, 100, z});
  }
  scene.finalize("stack");
  const Camera cam(originCamera(), 64, 48);
  const FragmentLists full = rasterize(scene, cam);
  ASSERT_EQ(full.generated, 20u * 64u * 48u);
  ASSERT_EQ(full.lost(), 0u);

  RasterConfig small;
  small.poolCapacity = 20000;
  small.growOnOverflow = false;
  const FragmentLists cut = rasterize(scene, cam, small);
  EXPECT_EQ(cut.generated, full.generated);
  // Tiles claim the pool in chunks of 512, so up to one partly used chunk per tile (6 here) may
  // stay empty; what was not stored is counted as lost, exactly.
  EXPECT_LE(cut.stored, 20000u);
  EXPECT_GE(cut.stored, 20000u - 6u * 512u);
  uint64_t inLists = 0;
  for (uint32_t h : cut.head)
    for (uint32_t i = h; i != kNullIndex; i = cut.nodes[i].next) ++inLists;
  EXPECT_EQ(inLists, cut.stored);
  for (size_t p = 0; p < cut.complexity.size(); ++p) EXPECT_EQ(cut.complexity[p], 20u);  // counts include lost ones

  small.growOnOverflow = true;
  RasterStats stats;
  const FragmentLists grown = rasterize(scene, cam, small, &stats);
  EXPECT_EQ(grown.lost(), 0u);
  EXPECT_EQ(stats.passes, 2);
  EXPECT_EQ(stats.overflowLost, cut.lost());
}

}  // namespace
}  // namespace lt
