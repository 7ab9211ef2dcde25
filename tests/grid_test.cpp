// The irregular grid (Pérard-Gayot et al. 2017) against Embree: closest hits agree (same triangle,
// or the same distance within 1e-4 relative — two triangles sharing an edge or vertex the ray
// passes through), any-hit queries agree, and the structure keeps its invariants.
#include <atomic>
#include <bit>
#include <limits>
#include <random>
#include <span>

#include <glm/geometric.hpp>
#include <tbb/parallel_for.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/geometry/embree_scene.h"
#include "layertrace/grid/irregular_grid.h"
#include "layertrace/geometry/ray_triangle.h"
#include "layertrace/scene/load.h"
#include "layertrace/util/parallel.h"
#include "layertrace/scene/surface.h"
#include "test_util.h"

namespace lt {
namespace {

struct Agreement {
  size_t rays = 0, agree = 0;
  double fraction() const { return rays ? double(agree) / double(rays) : 1.0; }
};

/// Bit for bit: the same floats, not merely equal ones (−0 ≠ +0).
bool sameBits(glm::vec3 a, glm::vec3 b) {
  return std::bit_cast<uint32_t>(a.x) == std::bit_cast<uint32_t>(b.x) && std::bit_cast<uint32_t>(a.y) == std::bit_cast<uint32_t>(b.y) &&
         std::bit_cast<uint32_t>(a.z) == std::bit_cast<uint32_t>(b.z);
}
bool sameBits(const GeoHit& a, const GeoHit& b) {
  return a.triangle == b.triangle && std::bit_cast<uint32_t>(a.t) == std::bit_cast<uint32_t>(b.t) && sameBits(a.ng, b.ng);
}

bool sameHit(const GeoHit& a, const GeoHit& b) {
  if (a.hit() != b.hit()) return false;
  if (!a.hit()) return true;
  return a.triangle == b.triangle || std::abs(a.t - b.t) <= 1e-4f * std::max(a.t, b.t) + 1e-6f;
}

/// Primary rays from a camera, diffuse bounces from their hits, and AO rays (any-hit, short).
Agreement compareWithEmbree(const Scene& scene, const CameraDesc& cd, const IrregularGrid& grid, int W, int H, uint64_t seed) {
  const EmbreeScene embree(scene);
  const Camera cam(withClipPlanes(cd, scene), W, H);
  const float diag = scene.bounds().diagonal();
  std::vector<uint8_t> ok(size_t(W) * size_t(H) * 3, 1);
  parallelFor(0, H, [&](int y) {
    std::mt19937_64 rng(seed + uint64_t(y));
    std::normal_distribution<float> g;
    for (int x = 0; x < W; ++x) {
      const size_t k = (size_t(y) * size_t(W) + size_t(x)) * 3;
      const glm::vec3 o = cd.eye, d = glm::normalize(cam.dirToWorld(cam.rayThrough({x + 0.5f, y + 0.5f})));
      const GeoHit e = embree.intersect(o, d, 0.0f, 1e30f), gh = grid.intersect(o, d, 0.0f, 1e30f);
      ok[k] = sameHit(e, gh);
      if (!e.hit()) continue;
      const glm::vec3 p = o + d * e.t;
      glm::vec3 n = glm::normalize(e.ng);
      if (glm::dot(n, d) > 0.0f) n = -n;
      glm::vec3 r = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
      if (glm::dot(r, n) < 0.0f) r = -r;
      const float eps = 1e-4f * diag;
      ok[k + 1] = sameHit(embree.intersect(p, r, eps, 1e30f), grid.intersect(p, r, eps, 1e30f));
      ok[k + 2] = embree.occluded(p, r, eps, 0.05f * diag) == grid.occluded(p, r, eps, 0.05f * diag);
    }
  });
  Agreement a;
  a.rays = ok.size();
  for (uint8_t v : ok) a.agree += v;
  return a;
}

/// The traversal as first written (irregular_grid_traverse.cpp before the packed copies), one
/// reference at a time: over the builder's cells (56-byte GridCell), its reference lists and
/// triangles read from the scene, with the scalar watertight test. The packed traversal (cells
/// of 32 bytes, 4-lane triangle blocks) must answer exactly as this one.
GeoHit referenceTraverse(const IrregularGrid& g, const Scene& scene, glm::vec3 o, glm::vec3 d, float tnear, float tfar, bool anyHit) {
  GeoHit best;
  float t0 = tnear, t1 = tfar;
  const glm::vec3 inv = 1.0f / d, lo = g.origin(), hi = g.boxMax(), voxel = g.voxelSize(), invVoxel = g.inverseVoxelSize();
  for (int i = 0; i < 3; ++i) {
    float a = (lo[i] - o[i]) * inv[i], b = (hi[i] - o[i]) * inv[i];
    if (a > b) std::swap(a, b);
    if (!(a == a)) a = -std::numeric_limits<float>::infinity();
    if (!(b == b)) b = std::numeric_limits<float>::infinity();
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  if (t0 > t1) return best;
  int v[3];
  const glm::vec3 p = (o + d * t0 - lo) * invVoxel;
  for (int i = 0; i < 3; ++i) v[i] = std::clamp(int(std::floor(p[i])), 0, g.virtualResolution(i) - 1);
  float bestT = tfar;
  const WatertightRay ray(o, d);
  const int maxSteps = 4 * (g.virtualResolution(0) + g.virtualResolution(1) + g.virtualResolution(2)) + 16;
  for (int step = 0; step < maxSteps; ++step) {
    const GridCell& c = g.cells()[g.cellAt(v)];
    for (uint32_t r = c.refBegin; r < c.refEnd; ++r) {
      const uint32_t tri = g.refs()[r];
      const glm::uvec3 ix = scene.triangles[tri];
      float t;
      glm::vec3 w;
      if (hitTriangleWatertight(ray, scene.positions[ix.x], scene.positions[ix.y], scene.positions[ix.z], tnear, bestT, t, &w)) {
        const float sum = w.x + w.y + w.z;  // an alpha-tested triangle's hole lets the ray pass
        if (scene.cutOut(tri) && !surfacePresent(scene, tri, w.y / sum, w.z / sum)) continue;
        if (anyHit) {
          best.t = t, best.triangle = tri;
          return best;
        }
        if (t < bestT || (t == bestT && tri < best.triangle)) bestT = t, best.t = t, best.triangle = tri;
      }
    }
    float tExit = std::numeric_limits<float>::infinity();
    int axis = 0;
    for (int i = 0; i < 3; ++i) {
      if (d[i] == 0.0f) continue;
      const float bound = lo[i] + float(d[i] > 0.0f ? c.ehi[i] : c.elo[i]) * voxel[i];
      const float t = (bound - o[i]) * inv[i];
      if (t < tExit) tExit = t, axis = i;
    }
    if (best.hit() && bestT <= tExit) break;
    if (tExit >= t1) break;
    const glm::vec3 q = (o + d * tExit - lo) * invVoxel;
    for (int i = 0; i < 3; ++i) {
      if (i == axis) {
        v[i] = d[i] > 0.0f ? c.ehi[i] : c.elo[i] - 1;
        continue;
      }
      const int face = std::clamp(int(std::floor(q[i])), c.elo[i], c.ehi[i] - 1);
      v[i] = d[i] > 0.0f ? std::max(face, v[i]) : d[i] < 0.0f ? std::min(face, v[i]) : face;  // never backwards
    }
    if (v[axis] < 0 || v[axis] >= g.virtualResolution(axis)) break;
  }
  return best;
}

/// The batch queries (several rays in flight) answer every ray exactly as the one-ray traversal —
/// closest hits (t, triangle and normal, to the bit) and any hits — in batches shorter and
/// longer than the rays in flight; returns the number of differing answers. Every closest hit's
/// normal must also be the scene triangle's (v1 − v0) × (v2 − v0), to the bit.
size_t batchDifferences(const Scene& scene, const IrregularGrid& grid, const std::vector<IrregularGrid::Query>& q) {
  std::vector<GeoHit> one(q.size());
  std::vector<uint8_t> oneAny(q.size());
  for (size_t i = 0; i < q.size(); ++i) {
    one[i] = grid.intersect(q[i].origin, q[i].dir, q[i].tnear, q[i].tfar);
    oneAny[i] = grid.occluded(q[i].origin, q[i].dir, q[i].tnear, q[i].tfar);
  }
  size_t differ = 0;
  for (const GeoHit& h : one)
    if (h.hit()) {
      const glm::uvec3 ix = scene.triangles[h.triangle];
      differ += !sameBits(h.ng, glm::cross(scene.positions[ix.y] - scene.positions[ix.x], scene.positions[ix.z] - scene.positions[ix.x]));
    }
  test::forEachSimdTarget([&](const SimdTarget&) {
  for (size_t batch : {size_t(1), size_t(5), size_t(16), size_t(17), size_t(256), q.size()}) {
    for (size_t b = 0; b < q.size(); b += batch) {
      const size_t n = std::min(batch, q.size() - b);
      const std::span<const IrregularGrid::Query> chunk(&q[b], n);
      // The batch (vector lanes) and the portable batch, on every vector target.
      std::vector<GeoHit> hits(n), portable(n);
      std::vector<uint8_t> any(n, 7), portableAny(n, 7);
      grid.intersect(chunk, hits);
      grid.occluded(chunk, any);
      grid.intersectPortable(chunk, portable);
      grid.occludedPortable(chunk, portableAny);
      for (size_t i = 0; i < n; ++i)
        differ += !sameBits(hits[i], one[b + i]) + (any[i] != oneAny[b + i]) + !sameBits(portable[i], one[b + i]) +
                  (portableAny[i] != oneAny[b + i]);
    }
  }
  });
  return differ;
}

/// The default scene and its camera (loaded, not captured).
Frame defaultSceneFrame() {
  FrameOptions o;
  o.scenePath = test::sourceDir() + "/scenes/default.json";
  Frame f;
  loadFrameScene(o, f);
  return f;
}

/// Primary rays through a W × H view, and from each hit a random (diffuse) ray and a short (AO)
/// ray; `extra` adds queries at each hit.
template <class Extra>
std::vector<IrregularGrid::Query> primaryAndBounceQueries(const IrregularGrid& grid, const Frame& f, int W, int H, Extra&& extra) {
  const Camera cam(withClipPlanes(f.camera.desc(), f.scene), W, H);
  const float diag = f.scene.bounds().diagonal();
  std::mt19937_64 rng(test::testSeed());
  std::normal_distribution<float> g;
  std::vector<IrregularGrid::Query> q;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const glm::vec3 eye = f.camera.desc().eye, d = glm::normalize(cam.dirToWorld(cam.rayThrough({x + 0.5f, y + 0.5f})));
      q.push_back({eye, d, 0.0f, 1e30f});
      const GeoHit h = grid.intersect(eye, d, 0.0f, 1e30f);
      if (!h.hit()) continue;
      const glm::vec3 p = eye + d * h.t, r = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
      q.push_back({p, r, 1e-4f * diag, 1e30f});
      q.push_back({p, r, 1e-4f * diag, 0.05f * diag});
      extra(q, eye, d, h);
    }
  return q;
}

/// Calls f(a, A, v, B) for every voxel v of the expanded box of every `stride`-th cell A, B being
/// the cell that owns v.
template <class F>
void forEachExpandedVoxel(const IrregularGrid& grid, size_t stride, F&& f) {
  const auto& cells = grid.cells();
  for (size_t a = 0; a < cells.size(); a += stride) {
    const GridCell& A = cells[a];
    for (int z = A.elo[2]; z < A.ehi[2]; ++z)
      for (int y = A.elo[1]; y < A.ehi[1]; ++y)
        for (int x = A.elo[0]; x < A.ehi[0]; ++x) {
          const int v[3] = {x, y, z};
          f(a, A, v, cells[grid.cellAt(v)]);
        }
  }
}

/// The parallel merge builds exactly the cells, references and voxel map of the serial one.
void expectParallelMergeEqualsSerial(const Scene& scene) {
  GridConfig serial;
  serial.parallelMerge = false;
  const IrregularGrid a(scene), b(scene, serial);
  ASSERT_EQ(a.cells().size(), b.cells().size());
  ASSERT_GT(a.stats().cellsInitial, a.cells().size());  // merging did something
  EXPECT_EQ(a.refs(), b.refs());
  size_t differ = 0;
  for (size_t c = 0; c < a.cells().size(); ++c) {
    const GridCell &x = a.cells()[c], &y = b.cells()[c];
    for (int i = 0; i < 3; ++i) differ += x.lo[i] != y.lo[i] || x.hi[i] != y.hi[i] || x.elo[i] != y.elo[i] || x.ehi[i] != y.ehi[i];
    differ += x.refBegin != y.refBegin || x.refEnd != y.refEnd;
  }
  EXPECT_EQ(differ, 0u);
  std::mt19937_64 rng(test::testSeed());
  for (int k = 0; k < 100000; ++k) {
    const int v[3] = {int(rng() % uint64_t(a.virtualResolution(0))), int(rng() % uint64_t(a.virtualResolution(1))),
                      int(rng() % uint64_t(a.virtualResolution(2)))};
    ASSERT_EQ(a.cellAt(v), b.cellAt(v)) << v[0] << "," << v[1] << "," << v[2];
  }
}

TEST(Grid, TriangleBoxOverlapMatchesSampling) {
  std::mt19937_64 rng(test::testSeed());
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int overlaps = 0;
  for (int i = 0; i < 3000; ++i) {
    const glm::vec3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    const glm::vec3 lo(u(rng) * 0.5f - 0.25f, u(rng) * 0.5f - 0.25f, u(rng) * 0.5f - 0.25f), hi = lo + glm::vec3(0.3f);
    // A sample of the triangle inside the box proves overlap: the test must then say so.
    bool sampled = false;
    for (int s = 0; s < 400 && !sampled; ++s) {
      float x = std::abs(u(rng)), y = std::abs(u(rng));
      if (x + y > 1.0f) x = 1.0f - x, y = 1.0f - y;
      const glm::vec3 p = a + (b - a) * x + (c - a) * y;
      sampled = glm::all(glm::greaterThanEqual(p, lo)) && glm::all(glm::lessThanEqual(p, hi));
    }
    const bool test = triangleBoxOverlap(a, b, c, lo, hi, 0.0f);
    if (sampled) {
      ASSERT_TRUE(test) << "case " << i;
    }
    overlaps += test;
  }
  EXPECT_GT(overlaps, 100);
}

// A triangle lying exactly on the shared face of two thin boxes far from the origin (a flat
// scene's padded slab: 4e-4 wide at x = -1.146, split in the middle) overlaps at least one of
// them. Before the test widened boxes by the rounding of their centre, it rejected such a
// triangle from both sides and the grid missed it (assimp's concave_polygon.obj: 0.4 % of
// primary rays).
TEST(Grid, TriangleOnTheFaceOfTwoThinBoxesFarFromTheOriginOverlapsOne) {
  std::mt19937_64 rng(test::testSeed() + 5);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int rejectedByBoth = 0;
  for (int i = 0; i < 20000; ++i) {
    const float plane = u(rng) * 1000.0f, width = std::abs(plane) * std::exp2(-12.0f + 4.0f * u(rng)) + 1e-6f;
    const float lo = plane - width, hi = plane + width;  // the two boxes [lo, plane] and [plane, hi] on x
    const glm::vec3 a(plane, u(rng), u(rng)), b(plane, u(rng), u(rng)), c(plane, u(rng), u(rng));
    const glm::vec3 box0Lo(lo, -2.0f, -2.0f), box0Hi(plane, 2.0f, 2.0f), box1Lo(plane, -2.0f, -2.0f), box1Hi(hi, 2.0f, 2.0f);
    rejectedByBoth += !triangleBoxOverlap(a, b, c, box0Lo, box0Hi, 0.0f) && !triangleBoxOverlap(a, b, c, box1Lo, box1Hi, 0.0f);
  }
  EXPECT_EQ(rejectedByBoth, 0);
}

/// Flat polygons (fans in a plane x = c, like assimp's concave_polygon.obj at c = -1.146) seen
/// obliquely: the grid's box is a thin padded slab around the plane, split through it.
TEST(Grid, FlatScenesAwayFromTheOriginAgreeWithEmbree) {
  for (const float c : {-1.146f, 3.7f, -17.3f, 123.4f}) {
    Scene s;
    const glm::vec3 centre(c, 2.4f, 2.35f);
    for (int i = 0; i < 24; ++i) {
      const float a0 = float(i) * 0.2618f, a1 = float(i + 1) * 0.2618f, r0 = 0.5f + 0.25f * float(i % 3), r1 = 0.5f + 0.25f * float((i + 1) % 3);
      test::addTriangle(s, centre, centre + glm::vec3(0.0f, r0 * std::sin(a0), r0 * std::cos(a0)),
                        centre + glm::vec3(0.0f, r1 * std::sin(a1), r1 * std::cos(a1)));
    }
    s.finalize("flat fan");
    const IrregularGrid grid(s);
    CameraDesc cd;
    cd.eye = centre + glm::vec3(0.834f, 1.07f, 2.38f);
    cd.target = centre;
    const Agreement a = compareWithEmbree(s, cd, grid, 320, 180, test::testSeed());
    EXPECT_GE(a.fraction(), 0.99999) << "plane x = " << c << ": " << a.agree << " of " << a.rays;
  }
}

/// `boxes` random small boxes over `side` × 0.2 × `side` units: a flat scene.
Scene flatSlab(int boxes, float side, uint32_t seed) {
  Scene s;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int i = 0; i < boxes; ++i) {
    const glm::vec3 lo(side * u(rng), 0.2f * u(rng), side * u(rng));
    s.append(makeBox(lo, lo + glm::vec3(0.05f + 0.1f * u(rng))));
  }
  s.finalize("slab");
  return s;
}

/// A flat scene: the top cells are not cubes (one cell high), and each axis is subdivided to its own
/// depth (irregular_grid.h; Pérard-Gayot et al. 2017's cubic octree cut the short axis as finely as
/// the long ones). The leaves are then not cubic in voxels, there are fewer of them, and every
/// voxel still maps to the cell that contains it; the grid agrees with Embree.
TEST(Grid, FlatSlabIsSubdividedPerAxisAndAgreesWithEmbree) {
  const Scene s = flatSlab(3000, 20.0f, 5);
  GridConfig initial;  // the cells as subdivided, before merging
  initial.merge = false;
  const IrregularGrid grid(s, initial);
  const GridStats& st = grid.stats();
  ASSERT_EQ(st.top[1], 1);
  ASSERT_GT(st.depth, 0);
  size_t boxLeaves = 0;  // in voxels; a cubic octree's leaves are cubes of voxels
  for (const GridCell& c : grid.cells()) boxLeaves += c.hi[1] - c.lo[1] != c.hi[0] - c.lo[0];
  EXPECT_GT(boxLeaves, grid.cells().size() / 2) << "leaves as high as wide: the short axes were cut as finely as the long one";
  EXPECT_LT(st.cellsInitial, size_t(st.top[0]) * size_t(st.top[2]) << (3 * st.depth - 1));
  for (int z = 0; z < grid.virtualResolution(2); ++z)
    for (int y = 0; y < grid.virtualResolution(1); ++y)
      for (int x = 0; x < grid.virtualResolution(0); x += 5) {
        const int v[3] = {x, y, z};
        const GridCell& c = grid.cells()[grid.cellAt(v)];
        for (int i = 0; i < 3; ++i) ASSERT_TRUE(c.lo[i] <= v[i] && v[i] < c.hi[i]) << x << " " << y << " " << z;
      }
  CameraDesc cd;
  cd.eye = {-2.0f, 2.0f, -2.0f};
  cd.target = {10.0f, 0.0f, 10.0f};
  // The subdivided grid above (its build is deterministic: not built again), then the default one.
  const IrregularGrid merged(s, GridConfig{});
  for (const IrregularGrid* built : {&grid, &merged}) {
    const IrregularGrid& g = *built;
    const Agreement a = compareWithEmbree(s, cd, g, test::sanitized() ? 160 : 320, test::sanitized() ? 90 : 180, test::testSeed());
    EXPECT_GE(a.fraction(), 0.99999) << a.agree << " of " << a.rays;
  }
}

/// The paper's rule (--preset paper): one octree depth per top cell, from its longest side. On a
/// flat slab its leaves are cubes of voxels, there are more of them than with a depth per axis,
/// the depth is the per-axis build's deepest, and the answers are Embree's.
TEST(Grid, OneDepthPerCellCutsEveryAxisAlikeAndAgreesWithEmbree) {
  const Scene s = flatSlab(800, 10.0f, 6);
  GridConfig perAxis;
  perAxis.merge = false;
  GridConfig cubic = perAxis;
  cubic.oneDepthPerCell = true;
  const IrregularGrid a(s, perAxis), b(s, cubic);
  ASSERT_EQ(a.stats().top[1], 1);
  EXPECT_EQ(b.stats().depth, a.stats().depth);
  EXPECT_GT(b.stats().cellsInitial, a.stats().cellsInitial);
  for (const GridCell& c : b.cells()) {
    ASSERT_EQ(c.hi[0] - c.lo[0], c.hi[1] - c.lo[1]);
    ASSERT_EQ(c.hi[0] - c.lo[0], c.hi[2] - c.lo[2]);
  }
  CameraDesc cd;
  cd.eye = {-2.0f, 2.0f, -2.0f};
  cd.target = {5.0f, 0.0f, 5.0f};
  const Agreement agree = compareWithEmbree(s, cd, b, 160, 90, test::testSeed());
  EXPECT_GE(agree.fraction(), 0.99999) << agree.agree << " of " << agree.rays;
}

/// Embree's rule for the ray's start, tnear < t: a ray starting on a triangle (an eye or a
/// bounce origin lying on it) does not hit it there — in the grid, the watertight and the
/// Möller–Trumbore test as in Embree.
TEST(Grid, RayStartingOnATriangleDoesNotHitItAtTnear) {
  Scene s;
  test::addTriangle(s, {1, 1, 0}, {-1, 1, 0}, {0, -1, 0});
  s.finalize("one triangle");
  const IrregularGrid grid(s);
  const EmbreeScene embree(s, EmbreeScene::Mode::Fast);
  const glm::vec3 onIt(0.0f, 0.2f, 0.0f), v0(1, 1, 0), v1(-1, 1, 0), v2(0, -1, 0);
  for (const glm::vec3 d : {glm::vec3(0.95f, 0.095f, 0.28f), glm::vec3(0.0f, 0.0f, 1.0f), glm::vec3(0.3f, -0.2f, -0.9f)}) {
    const glm::vec3 dir = glm::normalize(d);
    EXPECT_FALSE(embree.intersect(onIt, dir, 0.0f, 1e30f).hit());
    EXPECT_FALSE(grid.intersect(onIt, dir, 0.0f, 1e30f).hit());
    EXPECT_FALSE(grid.occluded(onIt, dir, 0.0f, 1e30f));
    float t = -1.0f;
    EXPECT_FALSE(hitTriangleWatertight(WatertightRay(onIt, dir), v0, v1, v2, 0.0f, 1e30f, t));
    EXPECT_FALSE(hitTriangle(onIt, dir, v0, v1 - v0, v2 - v0, 0.0f, 1e30f, t));
    // From just behind the plane the same rays hit at a tiny positive distance (when they
    // cross it): the rule drops t = tnear only.
    const glm::vec3 behind = onIt - dir * 1e-3f;
    EXPECT_EQ(grid.intersect(behind, dir, 0.0f, 1e30f).hit(), embree.intersect(behind, dir, 0.0f, 1e30f).hit());
    EXPECT_TRUE(grid.intersect(behind, dir, 0.0f, 1e30f).hit());
  }
}

TEST(Grid, CellsPartitionTheVirtualGridAndExpansionKeepsSubsets) {
  const Frame f = defaultSceneFrame();
  GridConfig whole;  // the expansion of Pérard-Gayot et al. 2017 (partial expansion: the next test)
  whole.partialExpansion = false;
  const IrregularGrid grid(f.scene, whole);
  const auto& cells = grid.cells();
  EXPECT_LT(grid.stats().cellsAfterMerge, grid.stats().cellsInitial);  // merging did something
  EXPECT_GT(grid.stats().expandedFaces, 0u);
  // Every voxel maps to the cell whose box contains it.
  for (int z = 0; z < grid.virtualResolution(2); z += 3)
    for (int y = 0; y < grid.virtualResolution(1); y += 3)
      for (int x = 0; x < grid.virtualResolution(0); x += 3) {
        const int v[3] = {x, y, z};
        const GridCell& c = cells[grid.cellAt(v)];
        for (int i = 0; i < 3; ++i) ASSERT_TRUE(c.lo[i] <= v[i] && v[i] < c.hi[i]);
      }
  // Expansion: every voxel inside a cell's expanded box belongs to a cell whose references are
  // a subset of that cell's (the traversal-correctness condition of Pérard-Gayot et al. 2017).
  const auto& refs = grid.refs();
  forEachExpandedVoxel(grid, 7, [&](size_t, const GridCell& A, const int*, const GridCell& B) {
    ASSERT_TRUE(std::includes(refs.begin() + A.refBegin, refs.begin() + A.refEnd, refs.begin() + B.refBegin, refs.begin() + B.refEnd));
  });
}

// Partial expansion (the default): every primitive that overlaps a voxel of a cell's expanded
// box is referenced by that cell — what makes skipping the swept voxels safe.
TEST(Grid, PartialExpansionReferencesEveryPrimitiveOfTheSweptVoxels) {
  const Frame f = defaultSceneFrame();
  const IrregularGrid grid(f.scene);
  GridConfig whole;
  whole.partialExpansion = false;
  EXPECT_GT(grid.stats().expandedFaces, IrregularGrid(f.scene, whole).stats().expandedFaces);
  const auto& refs = grid.refs();
  size_t checked = 0;
  forEachExpandedVoxel(grid, 5, [&](size_t a, const GridCell& A, const int* v, const GridCell& B) {
    const glm::vec3 lo = grid.origin() + glm::vec3(float(v[0]), float(v[1]), float(v[2])) * grid.voxelSize(), hi = lo + grid.voxelSize();
    for (uint32_t r = B.refBegin; r < B.refEnd; ++r) {
      const glm::uvec3 t = f.scene.triangles[refs[r]];
      if (!triangleBoxOverlap(f.scene.positions[t.x], f.scene.positions[t.y], f.scene.positions[t.z], lo, hi, 0.0f)) continue;
      ++checked;
      ASSERT_TRUE(std::binary_search(refs.begin() + A.refBegin, refs.begin() + A.refEnd, refs[r]))
          << "cell " << a << " skips triangle " << refs[r] << " in voxel " << v[0] << "," << v[1] << "," << v[2];
    }
  });
  EXPECT_GT(checked, 1000u);
}

TEST(Grid, ParallelMergeEqualsSerialOnTheDefaultScene) {
  const Frame f = defaultSceneFrame();
  expectParallelMergeEqualsSerial(f.scene);
}

// The grid's batch queries (several rays in flight) against its one-ray traversal on
// the default scene — primary rays, diffuse and AO rays from their hits, and the odd ones: rays
// that miss the grid's box, start outside it, run along an axis (direction components of 0),
// have an empty range, or start on a triangle.
TEST(Grid, BatchQueriesAnswerAsOneRayOnTheDefaultScene) {
  const Frame f = defaultSceneFrame();
  const IrregularGrid grid(f.scene);
  const float diag = f.scene.bounds().diagonal();
  const glm::vec3 centre = (grid.origin() + grid.boxMax()) * 0.5f;
  size_t hits = 0;
  std::vector<IrregularGrid::Query> q =
      primaryAndBounceQueries(grid, f, 96, 64, [&](std::vector<IrregularGrid::Query>& out, glm::vec3 eye, glm::vec3 d, const GeoHit& h) {
        ++hits;
        out.push_back({eye + d * h.t, -d, h.t * 0.5f, 1e30f});  // back along the primary ray
        out.push_back({eye, d, h.t, h.t});                      // an empty range (tnear = tfar)
      });
  for (int axis = 0; axis < 3; ++axis)
    for (float sign : {-1.0f, 1.0f}) {
      glm::vec3 d(0.0f);
      d[axis] = sign;
      q.push_back({centre, d, 0.0f, 1e30f});                // along an axis
      q.push_back({centre - d * diag * 3.0f, d, 0.0f, 1e30f});  // from outside the box, into it
      q.push_back({centre + d * diag * 3.0f, d, 0.0f, 1e30f});  // outside, away from it
    }
  EXPECT_GT(hits, q.size() / 8);
  EXPECT_EQ(batchDifferences(f.scene, grid, q), 0u) << "of " << q.size() << " rays";
}

TEST(Grid, AgreesWithEmbreeOnTheDefaultScene) {
  const Frame f = defaultSceneFrame();
  for (int variant = 0; variant < 3; ++variant) {  // plain; merged + expanded; + partial expansion
    GridConfig gc;
    gc.merge = variant > 0;
    gc.expansionPasses = variant > 0 ? 3 : 0;
    gc.partialExpansion = variant == 2;
    const IrregularGrid grid(f.scene, gc);
    if (variant == 2) {
      GridConfig whole;
      whole.partialExpansion = false;
      EXPECT_GT(grid.stats().expandedFaces, IrregularGrid(f.scene, whole).stats().expandedFaces);
    }
    const Agreement a = compareWithEmbree(f.scene, f.camera.desc(), grid, 320, 180, test::testSeed());
    EXPECT_GE(a.fraction(), 0.9999) << "variant " << variant << ": " << a.agree << " of " << a.rays;
  }
}

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// The watertight test alone: from points inside a closed mesh, rays aimed at its vertices and
// at points of its edges must hit some triangle — no crack between triangles sharing an edge,
// without any epsilon; and on one triangle, a ray through it hits at the plane's distance, a ray
// beside it or beyond tmax does not.
TEST(Grid, WatertightTestLeavesNoCrackAtSharedEdges) {
  Scene s = makeSphere({0.1f, -0.2f, 0.3f}, 1.0f, 17);
  s.finalize("sphere");
  std::mt19937_64 rng(test::testSeed());
  std::uniform_real_distribution<float> u(-0.4f, 0.4f), w(0.0f, 1.0f);
  size_t rays = 0, missed = 0;
  for (const glm::uvec3& t : s.triangles) {
    const glm::vec3 a = s.positions[t.x], b = s.positions[t.y];
    const float f = w(rng);
    for (const glm::vec3& target : {a, b, a + (b - a) * f, a + (b - a) * 0.5f}) {
      const glm::vec3 from = glm::vec3(0.1f, -0.2f, 0.3f) + glm::vec3(u(rng), u(rng), u(rng));
      const glm::vec3 d = glm::normalize(target - from);
      const WatertightRay ray(from, d);
      bool any = false;
      for (const glm::uvec3& k : s.triangles) {
        float th;
        any |= hitTriangleWatertight(ray, s.positions[k.x], s.positions[k.y], s.positions[k.z], 0.0f, 1e30f, th);
      }
      ++rays;
      missed += !any;
    }
  }
  EXPECT_GT(rays, 1000u);
  EXPECT_EQ(missed, 0u) << "of " << rays << " rays";
  // A ray beside a triangle misses it; through its interior, it hits at the plane's distance.
  const WatertightRay r({0.25f, 0.25f, -1.0f}, {0.0f, 0.0f, 1.0f});
  float t = 0.0f;
  EXPECT_TRUE(hitTriangleWatertight(r, {0, 0, 2}, {1, 0, 2}, {0, 1, 2}, 0.0f, 10.0f, t));
  EXPECT_EQ(t, 3.0f);
  EXPECT_FALSE(hitTriangleWatertight(WatertightRay({0.75f, 0.75f, -1.0f}, {0, 0, 1}), {0, 0, 2}, {1, 0, 2}, {0, 1, 2}, 0.0f, 10.0f, t));
  EXPECT_FALSE(hitTriangleWatertight(r, {0, 0, 2}, {1, 0, 2}, {0, 1, 2}, 0.0f, 2.5f, t));  // beyond tmax
}

// Rays aimed exactly at vertices and edge midpoints of a closed mesh, arriving from outside
// roughly along the surface normal (so they truly enter it, not graze a silhouette): both
// tracers must report a hit at the same distance.
TEST(Grid, RaysThroughSharedEdgesAndVerticesAgreeWithEmbree) {
  Scene s = makeSphere({0, 0, 0}, 1.0f, 24);
  s.append(makeBox({-3, -3, -3}, {3, 3, 3}));
  s.finalize("sphere-in-box");
  const EmbreeScene embree(s);
  const IrregularGrid grid(s);
  std::mt19937_64 rng(test::testSeed());
  std::normal_distribution<float> g;
  size_t rays = 0, agree = 0;
  for (const glm::uvec3& t : s.triangles) {
    const glm::vec3 targets[2] = {s.positions[t.x], 0.5f * (s.positions[t.x] + s.positions[t.y])};
    for (const glm::vec3& target : targets) {
      if (glm::length(target) > 1.01f) continue;  // the sphere only (the box is seen from inside)
      const glm::vec3 from = target + glm::normalize(glm::normalize(target) + 0.3f * glm::vec3(g(rng), g(rng), g(rng))) * 1.2f;
      const glm::vec3 d = glm::normalize(target - from);
      const GeoHit a = embree.intersect(from, d, 0.0f, 100.0f), b = grid.intersect(from, d, 0.0f, 100.0f);
      ++rays;
      agree += sameHit(a, b);
      if (!sameHit(a, b) && rays - agree < 4)
        ADD_FAILURE() << "embree " << a.hit() << " t " << a.t << " grid " << b.hit() << " t " << b.t;
    }
  }
  EXPECT_GT(rays, 500u);
  EXPECT_GE(double(agree) / double(rays), 0.9999) << agree << " of " << rays;
}

class RealSceneGrid : public ::testing::TestWithParam<std::pair<const char*, const char*>> {};

/// The parameter's scene file and camera, loaded into f.
void loadParamScene(const std::pair<const char*, const char*>& scene, Frame& f) {
  loadFrameScene(test::realSceneOptions(scene.first, scene.second), f);
}

// Primary, diffuse-bounce and AO rays agree with Embree for ≥ 99.99 % of rays.
// The packed, dispatched traversal against the reference traversal, bit for bit: primary rays
// and random rays from their hits, closest and any hit.
TEST_P(RealSceneGrid, PackedTraversalEqualsReference) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  Frame f;
  loadParamScene(GetParam(), f);
  const IrregularGrid grid(f.scene);
  const Camera cam(withClipPlanes(f.camera.desc(), f.scene), 320, 180);
  const float diag = f.scene.bounds().diagonal();
  std::atomic<size_t> differ{0}, hits{0}, rays{0};
  parallelFor(0, 180, [&](int y) {
    std::mt19937_64 rng(test::testSeed() + uint64_t(y));
    std::normal_distribution<float> g;
    for (int x = 0; x < 320; ++x) {
      const glm::vec3 eye = f.camera.desc().eye, d = glm::normalize(cam.dirToWorld(cam.rayThrough({x + 0.5f, y + 0.5f})));
      auto same = [](const GeoHit& a, const GeoHit& b) {
        return a.triangle == b.triangle && (!a.hit() || std::bit_cast<uint32_t>(a.t) == std::bit_cast<uint32_t>(b.t));
      };
      const GeoHit a = grid.intersect(eye, d, 0.0f, 1e30f), b = referenceTraverse(grid, f.scene, eye, d, 0.0f, 1e30f, false);
      differ += !same(a, b);
      ++rays;
      if (!b.hit()) continue;
      ++hits;
      const glm::vec3 p = eye + d * b.t;
      const glm::vec3 r = glm::normalize(glm::vec3(g(rng), g(rng), g(rng)));
      const float eps = 1e-4f * diag;
      differ += !same(grid.intersect(p, r, eps, 1e30f), referenceTraverse(grid, f.scene, p, r, eps, 1e30f, false));
      differ += grid.occluded(p, r, eps, 0.05f * diag) != referenceTraverse(grid, f.scene, p, r, eps, 0.05f * diag, true).hit();
      rays += 2;
    }
  });
  EXPECT_GT(hits.load(), rays.load() / 6);
  EXPECT_EQ(differ.load(), 0u) << "of " << rays.load() << " rays";
}

// The batch queries (several rays in flight) answer as the one-ray traversal, bit for
// bit, on primary rays and diffuse and AO rays from their hits.
TEST_P(RealSceneGrid, BatchQueriesAnswerAsOneRay) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  Frame f;
  loadParamScene(GetParam(), f);
  const IrregularGrid grid(f.scene);
  const std::vector<IrregularGrid::Query> q = primaryAndBounceQueries(grid, f, 160, 90, [](auto&&...) {});
  EXPECT_EQ(batchDifferences(f.scene, grid, q), 0u) << "of " << q.size() << " rays";
}

// Rays aimed at the edges of the virtual grid (two coordinates on voxel planes, to the float)
// pass within rounding through the corners where cells' faces meet — where a ray's rounded
// exit from one cell can fall a hair before its entry into the next. Every such ray must end
// (no step cap: before the monotone step rule, two cells handed a ray on engine back and forth
// until the cap and it missed a triangle 52 units away) and agree with robust Embree. The batch
// queries (the vector lanes) must answer these rays as the one-ray
// traversal does: they take the same steps, with the same rule against stepping back.
TEST_P(RealSceneGrid, RaysThroughVoxelEdgesEndAndAgreeWithEmbree) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  Frame f;
  loadParamScene(GetParam(), f);
  const IrregularGrid grid(f.scene);
  const EmbreeScene embree(f.scene);
  const glm::vec3 lo = grid.origin(), voxel = grid.voxelSize();
  const int rows = 64, perRow = 4096;
  std::atomic<size_t> giveUps{0}, disagree{0}, hits{0};
  std::vector<IrregularGrid::Query> queries(size_t(rows) * perRow, IrregularGrid::Query{{}, {0.0f, 0.0f, 1.0f}, 1.0f, 0.0f});
  std::vector<GeoHit> one(queries.size());  // (an empty range [1, 0] for a skipped ray: a miss)
  parallelFor(0, rows, [&](int row) {
    std::mt19937_64 rng(test::testSeed() + uint64_t(row));
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int k = 0; k < perRow; ++k) {
      const int a = k % 3, b = (a + 1) % 3, c = (a + 2) % 3;  // a, b on voxel planes, c anywhere
      glm::vec3 target;
      target[a] = lo[a] + float(int(u(rng) * float(grid.virtualResolution(a)))) * voxel[a];
      target[b] = lo[b] + float(int(u(rng) * float(grid.virtualResolution(b)))) * voxel[b];
      target[c] = lo[c] + u(rng) * float(grid.virtualResolution(c)) * voxel[c];
      const glm::vec3 from = lo + glm::vec3(u(rng), u(rng), u(rng)) * (grid.boxMax() - lo);
      if (!(glm::length(target - from) > 0.0f)) continue;
      const glm::vec3 d = glm::normalize(target - from);
      TraversalCounts counts;
      const GeoHit g = grid.intersect(from, d, 0.0f, 1e30f, &counts), e = embree.intersect(from, d, 0.0f, 1e30f);
      const size_t i = size_t(row) * perRow + size_t(k);
      queries[i] = {from, d, 0.0f, 1e30f};
      one[i] = g;
      giveUps += counts.giveUps;
      hits += e.hit();
      disagree += !sameHit(g, e);
    }
  });
  const size_t rays = size_t(rows) * perRow;
  EXPECT_EQ(giveUps.load(), 0u) << "of " << rays << " rays";
  EXPECT_GT(hits.load(), rays / 4);
  EXPECT_LE(disagree.load(), rays / 100000) << "of " << rays << " rays";
  test::forEachSimdTarget([&](const SimdTarget&) {
    std::vector<GeoHit> batch(queries.size());
    grid.intersect(queries, batch);
    size_t differ = 0;
    for (size_t i = 0; i < queries.size(); ++i) differ += !sameBits(batch[i], one[i]);
    EXPECT_EQ(differ, 0u) << "batch answers differing from the one-ray traversal, of " << rays << " rays";
  });
}

TEST_P(RealSceneGrid, ParallelMergeEqualsSerial) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  Frame f;
  loadParamScene(GetParam(), f);
  expectParallelMergeEqualsSerial(f.scene);
}

TEST_P(RealSceneGrid, AgreesWithEmbree) {
  ASSERT_TRUE(test::haveFetchedScenes()) << "run scripts/fetch-scenes.sh";
  Frame f;
  loadParamScene(GetParam(), f);
  for (bool partial : {false, true}) {
    GridConfig gc;
    gc.partialExpansion = partial;
    const IrregularGrid grid(f.scene, gc);
    const Agreement a = compareWithEmbree(f.scene, f.camera.desc(), grid, 320, 180, test::testSeed());
    EXPECT_GE(a.fraction(), 0.9999) << "partial " << partial << ": " << a.agree << " of " << a.rays;
  }
}

INSTANTIATE_TEST_SUITE_P(Scenes, RealSceneGrid,
                         ::testing::Values(std::make_pair("fzk-haus.json", "interior"), std::make_pair("am-thornish.json", "hall"),
                                           std::make_pair("engine.json", "interior"), std::make_pair("bunny.json", "front")),
                         [](const auto& p) { return test::sceneCaseName(p.param.first); });

}  // namespace
}  // namespace lt

namespace lt {
namespace {

// Embree wants flush-to-zero and denormals-are-zero while it runs; the calling thread must get
// its own mode back, or the caller's arithmetic on tiny values (a scene scaled to 1e-20) flushes.
TEST(Embree, RestoresTheCallersFloatingPointMode) {
  Scene s = makeBox({-1, -1, -3}, {1, 1, -2});
  s.finalize("box");
  volatile float tiny = 1e-38f;
  ASSERT_NE(tiny * 1e-3f, 0.0f) << "denormals must work before the test";
  for (EmbreeScene::Mode mode : {EmbreeScene::Mode::Fast, EmbreeScene::Mode::Robust, EmbreeScene::Mode::Capture}) {
    const EmbreeScene e(s, mode);
    EXPECT_NE(tiny * 1e-3f, 0.0f) << "after the build";
    if (mode != EmbreeScene::Mode::Capture) {
      EXPECT_GT(e.intersect({0, 0, 0}, {0, 0, -1}, 0.0f, 100.0f).t, 0.0f);
      EXPECT_FALSE(e.occluded({0, 0, 0}, {0, 0, 1}, 0.0f, 100.0f));
    }
    EXPECT_NE(tiny * 1e-3f, 0.0f) << "after queries";
  }
}

}  // namespace
}  // namespace lt
