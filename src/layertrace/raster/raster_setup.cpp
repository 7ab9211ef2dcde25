#include "layertrace/raster/raster_setup.h"

#include <cmath>

#include <glm/mat3x3.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

namespace lt::raster {
namespace {

constexpr float kGuardBand = 4.0f;   // clip x, y to ±4 w: keeps fixed-point products far below 2^63

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

/// Fixed-point edge function of edge a→b at p: positive on the inside of a triangle with
/// positive area (screen y points down).
inline int64_t edge(int64_t ax, int64_t ay, int64_t bx, int64_t by, int64_t px, int64_t py) {
  return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

void clipAndProject(const Scene& scene, const Camera& camera, const std::vector<glm::vec4>& clip, uint32_t t,
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

}  // namespace

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


void prepareRaster(const Scene& scene, const Camera& camera, const RasterConfig& config, RasterSetup& setup) {
  LT_CHECK(config.tileSize > 0, config.tileSize);
  LT_CHECK(config.triangleMask.empty() || config.triangleMask.size() == scene.triangles.size(), config.triangleMask.size());
  const int W = camera.width(), H = camera.height();

  // Vertices to clip space; normals to camera space (the view matrix is rigid).
  const glm::mat4 toClip = camera.clipProjection() * camera.view();
  const glm::mat3 normalToCam(camera.view());
  std::vector<glm::vec4>& clip = setup.clip;
  std::vector<glm::vec3>&camPos = setup.camPos, &camNormals = setup.camNormals;
  checkAllocation(cat("the rasterizer's vertices and triangles (", scene.positions.size(), " and ", scene.triangles.size(), ")"),
                  uint64_t(scene.positions.size()) * (sizeof(glm::vec4) + 2 * sizeof(glm::vec3)) + uint64_t(scene.triangles.size()) * sizeof(TriangleSetup));
  clip.resize(scene.positions.size());
  camPos.resize(scene.positions.size());
  camNormals.resize(scene.positions.size());
  parallelFor(tbb::blocked_range<size_t>(0, scene.positions.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t v = r.begin(); v != r.end(); ++v) {
      clip[v] = toClip * glm::vec4(scene.positions[v], 1.0f);
      camPos[v] = camera.toCamera(scene.positions[v]);
      camNormals[v] = normalToCam * scene.normals[v];
    }
  });
  setup.materialPacked.clear();
  setup.materialFlags.clear();
  for (const Material& m : scene.materials) {
    setup.materialPacked.push_back(packAlbedoSpec(m.albedo, m.specular));
    setup.materialFlags.push_back(surfaceFlags(scene, m));
  }

  // Clip and set up triangles in fixed chunks (the chunking, not the thread count, fixes the order).
  const size_t numTris = scene.triangles.size();
  const size_t chunkSize = std::max<size_t>(1024, (numTris + 255) / 256);
  const size_t numChunks = (numTris + chunkSize - 1) / chunkSize;
  std::vector<std::vector<SubTriangle>>& chunkSubs = setup.chunkSubs;
  chunkSubs.resize(numChunks);
  std::vector<TriangleSetup>& setups = setup.setups;
  setups.resize(numTris);
  parallelFor(size_t(0), numChunks, [&](size_t c) {
    chunkSubs[c].clear();
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
      clipAndProject(scene, camera, clip, uint32_t(t), chunkSubs[c]);
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
  std::vector<uint32_t>& chunkBase = setup.chunkBase;
  chunkBase.assign(numChunks + 1, 0);
  for (size_t c = 0; c < numChunks; ++c) chunkBase[c + 1] = chunkBase[c] + uint32_t(chunkSubs[c].size());
  std::vector<const SubTriangle*>& subs = setup.subs;  // pointers, not copies: the chunks stay
  subs.resize(chunkBase[numChunks]);
  parallelFor(size_t(0), numChunks, [&](size_t c) {
    for (size_t j = 0; j < chunkSubs[c].size(); ++j) subs[chunkBase[c] + j] = &chunkSubs[c][j];
  });

  // Bin sub-triangles to tiles: count, prefix sum (tile-major, chunk-minor), fill.
  const int ts = setup.tileSize = config.tileSize;
  const int tilesX = setup.tilesX = (W + ts - 1) / ts;
  setup.tilesY = (H + ts - 1) / ts;
  const size_t numTiles = setup.numTiles();
  std::vector<uint32_t>&counts = setup.counts, &offsets = setup.offsets;
  counts.assign(numChunks * numTiles, 0);
  auto forTiles = [&](const SubTriangle& s, auto&& f) {
    for (int ty = s.py0 / ts; ty <= s.py1 / ts; ++ty)
      for (int tx = s.px0 / ts; tx <= s.px1 / ts; ++tx) f(size_t(ty) * size_t(tilesX) + size_t(tx));
  };
  parallelFor(size_t(0), numChunks, [&](size_t c) {
    for (uint32_t i = chunkBase[c]; i < chunkBase[c + 1]; ++i) forTiles(*subs[i], [&](size_t tile) { ++counts[c * numTiles + tile]; });
  });
  std::vector<uint32_t>& tileStart = setup.tileStart;
  tileStart.resize(numTiles + 1);
  offsets.resize(numChunks * numTiles);
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
  setup.tileList.resize(running);
  parallelFor(size_t(0), numChunks, [&](size_t c) {
    for (uint32_t i = chunkBase[c]; i < chunkBase[c + 1]; ++i)
      forTiles(*subs[i], [&](size_t tile) { setup.tileList[offsets[c * numTiles + tile]++] = i; });
  });
}

}  // namespace lt::raster
