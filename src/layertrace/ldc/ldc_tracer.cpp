// Layered depth cube traversal (Bürger et al. 2007, §1.4): per LDI, a DDA over the coarse blocks
// testing the ray's depth range against the block's [min, max], then a DDA over the block's texels
// testing their samples; a hit shortens the ray for the remaining LDIs; the nearest hit wins.
#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "layertrace/ldc/ldc.h"

namespace lt {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/// The ray in one view's texel coordinates: x(t) = px + dx t, y(t) = py + dy t (texels, y down),
/// depth(t) = pz + dz t (scene units), t in scene units along the ray; ix, iy = 1/dx, 1/dy
/// (infinite for 0).
struct ViewRay {
  float px, py, dx, dy, pz, dz, ix, iy;
  ViewRay(float px_, float py_, float dx_, float dy_, float pz_, float dz_)
      : px(px_), py(py_), dx(dx_), dy(dy_), pz(pz_), dz(dz_), ix(1.0f / dx_), iy(1.0f / dy_) {}
  float x(float t) const { return px + dx * t; }
  float y(float t) const { return py + dy * t; }
  float depth(float t) const { return pz + dz * t; }
};

/// Narrows [t0, t1] to where p + d t lies in [lo, hi] (inv = 1/d); false when that is empty.
inline bool clipSlab(float p, float d, float inv, float lo, float hi, float& t0, float& t1) {
  if (d == 0.0f) return p >= lo && p <= hi;
  float a = (lo - p) * inv, b = (hi - p) * inv;
  if (a > b) std::swap(a, b);
  t0 = std::max(t0, a);
  t1 = std::min(t1, b);
  return t0 <= t1;
}

/// The ray's depth range over the part of [t0, t1] where it lies above the texel rectangle
/// [x0, x1] × [y0, y1]; false when it never does.
inline bool depthRangeOver(const ViewRay& r, float x0, float x1, float y0, float y1, float t0, float t1, float& zLo,
                           float& zHi) {
  if (!clipSlab(r.px, r.dx, r.ix, x0, x1, t0, t1) || !clipSlab(r.py, r.dy, r.iy, y0, y1, t0, t1)) return false;
  const float za = r.depth(t0), zb = r.depth(t1);
  zLo = std::min(za, zb), zHi = std::max(za, zb);
  return true;
}

/// A 2D DDA over cells of `size` texels, started in a cell clamped to [cx0, cx1] × [cy0, cy1]:
/// visits the cells in the order the ray crosses them. The exits are computed from the cell
/// index each time (no accumulated increments), with the ray's reciprocal direction.
struct Dda {
  int ix, iy, stepX, stepY;
  float nextX, nextY;  // exit parameters through x and y
  float size;
  const ViewRay* r;

  void start(const ViewRay& ray, float cellSize, float t, int cx0, int cx1, int cy0, int cy1) {
    r = &ray, size = cellSize;
    ix = std::clamp(int(std::floor(ray.x(t) / cellSize)), cx0, cx1);
    iy = std::clamp(int(std::floor(ray.y(t) / cellSize)), cy0, cy1);
    stepX = ray.dx > 0.0f ? 1 : ray.dx < 0.0f ? -1 : 0;
    stepY = ray.dy > 0.0f ? 1 : ray.dy < 0.0f ? -1 : 0;
    nextX = exitX(), nextY = exitY();
  }
  float exitX() const { return stepX == 0 ? kInf : (float(ix + (stepX > 0)) * size - r->px) * r->ix; }
  float exitY() const { return stepY == 0 ? kInf : (float(iy + (stepY > 0)) * size - r->py) * r->iy; }
  float exit() const { return std::min(nextX, nextY); }
  void step() {
    if (nextX < nextY) {
      ix += stepX;
      nextX = exitX();
    } else {
      iy += stepY;
      nextY = exitY();
    }
  }
};

}  // namespace

struct LdcTracer::ViewHit {
  float t = kInf;
  int view = -1;
  uint32_t sample = 0;
};

LdcTracer::LdcTracer(const Camera& camera, const LayeredDepthCube& ldc) : camera_(camera), ldc_(ldc) {}

template <bool AnyHit, class C>
bool LdcTracer::traceView(const LdcView& v, glm::vec3 wo, glm::vec3 wd, float tMin, float& tMax, bool found,
                          ViewHit& best, C& counters) const {
  const float texel = ldc_.texel, inv = 1.0f / texel, eps = ldc_.config.epsilon, hitDistance = ldc_.config.hitDistance;
  const glm::vec3 o = v.camera.toCamera(wo), d = v.camera.dirToCamera(wd);
  const ViewRay r{float(v.width) * 0.5f + o.x * inv, float(v.height) * 0.5f - o.y * inv, d.x * inv, -d.y * inv, -o.z, -d.z};
  // Clip to the view's box: the texel rectangle and the depth range of the padded scene box.
  float t0 = tMin, t1 = tMax;
  const float zBoxLo = texel, zBoxHi = v.camera.far() - texel;
  if (!clipSlab(r.px, r.dx, r.ix, 0.0f, float(v.width), t0, t1) || !clipSlab(r.py, r.dy, r.iy, 0.0f, float(v.height), t0, t1) ||
      !clipSlab(r.pz, r.dz, 1.0f / r.dz, zBoxLo, zBoxHi, t0, t1))
    return false;
  // A sample's patch lies within (0.5 + eps) texels of its centre across, and — because its axis
  // is the triangle's dominant one, |n_u|, |n_v| ≤ |n_axis| — within 2 (0.5 + eps) texels in depth.
  const float half = (0.5f + eps) * texel, margin = 2.0f * half * 1.001f;
  const int B = ldc_.config.block, slots = ldc_.config.blockIntervals;

  Dda blocks;
  blocks.start(r, float(B), t0, 0, v.blocksX - 1, 0, v.blocksY - 1);
  float blockEntry = t0;
  for (;;) {
    const float blockExit = std::min(blocks.exit(), t1);
    counters.iteration(1);
    const glm::vec2* spans = &v.blockIntervals[(size_t(blocks.iy) * size_t(v.blocksX) + size_t(blocks.ix)) * size_t(slots)];
    float zLo, zHi;
    const float bx0 = float(blocks.ix * B), by0 = float(blocks.iy * B);
    bool overlap = false;
    if (spans[0].x <= spans[0].y &&
        depthRangeOver(r, bx0 - eps, bx0 + float(B) + eps, by0 - eps, by0 + float(B) + eps, tMin, tMax, zLo, zHi))
      for (int k = 0; k < slots && spans[k].x <= spans[k].y && !overlap; ++k)
        overlap = zHi + margin >= spans[k].x && zLo - margin <= spans[k].y;
    if (overlap) {
      // The block's texels, entered where the ray enters the block.
      const int x0 = blocks.ix * B, y0 = blocks.iy * B;
      const int x1 = std::min(x0 + B, v.width) - 1, y1 = std::min(y0 + B, v.height) - 1;
      Dda cells;
      cells.start(r, 1.0f, blockEntry, x0, x1, y0, y1);
      for (int guard = 0; guard < 2 * B + 2; ++guard) {
        const float cellExit = std::min(cells.exit(), blockExit);
        counters.iteration(0);
        counters.pixel();
        const float cx = float(cells.ix), cy = float(cells.iy);
        const size_t p = v.texelIndex(cells.ix, cells.iy);
        const uint32_t first = v.offset[p], end = v.offset[p + 1];
        if (first < end && depthRangeOver(r, cx - eps, cx + 1.0f + eps, cy - eps, cy + 1.0f + eps, tMin, tMax, zLo, zHi)) {
          const glm::vec3 centre{(cx + 0.5f - float(v.width) * 0.5f) * texel, -(cy + 0.5f - float(v.height) * 0.5f) * texel, 0.0f};
          for (uint32_t i = first; i < end; ++i) {
            const FragmentNode& s = v.samples[i];
            if (s.depth < zLo - margin) continue;
            if (s.depth > zHi + margin) break;
            counters.interval();
            const glm::vec3 P{centre.x, centre.y, -s.depth};
            float t;
            if (hitDistance > 0.0f) {
              // The paper's test: the ray's nearest point to the sample within the distance.
              t = glm::dot(P - o, d) / glm::dot(d, d);
              if (!(t >= tMin && (found ? t < tMax : t <= tMax))) continue;
              if (glm::length(o + d * t - P) >= hitDistance) continue;
            } else {
              // Where the ray meets the sample's plane, inside the widened texel.
              const glm::vec3 n = decodeOctahedral(s.next);
              const float denom = glm::dot(d, n);
              if (denom == 0.0f) continue;
              t = glm::dot(P - o, n) / denom;
              // Only a strictly nearer sample replaces a hit (ties: the first one met).
              if (!(t >= tMin && (found ? t < tMax : t <= tMax))) continue;
              const glm::vec3 X = o + d * t;
              if (std::abs(X.x - P.x) > half || std::abs(X.y - P.y) > half) continue;
            }
            tMax = t;
            best = {t, v.axis, i};
            found = true;
            if constexpr (AnyHit) return true;
          }
        }
        // Texels after this one are entered beyond the best hit: nothing nearer is left (a
        // widened patch reaching back by eps texels is the same surface within the tolerance).
        if (cellExit >= blockExit || cellExit > tMax) break;
        cells.step();
        if (cells.ix < x0 || cells.ix > x1 || cells.iy < y0 || cells.iy > y1) break;
      }
    }
    if (blockExit >= t1 || blockExit > tMax) break;
    blockEntry = blockExit;
    blocks.step();
    if (blocks.ix < 0 || blocks.ix >= v.blocksX || blocks.iy < 0 || blocks.iy >= v.blocksY) break;
  }
  return found;
}

template <bool AnyHit, class C>
TraceHit LdcTracer::traceAny(const Ray& ray, C& counters) const {
  const glm::vec3 wo = camera_.toWorld(ray.origin), wd = camera_.dirToWorld(ray.dir);
  // A secondary ray ignores its own surface, sampled at texel resolution (ldc.h).
  const float tMin = ray.startsOnSurface ? ldc_.texel : 0.0f;
  float tMax = ray.maxDistance;
  ViewHit best;
  bool found = false;
  // The LDI of the ray's dominant axis first: a ray mostly along x mostly meets surfaces facing
  // x, and its hit there shortens the ray for the other two (the order changes only the work:
  // the nearest hit wins, ties to the view traced first).
  const glm::vec3 m = glm::abs(wd);
  int order[3] = {0, 1, 2};
  std::stable_sort(order, order + 3, [&](int a, int b) { return m[a] > m[b]; });
  for (int a : order) {
    found = traceView<AnyHit>(ldc_.views[size_t(a)], wo, wd, tMin, tMax, found, best, counters);
    if (AnyHit && found) break;
  }
  TraceHit hit;
  if (!found) return hit;
  const LdcView& v = ldc_.views[size_t(best.view)];
  const FragmentNode& s = v.samples[best.sample];
  hit.hit = true;
  hit.point = ray.origin + ray.dir * best.t;
  hit.normal = camera_.dirToCamera(v.camera.dirToWorld(decodeOctahedral(s.normal)));
  hit.albedoSpec = s.albedoSpec;
  hit.triangle = v.triangle[best.sample];
  if (!camera_.pixelOf(hit.point, hit.x, hit.y)) hit.x = hit.y = -1;
  return hit;
}

template TraceHit LdcTracer::traceAny<false>(const Ray&, RayCounters&) const;
template TraceHit LdcTracer::traceAny<false>(const Ray&, NoCounters&) const;
template TraceHit LdcTracer::traceAny<true>(const Ray&, RayCounters&) const;
template TraceHit LdcTracer::traceAny<true>(const Ray&, NoCounters&) const;

}  // namespace lt
