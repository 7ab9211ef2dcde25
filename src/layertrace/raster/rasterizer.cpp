#include "layertrace/raster/rasterizer.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

namespace lt {
namespace {

constexpr int64_t kSub = 256;        // 8 sub-pixel bits
constexpr float kGuardBand = 4.0f;   // clip x, y to ±4 w: keeps fixed-point products far below 2^63
constexpr uint32_t kAllocChunk = 512;  // pool nodes a tile claims at once

/// A triangle after clipping, in fixed-point pixel coordinates, with E > 0 inside.
struct SubTriangle {
  int64_t x[3], y[3];
  uint32_t triangle;
  int px0, py0, px1, py1;  // inclusive pixel bounds (clamped to the screen)
};

/// Per scene triangle, camera space: what a fragment needs to evaluate depth and attributes
/// where the pixel-centre ray meets the triangle's plane.
struct TriangleSetup {
  glm::vec3 v0, e1, e2;
  glm::vec3 planeNormal;
  float planeOffset;  // dot(planeNormal, v0)
  float d00, d01, d11, invDen;
};

// Clip planes in homogeneous clip space as dot(plane, v) >= 0.
const glm::vec4 kPlanes[6] = {
    {0, 0, 1, 1},            // near: z >= -w
    {0, 0, -1, 1},           // far:  z <= w
    {1, 0, 0, kGuardBand},  {-1, 0, 0, kGuardBand},  // guard band in x
    {0, 1, 0, kGuardBand},  {0, -1, 0, kGuardBand},  // guard band in y
};

bool lexLess(const glm::vec4& a, const glm::vec4& b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  if (a.z != b.z) return a.z < b.z;
  return a.w < b.w;
}

/// Sutherland–Hodgman against one plane. The intersection of an edge is computed from its
/// lexicographically smaller endpoint, so the two triangles sharing an edge get bit-identical
/// clipped vertices — clipping keeps the mesh watertight.
int clipAgainst(const glm::vec4* in, int n, const glm::vec4& plane, glm::vec4* out) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const glm::vec4& a = in[i];
    const glm::vec4& b = in[(i + 1) % n];
    const float da = glm::dot(plane, a), db = glm::dot(plane, b);
    if (da >= 0.0f) out[m++] = a;
    if ((da >= 0.0f) != (db >= 0.0f)) {
      const bool aFirst = lexLess(a, b);
      const glm::vec4& p = aFirst ? a : b;
      const glm::vec4& q = aFirst ? b : a;
      const float dp = aFirst ? da : db, dq = aFirst ? db : da;
      const float t = dp / (dp - dq);
      out[m++] = p + (q - p) * t;
    }
  }
  return m;
}

/// Fixed-point edge function of edge a→b at p: positive on the inside of a triangle with
/// positive area (screen y points down).
inline int64_t edge(int64_t ax, int64_t ay, int64_t bx, int64_t by, int64_t px, int64_t py) {
  return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

/// Top-left rule for y-down screens with E > 0 inside: a top edge runs horizontally to the
/// right, a left edge runs upwards. Pixels exactly on such edges are covered.
inline bool isTopLeft(int64_t dx, int64_t dy) { return (dy == 0 && dx > 0) || dy < 0; }

void setupTriangle(const Scene& scene, const Camera& camera, const std::vector<glm::vec4>& clip, uint32_t t,
                   std::vector<SubTriangle>& out) {
  const glm::uvec3 idx = scene.triangles[t];
  glm::vec4 poly[12], tmp[12];
  int n = 3;
  bool inside = true;
  for (int k = 0; k < 3; ++k) poly[k] = clip[idx[k]];
  for (const glm::vec4& plane : kPlanes) {
    const float d0 = glm::dot(plane, poly[0]), d1 = glm::dot(plane, poly[1]), d2 = glm::dot(plane, poly[2]);
    if (d0 < 0.0f && d1 < 0.0f && d2 < 0.0f) return;  // trivially outside
    inside = inside && d0 >= 0.0f && d1 >= 0.0f && d2 >= 0.0f;
  }
  if (!inside) {
    for (const glm::vec4& plane : kPlanes) {
      n = clipAgainst(poly, n, plane, tmp);
      if (n < 3) return;
      std::copy(tmp, tmp + n, poly);
    }
  }
  const float W = float(camera.width()), H = float(camera.height());
  int64_t fx[12], fy[12];
  for (int k = 0; k < n; ++k) {
    const float iw = 1.0f / poly[k].w;
    const float sx = (poly[k].x * iw * 0.5f + 0.5f) * W;
    const float sy = (0.5f - poly[k].y * iw * 0.5f) * H;
    fx[k] = std::llround(double(sx) * double(kSub));
    fy[k] = std::llround(double(sy) * double(kSub));
  }
  for (int k = 1; k + 1 < n; ++k) {  // fan
    SubTriangle s;
    int a = 0, b = k, c = k + 1;
    const int64_t area = edge(fx[a], fy[a], fx[b], fy[b], fx[c], fy[c]);
    if (area == 0) continue;
    if (area < 0) std::swap(b, c);
    s.x[0] = fx[a], s.y[0] = fy[a], s.x[1] = fx[b], s.y[1] = fy[b], s.x[2] = fx[c], s.y[2] = fy[c];
    const int64_t minx = std::min({s.x[0], s.x[1], s.x[2]}), maxx = std::max({s.x[0], s.x[1], s.x[2]});
    const int64_t miny = std::min({s.y[0], s.y[1], s.y[2]}), maxy = std::max({s.y[0], s.y[1], s.y[2]});
    // Pixel centres at i*256 + 128 inside [min, max].
    auto first = [](int64_t v) { return (v - kSub / 2 + kSub - 1 >= 0) ? (v - kSub / 2 + kSub - 1) / kSub : -((kSub / 2 - v) / kSub); };
    auto last = [](int64_t v) { return (v - kSub / 2 >= 0) ? (v - kSub / 2) / kSub : -((kSub / 2 - v + kSub - 1) / kSub); };
    s.px0 = int(std::max<int64_t>(first(minx), 0));
    s.py0 = int(std::max<int64_t>(first(miny), 0));
    s.px1 = int(std::min<int64_t>(last(maxx), camera.width() - 1));
    s.py1 = int(std::min<int64_t>(last(maxy), camera.height() - 1));
    if (s.px0 > s.px1 || s.py0 > s.py1) continue;
    s.triangle = t;
    out.push_back(s);
  }
}

struct TileAllocator {
  uint32_t next = 0, end = 0;
};

struct RasterPass {
  const Scene& scene;
  const Camera& camera;
  const std::vector<SubTriangle>& subs;
  const std::vector<uint32_t>& tileStart;  // flat list offsets per tile
  const std::vector<uint32_t>& tileList;
  const std::vector<TriangleSetup>& setups;
  const std::vector<glm::vec3>& camNormals;
  const std::vector<uint32_t>& materialPacked;
  int tileSize, tilesX;

  uint64_t run(FragmentLists& lists) const {
    std::atomic<uint64_t> cursor{0}, generated{0}, stored{0};
    const uint64_t capacity = lists.nodes.size();
    const size_t numTiles = tileStart.size() - 1;
    parallelFor(tbb::blocked_range<size_t>(0, numTiles, 1), [&](const tbb::blocked_range<size_t>& r) {
      TileAllocator alloc;
      uint64_t gen = 0, sto = 0;
      for (size_t tile = r.begin(); tile != r.end(); ++tile) {
        const int tx0 = int(tile % size_t(tilesX)) * tileSize, ty0 = int(tile / size_t(tilesX)) * tileSize;
        const int tx1 = std::min(tx0 + tileSize, camera.width()) - 1, ty1 = std::min(ty0 + tileSize, camera.height()) - 1;
        for (uint32_t i = tileStart[tile]; i < tileStart[tile + 1]; ++i) {
          const SubTriangle& s = subs[tileList[i]];
          rasterizeInTile(s, std::max(tx0, s.px0), std::max(ty0, s.py0), std::min(tx1, s.px1), std::min(ty1, s.py1),
                          lists, alloc, cursor, capacity, gen, sto);
        }
      }
      generated += gen;
      stored += sto;
    });
    lists.generated = generated;
    lists.stored = stored;
    return generated - stored;
  }

  void rasterizeInTile(const SubTriangle& s, int x0, int y0, int x1, int y1, FragmentLists& lists, TileAllocator& alloc,
                       std::atomic<uint64_t>& cursor, uint64_t capacity, uint64_t& gen, uint64_t& sto) const {
    if (x0 > x1 || y0 > y1) return;
    int64_t A[3], B[3], C[3];  // E(p) = A px + B py + C, with the top-left bias folded into C
    for (int e = 0; e < 3; ++e) {
      const int a = e, b = (e + 1) % 3;
      const int64_t dx = s.x[b] - s.x[a], dy = s.y[b] - s.y[a];
      A[e] = -dy;
      B[e] = dx;
      C[e] = dy * s.x[a] - dx * s.y[a] - (isTopLeft(dx, dy) ? 0 : 1);  // covered iff E >= 0
    }
    const TriangleSetup& ts = setups[s.triangle];
    const glm::uvec3 vi = scene.triangles[s.triangle];
    const uint32_t albedoSpec = materialPacked[scene.triMaterial[s.triangle]];
    const bool ortho = camera.orthographic();
    for (int py = y0; py <= y1; ++py) {
      const int64_t cy = int64_t(py) * kSub + kSub / 2;
      int64_t cx = int64_t(x0) * kSub + kSub / 2;
      int64_t e0 = A[0] * cx + B[0] * cy + C[0], e1 = A[1] * cx + B[1] * cy + C[1], e2 = A[2] * cx + B[2] * cy + C[2];
      const int64_t s0 = A[0] * kSub, s1 = A[1] * kSub, s2 = A[2] * kSub;
      for (int px = x0; px <= x1; ++px, e0 += s0, e1 += s1, e2 += s2) {
        if ((e0 | e1 | e2) < 0) continue;
        ++gen;
        const size_t pixel = lists.pixelIndex(px, py);
        ++lists.complexity[pixel];
        if (alloc.next == alloc.end) {
          const uint64_t base = cursor.fetch_add(kAllocChunk, std::memory_order_relaxed);
          if (base >= capacity) continue;  // pool exhausted: counted as lost (generated - stored)
          alloc.next = uint32_t(base);
          alloc.end = uint32_t(std::min<uint64_t>(base + kAllocChunk, capacity));
        }
        const uint32_t node = alloc.next++;
        ++sto;
        // Depth and attributes where the pixel-centre ray meets the plane (perspective-correct).
        // (An orthographic ray starts at its pixel's point on the z = 0 plane, not at the eye.)
        const glm::vec2 centre{float(px) + 0.5f, float(py) + 0.5f};
        const glm::vec3 dir = camera.rayThrough(centre);
        const glm::vec3 origin = ortho ? camera.rayOrigin(centre) : glm::vec3(0.0f);
        const float offset = ortho ? ts.planeOffset - glm::dot(ts.planeNormal, origin) : ts.planeOffset;
        const float denom = glm::dot(ts.planeNormal, dir);
        float depth = denom != 0.0f ? offset / denom : camera.far();
        if (!(depth >= camera.near())) depth = camera.near();
        if (!(depth <= camera.far())) depth = camera.far();
        const glm::vec3 vp = (ortho ? origin + dir * depth : dir * depth) - ts.v0;
        const float d20 = glm::dot(vp, ts.e1), d21 = glm::dot(vp, ts.e2);
        float b1 = std::clamp((ts.d11 * d20 - ts.d01 * d21) * ts.invDen, 0.0f, 1.0f);
        float b2 = std::clamp((ts.d00 * d21 - ts.d01 * d20) * ts.invDen, 0.0f, 1.0f);
        if (b1 + b2 > 1.0f) {
          const float sum = b1 + b2;
          b1 /= sum, b2 /= sum;
        }
        const glm::vec3 n = camNormals[vi.x] * (1.0f - b1 - b2) + camNormals[vi.y] * b1 + camNormals[vi.z] * b2;
        FragmentNode& f = lists.nodes[node];
        f.depth = depth;
        f.normal = encodeOctahedral(n);
        f.albedoSpec = albedoSpec;
        f.next = lists.head[pixel];
        lists.head[pixel] = node;
        lists.triangle[node] = s.triangle;
      }
    }
  }
};

}  // namespace

FragmentLists rasterize(const Scene& scene, const Camera& camera, const RasterConfig& config, RasterStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  const int W = camera.width(), H = camera.height();
  LT_CHECK(config.tileSize > 0, config.tileSize);
  LT_CHECK(config.triangleMask.empty() || config.triangleMask.size() == scene.triangles.size(), config.triangleMask.size());

  // Vertices to clip space; normals to camera space (the view matrix is rigid).
  const glm::mat4 toClip = camera.clipProjection() * camera.view();
  const glm::mat3 normalToCam(camera.view());
  std::vector<glm::vec4> clip(scene.positions.size());
  std::vector<glm::vec3> camPos(scene.positions.size()), camNormals(scene.positions.size());
  parallelFor(tbb::blocked_range<size_t>(0, scene.positions.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t v = r.begin(); v != r.end(); ++v) {
      clip[v] = toClip * glm::vec4(scene.positions[v], 1.0f);
      camPos[v] = camera.toCamera(scene.positions[v]);
      camNormals[v] = normalToCam * scene.normals[v];
    }
  });
  std::vector<uint32_t> materialPacked;
  for (const Material& m : scene.materials) materialPacked.push_back(packAlbedoSpec(m.albedo, m.specular));

  // Clip and set up triangles in fixed chunks (the chunking, not the thread count, fixes the order).
  const size_t numTris = scene.triangles.size();
  const size_t chunkSize = std::max<size_t>(1024, (numTris + 255) / 256);
  const size_t numChunks = (numTris + chunkSize - 1) / chunkSize;
  std::vector<std::vector<SubTriangle>> chunkSubs(numChunks);
  std::vector<TriangleSetup> setups(numTris);
  parallelFor(size_t(0), numChunks, [&](size_t c) {
    for (size_t t = c * chunkSize; t < std::min(numTris, (c + 1) * chunkSize); ++t) {
      if (!config.triangleMask.empty() && config.triangleMask[t] != config.maskValue) continue;
      if (config.frontFacesOnly) {
        // Counter-clockwise seen from the eye is the front (OpenGL, glTF, OBJ): the camera-space
        // normal of the winding points back toward the eye at the origin (orthographic: toward +z).
        const glm::uvec3 i = scene.triangles[t];
        const glm::vec3 a = camPos[i.x], n = glm::cross(camPos[i.y] - a, camPos[i.z] - a);
        if (!(glm::dot(n, camera.orthographic() ? glm::vec3(0.0f, 0.0f, -1.0f) : a) < 0.0f)) continue;
      }
      const size_t before = chunkSubs[c].size();
      setupTriangle(scene, camera, clip, uint32_t(t), chunkSubs[c]);
      if (chunkSubs[c].size() == before) continue;
      const glm::uvec3 i = scene.triangles[t];
      TriangleSetup& s = setups[t];
      s.v0 = camPos[i.x];
      s.e1 = camPos[i.y] - s.v0;
      s.e2 = camPos[i.z] - s.v0;
      s.planeNormal = glm::cross(s.e1, s.e2);
      s.planeOffset = glm::dot(s.planeNormal, s.v0);
      s.d00 = glm::dot(s.e1, s.e1), s.d01 = glm::dot(s.e1, s.e2), s.d11 = glm::dot(s.e2, s.e2);
      const float den = s.d00 * s.d11 - s.d01 * s.d01;
      s.invDen = den != 0.0f ? 1.0f / den : 0.0f;
    }
  });
  std::vector<uint32_t> chunkBase(numChunks + 1, 0);
  for (size_t c = 0; c < numChunks; ++c) chunkBase[c + 1] = chunkBase[c] + uint32_t(chunkSubs[c].size());
  std::vector<SubTriangle> subs(chunkBase[numChunks]);
  parallelFor(size_t(0), numChunks, [&](size_t c) { std::copy(chunkSubs[c].begin(), chunkSubs[c].end(), subs.begin() + chunkBase[c]); });
  chunkSubs.clear();

  // Bin sub-triangles to tiles: count, prefix sum (tile-major, chunk-minor), fill.
  const int ts = config.tileSize;
  const int tilesX = (W + ts - 1) / ts, tilesY = (H + ts - 1) / ts;
  const size_t numTiles = size_t(tilesX) * size_t(tilesY);
  std::vector<uint32_t> counts(numChunks * numTiles, 0);
  auto forTiles = [&](const SubTriangle& s, auto&& f) {
    for (int ty = s.py0 / ts; ty <= s.py1 / ts; ++ty)
      for (int tx = s.px0 / ts; tx <= s.px1 / ts; ++tx) f(size_t(ty) * size_t(tilesX) + size_t(tx));
  };
  parallelFor(size_t(0), numChunks, [&](size_t c) {
    for (uint32_t i = chunkBase[c]; i < chunkBase[c + 1]; ++i) forTiles(subs[i], [&](size_t tile) { ++counts[c * numTiles + tile]; });
  });
  std::vector<uint32_t> tileStart(numTiles + 1, 0);
  std::vector<uint32_t> offsets(numChunks * numTiles);
  uint64_t running = 0;
  for (size_t tile = 0; tile < numTiles; ++tile) {
    tileStart[tile] = uint32_t(running);
    for (size_t c = 0; c < numChunks; ++c) {
      offsets[c * numTiles + tile] = uint32_t(running);
      running += counts[c * numTiles + tile];
    }
  }
  if (running > 0xFFFFFFF0ull) inputError("scene ", scene.name, ": ", running, " triangle-tile pairs exceed the binning limit");
  tileStart[numTiles] = uint32_t(running);
  std::vector<uint32_t> tileList(running);
  parallelFor(size_t(0), numChunks, [&](size_t c) {
    for (uint32_t i = chunkBase[c]; i < chunkBase[c + 1]; ++i)
      forTiles(subs[i], [&](size_t tile) { tileList[offsets[c * numTiles + tile]++] = i; });
  });

  const RasterPass pass{scene, camera, subs, tileStart, tileList, setups, camNormals, materialPacked, ts, tilesX};
  uint64_t capacity = config.poolCapacity ? config.poolCapacity : std::max<uint64_t>(uint64_t(W) * uint64_t(H) * 8, 1u << 20);
  if (capacity > kMaxPoolFragments)
    inputError("fragment pool capacity ", capacity, " exceeds the 32-bit index limit of ", kMaxPoolFragments);
  RasterStats st;
  st.subTriangles = subs.size();
  FragmentLists lists;
  lists.width = W;
  lists.height = H;
  for (;;) {
    ++st.passes;
    lists.head.assign(size_t(W) * size_t(H), kNullIndex);
    lists.complexity.assign(size_t(W) * size_t(H), 0);
    lists.nodes.resize(0);
    lists.triangle.resize(0);
    checkAllocation(cat("the fragment pool (", capacity, " fragments)"), capacity * (sizeof(FragmentNode) + sizeof(uint32_t)));
    lists.nodes.resize(capacity);
    lists.triangle.resize(capacity);
    const uint64_t lost = pass.run(lists);
    if (lost == 0 || !config.growOnOverflow || st.passes > 1) break;
    st.overflowLost = lost;
    // Every tile may leave at most one partly used allocation chunk behind.
    capacity = lists.generated + numTiles * kAllocChunk;
    if (capacity > kMaxPoolFragments)
      inputError("scene ", scene.name, ": ", lists.generated, " fragments exceed the 32-bit index limit of ", kMaxPoolFragments);
  }
  st.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (stats) *stats = st;
  return lists;
}

}  // namespace lt
