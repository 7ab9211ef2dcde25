#include "layertrace/raster/rasterizer.h"

#include <algorithm>
#include <atomic>
#include <chrono>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/raster/raster_setup.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

namespace lt {
namespace {

using raster::RasterSetup;

constexpr uint32_t kAllocChunk = 512;  // pool nodes a tile claims at once

struct TileAllocator {
  uint32_t next = 0, end = 0;
};

/// The reference pass (Hofmann et al. 2017, §4.1): every fragment is linked into its pixel's list
/// in a shared pool; each tile claims pool chunks from one atomic counter.
struct ListPass {
  const Scene& scene;
  const Camera& camera;
  const RasterSetup& setup;

  uint64_t run(FragmentLists& lists) const {
    std::atomic<uint64_t> cursor{0}, generated{0}, stored{0};
    const uint64_t capacity = lists.nodes.size();
    parallelFor(tbb::blocked_range<size_t>(0, setup.numTiles(), 1), [&](const tbb::blocked_range<size_t>& r) {
      TileAllocator alloc;
      uint64_t gen = 0, sto = 0;
      for (size_t tile = r.begin(); tile != r.end(); ++tile) {
        int tx0, ty0, tx1, ty1;
        setup.tileBounds(tile, camera, tx0, ty0, tx1, ty1);
        for (uint32_t i = setup.tileStart[tile]; i < setup.tileStart[tile + 1]; ++i) {
          const RasterSetup::Binned b = setup.binned(scene, i);
          const raster::SubTriangle& s = b.sub;
          const raster::TriangleSetup& ts = b.setup;
          raster::forEachCovered(s, std::max(tx0, s.px0), std::max(ty0, s.py0), std::min(tx1, s.px1), std::min(ty1, s.py1),
                                 [&](int px, int py) {
                                   const raster::PixelRay ray = raster::pixelRay(camera, px, py);
                                   const float depth = raster::fragmentDepth(camera, ts, ray);
                                   if ((b.flags & RasterSetup::kCutOut) && !raster::fragmentPresent(scene, camera, ts, s.triangle, ray, depth))
                                     return;  // discarded by the alpha test
                                   ++gen;
                                   const size_t pixel = lists.pixelIndex(px, py);
                                   ++lists.complexity[pixel];
                                   if (alloc.next == alloc.end) {
                                     const uint64_t base = cursor.fetch_add(kAllocChunk, std::memory_order_relaxed);
                                     if (base >= capacity) return;  // pool exhausted: counted as lost (generated - stored)
                                     alloc.next = uint32_t(base);
                                     alloc.end = uint32_t(std::min<uint64_t>(base + kAllocChunk, capacity));
                                   }
                                   const uint32_t node = alloc.next++;
                                   ++sto;
                                   FragmentNode& f = lists.nodes[node];
                                   f.depth = depth;
                                   f.normal = raster::fragmentNormal(camera, ts, setup.camNormals.data(), b.vertices, ray, depth);
                                   f.albedoSpec = raster::fragmentAlbedoSpec(scene, camera, b, ray, depth);
                                   f.next = lists.head[pixel];
                                   lists.head[pixel] = node;
                                   lists.triangle[node] = s.triangle;
                                 });
        }
      }
      generated += gen;
      stored += sto;
    });
    lists.generated = generated;
    lists.stored = stored;
    return generated - stored;
  }
};

}  // namespace

FragmentLists rasterize(const Scene& scene, const Camera& camera, const RasterConfig& config, RasterStats* stats) {
  const auto start = std::chrono::steady_clock::now();
  const int W = camera.width(), H = camera.height();
  RasterSetup setup;
  raster::prepareRaster(scene, camera, config, setup);

  const ListPass pass{scene, camera, setup};
  uint64_t capacity = config.poolCapacity ? config.poolCapacity : std::max<uint64_t>(uint64_t(W) * uint64_t(H) * 8, 1u << 20);
  if (capacity > kMaxPoolFragments)
    inputError("fragment pool capacity ", capacity, " exceeds the 32-bit index limit of ", kMaxPoolFragments);
  RasterStats st;
  st.subTriangles = setup.subs.size();
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
    capacity = lists.generated + setup.numTiles() * kAllocChunk;
    if (capacity > kMaxPoolFragments)
      inputError("scene ", scene.name, ": ", lists.generated, " fragments exceed the 32-bit index limit of ", kMaxPoolFragments);
  }
  st.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (stats) *stats = st;
  return lists;
}

}  // namespace lt
