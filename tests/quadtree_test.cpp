// Widmer et al. 2015's plane/box quad-tree (quadtree/quadtree.h): ray–plane hits on flat surfaces are
// exact against Embree at odd sizes and in every octant, a flat floor compresses into few plane
// nodes, a depth step carries the discontinuity hint and an occlusion hit continues into the next
// layer, and on a real scene the quadtree agrees with the independent oracle wherever the oracle
// hits a surface that is flat around its pixel.
#include <random>

#include <glm/geometric.hpp>

#include "layertrace/eval/image_oracle.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/scene/load.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/util/error.h"
#include "test_util.h"

namespace lt {
namespace {

/// A floor and a ceiling tilted toward the camera at the origin: they rise with distance (seed
/// 002's planes are exact only if fitted in 1/depth; in linear depth they would not be planar).
Scene tiltedCorridor() {
  Scene s = makeQuad({-60, -2, 5}, {120, 0, 0}, {0, 30, -100});
  s.append(makeQuad({-60, 4, 5}, {0, 30, -100}, {120, 0, 0}));  // a parallel ceiling, facing down
  s.finalize("tilted-corridor");
  return s;
}

/// Pixels of `layer` under plane nodes of level `level` or coarser: a plane node's children are
/// all planes (Algorithm 2), so these are the level's plane nodes times their area.
size_t pixelsUnderPlanes(const Quadtree& t, int layer, int level) {
  size_t n = 0;
  for (int y = 0; y < t.levels[size_t(level)].height; ++y)
    for (int x = 0; x < t.levels[size_t(level)].width; ++x) n += t.node(layer, level, x, y).kind() == QuadNode::Plane;
  return n << (2 * level);
}

// Analytic planes — hits exact to 1e-4 relative, odd sizes, every octant; the
// floor compresses into few plane nodes.
TEST(Quadtree, HitsOnATiltedFloorAndCeilingAreExactInEveryOctantAtOddSizes) {
  const Scene scene = tiltedCorridor();
  for (auto [W, H] : {std::pair{64, 48}, std::pair{67, 45}, std::pair{131, 29}}) {
    SCOPED_TRACE(std::to_string(W) + "x" + std::to_string(H));
    const Frame f = test::frameOf(scene, test::originCamera(60.0f, 0.05f, 200.0f), W, H, 2, 0.1f);
    const BuiltTracer q = buildTracer("quadtree", f, TracerOptions{}), embree = buildReference(f);
    size_t covered = 0;
    for (uint8_t c : f.layers.count) covered += c > 0;
    ASSERT_GT(covered, size_t(W * H) / 2);
    // The flat floor merges into large plane nodes: all but its border in nodes of 4×4 pixels
    // or more (the border meets the sky and the image edge at odd sizes).
    EXPECT_GE(double(pixelsUnderPlanes(*q.quadtree, 0, 2)), 0.8 * double(covered));

    // Rays from free space between the planes (a random pixel, 20–90 % of the way to its
    // surface) in random directions; kept where Embree's hit lies inside the image.
    std::mt19937 rng{uint32_t(test::testSeed())};
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    size_t compared = 0, hits = 0, octant[8] = {};
    for (int i = 0; i < 20000 && compared < 3000; ++i) {
      const int x = int(u(rng) * float(W - 1)), y = int(u(rng) * float(H - 1));
      if (f.layers.countAt(x, y) == 0) continue;
      Ray ray;
      // Along the pixel centre's camera ray, where the stored depth is the surface's: a point off
      // the centre can lie at or under a grazing floor, whose depth changes many-fold across one
      // pixel near the horizon. (Every draw its own statement or in a braced list: the same rays
      // from every compiler.)
      const float along = 0.2f + 0.7f * u(rng);
      ray.origin = f.camera.rayThrough({float(x) + 0.5f, float(y) + 0.5f}) * (f.layers.pixel(x, y)[0].depth * along);
      ray.dir = glm::normalize(glm::vec3{u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f});
      ray.startsOnSurface = false;
      RayCounters c;
      const TraceHit truth = embree.tracer->trace(ray, c);
      int tx, ty;
      if (!truth.hit || !f.camera.pixelOf(truth.point, tx, ty) || -ray.origin.z < f.camera.near()) continue;
      // Only where the plane hit covers the whole pixel: the pixel and its eight neighbours are
      // sampled on it. (A pixel on the far rim holds the plane's end, and its plane node, the
      // method's own approximation, extends the plane across the whole pixel.)
      auto onPlane = [&](int px, int py) {
        return px >= 0 && py >= 0 && px < W && py < H && f.layers.countAt(px, py) > 0 &&
               f.layers.triangle[f.layers.pixelIndex(px, py) * size_t(f.layers.k)] / 2 == truth.triangle / 2;
      };
      bool covered9 = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) covered9 = covered9 && onPlane(tx + dx, ty + dy);
      if (!covered9) continue;
      ++compared;
      // Octant of the traversal: screen x and y steps (Algorithm 4) and whether depth grows.
      const ScreenSegment seg = makeScreenSegment(f.camera, ray);
      ++octant[(seg.p1.x > seg.p0.x) | (seg.p1.y > seg.p0.y) << 1 | (seg.k1 < seg.k0) << 2];
      const TraceHit h = q.tracer->trace(ray, c);
      if (!h.hit) continue;
      ++hits;
      // Relative to the ray's length, or to 1 % of the point's distance from the eye for rays
      // that start a hair above the floor (float coordinates carry ~1e-7 of the latter).
      const float scale = std::max(glm::length(truth.point - ray.origin), 0.01f * glm::length(truth.point));
      ASSERT_LE(glm::length(h.point - truth.point), 1e-4f * scale)
          << "ray " << i << " hit pixel " << h.x << "," << h.y << ", Embree's " << tx << "," << ty;
    }
    EXPECT_GT(compared, 1000u);
    EXPECT_GE(double(hits), 0.99 * double(compared)) << "rays that reach a plane inside the image must hit it";
    for (size_t o : octant) EXPECT_GT(o, 20u) << "every octant of directions is exercised";
  }
}

/// A near wall covering the left half of the view in front of a far wall.
Frame depthStepFrame(int k) {
  Scene s = makeQuad({-10, -10, -2}, {10, 0, 0}, {0, 20, 0});
  s.append(makeQuad({-50, -50, -4}, {100, 0, 0}, {0, 100, 0}));
  s.finalize("depth-step");
  return test::frameOf(s, test::originCamera(60.0f, 0.05f, 100.0f), 65, 49, k, 0.1f);
}

// A depth step — the discontinuity hint is set along it, a ray passing behind the
// near wall records an occlusion hit, and the next layer finds the hidden far wall.
TEST(Quadtree, DepthStepFlagsTheEdgeAndTheNextLayerFindsTheHiddenSurface) {
  const Frame f = depthStepFrame(4);
  const BuiltTracer q = buildTracer("quadtree", f, TracerOptions{}), embree = buildReference(f);
  const Quadtree& t = *q.quadtree;
  const int edge = f.camera.width() / 2;  // screen x = 0 projects to the centre column's edge
  for (int y = 5; y < f.camera.height() - 5; y += 7) {
    EXPECT_TRUE(t.node(0, 0, edge - 1, y).discontinuity() || t.node(0, 0, edge, y).discontinuity()) << "row " << y;
    EXPECT_FALSE(t.node(0, 0, 5, y).discontinuity()) << "row " << y;
    EXPECT_FALSE(t.node(0, 0, f.camera.width() - 5, y).discontinuity()) << "row " << y;
  }
  // From free space right of the step, between the walls' depths, leftward and deeper: it
  // passes behind the near wall and meets the far wall where only layer 1 stores it.
  Ray ray;
  ray.origin = {0.5f, 0.1f, -3.0f};
  ray.dir = glm::normalize(glm::vec3(-1.0f, 0.0f, -0.3f));
  ray.startsOnSurface = false;
  RayCounters c, unused;
  const TraceHit truth = embree.tracer->trace(ray, unused);
  ASSERT_TRUE(truth.hit);
  const TraceHit h = q.tracer->trace(ray, c);
  ASSERT_TRUE(h.hit);
  EXPECT_EQ(h.layer, 1);
  if (kCountersCompiled) {  // counters exist unless compiled out
    EXPECT_GE(c.occlusions, 1u);
  }
  EXPECT_LE(glm::length(h.point - truth.point), 1e-4f * glm::length(truth.point - ray.origin));
  // With one layer the hidden wall is not stored: an information miss, the occlusion still seen.
  const Frame one = depthStepFrame(1);
  const BuiltTracer q1 = buildTracer("quadtree", one, TracerOptions{});
  RayCounters c1;
  EXPECT_FALSE(q1.tracer->trace(ray, c1).hit);
  if (kCountersCompiled) {
    EXPECT_GE(c1.occlusions, 1u);
  }
}

// Where the independent oracle hits the true surface (Embree's triangle) and that
// surface is flat around its pixel (the pixel and its 8 neighbours store the same triangle in
// that layer and carry no discontinuity hint), the quadtree hits the same triangle. Elsewhere
// the two differ by design: the oracle hits z-thickness intervals (also where the ray only
// passes behind a surface), the quadtree intersects planes.
TEST(Quadtree, AgreesWithTheIndependentOracleOnFlatSurfaces) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 400, o.height = 225;
  const Frame f = buildFrame(o);
  const BuiltTracer q = buildTracer("quadtree", f, TracerOptions{}), embree = buildReference(f);
  const ImageSpaceOracle oracle(f.camera, f.layers);
  const std::vector<Ray> rays = test::sampleRays(f, 20000, test::testSeed(), false);
  const LayerArrays& L = f.layers;
  auto flatAround = [&](int x, int y, int layer) {
    const uint32_t tri = L.triangle[L.pixelIndex(x, y) * size_t(L.k) + size_t(layer)];
    if (q.quadtree->node(layer, 0, x, y).discontinuity()) return false;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int nx = x + dx, ny = y + dy;
        if (nx < 0 || ny < 0 || nx >= L.width || ny >= L.height || L.countAt(nx, ny) <= layer) return false;
        if (L.triangle[L.pixelIndex(nx, ny) * size_t(L.k) + size_t(layer)] != tri) return false;
      }
    return true;
  };
  size_t flat = 0, agree = 0;
  for (const Ray& ray : rays) {
    const OracleAnswer a = oracle.answer(ray);
    if (!a.hit.hit || a.ambiguous || !flatAround(a.hit.x, a.hit.y, a.hit.layer)) continue;
    RayCounters c;
    if (embree.tracer->trace(ray, c).triangle != a.hit.triangle) continue;
    ++flat;
    const TraceHit h = q.tracer->trace(ray, c);
    agree += h.hit && h.triangle == a.hit.triangle;
  }
  EXPECT_GT(flat, rays.size() / 8);
  EXPECT_GE(double(agree), 0.98 * double(flat)) << agree << " of " << flat;
  ::testing::Test::RecordProperty("flat_agreement", std::to_string(double(agree) / double(flat)));
}

// The paper's rules (--preset paper), each against the default on the same rays.

// Algorithm 3 from the root: mostly the pixel start's hits, for more node visits. Not all of them:
// from the root the walk also meets the coarse nodes over the origin pixel, whose proxy planes
// and occlusion volumes can end a layer earlier (3.4 % of these rays answer differently).
TEST(Quadtree, RootStartFindsThePixelStartsHitsWithMoreVisits) {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  o.width = 240, o.height = 136;
  const Frame f = buildFrame(o);
  const std::vector<Ray> rays = test::sampleRays(f, 12000, test::testSeed() + 61);
  TracerOptions root;
  root.quadtree.rootStart = true;
  const BuiltTracer a = buildTracer("quadtree", f, TracerOptions{}), b = buildTracer("quadtree", f, root);
  size_t same = 0, hits = 0;
  uint64_t visitsA = 0, visitsB = 0;
  for (const Ray& r : rays) {
    RayCounters ca, cb;
    const TraceHit ha = a.tracer->trace(r, ca), hb = b.tracer->trace(r, cb);
    hits += ha.hit;
    same += ha.hit == hb.hit && (!ha.hit || (ha.x == hb.x && ha.y == hb.y && ha.layer == hb.layer));
    visitsA += ca.iterations, visitsB += cb.iterations;
  }
  EXPECT_GT(hits, rays.size() / 4);
  EXPECT_GE(double(same), 0.95 * double(rays.size()));
  EXPECT_LT(same, rays.size()) << "the rule must change something, or the option does not reach the walk";
  if (kCountersCompiled) {
    EXPECT_GT(visitsB, visitsA + rays.size()) << "a root start descends: at least one more visit per ray on average";
  }
}

// Algorithm 1 line 10 as printed, step(λ_h, |d|)·d: a leaf keeps only the derivatives at or above
// λ_h. The tilted floor's w slopes are small, so its leaves become fronto-parallel (b = c = 0)
// where the default keeps the slopes.
TEST(Quadtree, PrintedLine10ZeroesTheSmallDerivatives) {
  const Frame f = test::frameOf(tiltedCorridor(), test::originCamera(60.0f, 0.05f, 200.0f), 96, 64, 2, 0.1f);
  QuadtreeConfig printed;
  printed.printedLine10 = true;
  const Quadtree def = buildQuadtree(f.layers, f.camera, QuadtreeConfig{}), pr = buildQuadtree(f.layers, f.camera, printed);
  size_t sloped = 0, small = 0, planes = 0;
  for (int y = 0; y < f.camera.height(); ++y)
    for (int x = 0; x < f.camera.width(); ++x) {
      const QuadNode& d = def.node(0, 0, x, y);
      const QuadNode& p = pr.node(0, 0, x, y);
      if (d.kind() != QuadNode::Plane) continue;
      ++planes;
      sloped += d.c != 0.0f;
      for (float g : {p.b, p.c}) small += g != 0.0f && std::abs(g) < printed.lambdaH;
    }
  ASSERT_GT(planes, size_t(f.camera.width() * f.camera.height()) / 2);
  EXPECT_GT(sloped, planes / 2) << "the default keeps the floor's small w slopes";
  EXPECT_EQ(small, 0u) << "as printed, no derivative below lambda-h survives";
}

// Algorithm 1 line 8 as printed, mix(df, db, abs(df) < abs(db)), takes the one-sided derivative
// of larger magnitude; the default the smaller. With line 10 keeping every derivative, each
// printed slope is at least the default's in magnitude, and larger where a pixel's two
// neighbours disagree (at the default scene's silhouettes and corners).
TEST(Quadtree, PrintedLine8TakesTheLargerDerivative) {
  const Frame f = buildFrame(test::defaultSceneOptions(96, 64));
  QuadtreeConfig smaller;
  smaller.lambdaH = 1e30f;  // line 10 zeroes nothing
  QuadtreeConfig larger = smaller;
  larger.printedLine8 = true;
  const Quadtree a = buildQuadtree(f.layers, f.camera, smaller), b = buildQuadtree(f.layers, f.camera, larger);
  size_t planes = 0, steeper = 0, flatter = 0;
  for (int y = 0; y < f.camera.height(); ++y)
    for (int x = 0; x < f.camera.width(); ++x) {
      const QuadNode& s = a.node(0, 0, x, y);
      const QuadNode& l = b.node(0, 0, x, y);
      if (s.kind() != QuadNode::Plane) continue;
      ++planes;
      for (int axis = 0; axis < 2; ++axis) {
        const float gs = std::abs(axis == 0 ? s.b : s.c), gl = std::abs(axis == 0 ? l.b : l.c);
        flatter += gl < gs;
        steeper += gl > gs * 1.5f;
      }
    }
  ASSERT_GT(planes, size_t(f.camera.width() * f.camera.height()) / 2);
  EXPECT_EQ(flatter, 0u);
  EXPECT_GT(steeper, planes / 50) << "the silhouettes and corners have neighbours that disagree";
}

// The pseudo-code reports a plane crossed from behind as an occlusion, not a hit. Rays from under
// the tilted floor going up cross it from behind: the default hits it (Embree does too), the
// paper's rule never does.
TEST(Quadtree, BackfaceHitsOffNeverHitsAPlaneCrossedFromBehind) {
  const Frame f = test::frameOf(tiltedCorridor(), test::originCamera(60.0f, 0.05f, 200.0f), 96, 64, 2, 0.1f);
  TracerOptions paper;
  paper.quadtree.backfaceHits = false;
  const BuiltTracer on = buildTracer("quadtree", f, TracerOptions{}), off = buildTracer("quadtree", f, paper);
  std::mt19937 rng{uint32_t(test::testSeed() + 62)};
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  size_t rays = 0, floorOn = 0, floorOff = 0;
  for (int y = f.camera.height() / 2 + 4; y < f.camera.height(); y += 2)
    for (int x = 8; x < f.camera.width() - 8; x += 3) {
      if (f.layers.countAt(x, y) == 0 || f.layers.triangle[f.layers.pixelIndex(x, y) * size_t(f.layers.k)] / 2 != 0) continue;
      Ray r;
      // Just under the floor on the pixel's camera ray, going up and a little sideways.
      r.origin = f.camera.rayThrough({float(x) + 0.5f, float(y) + 0.5f}) * (f.layers.pixel(x, y)[0].depth * 1.3f);
      r.dir = glm::normalize(glm::vec3{0.3f * (u(rng) - 0.5f), 1.0f, -0.3f * u(rng)});
      r.startsOnSurface = false;
      ++rays;
      RayCounters c;
      const TraceHit a = on.tracer->trace(r, c), b = off.tracer->trace(r, c);
      floorOn += a.hit && a.triangle / 2 == 0;
      floorOff += b.hit && b.triangle / 2 == 0;
    }
  ASSERT_GT(rays, 100u);
  EXPECT_GE(double(floorOn), 0.9 * double(rays));
  EXPECT_EQ(floorOff, 0u);
}

TEST(Quadtree, RejectsNegativeThresholdsNamingTheOption) {
  QuadtreeConfig c;
  c.gammaDist = -1.0f;
  try {
    validateQuadtreeConfig(c);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("--quadtree-gamma-dist"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lt
