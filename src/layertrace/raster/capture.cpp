#include "layertrace/raster/capture.h"

#include <algorithm>
#include <atomic>
#include <chrono>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/raster/raster_setup.h"
#include "layertrace/util/cpu_dispatch.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

namespace lt {
namespace {

using raster::RasterSetup;

constexpr int kMaxTileSize = 256;  // a span never leaves its tile

double msBetween(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

/// One tile: every fragment of the tile's triangles goes straight into its pixel's k slots
/// (seed 000 §4.2's insertion sort, run as the fragments arrive instead of over a finished
/// list). A fragment behind a full pixel's k-th is counted and dropped before its normal is
/// evaluated.
LT_CPU_DISPATCH void captureTile(const Scene& scene, const Camera& camera, const RasterSetup& setup, const LayerConfig& config, size_t tile,
                 LayerArrays& out, std::vector<uint32_t>& complexity, uint64_t& generated) {
  int tx0, ty0, tx1, ty1;
  setup.tileBounds(tile, camera, tx0, ty0, tx1, ty1);
  const int k = config.k;
  for (int y = ty0; y <= ty1; ++y) {
    const size_t row = out.pixelIndex(tx0, y);
    std::fill_n(&out.count[row], tx1 - tx0 + 1, uint8_t(0));
    std::fill_n(&complexity[row], tx1 - tx0 + 1, 0u);
  }
  uint64_t gen = 0;
  float depths[kMaxTileSize];
  for (uint32_t i = setup.tileStart[tile]; i < setup.tileStart[tile + 1]; ++i) {
    const raster::SubTriangle& s = *setup.subs[setup.tileList[i]];
    const raster::TriangleSetup& ts = setup.setups[s.triangle];
    const glm::uvec3 vi = scene.triangles[s.triangle];
    const uint32_t albedoSpec = setup.materialPacked[scene.triMaterial[s.triangle]];
    raster::forEachCoveredSpan(s, std::max(tx0, s.px0), std::max(ty0, s.py0), std::min(tx1, s.px1), std::min(ty1, s.py1),
                               [&](int py, int xa, int xb) {
                                 // Depths of the whole span first: one loop the compiler
                                 // vectorizes (the same IEEE operations per lane, so the same bits).
                                 const int n = xb - xa + 1;
                                 raster::spanDepths(camera, ts, py, xa, n, depths);
                                 gen += uint64_t(n);
                                 for (int d = 0; d < n; ++d) {
                                   const int px = xa + d;
                                   const size_t pixel = out.pixelIndex(px, py);
                                   ++complexity[pixel];
                                   const float depth = depths[d];
                                   FragmentNode* slot = &out.slots[pixel * size_t(k)];
                                   uint32_t* tri = &out.triangle[pixel * size_t(k)];
                                   const int count = out.count[pixel];
                                   // The newest fragment ranks first among equal depths (see capture.h).
                                   if (count == k && depth > slot[k - 1].depth) continue;
                                   int j = std::min(count, k - 1);
                                   for (; j > 0 && depth <= slot[j - 1].depth; --j) slot[j] = slot[j - 1], tri[j] = tri[j - 1];
                                   const uint32_t normal =
                                       raster::fragmentNormal(camera, ts, setup.camNormals.data(), vi, raster::pixelRay(camera, px, py), depth);
                                   slot[j] = {depth, normal, albedoSpec, 0u};
                                   tri[j] = s.triangle;
                                   out.count[pixel] = uint8_t(std::min(count + 1, k));
                                 }
                               });
  }
  for (int y = ty0; y <= ty1; ++y)
    for (int x = tx0; x <= tx1; ++x) {
      const size_t pixel = out.pixelIndex(x, y);
      FragmentNode* slot = &out.slots[pixel * size_t(k)];
      const int n = out.count[pixel];
      for (int i = 0; i < n; ++i) slot[i].setThickness(config.thicknessAt(slot[i].depth));
      for (int i = n; i < k; ++i) slot[i] = FragmentNode{0.0f, 0u, 0u, 0u}, out.triangle[pixel * size_t(k) + size_t(i)] = kNullIndex;
    }
  generated += gen;
}

}  // namespace

LayerCapture::LayerCapture() : setup_(std::make_unique<RasterSetup>()) {}
LayerCapture::~LayerCapture() = default;
LayerCapture::LayerCapture(LayerCapture&&) noexcept = default;
LayerCapture& LayerCapture::operator=(LayerCapture&&) noexcept = default;
LayerCapture::LayerCapture(const LayerCapture&) : LayerCapture() {}
LayerCapture& LayerCapture::operator=(const LayerCapture&) { return *this; }

size_t LayerCapture::scratchBytes() const {
  if (!setup_) return 0;
  const RasterSetup& s = *setup_;
  size_t bytes = s.clip.capacity() * sizeof(glm::vec4) + (s.camPos.capacity() + s.camNormals.capacity()) * sizeof(glm::vec3) +
                 s.setups.capacity() * sizeof(raster::TriangleSetup) + s.subs.capacity() * sizeof(raster::SubTriangle*) +
                 (s.materialPacked.capacity() + s.chunkBase.capacity() + s.counts.capacity() + s.offsets.capacity() +
                  s.tileStart.capacity() + s.tileList.capacity()) *
                     sizeof(uint32_t);
  for (const auto& c : s.chunkSubs) bytes += c.capacity() * sizeof(raster::SubTriangle);
  return bytes;
}

void LayerCapture::capture(const Scene& scene, const Camera& camera, const RasterConfig& rasterConfig, const LayerConfig& config,
                           LayerArrays& layers, std::vector<uint32_t>& complexity, CaptureStats* stats) {
  validateLayerConfig(config);
  LT_CHECK(rasterConfig.tileSize > 0 && rasterConfig.tileSize <= kMaxTileSize, rasterConfig.tileSize);
  if (config.adaptiveThickness || config.minSeparation > 0.0f)
    inputError("tile-local capture: adaptive thickness and --min-separation need whole fragment lists (use the list pipeline)");
  if (!setup_) setup_ = std::make_unique<RasterSetup>();
  const auto t0 = std::chrono::steady_clock::now();
  raster::prepareRaster(scene, camera, rasterConfig, *setup_);
  const auto t1 = std::chrono::steady_clock::now();

  const size_t pixels = size_t(camera.width()) * size_t(camera.height()), k = size_t(config.k);
  if (layers.slots.size() != pixels * k)
    checkAllocation(cat("the k-layer arrays (k = ", config.k, ")"), pixels * (k * (sizeof(FragmentNode) + sizeof(uint32_t)) + 1));
  layers.width = camera.width();
  layers.height = camera.height();
  layers.k = config.k;
  layers.slots.resize(pixels * k);  // every element is written by its tile below
  layers.count.resize(pixels);
  layers.triangle.resize(pixels * k);
  complexity.resize(pixels);

  std::atomic<uint64_t> generated{0};
  const RasterSetup& setup = *setup_;
  parallelFor(tbb::blocked_range<size_t>(0, setup.numTiles(), 1), [&](const tbb::blocked_range<size_t>& r) {
    uint64_t gen = 0;
    for (size_t tile = r.begin(); tile != r.end(); ++tile) captureTile(scene, camera, setup, config, tile, layers, complexity, gen);
    generated += gen;
  });
  const auto t2 = std::chrono::steady_clock::now();
  if (stats) {
    stats->setupMs = msBetween(t0, t1);
    stats->tilesMs = msBetween(t1, t2);
    stats->generated = generated;
    stats->subTriangles = setup.subs.size();
  }
}

}  // namespace lt
