// Layered depth cube construction (Bürger et al. 2007, §1.2–1.3); the choices are in ldc.h.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>

#include "layertrace/raster/rasterizer.h"
#include "layertrace/ldc/ldc.h"
#include "layertrace/scene/surface.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

namespace lt {
namespace {

constexpr uint8_t kNoAxis = 3;

/// Geometric (unnormalised) normal of a triangle.
glm::vec3 faceNormal(const Scene& scene, uint32_t t) {
  const glm::uvec3 i = scene.triangles[t];
  const glm::vec3 a = scene.positions[i.x];
  return glm::cross(scene.positions[i.y] - a, scene.positions[i.z] - a);
}

/// Fig. 5: the axis the triangle faces most (largest |normal component|; ties to the lower axis).
uint8_t dominantAxis(glm::vec3 n) {
  const glm::vec3 m = glm::abs(n);
  uint8_t a = 0;
  if (m.y > m.x) a = 1;
  if (m.z > m[a]) a = 2;
  return a;
}

/// The orthographic camera of axis a: it looks along +a from one texel before the box, its right
/// vector is -e[(a+1)%3] and its up vector e[(a+2)%3]; one pixel is one texel.
Camera axisCamera(const Bounds& box, float texel, int a, int width, int height) {
  const int v = (a + 2) % 3;
  CameraDesc d;
  d.name = cat("ldc axis ", "xyz"[a]);
  d.eye = box.center();
  d.eye[a] = box.lo[a] - texel;
  d.target = d.eye;
  d.target[a] += 1.0f;
  d.up = glm::vec3(0.0f);
  d.up[v] = 1.0f;
  d.near = 0.5f * texel;
  d.far = box.hi[a] - d.eye[a] + texel;
  d.orthoHeight = float(height) * texel;
  return Camera(d, width, height);
}

/// Fragments the rasterizer will produce for the triangles of one axis, estimated from their
/// projected areas (the pool then grows at most once, with the exact count).
uint64_t estimateFragments(const Scene& scene, std::span<const uint8_t> axisOf, int a, float texel) {
  double texels = 0.0;
  for (size_t t = 0; t < axisOf.size(); ++t)
    if (axisOf[t] == a) texels += 0.5 * std::abs(double(faceNormal(scene, uint32_t(t))[a])) / (double(texel) * texel) + 1.0;
  return uint64_t(std::min(texels * 1.05 + 65536.0, double(kMaxPoolFragments)));
}

/// Per sample: (depth, triangle) order within a texel.
struct SampleKey {
  float depth;
  uint32_t triangle;
  uint32_t index;
};

void buildView(const Scene& scene, std::span<const uint8_t> axisOf, std::span<const glm::vec3> unitNormals,
               const std::vector<uint32_t>& materialPacked, LdcView& view, const LdcConfig& config) {
  const auto start = std::chrono::steady_clock::now();
  const int a = view.axis, W = view.width, H = view.height;
  const size_t texels = size_t(W) * size_t(H);
  const Camera& cam = view.camera;

  RasterConfig rc;
  rc.triangleMask = axisOf;
  rc.maskValue = uint8_t(a);
  rc.poolCapacity = estimateFragments(scene, axisOf, a, cam.pixelFootprint(1.0f));
  const FragmentLists lists = rasterize(scene, cam, rc);
  LT_CHECK(lists.lost() == 0, lists.lost());

  // Triangles of this axis that no texel centre sampled: one sample at their centroid's texel.
  std::vector<uint8_t> covered(axisOf.size(), 0);
  parallelFor(tbb::blocked_range<size_t>(0, texels, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t p = r.begin(); p != r.end(); ++p)
      for (uint32_t n = lists.head[p]; n != kNullIndex; n = lists.nodes[n].next)
        std::atomic_ref<uint8_t>(covered[lists.triangle[n]]).store(1, std::memory_order_relaxed);
  });
  struct Extra {
    size_t texel;
    FragmentNode node;
    uint32_t triangle;
  };
  std::vector<Extra> extras;
  const glm::mat3 toView(cam.view());
  for (size_t t = 0; t < axisOf.size(); ++t) {
    if (axisOf[t] != a) continue;
    ++view.triangles;
    if (covered[t]) continue;
    // A cut-out whose centroid falls in a hole has no surface to sample there.
    if (scene.cutOut(uint32_t(t)) && !surfacePresent(scene, uint32_t(t), 1.0f / 3.0f, 1.0f / 3.0f)) continue;
    ++view.lostTriangles;
    const glm::uvec3 i = scene.triangles[t];
    const glm::vec3 c = cam.toCamera((scene.positions[i.x] + scene.positions[i.y] + scene.positions[i.z]) / 3.0f);
    const glm::vec2 px = cam.project(c);
    const int x = std::clamp(int(std::floor(px.x)), 0, W - 1), y = std::clamp(int(std::floor(px.y)), 0, H - 1);
    const glm::vec3 shading = scene.normals[i.x] + scene.normals[i.y] + scene.normals[i.z];
    // The sample stands at the texel centre: the triangle's plane there (its normal's view-axis
    // component is the dominant one, so the division is safe).
    const glm::vec3 n = toView * unitNormals[t], centre = cam.rayOrigin({float(x) + 0.5f, float(y) + 0.5f});
    Extra e;
    e.texel = view.texelIndex(x, y);
    e.node.depth = -(c.z - (n.x * (centre.x - c.x) + n.y * (centre.y - c.y)) / n.z);
    e.node.normal = encodeOctahedral(toView * shading);
    e.node.albedoSpec = materialPacked[scene.triMaterial[t]];
    if (surfaceTextured(scene, uint32_t(t)))  // the centroid's texel, at the level of one texel of this view
      e.node.albedoSpec = packSurfaceColor(surfaceColor(scene, uint32_t(t), 1.0f / 3.0f, 1.0f / 3.0f, cam.pixelFootprint(1.0f)));
    e.node.next = encodeOctahedral(toView * unitNormals[t]);
    e.triangle = uint32_t(t);
    extras.push_back(e);
  }

  // Exact-size storage: counts, prefix sum, fill, sort per texel.
  checkAllocation(cat("the layered depth cube's ", "xyz"[a], " offsets (", texels, " texels)"), (texels + 1) * sizeof(uint32_t));
  view.offset.assign(texels + 1, 0);
  for (size_t p = 0; p < texels; ++p) view.offset[p + 1] = lists.complexity[p];
  for (const Extra& e : extras) ++view.offset[e.texel + 1];
  uint64_t total = 0;
  for (size_t p = 0; p <= texels; ++p) {
    total += view.offset[p];
    if (total > 0xFFFFFFF0ull) inputError("scene ", scene.name, ": the layered depth cube's ", "xyz"[a], " view exceeds 2^32 samples");
    view.offset[p] = uint32_t(total);
  }
  checkAllocation(cat("the layered depth cube's ", "xyz"[a], " samples (", total, ")"), total * (sizeof(FragmentNode) + sizeof(uint32_t)));
  view.samples.resize(total);
  view.triangle.resize(total);
  parallelFor(tbb::blocked_range<size_t>(0, texels, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t p = r.begin(); p != r.end(); ++p) {
      uint32_t out = view.offset[p];
      for (uint32_t n = lists.head[p]; n != kNullIndex; n = lists.nodes[n].next, ++out) {
        FragmentNode f = lists.nodes[n];
        f.next = encodeOctahedral(toView * unitNormals[lists.triangle[n]]);
        view.samples[out] = f;
        view.triangle[out] = lists.triangle[n];
      }
    }
  });
  // Centroid samples go after the texel's list fragments (extras are in triangle order; a stable
  // sort by texel keeps that order within a texel).
  std::stable_sort(extras.begin(), extras.end(), [](const Extra& x, const Extra& y) { return x.texel < y.texel; });
  for (size_t e = 0, rank = 0; e < extras.size(); ++e) {
    rank = e > 0 && extras[e - 1].texel == extras[e].texel ? rank + 1 : 0;
    const size_t slot = view.offset[extras[e].texel] + lists.complexity[extras[e].texel] + rank;
    view.samples[slot] = extras[e].node;
    view.triangle[slot] = extras[e].triangle;
  }
  parallelFor(tbb::blocked_range<size_t>(0, texels, 1024), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<SampleKey> keys;
    std::vector<FragmentNode> nodes;
    for (size_t p = r.begin(); p != r.end(); ++p) {
      const uint32_t b = view.offset[p], e = view.offset[p + 1];
      if (e - b < 2) continue;
      keys.clear();
      for (uint32_t i = b; i < e; ++i) keys.push_back({view.samples[i].depth, view.triangle[i], i});
      std::sort(keys.begin(), keys.end(), [](const SampleKey& x, const SampleKey& y) {
        return x.depth != y.depth ? x.depth < y.depth : x.triangle < y.triangle;
      });
      nodes.assign(view.samples.begin() + b, view.samples.begin() + e);
      for (uint32_t i = 0; i < e - b; ++i) {
        view.samples[b + i] = nodes[keys[i].index - b];
        view.triangle[b + i] = keys[i].triangle;
      }
    }
  });

  // §1.3: per block of config.block² texels, the depth range of its samples — as up to
  // config.blockIntervals disjoint intervals: sort the depths and split at the widest gaps.
  const int B = config.block, slots = config.blockIntervals;
  view.blocksX = (W + B - 1) / B;
  view.blocksY = (H + B - 1) / B;
  const size_t blocks = size_t(view.blocksX) * size_t(view.blocksY);
  const float inf = std::numeric_limits<float>::infinity();
  view.blockIntervals.assign(blocks * size_t(slots), glm::vec2(inf, -inf));
  parallelFor(size_t(0), size_t(view.blocksY), [&](size_t by) {
    std::vector<float> depths;
    std::vector<uint32_t> gaps;
    for (size_t bx = 0; bx < size_t(view.blocksX); ++bx) {
      depths.clear();
      for (int y = int(by) * B; y < std::min(H, int(by + 1) * B); ++y)
        for (int x = int(bx) * B; x < std::min(W, int(bx + 1) * B); ++x)
          for (uint32_t i = view.offset[view.texelIndex(x, y)]; i < view.offset[view.texelIndex(x, y) + 1]; ++i)
            depths.push_back(view.samples[i].depth);
      if (depths.empty()) continue;
      std::sort(depths.begin(), depths.end());
      // The slots - 1 widest gaps (ties: the nearer gap) become the splits, in depth order.
      gaps.clear();
      for (uint32_t g = 1; g < depths.size(); ++g) gaps.push_back(g);
      const size_t splits = std::min(gaps.size(), size_t(slots - 1));
      std::partial_sort(gaps.begin(), gaps.begin() + std::ptrdiff_t(splits), gaps.end(), [&](uint32_t g, uint32_t h) {
        const float wg = depths[g] - depths[g - 1], wh = depths[h] - depths[h - 1];
        return wg != wh ? wg > wh : g < h;
      });
      gaps.resize(splits);
      std::sort(gaps.begin(), gaps.end());
      glm::vec2* out = &view.blockIntervals[(by * size_t(view.blocksX) + bx) * size_t(slots)];
      uint32_t first = 0;
      for (size_t k = 0; k <= splits; ++k) {
        const uint32_t end = k < splits ? gaps[k] : uint32_t(depths.size());
        out[k] = {depths[first], depths[end - 1]};
        first = end;
      }
    }
  });
  view.rasterMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

void validateLdcConfig(const LdcConfig& c) {
  if (c.resolution < 16 || c.resolution > 16384) inputError("--ldc-resolution ", c.resolution, ": must be between 16 and 16384");
  if (c.block < 1 || c.block > 256) inputError("--ldc-block ", c.block, ": must be between 1 and 256");
  if (!(c.epsilon >= 0.0f && c.epsilon <= 4.0f)) inputError("--ldc-epsilon ", c.epsilon, ": must be between 0 and 4 (texels)");
  if (!(c.hitDistance >= 0.0f) || !std::isfinite(c.hitDistance))
    inputError("--ldc-hit-distance ", c.hitDistance, ": must be a finite distance >= 0");
  if (c.blockIntervals < 1 || c.blockIntervals > 16)
    inputError("--ldc-block-intervals ", c.blockIntervals, ": must be between 1 and 16");
}

size_t LdcView::memoryBytes() const {
  return offset.size() * sizeof(uint32_t) + samples.size() * sizeof(FragmentNode) + triangle.size() * sizeof(uint32_t) +
         blockIntervals.size() * sizeof(glm::vec2);
}

LayeredDepthCube buildLdc(const Scene& scene, const LdcConfig& config) {
  validateLdcConfig(config);
  const auto start = std::chrono::steady_clock::now();
  LayeredDepthCube ldc;
  ldc.config = config;
  const Bounds b = scene.bounds();
  if (scene.triangles.empty() || b.empty()) inputError("scene ", scene.name, ": no triangles for the layered depth cube");
  const glm::vec3 extent = b.hi - b.lo;
  const float longest = std::max({extent.x, extent.y, extent.z});
  if (!std::isfinite(longest) || !(longest > 0.0f))
    inputError("scene ", scene.name, ": bounding box extent ", longest, " cannot hold a layered depth cube");
  // One texel of padding on each side of the longest axis: `resolution` texels span it exactly.
  ldc.texel = longest / float(config.resolution - 2);
  ldc.box.lo = b.lo - glm::vec3(ldc.texel);
  ldc.box.hi = b.hi + glm::vec3(ldc.texel);
  uint64_t texels = 0;
  for (int a = 0; a < 3; ++a) {
    LdcView& v = ldc.views[size_t(a)];
    v.axis = a;
    const int u = (a + 1) % 3, w = (a + 2) % 3;
    v.width = std::max(1, int(std::ceil((ldc.box.hi[u] - ldc.box.lo[u]) / ldc.texel)));
    v.height = std::max(1, int(std::ceil((ldc.box.hi[w] - ldc.box.lo[w]) / ldc.texel)));
    texels += uint64_t(v.width) * uint64_t(v.height);
  }
  // Rasterizer heads and counters plus the offsets, before any sample exists.
  checkAllocation(cat("the layered depth cube (--ldc-resolution ", config.resolution, ": ", texels, " texels)"), texels * 3 * sizeof(uint32_t));

  const size_t n = scene.triangles.size();
  std::vector<uint8_t> axisOf(n, kNoAxis);
  std::vector<glm::vec3> unitNormals(n, glm::vec3(0.0f));
  std::atomic<uint64_t> degenerate{0};
  parallelFor(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
    uint64_t local = 0;
    for (size_t t = r.begin(); t != r.end(); ++t) {
      const glm::vec3 nrm = faceNormal(scene, uint32_t(t));
      const float len = glm::length(nrm);
      if (!(len > 0.0f) || !std::isfinite(len)) {
        ++local;
        continue;
      }
      axisOf[t] = dominantAxis(nrm);
      unitNormals[t] = nrm / len;
    }
    degenerate += local;
  });
  ldc.degenerateTriangles = degenerate;
  std::vector<uint32_t> materialPacked;
  for (const Material& m : scene.materials) materialPacked.push_back(packAlbedoSpec(m.albedo, m.specular));
  for (int a = 0; a < 3; ++a) {
    LdcView& v = ldc.views[size_t(a)];
    v.camera = axisCamera(ldc.box, ldc.texel, a, v.width, v.height);
    buildView(scene, axisOf, unitNormals, materialPacked, v, config);
  }
  ldc.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return ldc;
}

}  // namespace lt
