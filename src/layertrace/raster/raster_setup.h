// The rasterizer's front end and per-fragment arithmetic, shared by the two capture passes: the
// reference pass that links every fragment into per-pixel lists (rasterizer.cpp) and the
// tile-local pass that sorts into the k layers while a tile is in cache (capture.cpp). Both call
// the same inline functions in the same order, so a fragment's depth, normal and albedo are the
// same bits in either pass (capture_test checks the arrays bit for bit).
//
// Internal to raster/: nothing above it includes this header.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "layertrace/raster/fragment.h"
#include "layertrace/raster/rasterizer.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"
#include "layertrace/scene/surface.h"

namespace lt::raster {

inline constexpr int64_t kSub = 256;  // 8 sub-pixel bits

/// A triangle after clipping, in fixed-point pixel coordinates, with E > 0 inside.
/// Sutherland–Hodgman against one plane: keeps the part of the polygon in[0..n) where
/// dot(plane, p) ≥ 0, into `out` (room for n + 1 points); returns its size. The intersection of an
/// edge is computed from its lexicographically smaller endpoint, so the two triangles sharing an
/// edge get bit-identical clipped vertices — clipping keeps the mesh watertight. Any affine
/// attribute carried in a coordinate is interpolated exactly along the edge.
int clipAgainst(const glm::vec4* in, int n, const glm::vec4& plane, glm::vec4* out);

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

/// Everything the front end produces for one view: clipped sub-triangles binned to screen tiles
/// (each tile's list in ascending sub-triangle order, so every pixel sees its fragments in one
/// order whatever the tile size or thread count). The vectors keep their capacity when the
/// object is reused for the next frame.
struct RasterSetup {
  std::vector<glm::vec4> clip;
  std::vector<glm::vec3> camPos, camNormals;
  std::vector<uint32_t> materialPacked;
  /// Per material: kSampled (textured: the albedo is sampled per fragment), kCutOut (alpha-tested).
  std::vector<uint8_t> materialFlags;
  std::vector<TriangleSetup> setups;
  std::vector<std::vector<SubTriangle>> chunkSubs;
  std::vector<uint32_t> chunkBase;
  std::vector<const SubTriangle*> subs;  ///< all chunks' sub-triangles in triangle order
  std::vector<uint32_t> counts, offsets;
  std::vector<uint32_t> tileStart;  ///< per tile, offsets into tileList; numTiles + 1 entries
  std::vector<uint32_t> tileList;   ///< sub-triangle indices
  std::vector<uint32_t> listOffset;  ///< the list-producing capture's first node per pixel
  int tileSize = 0, tilesX = 0, tilesY = 0;

  size_t numTiles() const { return size_t(tilesX) * size_t(tilesY); }

  /// The i-th entry of the tile bins with what a fragment of it needs.
  struct Binned {
    const SubTriangle& sub;
    const TriangleSetup& setup;
    glm::uvec3 vertices;
    uint32_t albedoSpec;  ///< the material's constant albedo and specular (used unless kSampled)
    uint8_t flags;        ///< materialFlags of its material
  };
  static constexpr uint8_t kSampled = kSurfaceSampled, kCutOut = kSurfaceCutOut;
  Binned binned(const Scene& scene, uint32_t i) const {
    const SubTriangle& s = *subs[tileList[i]];
    const uint32_t m = scene.triMaterial[s.triangle];
    return {s, setups[s.triangle], scene.triangles[s.triangle], materialPacked[m], materialFlags[m]};
  }
  /// Inclusive pixel bounds of `tile`, clamped to the screen.
  void tileBounds(size_t tile, const Camera& camera, int& x0, int& y0, int& x1, int& y1) const {
    x0 = int(tile % size_t(tilesX)) * tileSize, y0 = int(tile / size_t(tilesX)) * tileSize;
    x1 = std::min(x0 + tileSize, camera.width()) - 1, y1 = std::min(y0 + tileSize, camera.height()) - 1;
  }
};

/// Transforms, culls (RasterConfig::frontFacesOnly, triangleMask), clips and bins every scene
/// triangle for `camera` into `setup`. Throws InputError when the bins exceed 32-bit offsets.
void prepareRaster(const Scene& scene, const Camera& camera, const RasterConfig& config, RasterSetup& setup);

/// Top-left rule for y-down screens with E > 0 inside: a top edge runs horizontally to the
/// right, a left edge runs upwards. Pixels exactly on such edges are covered.
inline bool isTopLeft(int64_t dx, int64_t dy) { return (dy == 0 && dx > 0) || dy < 0; }

/// The edge functions of `s` at pixel centres: E(p) = A px + B py + C in fixed point, with the
/// top-left bias folded into C, so a centre is covered iff E >= 0 for all three edges.
struct EdgeFunctions {
  int64_t A[3], B[3], C[3];
  explicit EdgeFunctions(const SubTriangle& s) {
    for (int e = 0; e < 3; ++e) {
      const int a = e, b = (e + 1) % 3;
      const int64_t dx = s.x[b] - s.x[a], dy = s.y[b] - s.y[a];
      A[e] = -dy;
      B[e] = dx;
      C[e] = dy * s.x[a] - dx * s.y[a] - (isTopLeft(dx, dy) ? 0 : 1);
    }
  }
  int64_t at(int e, int px, int py) const { return A[e] * (int64_t(px) * kSub + kSub / 2) + B[e] * (int64_t(py) * kSub + kSub / 2) + C[e]; }
};

/// Calls f(px, py) for every pixel centre of [x0, x1] × [y0, y1] that `s` covers, row by row,
/// left to right, testing each pixel's three edge functions (the reference).
template <class F>
inline void forEachCovered(const SubTriangle& s, int x0, int y0, int x1, int y1, F&& f) {
  if (x0 > x1 || y0 > y1) return;
  const EdgeFunctions E(s);
  const int64_t s0 = E.A[0] * kSub, s1 = E.A[1] * kSub, s2 = E.A[2] * kSub;
  for (int py = y0; py <= y1; ++py) {
    int64_t e0 = E.at(0, x0, py), e1 = E.at(1, x0, py), e2 = E.at(2, x0, py);
    for (int px = x0; px <= x1; ++px, e0 += s0, e1 += s1, e2 += s2)
      if ((e0 | e1 | e2) >= 0) f(px, py);
  }
}

/// The same pixels in the same order, found per row as the exact integer span where all three
/// edge functions are >= 0 (E is linear in px: each edge bounds the span from one side), so the
/// loop visits covered pixels only — thin and slanted triangles waste no tests on their
/// bounding box. Calls g(py, xa, xb) for each non-empty row span [xa, xb]. capture_test checks
/// it against forEachCovered through the whole pipeline.
template <class G>
inline void forEachCoveredSpan(const SubTriangle& s, int x0, int y0, int x1, int y1, G&& g) {
  if (x0 > x1 || y0 > y1) return;
  const EdgeFunctions E(s);
  for (int py = y0; py <= y1; ++py) {
    int64_t lo = 0, hi = x1 - x0;  // pixel offsets from x0
    for (int e = 0; e < 3; ++e) {
      const int64_t v = E.at(e, x0, py), step = E.A[e] * kSub;  // E at x0 + i is v + i * step
      if (step > 0) {
        if (v < 0) lo = std::max(lo, (-v + step - 1) / step);  // first i with v + i * step >= 0
      } else if (step < 0) {
        if (v < 0) lo = hi + 1;                  // decreasing and already negative: empty
        else hi = std::min(hi, v / -step);       // last i with v + i * step >= 0
      } else if (v < 0) {
        lo = hi + 1;
      }
    }
    if (lo <= hi) g(py, x0 + int(lo), x0 + int(hi));
  }
}

/// The pixel-centre ray of (px, py) in camera space: direction with depth component 1, origin
/// (the eye, or the pixel's point on z = 0 for an orthographic camera).
struct PixelRay {
  glm::vec3 origin, dir;
};
inline PixelRay pixelRay(const Camera& camera, int px, int py) {
  const glm::vec2 centre{float(px) + 0.5f, float(py) + 0.5f};
  return {camera.orthographic() ? camera.rayOrigin(centre) : glm::vec3(0.0f), camera.rayThrough(centre)};
}

/// Depth where the pixel-centre ray meets the triangle's plane, clamped to [near, far]
/// (perspective-correct; an orthographic ray starts at its pixel's point on z = 0).
inline float fragmentDepth(const Camera& camera, const TriangleSetup& ts, const PixelRay& ray) {
  const float offset = camera.orthographic() ? ts.planeOffset - glm::dot(ts.planeNormal, ray.origin) : ts.planeOffset;
  const float denom = glm::dot(ts.planeNormal, ray.dir);
  float depth = denom != 0.0f ? offset / denom : camera.far();
  if (!(depth >= camera.near())) depth = camera.near();
  if (!(depth <= camera.far())) depth = camera.far();
  return depth;
}

/// fragmentDepth for the n pixels xa .. xa + n - 1 of row py, written to out[0 .. n): for a
/// pinhole camera the loop is straight-line float code the compiler vectorizes, performing
/// per lane exactly fragmentDepth's operations in its order (glm::dot sums (x + y) + z), so
/// every depth has the same bits (capture_test compares the pipelines byte for byte).
inline void spanDepths(const Camera& camera, const TriangleSetup& ts, int py, int xa, int n, float* out) {
  if (camera.orthographic()) {
    for (int i = 0; i < n; ++i) out[i] = fragmentDepth(camera, ts, pixelRay(camera, xa + i, py));
    return;
  }
  const float scale = camera.pixelFootprint(1.0f), halfW = float(camera.width()) * 0.5f;
  const float dirY = camera.rayThrough({0.5f, float(py) + 0.5f}).y;
  const float nx = ts.planeNormal.x, rowTerm = ts.planeNormal.y * dirY, zTerm = ts.planeNormal.z * -1.0f;
  const float offset = ts.planeOffset, near = camera.near(), far = camera.far();
  for (int i = 0; i < n; ++i) {
    const float dirX = (float(xa + i) + 0.5f - halfW) * scale;
    const float denom = (nx * dirX + rowTerm) + zTerm;
    float depth = denom != 0.0f ? offset / denom : far;
    depth = depth >= near ? depth : near;  // also NaN → near, as fragmentDepth
    depth = depth <= far ? depth : far;
    out[i] = depth;
  }
}

/// The barycentric weights (of the second and third vertex) where the pixel-centre ray meets the
/// triangle's plane at `depth`, clamped to the triangle: a pixel centre on a silhouette may meet
/// the plane just outside it.
inline glm::vec2 fragmentBarycentrics(const Camera& camera, const TriangleSetup& ts, const PixelRay& ray, float depth) {
  const glm::vec3 vp = (camera.orthographic() ? ray.origin + ray.dir * depth : ray.dir * depth) - ts.v0;
  const float d20 = glm::dot(vp, ts.e1), d21 = glm::dot(vp, ts.e2);
  float b1 = std::clamp((ts.d11 * d20 - ts.d01 * d21) * ts.invDen, 0.0f, 1.0f);
  float b2 = std::clamp((ts.d00 * d21 - ts.d01 * d20) * ts.invDen, 0.0f, 1.0f);
  if (b1 + b2 > 1.0f) {
    const float sum = b1 + b2;
    b1 /= sum, b2 /= sum;
  }
  return {b1, b2};
}

/// The octahedral-encoded interpolated normal at that depth.
inline uint32_t fragmentNormal(const Camera& camera, const TriangleSetup& ts, const glm::vec3* camNormals, glm::uvec3 vi,
                               const PixelRay& ray, float depth) {
  const glm::vec2 b = fragmentBarycentrics(camera, ts, ray, depth);
  const glm::vec3 n = camNormals[vi.x] * (1.0f - b.x - b.y) + camNormals[vi.y] * b.x + camNormals[vi.z] * b.y;
  return encodeOctahedral(n);
}

/// Whether the fragment survives its material's alpha test (Binned::kCutOut; a fragment shader's
/// discard): a cut-away fragment is not generated at all, in every capture alike.
inline bool fragmentPresent(const Scene& scene, const Camera& camera, const TriangleSetup& ts, uint32_t triangle, const PixelRay& ray,
                            float depth) {
  const glm::vec2 b = fragmentBarycentrics(camera, ts, ray, depth);
  return surfacePresent(scene, triangle, b.x, b.y);
}

/// The fragment's albedo and specular: its material's constant, or (Binned::kSampled) its textures
/// sampled at the fragment with the footprint of the pixel at that depth (surfaceColor).
inline uint32_t fragmentAlbedoSpec(const Scene& scene, const Camera& camera, const RasterSetup::Binned& b, const PixelRay& ray, float depth) {
  if (!(b.flags & RasterSetup::kSampled)) return b.albedoSpec;
  const glm::vec2 w = fragmentBarycentrics(camera, b.setup, ray, depth);
  const float nl = glm::length(b.setup.planeNormal), dl = glm::length(ray.dir);
  const float cosine = nl > 0.0f && dl > 0.0f ? glm::dot(b.setup.planeNormal, ray.dir) / (nl * dl) : 1.0f;
  return packSurfaceColor(surfaceColor(scene, b.sub.triangle, w.x, w.y, textureFootprint(camera.pixelFootprint(depth), cosine)));
}

}  // namespace lt::raster
