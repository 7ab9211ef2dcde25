// The tile capture is compiled once per vector target: this file includes itself through
// hwy/foreach_target.h (the section at its end); everything else in it is compiled once.
#ifndef LAYERTRACE_RASTER_CAPTURE_ONCE
#define LAYERTRACE_RASTER_CAPTURE_ONCE
#include "layertrace/raster/capture.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/raster/raster_setup.h"
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

/// Where the list-producing pass writes (FragmentLists in exact-size storage): pixel p's
/// fragments occupy nodes [offset[p], offset[p] + complexity[p]) in generation order, each node's
/// `next` naming the one generated before it, so a list read from its head is last-generated-
/// first — the reference pool's order. `cursor` (the lists' head array) counts up from offset[p]
/// during the pass and becomes the head at the end.
struct ListOutput {
  FragmentNode* nodes;
  uint32_t* triangle;
  const uint32_t* offset;
  uint32_t* cursor;
};

/// Every fragment of tile `tile` (inclusive pixel bounds tx0…tx1 × ty0…ty1), in the order the
/// lists keep (the tile's sub-triangles ascending, rows top-down, pixels left to right):
/// f(binned sub-triangle, its index in the tile's list, px, py, depth). Returns the count.
/// Fragments an alpha test removes (raster::fragmentPresent) are skipped and not counted.
template <class F>
inline uint64_t forEachFragment(const Scene& scene, const Camera& camera, const RasterSetup& setup, size_t tile, int tx0, int ty0,
                                int tx1, int ty1, F&& f) {
  uint64_t gen = 0;
  float depths[kMaxTileSize];
  for (uint32_t i = setup.tileStart[tile]; i < setup.tileStart[tile + 1]; ++i) {
    const RasterSetup::Binned b = setup.binned(scene, i);
    const raster::SubTriangle& s = b.sub;
    raster::forEachCoveredSpan(s, std::max(tx0, s.px0), std::max(ty0, s.py0), std::min(tx1, s.px1), std::min(ty1, s.py1),
                               [&](int py, int xa, int xb) {
                                 // Depths of the whole span first: one loop the compiler
                                 // vectorizes (the same IEEE operations per lane, so the same bits).
                                 const int n = xb - xa + 1;
                                 raster::spanDepths(camera, b.setup, py, xa, n, depths);
                                 if (!(b.flags & RasterSetup::kCutOut)) {
                                   gen += uint64_t(n);
                                   for (int d = 0; d < n; ++d) f(b, i, xa + d, py, depths[d]);
                                   return;
                                 }
                                 for (int d = 0; d < n; ++d)  // alpha-tested: cut-away fragments do not exist
                                   if (raster::fragmentPresent(scene, camera, b.setup, s.triangle, raster::pixelRay(camera, xa + d, py), depths[d]))
                                     ++gen, f(b, i, xa + d, py, depths[d]);
                               });
  }
  return gen;
}

/// One tile: every fragment of the tile's triangles goes straight into its pixel's k slots
/// (the insertion sort of Hofmann et al. 2017, §4.2, run as the fragments arrive instead of over a
/// finished list). Without lists, a fragment behind a full pixel's k-th is counted and dropped
/// before its normal is evaluated; with lists (kLists) every fragment is also written to its
/// pixel's list.
template <bool kLists>
inline void captureTileImpl(const Scene& scene, const Camera& camera, const RasterSetup& setup, const LayerConfig& config,
                            size_t tile, LayerArrays& out, std::vector<uint32_t>& complexity, uint64_t& generated,
                            const ListOutput& lists) {
  int tx0, ty0, tx1, ty1;
  setup.tileBounds(tile, camera, tx0, ty0, tx1, ty1);
  const int k = config.k;
  for (int y = ty0; y <= ty1; ++y) {
    const size_t row = out.pixelIndex(tx0, y);
    std::fill_n(&out.count[row], tx1 - tx0 + 1, uint8_t(0));
    if constexpr (!kLists) std::fill_n(&complexity[row], tx1 - tx0 + 1, 0u);  // the counting pass set it
  }
  const uint64_t gen = forEachFragment(scene, camera, setup, tile, tx0, ty0, tx1, ty1,
                                       [&](const RasterSetup::Binned& b, uint32_t, int px, int py, float depth) {
    const size_t pixel = out.pixelIndex(px, py);
    auto normal = [&] { return raster::fragmentNormal(camera, b.setup, setup.camNormals.data(), b.vertices, raster::pixelRay(camera, px, py), depth); };
    auto albedoSpec = [&] { return raster::fragmentAlbedoSpec(scene, camera, b, raster::pixelRay(camera, px, py), depth); };
    uint32_t packed = 0, colour = 0;
    if constexpr (kLists) {
      packed = normal();
      colour = albedoSpec();
      const uint32_t node = lists.cursor[pixel]++;
      lists.nodes[node] = {depth, packed, colour, node == lists.offset[pixel] ? kNullIndex : node - 1};
      lists.triangle[node] = b.sub.triangle;
    } else {
      ++complexity[pixel];
    }
    FragmentNode* slot = &out.slots[pixel * size_t(k)];
    uint32_t* tri = &out.triangle[pixel * size_t(k)];
    const int count = out.count[pixel];
    // The newest fragment ranks first among equal depths (see capture.h).
    if (count == k && depth > slot[k - 1].depth) return;
    int j = std::min(count, k - 1);
    for (; j > 0 && depth <= slot[j - 1].depth; --j) slot[j] = slot[j - 1], tri[j] = tri[j - 1];
    if constexpr (!kLists) packed = normal(), colour = albedoSpec();
    slot[j] = {depth, packed, colour, 0u};
    tri[j] = b.sub.triangle;
    out.count[pixel] = uint8_t(std::min(count + 1, k));
  });
  for (int y = ty0; y <= ty1; ++y)
    for (int x = tx0; x <= tx1; ++x) {
      const size_t pixel = out.pixelIndex(x, y);
      FragmentNode* slot = &out.slots[pixel * size_t(k)];
      const int n = out.count[pixel];
      for (int i = 0; i < n; ++i) slot[i].setThickness(config.thicknessAt(slot[i].depth));
      for (int i = n; i < k; ++i) slot[i] = FragmentNode{0.0f, 0u, 0u, 0u}, out.triangle[pixel * size_t(k) + size_t(i)] = kNullIndex;
      if constexpr (kLists) lists.cursor[pixel] = lists.cursor[pixel] == lists.offset[pixel] ? kNullIndex : lists.cursor[pixel] - 1;
    }
  generated += gen;
}

// One tile's capture, compiled for every vector target of Google Highway and dispatched to the
// best one of the CPU (the end of this file): the span's depth loop vectorizes to 8 lanes with
// AVX2 and 16 with AVX-512.
void captureTile(const Scene& scene, const Camera& camera, const RasterSetup& setup, const LayerConfig& config, size_t tile,
                 LayerArrays& out, std::vector<uint32_t>& complexity, uint64_t& generated);
void captureTileWithLists(const Scene& scene, const Camera& camera, const RasterSetup& setup, const LayerConfig& config, size_t tile,
                          LayerArrays& out, std::vector<uint32_t>& complexity, uint64_t& generated, const ListOutput& lists);

/// Pass `layer` of depth peeling over one tile (LayerCapture::capturePeeled): the nearest fragment
/// behind the pixel's layer − 1 becomes its slot `layer`.
void peelTile(const Scene& scene, const Camera& camera, const RasterSetup& setup, const LayerConfig& config, size_t tile, int layer,
              LayerArrays& out, std::vector<uint32_t>& complexity, uint64_t& generated) {
  int tx0, ty0, tx1, ty1;
  setup.tileBounds(tile, camera, tx0, ty0, tx1, ty1);
  const int k = config.k, tw = tx1 - tx0 + 1, th = ty1 - ty0 + 1;
  if (layer == 0)
    for (int y = ty0; y <= ty1; ++y) {
      std::fill_n(&out.count[out.pixelIndex(tx0, y)], tw, uint8_t(0));
      std::fill_n(&complexity[out.pixelIndex(tx0, y)], tw, 0u);
    }
  // The pass's winner per pixel of the tile: depth, triangle and the binned sub-triangle.
  constexpr uint32_t kNone = 0xFFFFFFFFu;
  thread_local std::vector<float> bestDepth;
  thread_local std::vector<uint32_t> bestTriangle, bestBin;
  bestDepth.assign(size_t(tw) * size_t(th), std::numeric_limits<float>::infinity());
  bestTriangle.assign(size_t(tw) * size_t(th), kNone);
  bestBin.assign(size_t(tw) * size_t(th), kNone);
  const uint64_t gen = forEachFragment(scene, camera, setup, tile, tx0, ty0, tx1, ty1,
                                       [&](const RasterSetup::Binned& b, uint32_t i, int px, int py, float depth) {
    const size_t pixel = out.pixelIndex(px, py);
    const uint32_t triangle = b.sub.triangle;
    if (layer == 0) {
      ++complexity[pixel];
    } else {
      // Only what lies behind the previous layer.
      if (out.count[pixel] != layer) return;
      const size_t prev = pixel * size_t(k) + size_t(layer - 1);
      const float prevDepth = out.slots[prev].depth;
      if (config.minSeparation > 0.0f ? depth < prevDepth + config.minSeparation
                                      : !(depth > prevDepth || (depth == prevDepth && triangle < out.triangle[prev])))
        return;
    }
    const size_t local = size_t(py - ty0) * size_t(tw) + size_t(px - tx0);
    if (depth < bestDepth[local] || (depth == bestDepth[local] && triangle > bestTriangle[local]))
      bestDepth[local] = depth, bestTriangle[local] = triangle, bestBin[local] = i;
  });
  for (int y = ty0; y <= ty1; ++y)
    for (int x = tx0; x <= tx1; ++x) {
      const size_t local = size_t(y - ty0) * size_t(tw) + size_t(x - tx0), pixel = out.pixelIndex(x, y);
      const size_t slot = pixel * size_t(k) + size_t(layer);
      if (bestBin[local] != kNone) {
        const RasterSetup::Binned b = setup.binned(scene, bestBin[local]);
        const float depth = bestDepth[local];
        const raster::PixelRay ray = raster::pixelRay(camera, x, y);
        const uint32_t packed = raster::fragmentNormal(camera, b.setup, setup.camNormals.data(), b.vertices, ray, depth);
        out.slots[slot] = {depth, packed, raster::fragmentAlbedoSpec(scene, camera, b, ray, depth), 0u};
        out.slots[slot].setThickness(config.thicknessAt(depth));
        out.triangle[slot] = b.sub.triangle;
        out.count[pixel] = uint8_t(layer + 1);
      } else {
        out.slots[slot] = FragmentNode{0.0f, 0u, 0u, 0u};
        out.triangle[slot] = kNullIndex;
      }
    }
  generated += gen;
}

/// The counting pass of the list-producing capture: fragments per pixel (coverage, and for
/// alpha-tested triangles the alpha test at the fragment's depth, as forEachFragment).
void countTile(const Scene& scene, const Camera& camera, const RasterSetup& setup, size_t tile, int width, std::vector<uint32_t>& complexity) {
  int tx0, ty0, tx1, ty1;
  setup.tileBounds(tile, camera, tx0, ty0, tx1, ty1);
  for (int y = ty0; y <= ty1; ++y) std::fill_n(&complexity[size_t(y) * size_t(width) + size_t(tx0)], tx1 - tx0 + 1, 0u);
  float depths[kMaxTileSize];
  for (uint32_t i = setup.tileStart[tile]; i < setup.tileStart[tile + 1]; ++i) {
    const RasterSetup::Binned b = setup.binned(scene, i);
    const raster::SubTriangle& s = b.sub;
    raster::forEachCoveredSpan(s, std::max(tx0, s.px0), std::max(ty0, s.py0), std::min(tx1, s.px1), std::min(ty1, s.py1),
                               [&](int py, int xa, int xb) {
                                 uint32_t* row = &complexity[size_t(py) * size_t(width)];
                                 if (!(b.flags & RasterSetup::kCutOut)) {
                                   for (int x = xa; x <= xb; ++x) ++row[x];
                                   return;
                                 }
                                 raster::spanDepths(camera, b.setup, py, xa, xb - xa + 1, depths);
                                 for (int x = xa; x <= xb; ++x)
                                   row[x] += raster::fragmentPresent(scene, camera, b.setup, s.triangle, raster::pixelRay(camera, x, py), depths[x - xa]);
                               });
  }
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
                  s.tileStart.capacity() + s.tileList.capacity() + s.listOffset.capacity()) *
                     sizeof(uint32_t);
  for (const auto& c : s.chunkSubs) bytes += c.capacity() * sizeof(raster::SubTriangle);
  return bytes;
}

namespace {

/// Validates, sets up the view and sizes the k-layer arrays and the complexity counters.
void beginCapture(const Scene& scene, const Camera& camera, const RasterConfig& rasterConfig, const LayerConfig& config,
                  RasterSetup& setup, LayerArrays& layers, std::vector<uint32_t>& complexity, bool peeling = false) {
  validateLayerConfig(config);
  LT_CHECK(rasterConfig.tileSize > 0 && rasterConfig.tileSize <= kMaxTileSize, rasterConfig.tileSize);
  if (peeling && config.adaptiveThickness)
    inputError("--adaptive-thickness: needs every fragment of a pixel, which depth peeling does not keep (use --capture lists)");
  if (!peeling && (config.adaptiveThickness || config.minSeparation > 0.0f))
    inputError("tile-local capture: adaptive thickness and --min-separation sort whole fragment lists (sortAndTruncate)");
  raster::prepareRaster(scene, camera, rasterConfig, setup);
  const size_t pixels = size_t(camera.width()) * size_t(camera.height()), k = size_t(config.k);
  if (layers.slots.size() != pixels * k)
    checkAllocation(cat("the k-layer arrays (k = ", config.k, ")"), pixels * (k * (sizeof(FragmentNode) + sizeof(uint32_t)) + 1));
  layers.width = camera.width();
  layers.height = camera.height();
  layers.k = config.k;
  layers.slots.resize(pixels * k);  // every element is written by its tile
  layers.count.resize(pixels);
  layers.triangle.resize(pixels * k);
  complexity.resize(pixels);
}

template <class Body>
uint64_t forEachTile(const RasterSetup& setup, const Camera& camera, const TileDone* onTile, Body&& body) {
  std::atomic<uint64_t> generated{0};
  parallelFor(tbb::blocked_range<size_t>(0, setup.numTiles(), 1), [&](const tbb::blocked_range<size_t>& r) {
    uint64_t gen = 0;
    for (size_t tile = r.begin(); tile != r.end(); ++tile) {
      body(tile, gen);
      if (onTile) {
        int x0, y0, x1, y1;
        setup.tileBounds(tile, camera, x0, y0, x1, y1);
        (*onTile)(x0, y0, x1, y1);
      }
    }
    generated += gen;
  });
  return generated;
}

}  // namespace

void LayerCapture::capture(const Scene& scene, const Camera& camera, const RasterConfig& rasterConfig, const LayerConfig& config,
                           LayerArrays& layers, std::vector<uint32_t>& complexity, CaptureStats* stats, const TileDone* onTile) {
  if (!setup_) setup_ = std::make_unique<RasterSetup>();
  const RasterSetup& setup = *setup_;
  const auto t0 = std::chrono::steady_clock::now();
  beginCapture(scene, camera, rasterConfig, config, *setup_, layers, complexity);
  const auto t1 = std::chrono::steady_clock::now();
  const uint64_t generated =
      forEachTile(setup, camera, onTile, [&](size_t tile, uint64_t& gen) { captureTile(scene, camera, setup, config, tile, layers, complexity, gen); });
  const auto t2 = std::chrono::steady_clock::now();
  if (stats) *stats = CaptureStats{msBetween(t0, t1), msBetween(t1, t2), generated, setup.subs.size()};
}

void LayerCapture::capturePeeled(const Scene& scene, const Camera& camera, const RasterConfig& rasterConfig, const LayerConfig& config,
                                 LayerArrays& layers, std::vector<uint32_t>& complexity, CaptureStats* stats) {
  if (!setup_) setup_ = std::make_unique<RasterSetup>();
  const RasterSetup& setup = *setup_;
  const auto t0 = std::chrono::steady_clock::now();
  beginCapture(scene, camera, rasterConfig, config, *setup_, layers, complexity, true);
  const auto t1 = std::chrono::steady_clock::now();
  uint64_t generated = 0;
  for (int layer = 0; layer < config.k; ++layer)  // one geometry pass per layer, over the whole view
    generated += forEachTile(setup, camera, nullptr, [&](size_t tile, uint64_t& gen) {
      peelTile(scene, camera, setup, config, tile, layer, layers, complexity, gen);
    });
  const auto t2 = std::chrono::steady_clock::now();
  if (stats) *stats = CaptureStats{msBetween(t0, t1), msBetween(t1, t2), generated, setup.subs.size()};
}

void LayerCapture::captureWithLists(const Scene& scene, const Camera& camera, const RasterConfig& rasterConfig,
                                    const LayerConfig& config, LayerArrays& layers, FragmentLists& lists, CaptureStats* stats,
                                    const TileDone* onTile) {
  if (!setup_) setup_ = std::make_unique<RasterSetup>();
  RasterSetup& setup = *setup_;
  const auto t0 = std::chrono::steady_clock::now();
  beginCapture(scene, camera, rasterConfig, config, setup, layers, lists.complexity);
  const auto t1 = std::chrono::steady_clock::now();
  const int W = camera.width();
  const size_t pixels = size_t(W) * size_t(camera.height());
  lists.width = W;
  lists.height = camera.height();
  forEachTile(setup, camera, nullptr, [&](size_t tile, uint64_t&) { countTile(scene, camera, setup, tile, W, lists.complexity); });
  // Exact-size storage: pixel p's nodes start at the prefix sum of the counts before it.
  std::vector<uint32_t>& offset = setup.listOffset;
  offset.resize(pixels);
  const uint64_t total = parallelExclusiveScan(lists.complexity.data(), offset.data(), pixels, kMaxPoolFragments);
  if (total > kMaxPoolFragments)
    inputError("scene ", scene.name, ": ", total, " fragments exceed the 32-bit index limit of ", kMaxPoolFragments);
  if (total > lists.nodes.capacity())
    checkAllocation(cat("the fragment lists (", total, " fragments)"), total * (sizeof(FragmentNode) + sizeof(uint32_t)));
  lists.nodes.resize(total);
  lists.triangle.resize(total);
  lists.head.assign(offset.begin(), offset.end());  // the pass's cursors, then the heads
  const ListOutput out{lists.nodes.data(), lists.triangle.data(), offset.data(), lists.head.data()};
  const uint64_t generated = forEachTile(setup, camera, onTile, [&](size_t tile, uint64_t& gen) {
    captureTileWithLists(scene, camera, setup, config, tile, layers, lists.complexity, gen, out);
  });
  LT_CHECK(generated == total, generated, total);
  lists.generated = lists.stored = total;
  const auto t2 = std::chrono::steady_clock::now();
  if (stats) *stats = CaptureStats{msBetween(t0, t1), msBetween(t1, t2), generated, setup.subs.size()};
}

}  // namespace lt
#endif  // LAYERTRACE_RASTER_CAPTURE_ONCE

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "layertrace/raster/capture.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace lt::HWY_NAMESPACE {
// (flatten: the tile's loops inlined here, so compiled for the target; no FMA contraction, so
// every target writes the same bytes)
[[gnu::flatten]] void captureTileTarget(const Scene& scene, const Camera& camera, const RasterSetup& setup, const LayerConfig& config,
                                        size_t tile, LayerArrays& out, std::vector<uint32_t>& complexity, uint64_t& generated) {
  captureTileImpl<false>(scene, camera, setup, config, tile, out, complexity, generated, ListOutput{});
}
[[gnu::flatten]] void captureTileWithListsTarget(const Scene& scene, const Camera& camera, const RasterSetup& setup,
                                                 const LayerConfig& config, size_t tile, LayerArrays& out,
                                                 std::vector<uint32_t>& complexity, uint64_t& generated, const ListOutput& lists) {
  captureTileImpl<true>(scene, camera, setup, config, tile, out, complexity, generated, lists);
}
}  // namespace lt::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lt {
namespace {
HWY_EXPORT(captureTileTarget);
HWY_EXPORT(captureTileWithListsTarget);

void captureTile(const Scene& scene, const Camera& camera, const RasterSetup& setup, const LayerConfig& config, size_t tile,
                 LayerArrays& out, std::vector<uint32_t>& complexity, uint64_t& generated) {
  HWY_DYNAMIC_DISPATCH(captureTileTarget)(scene, camera, setup, config, tile, out, complexity, generated);
}
void captureTileWithLists(const Scene& scene, const Camera& camera, const RasterSetup& setup, const LayerConfig& config, size_t tile,
                          LayerArrays& out, std::vector<uint32_t>& complexity, uint64_t& generated, const ListOutput& lists) {
  HWY_DYNAMIC_DISPATCH(captureTileWithListsTarget)(scene, camera, setup, config, tile, out, complexity, generated, lists);
}
}  // namespace
}  // namespace lt
#endif
