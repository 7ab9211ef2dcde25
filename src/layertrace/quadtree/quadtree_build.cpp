// Construction of the plane/box quad-tree (Widmer et al. 2015, supplement, Algorithms 1 and 2).
#include <algorithm>
#include <chrono>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <glm/vec3.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/util/parallel.h"
#include "layertrace/quadtree/quadtree.h"
#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"

namespace lt {

void validateQuadtreeConfig(const QuadtreeConfig& c) {
  auto check = [](const char* option, float v) {
    if (!(v >= 0.0f) || !std::isfinite(v)) inputError(option, " ", v, ": must be a finite value >= 0");
  };
  check("--quadtree-lambda-h", c.lambdaH);
  check("--quadtree-lambda-d", c.lambdaD);
  check("--quadtree-gamma-norm", c.gammaNorm);
  check("--quadtree-gamma-dist", c.gammaDist);
  check("depthScale", c.depthScale);
}

namespace {

/// The scale at which λ_h = 10⁻³ is the w slope of a surface seen at 85° from its normal at the
/// median front-layer depth (quadtree.h), the median from at most ~64k samples.
float defaultDepthScale(const LayerArrays& layers, float focal) {
  std::vector<float> depths;
  const size_t pixels = layers.count.size(), stride = std::max<size_t>(1, pixels / 65536);
  for (size_t p = 0; p < pixels; p += stride)
    if (layers.count[p] > 0) depths.push_back(layers.slots[p * size_t(layers.k)].depth);
  if (depths.empty()) return 1.0f;
  auto mid = depths.begin() + std::ptrdiff_t(depths.size() / 2);
  std::nth_element(depths.begin(), mid, depths.end());
  // A surface at angle θ to the view ray has dw/dx = depthScale · tan θ / (depth · focal) per
  // pixel (w = depthScale / depth).
  const float grazing = std::tan(glm::radians(85.0f));
  return *mid > 0.0f ? 1e-3f * *mid * focal / grazing : 1.0f;
}

/// [lo, hi] of w over a node `size` pixels wide.
void nodeRange(const QuadNode& n, float size, float& lo, float& hi) {
  if (n.kind() == QuadNode::Plane) {
    const float r = 0.5f * size * (std::abs(n.b) + std::abs(n.c));
    lo = n.a - r, hi = n.a + r;
  } else {
    lo = n.a, hi = n.b;
  }
}

/// Algorithm 1 for pixel (x, y) of `layer`: a plane through the pixel's own w with, per axis,
/// the one-sided derivative of smaller magnitude (line 8; as printed, the larger:
/// printedLine8), zeroed above λ_h (line 10), and the
/// Laplacian discontinuity hint (line 3).
/// `w` holds the layer's w per pixel, NaN where the layer holds nothing.
QuadNode leafNode(const float* w0, int W, int H, const QuadtreeConfig& cfg, int x, int y) {
  auto wAt = [&](int px, int py) { return w0[size_t(py) * size_t(W) + size_t(px)]; };
  QuadNode n{};
  const float w = wAt(x, y);
  if (std::isnan(w)) return n;
  bool discontinuity = false;
  float grad[2] = {0.0f, 0.0f}, laplacian = 0.0f;
  for (int axis = 0; axis < 2; ++axis) {
    const int dx = axis == 0, dy = axis == 1;
    const bool hasPrev = axis == 0 ? x > 0 : y > 0, hasNext = axis == 0 ? x + 1 < W : y + 1 < H;
    const float prev = hasPrev ? wAt(x - dx, y - dy) : std::nanf(""), next = hasNext ? wAt(x + dx, y + dy) : std::nanf("");
    // A neighbour inside the image without a surface in this layer: the surface ends here.
    // (Outside the image is unknown, not a discontinuity.)
    if ((hasPrev && std::isnan(prev)) || (hasNext && std::isnan(next))) discontinuity = true;
    const float fwd = next - w, bwd = w - prev;  // NaN where missing
    float d = 0.0f;
    if (!std::isnan(fwd) && !std::isnan(bwd)) {
      const bool forwardSmaller = std::abs(fwd) < std::abs(bwd);
      d = forwardSmaller != cfg.printedLine8 ? fwd : bwd;  // printedLine8: the larger (QuadtreeConfig)
      // The paper's getLaplacian sums both axes; we add the absolute second differences so a
      // saddle (a step up in x, down in y) cannot cancel out.
      laplacian += std::abs(fwd - bwd);
    } else if (!std::isnan(fwd)) {
      d = fwd;
    } else if (!std::isnan(bwd)) {
      d = bwd;
    }
    // Line 10's comment ("zero large derivatives that connect different surfaces") is what we
    // implement; the pseudo-code's step(λ_h, |d|)·d would keep exactly those (printedLine10).
    if (cfg.printedLine10) grad[axis] = std::abs(d) >= cfg.lambdaH ? d : 0.0f;
    else grad[axis] = std::abs(d) > cfg.lambdaH ? 0.0f : d;
  }
  if (laplacian >= cfg.lambdaD) discontinuity = true;
  n.a = w, n.b = grad[0], n.c = grad[1];
  n.flags = QuadNode::Plane | (discontinuity ? QuadNode::kDiscontinuity : 0u);
  return n;
}

/// Algorithm 2 for one parent from its four children (Empty where outside the child level).
/// `childSize` is the children's width in pixels, `rootSize` the unit of the normals.
QuadNode parentNode(const QuadNode (&ch)[4], float childSize, float rootSize, const QuadtreeConfig& cfg) {
  uint32_t discontinuity = 0;
  bool allPlanes = true, any = false;
  for (const QuadNode& q : ch) {
    discontinuity |= q.flags & QuadNode::kDiscontinuity;
    allPlanes = allPlanes && q.kind() == QuadNode::Plane;
    any = any || q.kind() != QuadNode::Empty;
  }
  QuadNode out{};
  if (!any) return out;
  if (allPlanes) {
    // Line 6: the proxy normal is the normalised mean of the children's normals, taken in
    // (x, y, w) with x, y in root widths (the paper's texture coordinates).
    glm::vec3 normal[4], sum(0.0f);
    for (int i = 0; i < 4; ++i) sum += normal[i] = glm::normalize(glm::vec3(-ch[i].b * rootSize, -ch[i].c * rootSize, 1.0f));
    const glm::vec3 proxy = glm::normalize(sum);
    float maxAngle = 0.0f;
    for (const glm::vec3& n : normal) maxAngle = std::max(maxAngle, 1.0f - glm::dot(proxy, n));
    if (maxAngle < cfg.gammaNorm) {
      // Line 10: with the proxy's slope fixed, its origin is the least-squares fit to the child
      // planes sampled at the corners of their cells (the extremes of the difference of two
      // planes over a rectangle); the fit error p_i is the largest relative deviation there.
      const float gx = -proxy.x / (proxy.z * rootSize), gy = -proxy.y / (proxy.z * rootSize);
      const float h = 0.5f * childSize;
      float value[4][4], residual[4][4], mean = 0.0f;
      for (int i = 0; i < 4; ++i) {
        // Child centre relative to the parent's centre.
        const float cx = (i & 1) ? h : -h, cy = (i & 2) ? h : -h;
        for (int corner = 0; corner < 4; ++corner) {
          const float ox = (corner & 1) ? h : -h, oy = (corner & 2) ? h : -h;
          value[i][corner] = ch[i].a + ch[i].b * ox + ch[i].c * oy;
          residual[i][corner] = value[i][corner] - gx * (cx + ox) - gy * (cy + oy);
          mean += residual[i][corner];
        }
      }
      mean *= 1.0f / 16.0f;
      float maxError = 0.0f;
      for (int i = 0; i < 4; ++i)
        for (int corner = 0; corner < 4; ++corner)
          maxError = std::max(maxError, std::abs(residual[i][corner] - mean) / std::max(std::abs(value[i][corner]), 1e-30f));
      if (maxError < cfg.gammaDist) {
        out.a = mean, out.b = gx, out.c = gy;
        out.flags = QuadNode::Plane | discontinuity;
        return out;
      }
    }
  }
  // Lines 18–21: a box over the children's depth ranges.
  float lo = INFINITY, hi = -INFINITY;
  for (const QuadNode& q : ch) {
    if (q.kind() == QuadNode::Empty) continue;
    float l, u;
    nodeRange(q, childSize, l, u);
    lo = std::min(lo, l), hi = std::max(hi, u);
  }
  out.a = lo, out.b = hi;
  out.flags = QuadNode::Box | discontinuity;
  return out;
}

}  // namespace

Quadtree buildQuadtree(const LayerArrays& layers, const Camera& camera, const QuadtreeConfig& config) {
  validateQuadtreeConfig(config);
  const auto start = std::chrono::steady_clock::now();
  Quadtree t;
  t.width = layers.width, t.height = layers.height, t.k = layers.k;
  t.config = config;
  t.depthScale = config.depthScale > 0.0f ? config.depthScale : defaultDepthScale(layers, camera.focal());
  // Ceil-sized levels up to a 1×1 root (non-power-of-two sizes: nodes past the image are empty).
  for (int w = t.width, h = t.height;; w = (w + 1) / 2, h = (h + 1) / 2) {
    t.levels.push_back({w, h, t.nodesPerLayer});
    t.nodesPerLayer += size_t(w) * size_t(h);
    if (w == 1 && h == 1) break;
  }
  const float rootSize = float(1 << (t.levelCount() - 1));
  checkAllocation(cat("the quad-tree (", t.nodesPerLayer * size_t(t.k), " nodes)"), t.nodesPerLayer * size_t(t.k) * sizeof(QuadNode));
  t.nodes.resize(t.nodesPerLayer * size_t(t.k));
  t.kindCounts.assign(t.levels.size(), {0, 0, 0});
  std::vector<float> w(size_t(t.width) * size_t(t.height));
  for (int layer = 0; layer < t.k; ++layer) {
    QuadNode* base = &t.nodes[size_t(layer) * t.nodesPerLayer];
    // One division per pixel: the layer's w, read nine times by Algorithm 1.
    parallelFor(tbb::blocked_range<size_t>(0, w.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t p = r.begin(); p != r.end(); ++p)
        w[p] = layers.count[p] > layer ? t.depthScale / layers.slots[p * size_t(layers.k) + size_t(layer)].depth : std::nanf("");
    });
    parallelFor(tbb::blocked_range<int>(0, t.height, 8), [&](const tbb::blocked_range<int>& r) {
      for (int y = r.begin(); y != r.end(); ++y)
        for (int x = 0; x < t.width; ++x) base[size_t(y) * size_t(t.width) + size_t(x)] = leafNode(w.data(), t.width, t.height, config, x, y);
    });
    for (int l = 1; l < t.levelCount(); ++l) {
      const QuadtreeLevel& cl = t.levels[size_t(l - 1)];
      const QuadtreeLevel& pl = t.levels[size_t(l)];
      const float childSize = float(1 << (l - 1));
      parallelFor(tbb::blocked_range<int>(0, pl.height, 8), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y != r.end(); ++y)
          for (int x = 0; x < pl.width; ++x) {
            QuadNode ch[4] = {};
            for (int i = 0; i < 4; ++i) {
              const int cx = 2 * x + (i & 1), cy = 2 * y + (i >> 1);
              if (cx < cl.width && cy < cl.height) ch[i] = base[cl.offset + size_t(cy) * size_t(cl.width) + size_t(cx)];
            }
            base[pl.offset + size_t(y) * size_t(pl.width) + size_t(x)] = parentNode(ch, childSize, rootSize, config);
          }
      });
    }
    for (int l = 0; l < t.levelCount(); ++l) {
      const QuadtreeLevel& lv = t.levels[size_t(l)];
      for (size_t i = 0; i < size_t(lv.width) * size_t(lv.height); ++i) ++t.kindCounts[size_t(l)][base[lv.offset + i].kind()];
    }
  }
  t.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return t;
}

}  // namespace lt
