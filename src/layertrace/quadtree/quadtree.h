// The adaptive acceleration structure for screen-space ray tracing of Widmer et al. 2015 (HPG
// 2015, supplement Algorithms 1–4): per depth layer a quad-tree whose nodes are planes where the
// depth is locally planar and min/max boxes elsewhere, traced root to leaf with a stackless
// walk that climbs by the most significant changed bit of the node coordinate.
//
// DEPTH SPACE (Widmer et al. 2015 leave it open; our choice): planes are fitted and
// intersected in w = depthScale / depth over pixel coordinates. A planar triangle is planar in
// (x, y, 1/depth) — perspective projection maps planes to planes there, but not in linear depth —
// and a ray is a straight line in the same space (1/depth is linear along its screen projection,
// screen_segment.h), so a ray–plane hit on a flat surface is exact. w is the depth-buffer value
// of a camera whose near plane is at depthScale (reversed-Z with an infinite far plane), the
// space in which the paper's λ = 10⁻³ is expressed. That value's meaning depends on the near
// plane, which the paper does not give; we fix it by what λ_h decides. A surface at angle θ to
// the view ray has a w slope of depthScale · tan θ / (depth · focal) per pixel, so depthScale
// defaults to the value at which λ_h = 10⁻³ is the slope of a surface seen at 85° at the
// frame's median front-layer depth: steeper counts as "connecting different surfaces". Tying
// the scale to the view (not the scene bounds, which a skybox can make 8,000 units wide) keeps
// the thresholds' meaning at any scene scale and resolution. (A tenth of the median depth, our
// first choice, zeroed the slopes of spheres beyond 63° at 400 × 225 and broke their hits into
// fronto-parallel steps.)
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/trace/tracer.h"
#include "layertrace/util/default_init.h"

namespace lt {

struct QuadtreeConfig {
  /// Algorithm 1 line 10: a one-sided derivative (w per pixel) above λ_h connects different
  /// surfaces and is zeroed.
  float lambdaH = 1e-3f;
  /// Algorithm 1 line 3: discontinuity hint where the Laplacian of w exceeds λ_d.
  float lambdaD = 1e-3f;
  /// Algorithm 2: four child planes merge into a proxy plane when every 1 − dot(N_proxy, N_i)
  /// is below γ_norm (normals in (x, y, w) with x, y in units of the root node's width)...
  float gammaNorm = 1e-4f;
  /// ...and the proxy stays within γ_dist of every child plane over the child's whole cell,
  /// relative to w (so γ_dist bounds the relative depth error of a proxy-plane hit). The paper
  /// gives no γ values; these keep hits on flat surfaces exact to ~1e-5 (a sweep:
  /// `bench --experiment gamma`).
  float gammaDist = 1e-5f;
  /// w = depthScale / depth; 0 = derived from the view (see above).
  float depthScale = 0.0f;
  /// Algorithm 3, line 1: each layer's walk starts at the root and descends. Off (the default),
  /// it starts at the ray's first pixel: every box above that pixel holds the surface the ray
  /// leaves, so the descent decides nothing (quadtree_tracer.cpp).
  bool rootStart = false;
  /// Algorithm 1, line 8 as printed: mix(d_f, d_b, |d_f| < |d_b|), which in GLSL picks d_b, the
  /// one-sided derivative of LARGER magnitude, where d_f is the smaller. Off (the default), the
  /// smaller one, which is what the line's purpose ("enforce smoothness") asks: across a depth
  /// step the larger derivative is the one that spans it.
  bool printedLine8 = false;
  /// Algorithm 1, line 10 as printed: step(λ_h, |d|)·d, which keeps the derivatives at or above
  /// λ_h and zeroes the small ones. Off (the default), the line does what its comment says: it
  /// zeroes the large derivatives that connect different surfaces.
  bool printedLine10 = false;
  /// A plane crossed from behind is a hit (the back face of an object seen from behind, which
  /// Embree hits too). Off, as in the single-layer pseudo-code, it is an occlusion only.
  bool backfaceHits = true;
};

/// One node: 16 bytes. Plane: w(x, y) = a + b (x − cx) + c (y − cy) about the node's centre
/// (cx, cy), in pixels. Box: w in [a, b]. Empty: no surface of this layer under the node.
/// Trivial (no member initialisers): the node arrays are allocated uninitialised and written
/// once by the parallel build; `QuadNode{}` is an empty node.
struct QuadNode {
  enum Kind : uint32_t { Empty = 0, Plane = 1, Box = 2 };
  static constexpr uint32_t kKindMask = 3, kDiscontinuity = 4;
  float a, b, c;
  uint32_t flags;
  Kind kind() const { return Kind(flags & kKindMask); }
  bool discontinuity() const { return (flags & kDiscontinuity) != 0; }
};

struct QuadtreeLevel {
  int width = 0, height = 0;  ///< ceil(W / 2^level) × ceil(H / 2^level): nodes past the image are empty
  size_t offset = 0;          ///< first node of the level within one layer's nodes
};

/// One quad-tree per layer of the k-layer arrays, all with the same level sizes. Level 0 is one
/// node per pixel; the top level is a single root.
struct Quadtree {
  int width = 0, height = 0, k = 0;
  float depthScale = 1.0f;
  QuadtreeConfig config;  ///< what it was built with (the tracer reads the traversal rules)
  std::vector<QuadtreeLevel> levels;
  size_t nodesPerLayer = 0;
  PoolVector<QuadNode> nodes;         ///< layer-major: [layer][level offset + y · level width + x]
  /// Per level, nodes of each kind summed over the layers (Empty, Plane, Box).
  std::vector<std::array<uint64_t, 3>> kindCounts;
  double buildMs = 0.0;

  int levelCount() const { return int(levels.size()); }
  const QuadNode& node(int layer, int level, int x, int y) const {
    const QuadtreeLevel& l = levels[size_t(level)];
    return nodes[size_t(layer) * nodesPerLayer + l.offset + size_t(y) * size_t(l.width) + size_t(x)];
  }
  size_t memoryBytes() const { return nodes.size() * sizeof(QuadNode); }
};

/// Algorithms 1 and 2 for every layer (parallel over rows). Throws InputError naming the option
/// for a negative or non-finite threshold.
Quadtree buildQuadtree(const LayerArrays& layers, const Camera& camera, const QuadtreeConfig& config);

/// InputError naming the option (--lambda-h, --lambda-d, --gamma-norm, --gamma-dist).
void validateQuadtreeConfig(const QuadtreeConfig& config);

class QuadtreeTracer : public TracerImpl<QuadtreeTracer> {
 public:
  QuadtreeTracer(const Camera& camera, const LayerArrays& layers, const Quadtree& tree);
  const char* name() const override { return "quadtree"; }
  /// Algorithms 3–4 per layer, continued from layer to layer at occlusion hits (trace/tracer.h).
  template <class C>
  TraceHit traceImpl(const Ray& ray, C& counters) const;

 private:
  struct Line;
  struct LayerResult;
  template <class C>
  LayerResult traceLayer(int layer, const Line& line, float sStart, float sEnd, C& counters) const;

  const Camera& camera_;
  const LayerArrays& layers_;
  const Quadtree& tree_;
};

}  // namespace lt
