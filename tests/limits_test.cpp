// Limits at scale. Every large structure states its size before it allocates and
// is refused with one line naming it when that would break --max-memory; sizes parse with
// units; the grid builds on scenes of degenerate extent (flat, tiny and far from the origin,
// huge) and answers as Embree does there.
#include <glm/geometric.hpp>

#include "layertrace/geometry/embree_scene.h"
#include "layertrace/grid/irregular_grid.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/raster/raster_setup.h"
#include "layertrace/raster/rasterizer.h"
#include "layertrace/scene/load.h"
#include "layertrace/quadtree/quadtree.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"
#include "layertrace/hybrid/known_space.h"
#include "test_util.h"

namespace lt {
namespace {

/// Sets --max-memory for one scope.
struct MemoryLimit {
  explicit MemoryLimit(uint64_t bytes) { setMemoryLimit(bytes); }
  ~MemoryLimit() { setMemoryLimit(0); }
};

TEST(Limits, ByteSizesParseWithBinaryUnits) {
  EXPECT_EQ(parseByteSize("--max-memory", "65536"), 65536u);
  EXPECT_EQ(parseByteSize("--max-memory", "512M"), 512ull << 20);
  EXPECT_EQ(parseByteSize("--max-memory", "2G"), 2ull << 30);
  EXPECT_EQ(parseByteSize("--max-memory", "1.5GiB"), 3ull << 29);
  EXPECT_EQ(parseByteSize("--max-memory", "4kb"), 4096u);
  for (const char* bad : {"", "abc", "0", "-1G", "12Q", "1e30T", "nan"}) {
    try {
      parseByteSize("--max-memory", bad);
      ADD_FAILURE() << "accepted " << bad;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("--max-memory"), std::string::npos) << e.what();
    }
  }
}

/// Expects `build` to throw an InputError that names `what` and the limit.
template <class F>
void expectRefused(const char* what, F&& build) {
  try {
    build();
    ADD_FAILURE() << what << " was built past the limit";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find(what), std::string::npos) << m;
    EXPECT_NE(m.find("--max-memory"), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
}

// Every structure checks before it allocates: with a limit just above what the process holds,
// each is refused by name; without the limit each builds.
TEST(Limits, EveryStructureIsRefusedByNameBeforeItAllocates) {
  Scene scene = makeSphere({0, 0, -6}, 2.0f, 256);  // 65 000 triangles
  scene.append(makeBox({-8, -3, -12}, {8, 6, 1}));
  scene.finalize("limits");
  const Frame f = test::frameOf(scene, test::originCamera(), 640, 480, 4, 0.05f);
  ASSERT_GT(scene.triangleCount(), 50000u);
  const FragmentLists lists = rasterize(f.scene, f.camera);
  {
    const MemoryLimit limit(residentBytes() + (1u << 20));
    expectRefused("rasterizer's vertices and triangles", [&] { rasterize(f.scene, f.camera); });
    expectRefused("k-layer arrays", [&] { sortAndTruncate(lists, LayerConfig{}); });
    expectRefused("interval", [&] { buildIntervalPyramid(f.layers, f.camera, PyramidConfig{}); });
    expectRefused("quad-tree", [&] { buildQuadtree(f.layers, f.camera, QuadtreeConfig{}); });
    expectRefused("Embree BVH", [&] { EmbreeScene e(f.scene, EmbreeScene::Mode::Fast); });
    expectRefused("irregular grid", [&] { IrregularGrid g(f.scene); });
    expectRefused("unsampled depths", [&] { buildTracer("hybrid", f, TracerOptions{}); });  // its first structure
    expectRefused("solid intervals", [&] { solidIntervals(f.camera, CaptureCoverage{f.layers, f.lists.complexity}, 20.0f); });
    expectRefused("layered depth cube", [&] { buildLdc(f.scene, LdcConfig{}); });
  }
  {
    // Past the rasterizer's setup, its fragment pool is the next refused.
    const uint64_t setup = uint64_t(scene.positions.size()) * (sizeof(glm::vec4) + 2 * sizeof(glm::vec3)) +
                           uint64_t(scene.triangles.size()) * sizeof(raster::TriangleSetup);
    const MemoryLimit limit(residentBytes() + setup + (1u << 20));
    expectRefused("fragment pool", [&] { rasterize(f.scene, f.camera); });
    // The grid's top level (a huge λ1; it took 4 GB under a 2 GB limit before it was checked).
    GridConfig dense;
    dense.lambda1 = 1e9f;
    expectRefused("irregular grid's top level", [&] { IrregularGrid g(f.scene, dense); });
  }
  EXPECT_NO_THROW(IrregularGrid g(f.scene));
  EXPECT_NO_THROW(buildTracer("hybrid", f, TracerOptions{}));
}

// A scene a micrometre across, framed by the automatic camera: the default near plane and the
// geometric tracers' origin offset scale with it (an absolute floor of 1e-4 clipped the whole
// scene away, and skipped it as the rays' offset).
TEST(Limits, ASceneAMicrometreAcrossIsCapturedAndTraced) {
  Scene s = makeBox({0, 0, 0}, {1e-6f, 1e-6f, 1e-6f});
  s.append(makeSphere({3e-6f, 0, 0}, 1e-6f, 16));
  s.finalize("tiny");
  const Frame f = test::frameOf(s, withClipPlanes(autoCamera(s), s), 96, 64, 4, 1e-8f);
  EXPECT_GT(f.layers.countAt(48, 32), 0) << "the centre pixel sees the scene";
  const BuiltTracer embree = buildTracer("embree", f, TracerOptions{});
  const std::vector<Ray> rays = test::sampleRays(f, 2000, test::testSeed());
  ASSERT_GT(rays.size(), 500u);
  size_t hits = 0;
  for (const Ray& r : rays) {
    RayCounters c;
    hits += embree.tracer->trace(r, c).hit;
  }
  EXPECT_GT(hits, rays.size() / 10);
}

/// Mirror-ish rays from random points above a scene toward it; the grid must answer as Embree.
void expectGridAgreesWithEmbree(const Scene& scene, glm::vec3 eye, glm::vec3 target, float spreadFraction) {
  const IrregularGrid grid(scene);
  const EmbreeScene embree(scene, EmbreeScene::Mode::Robust);
  std::mt19937 rng{uint32_t(test::testSeed())};
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const float spread = spreadFraction * glm::length(target - eye);
  size_t hits = 0, same = 0, n = 2000;
  for (size_t i = 0; i < n; ++i) {
    const glm::vec3 aim = target + spread * glm::vec3(u(rng), u(rng), u(rng)) * glm::vec3(1.0f, 1.0f, 0.0f);
    const glm::vec3 d = glm::normalize(aim - eye);
    const GeoHit a = grid.intersect(eye, d, 0.0f, 1e30f), b = embree.intersect(eye, d, 0.0f, 1e30f);
    hits += b.hit();
    same += a.hit() == b.hit() && (!a.hit() || a.triangle == b.triangle || std::abs(a.t - b.t) <= 1e-4f * b.t);
  }
  EXPECT_GT(hits, n / 4) << "too few hits for the comparison to mean anything";
  EXPECT_GE(double(same), 0.999 * double(n));
}

// Degenerate extents never divide by zero: a flat scene (zero extent in z), a tiny scene a
// million units from the origin (its size vanishes next to its coordinates in float), and a
// huge one.
TEST(Limits, GridBuildsOnFlatTinyFarAndHugeScenes) {
  {
    // Flat in z at z = -1e6: 1e-4 of the extent (20) is below the float spacing there (0.0625),
    // so a padding relative to the extent alone leaves the box zero-thick.
    SCOPED_TRACE("flat and far");
    Scene s = makeQuad({-10, -10, -1e6f}, {20, 0, 0}, {0, 20, 0});
    s.append(makeQuad({-2, -2, -1e6f}, {1, 0, 0}, {0, 1, 0}));
    s.finalize("flat");
    expectGridAgreesWithEmbree(s, {0.3f, 0.2f, -1e6f + 10.0f}, {0, 0, -1e6f}, 0.5f);
  }
  {
    SCOPED_TRACE("tiny and far");
    const glm::vec3 c(1e6f, -1e6f, 1e6f);
    Scene s = makeBox(c, c + glm::vec3(0.5f));
    s.finalize("tiny-far");
    expectGridAgreesWithEmbree(s, c + glm::vec3(0.25f, 0.2f, 3.0f), c + glm::vec3(0.25f), 0.1f);
  }
  {
    SCOPED_TRACE("huge");
    Scene s = makeSphere({0, 0, 0}, 1e12f, 32);
    s.finalize("huge");
    expectGridAgreesWithEmbree(s, {1e11f, 2e11f, 5e12f}, {0, 0, 0}, 0.1f);
  }
}

// ≥ 10 M triangles. A height field of 2238² vertices (10.0 M triangles) builds into
// a grid (coarse densities keep the build to seconds) whose references cover every triangle,
// with no 32-bit index wrapping, and rays straight down hit the analytically expected triangle.
// With a memory limit the same build is refused with one line instead. Release only (the
// "AtScale" tests are labelled like the real-scene ones).
TEST(Limits, GridAtScaleOfTenMillionTriangles) {
  constexpr int n = 2238;
  auto height = [](float x, float z) { return 0.25f * std::sin(0.05f * x) * std::cos(0.07f * z); };
  Scene s;
  s.positions.resize(size_t(n) * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) s.positions[size_t(i) * n + size_t(j)] = {float(j), height(float(j), float(i)), float(i)};
  s.triangles.reserve(size_t(2) * (n - 1) * (n - 1));
  for (int i = 0; i + 1 < n; ++i)
    for (int j = 0; j + 1 < n; ++j) {
      const uint32_t a = uint32_t(i * n + j), b = a + 1, c = a + uint32_t(n), d = c + 1;
      s.triangles.push_back({a, c, b});  // triangle 2q: the half with x − j + z − i < 1
      s.triangles.push_back({b, c, d});
    }
  s.finalize("height-field");
  ASSERT_GE(s.triangleCount(), 10'000'000u);
  GridConfig config;
  config.lambda1 = 0.01f, config.lambda2 = 0.5f, config.maxDepth = 2, config.expansionPasses = 1;
  {
    const MemoryLimit limit(residentBytes() + (8u << 20));
    expectRefused("irregular grid", [&] { IrregularGrid g(s, config); });
  }
  const IrregularGrid grid(s, config);
  EXPECT_GE(grid.stats().refs, s.triangleCount());
  std::mt19937 rng{uint32_t(test::testSeed())};
  std::uniform_real_distribution<float> u(0.0f, float(n - 1));
  for (int k = 0; k < 500; ++k) {
    const float x = u(rng), z = u(rng);
    const GeoHit h = grid.intersect({x, 10.0f, z}, {0.0f, -1.0f, 0.0f}, 0.0f, 100.0f);
    ASSERT_TRUE(h.hit()) << x << "," << z;
    const int j = std::min(int(x), n - 2), i = std::min(int(z), n - 2);
    const uint32_t quad = uint32_t(i * (n - 1) + j), expected = 2 * quad + ((x - float(j)) + (z - float(i)) < 1.0f ? 0u : 1u);
    const bool onDiagonal = std::abs((x - float(j)) + (z - float(i)) - 1.0f) < 1e-3f;
    if (!onDiagonal) {
      EXPECT_EQ(h.triangle, expected) << x << "," << z;
    }
    EXPECT_NEAR(10.0f - h.t, height(x, z), 0.01f);  // the piecewise-linear surface is within 0.01 of it
  }
}

}  // namespace
}  // namespace lt

