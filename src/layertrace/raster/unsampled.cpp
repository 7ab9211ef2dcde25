#include "layertrace/raster/unsampled.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>

#include <glm/geometric.hpp>

#include "layertrace/raster/raster_setup.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

namespace lt {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
/// Projected coordinates beyond this many pixels are clipped to the view's guard band before the
/// thin-triangle rule samples them: floats there still step by 1/8 pixel.
constexpr float kFarPixels = float(1 << 20);

/// A convex polygon in screen space with 1/depth at its corners (affine across a triangle's
/// plane, so exact at every point clipping makes along an edge): (x, y, 1/depth, 1).
struct Poly {
  int n = 0;
  glm::vec4 p[8];
  /// Keeps the part where sign · (p[axis] − at) ≥ 0.
  Poly clip(int axis, float at, float sign) const {
    glm::vec4 plane(0.0f, 0.0f, 0.0f, -sign * at);
    plane[axis] = sign;
    Poly out;
    out.n = raster::clipAgainst(p, n, plane, out.p);
    return out;
  }
};

/// The x-range where the triangle crosses the horizontal line y (empty: lo > hi).
void spanAt(const glm::vec3 v[3], float y, float& lo, float& hi) {
  lo = kInf, hi = -kInf;
  for (int i = 0; i < 3; ++i) {
    const glm::vec3 a = v[i], b = v[(i + 1) % 3];
    if ((a.y - y) * (b.y - y) > 0.0f || a.y == b.y) continue;
    const float x = a.x + (b.x - a.x) * ((y - a.y) / (b.y - a.y));
    lo = std::min(lo, x), hi = std::max(hi, x);
  }
}

/// The pixels where a triangle has depths the pixel's solid intervals do not hold —
/// where it lies in front of the pixel's first stored surface, or behind the end of its last
/// one, by more than `lastThicknessPx` footprints (the hybrid's solid intervals, known_space.h).
/// That happens where a triangle covers part of a pixel but not its centre (no sample stored it
/// there) in front of what the pixel stores, and where a surface seen at a grazing angle spans
/// more depth inside one pixel than its stored interval holds (found on assimp's heffalump.sib
/// seen from just below its base: its far part one pixel row high, several units deep; 2 % of
/// the hybrid's reflection rays passed through it as known-empty space). Knowledge ends at the
/// triangle's nearest depth in such a pixel (`mark`). A mesh's neighbouring triangles lie within
/// that margin of each other, and a pixel whose centre a triangle covers holds it (or is
/// truncated in front of it) within its depth change across the pixel: those pixels are not
/// marked unless the triangle changes depth by more than the margin across a pixel somewhere.
///
/// Every pixel the triangle overlaps also gets the triangle's nearest depth in its
/// square where that lies in front of the pixel's first stored surface (`front`): the solid
/// intervals start there (known_space.h). Where the square lies inside the triangle that is the
/// plane's value at the nearest corner (1/depth is affine: the centre's plus half the gradient's
/// L1 norm); on the triangle's border, the clipped polygon's.
template <class Mark, class Front>
void markUnheldDepths(const glm::vec3 v[3], const LayerArrays& layers, float focal, float lastThicknessPx, Mark&& mark, Front&& front) {
  const float area = (v[1].x - v[0].x) * (v[2].y - v[0].y) - (v[2].x - v[0].x) * (v[1].y - v[0].y);
  if (!(std::abs(area) > 1e-4f)) return;  // edge-on: the thin-triangle rule's case
  // 1/depth is affine on screen: its gradient, and the largest depth change across a pixel in
  // footprints (depth / focal), which is largest at the farthest corner.
  const float gx = ((v[1].z - v[0].z) * (v[2].y - v[0].y) - (v[2].z - v[0].z) * (v[1].y - v[0].y)) / area;
  const float gy = ((v[2].z - v[0].z) * (v[1].x - v[0].x) - (v[1].z - v[0].z) * (v[2].x - v[0].x)) / area;
  const float halfSpread = 0.5f * (std::abs(gx) + std::abs(gy));  // centre to the farthest corner, in 1/depth
  const float farthest = 1.0f / std::min({v[0].z, v[1].z, v[2].z});
  const bool grazing = !(focal * farthest * (std::abs(gx) + std::abs(gy)) < 0.5f * lastThicknessPx);
  const int W = layers.width, H = layers.height;
  const float ylo = std::min({v[0].y, v[1].y, v[2].y}), yhi = std::max({v[0].y, v[1].y, v[2].y});
  const int y0 = std::max(int(std::floor(ylo)), 0), y1 = std::min(int(std::floor(yhi)), H - 1);
  Poly tri;
  tri.n = 3;
  for (int i = 0; i < 3; ++i) tri.p[i] = glm::vec4(v[i], 1.0f);
  const size_t k = size_t(layers.k);
  const float margin = lastThicknessPx / focal;  // the margin's footprints per unit depth
  for (int y = y0; y <= y1; ++y) {
    const Poly band = tri.clip(1, float(y), 1.0f).clip(1, float(y + 1), -1.0f);
    if (band.n < 3) continue;
    float xlo = kInf, xhi = -kInf;
    for (int i = 0; i < band.n; ++i) xlo = std::min(xlo, band.p[i].x), xhi = std::max(xhi, band.p[i].x);
    float clo, chi;  // the centres the triangle covers on this row
    spanAt(v, float(y) + 0.5f, clo, chi);
    // The squares inside the triangle: both their corners on the row's top and bottom lines
    // inside it (it is convex).
    float tlo, thi, blo, bhi;
    spanAt(v, float(y), tlo, thi);
    spanAt(v, float(y + 1), blo, bhi);
    const float inLo = std::max(tlo, blo), inHi = std::min(thi, bhi);
    const int x0 = std::max(int(std::floor(xlo)), 0), x1 = std::min(int(std::floor(xhi)), W - 1);
    for (int x = x0; x <= x1; ++x) {
      const float c = float(x) + 0.5f;
      const size_t p = size_t(y) * size_t(W) + size_t(x);
      float most, least;  // 1/depth over the triangle's part of the square
      if (float(x) >= inLo && float(x + 1) <= inHi) {
        const float centre = v[0].z + gx * (c - v[0].x) + gy * (float(y) + 0.5f - v[0].y);
        most = centre + halfSpread, least = centre - halfSpread;
      } else {
        const Poly cell = band.clip(0, float(x), 1.0f).clip(0, float(x + 1), -1.0f);
        if (cell.n < 3) continue;
        most = 0.0f, least = kInf;
        for (int i = 0; i < cell.n; ++i) most = std::max(most, cell.p[i].z), least = std::min(least, cell.p[i].z);
      }
      if (!(most > 0.0f) || !(least > 0.0f)) continue;
      const float nearest = 1.0f / most, deepest = 1.0f / least;
      const size_t n = layers.count[p];
      const FragmentNode* slot = &layers.slots[p * k];
      if (n > 0 && nearest < slot[0].depth) front(p, nearest * (1.0f - 1e-5f));
      if (!grazing && c >= clo && c <= chi) continue;  // a covered centre holds it
      bool unheld = n == 0;
      if (!unheld) {
        // The end of the pixel's last solid interval (known_space.h solidIntervals): its back,
        // or the margin's footprints behind its front.
        const float back = n == k ? kInf : std::max(slot[n - 1].back(), slot[n - 1].depth * (1.0f + margin));
        unheld = nearest < slot[0].depth * (1.0f - margin) || deepest > back;
      }
      if (unheld) mark(p, nearest * (1.0f - 1e-5f));
    }
  }
}

/// The part of a camera-space polygon (≤ 4 corners: a triangle clipped to the near plane) inside
/// the view with two pixels of guard band, clipped in camera space so that a triangle passing
/// next to the eye keeps exact screen coordinates: the side planes x_px = −2, W + 2 and y_px = −2,
/// H + 2 (through the eye for a perspective camera, of constant x and y for an orthographic one).
/// A polygon inside them comes back unchanged. Returns the corners written to `out` (0: none).
int clipToGuardBand(const glm::vec4* polygon, int n, const Camera& camera, int W, int H, glm::vec4 (&out)[8]) {
  glm::vec4 side[2][8];
  int m = n;
  std::copy(polygon, polygon + n, side[0]);
  const float f = camera.focal(), gx = 0.5f * float(W) + 2.0f, gy = 0.5f * float(H) + 2.0f;
  const glm::vec4 perspective[4] = {{f, 0.0f, -gx, 0.0f}, {-f, 0.0f, -gx, 0.0f}, {0.0f, -f, -gy, 0.0f}, {0.0f, f, -gy, 0.0f}};
  const glm::vec4 orthographic[4] = {{f, 0.0f, 0.0f, gx}, {-f, 0.0f, 0.0f, gx}, {0.0f, -f, 0.0f, gy}, {0.0f, f, 0.0f, gy}};
  const glm::vec4* planes = camera.orthographic() ? orthographic : perspective;
  for (int i = 0; i < 4 && m >= 3; ++i) m = raster::clipAgainst(side[i % 2], m, planes[i], side[(i + 1) % 2]);
  if (m < 3) return 0;
  std::copy(side[0], side[0] + m, out);  // four clips: the result is back in side[0]
  return m;
}

/// markUnheldDepths over the part of a camera-space polygon (the triangle clipped to the near
/// plane) inside the view with two pixels of guard band (clipToGuardBand; an orthographic
/// camera's polygon is taken whole, its projection is affine).
template <class Mark, class Front>
void markUnheldInView(const glm::vec4* polygon, int n, const Camera& camera, const LayerArrays& layers, float lastThicknessPx, Mark&& mark,
                      Front&& front) {
  glm::vec4 inView[8];
  int m = n;
  std::copy(polygon, polygon + n, inView);
  if (!camera.orthographic()) m = clipToGuardBand(polygon, n, camera, layers.width, layers.height, inView);
  for (int h = 0; h + 2 < m; ++h) {  // the clipped polygon as a fan of triangles in its plane
    const int c[3] = {0, h + 1, h + 2};
    glm::vec3 v[3];
    for (int i = 0; i < 3; ++i) {
      const glm::vec3 q(inView[c[i]]);
      v[i] = glm::vec3(camera.project(q), 1.0f / std::max(-q.z, camera.near()));
    }
    markUnheldDepths(v, layers, camera.focal(), lastThicknessPx, mark, front);
  }
}

/// A per-pixel nearest depth that threads lower concurrently, sized at the first mark.
class MinDepths {
 public:
  explicit MinDepths(size_t pixels) : pixels_(pixels) {}
  void mark(size_t p, float depth) {
    std::call_once(sized_, [&] { bits_.assign(pixels_, std::bit_cast<uint32_t>(kInf)); });
    // Depths are positive: their bits order like the floats, so an integer min is a float min.
    std::atomic_ref<uint32_t> cell(bits_[p]);
    const uint32_t mine = std::bit_cast<uint32_t>(depth);
    uint32_t cur = cell.load(std::memory_order_relaxed);
    while (mine < cur && !cell.compare_exchange_weak(cur, mine, std::memory_order_relaxed)) {}
  }
  /// The depths (empty when nothing was marked).
  std::vector<float> depths() const {
    std::vector<float> out(bits_.size());
    for (size_t p = 0; p < out.size(); ++p) out[p] = std::bit_cast<float>(bits_[p]);
    return out;
  }

 private:
  size_t pixels_;
  std::vector<uint32_t> bits_;
  std::once_flag sized_;
};

}  // namespace

UnsampledDepths unsampledDepths(const Scene& scene, const Camera& camera, const LayerArrays& layers, float lastThicknessPx) {
  const int W = layers.width, H = layers.height;
  const size_t pixels = size_t(W) * size_t(H);
  checkAllocation("the hybrid's unsampled depths", 2 * pixels * sizeof(uint32_t));  // before the pass that may need it
  MinDepths unsampled(pixels), nearestFront(pixels);
  parallelFor(size_t(0), scene.triangleCount(), [&](size_t t) {
    const glm::uvec3 tri = scene.triangles[t];
    const glm::vec3 world[3] = {scene.positions[tri.x], scene.positions[tri.y], scene.positions[tri.z]};
    glm::vec4 cam[3], clipped[4];  // camera space, w = 1
    for (int i = 0; i < 3; ++i) cam[i] = glm::vec4(camera.toCamera(world[i]), 1.0f);
    const int n = raster::clipAgainst(cam, 3, glm::vec4(0.0f, 0.0f, -1.0f, -camera.near()), clipped);  // z ≤ −near
    if (n < 2) return;
    float nearest = kInf;
    for (int i = 0; i < n; ++i) nearest = std::min(nearest, -clipped[i].z);
    auto markPixel = [&](size_t p, float depth) { unsampled.mark(p, depth); };
    markUnheldInView(clipped, n, camera, layers, lastThicknessPx, markPixel, [&](size_t p, float depth) { nearestFront.mark(p, depth); });
    // The thin-triangle rule looks at the projected polygon — but one reaching close to the eye
    // plane beside the view lands ~10⁸ pixels out, where the half-pixel steps below no longer
    // advance a float (an endless loop, found by a sweep of assimp's models: IndexedLineSet.x3d
    // through a 1° lens) and its coordinates carry errors of pixels. Such a polygon is clipped to
    // the guard band in camera space first. Only then: a polygon clipped there can turn into a
    // sliver along the band's edge that would mark the border pixels for a surface that never
    // covers them (tried on every polygon, it moved 10 % of oa_shouse's reflection rays to
    // geometry).
    glm::vec2 s[8];
    int m = n;
    bool far = false;
    for (int i = 0; i < n; ++i) s[i] = camera.project(glm::vec3(clipped[i])), far |= !(std::max(std::abs(s[i].x), std::abs(s[i].y)) < kFarPixels);
    if (far) {
      glm::vec4 inBand[8];
      m = clipToGuardBand(clipped, n, camera, W, H, inBand);
      for (int i = 0; i < m; ++i) s[i] = camera.project(glm::vec3(inBand[i]));
    }
    if (m < 2) return;
    // The two farthest points, and how far the others lie from the line through them.
    int a = 0, b = 1;
    float longest = -1.0f;
    for (int i = 0; i < m; ++i)
      for (int j = i + 1; j < m; ++j)
        if (const float d = glm::length(s[j] - s[i]); d > longest) longest = d, a = i, b = j;
    if (!(longest > 2.0f) || !std::isfinite(longest)) return;  // small (or off to infinity): not ours
    const glm::vec2 axis = (s[b] - s[a]) / longest;
    float width = 0.0f;
    for (int i = 0; i < m; ++i) width = std::max(width, std::abs(axis.x * (s[i].y - s[a].y) - axis.y * (s[i].x - s[a].x)));
    if (!(width < 1.0f)) return;  // thick enough that pixel centres sample it along its length
    // The part of the line inside the view (with a pixel's margin), sampled every half pixel.
    const glm::vec2 lo(-1.0f), hi(float(W) + 1.0f, float(H) + 1.0f);
    float t0 = 0.0f, t1 = longest;
    for (int k = 0; k < 2; ++k) {
      if (axis[k] == 0.0f) {
        if (s[a][k] < lo[k] || s[a][k] > hi[k]) return;
        continue;
      }
      float e0 = (lo[k] - s[a][k]) / axis[k], e1 = (hi[k] - s[a][k]) / axis[k];
      if (e0 > e1) std::swap(e0, e1);
      t0 = std::max(t0, e0), t1 = std::min(t1, e1);
    }
    if (!(t0 <= t1)) return;
    const size_t k = size_t(layers.k);
    for (float u = t0;; u = std::min(u + 0.5f, t1)) {
      const glm::vec2 q = s[a] + axis * u;
      const int px = int(std::floor(q.x)), py = int(std::floor(q.y));
      for (int y = std::max(py - 1, 0); y <= std::min(py + 1, H - 1); ++y)
        for (int x = std::max(px - 1, 0); x <= std::min(px + 1, W - 1); ++x) {
          const size_t p = size_t(y) * size_t(W) + size_t(x);
          bool stored = false;
          for (size_t i = 0; i < size_t(layers.count[p]) && !stored; ++i) stored = layers.triangle[p * k + i] == uint32_t(t);
          if (!stored) markPixel(p, nearest);
        }
      if (u >= t1) break;
    }
  });
  return {unsampled.depths(), nearestFront.depths()};
}

}  // namespace lt
