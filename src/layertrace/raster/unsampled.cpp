#include "layertrace/raster/unsampled.h"

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>

#include <glm/geometric.hpp>

#include "layertrace/util/memory.h"
#include "layertrace/util/parallel.h"

namespace lt {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/// The triangle clipped to the near side of z = −near (camera space; Sutherland–Hodgman on one
/// plane): up to four points, returned count.
int clipToNear(const glm::vec3 in[3], float near, glm::vec3 out[4]) {
  int n = 0;
  for (int i = 0; i < 3; ++i) {
    const glm::vec3 a = in[i], b = in[(i + 1) % 3];
    const bool aIn = a.z <= -near, bIn = b.z <= -near;
    if (aIn) out[n++] = a;
    if (aIn != bIn) out[n++] = a + (b - a) * ((-near - a.z) / (b.z - a.z));
  }
  return n;
}

}  // namespace

std::vector<float> unsampledDepths(const Scene& scene, const Camera& camera, const LayerArrays& layers) {
  const int W = layers.width, H = layers.height;
  const size_t pixels = size_t(W) * size_t(H);
  checkAllocation("the hybrid's unsampled depths", pixels * sizeof(uint32_t));  // before the pass that may need it
  // Depths are positive: their bits order like the floats, so an integer min is a float min.
  std::vector<uint32_t> bits;  // sized at the first unstored crossing: empty when there is none
  std::once_flag sized;
  parallelFor(size_t(0), scene.triangleCount(), [&](size_t t) {
    const glm::uvec3 tri = scene.triangles[t];
    const glm::vec3 world[3] = {scene.positions[tri.x], scene.positions[tri.y], scene.positions[tri.z]};
    glm::vec3 cam[3], clipped[4];
    for (int i = 0; i < 3; ++i) cam[i] = camera.toCamera(world[i]);
    const int n = clipToNear(cam, camera.near(), clipped);
    if (n < 2) return;
    glm::vec2 s[4];
    float nearest = kInf;
    for (int i = 0; i < n; ++i) s[i] = camera.project(clipped[i]), nearest = std::min(nearest, -clipped[i].z);
    // The two farthest points, and how far the others lie from the line through them.
    int a = 0, b = 1;
    float longest = -1.0f;
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j)
        if (const float d = glm::length(s[j] - s[i]); d > longest) longest = d, a = i, b = j;
    if (!(longest > 2.0f) || !std::isfinite(longest)) return;  // small (or off to infinity): not ours
    const glm::vec2 axis = (s[b] - s[a]) / longest;
    float width = 0.0f;
    for (int i = 0; i < n; ++i) width = std::max(width, std::abs(axis.x * (s[i].y - s[a].y) - axis.y * (s[i].x - s[a].x)));
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
          if (stored) continue;
          std::call_once(sized, [&] { bits.assign(pixels, std::bit_cast<uint32_t>(kInf)); });
          std::atomic_ref<uint32_t> cell(bits[p]);
          const uint32_t mine = std::bit_cast<uint32_t>(nearest);
          uint32_t cur = cell.load(std::memory_order_relaxed);
          while (mine < cur && !cell.compare_exchange_weak(cur, mine, std::memory_order_relaxed)) {}
        }
      if (u >= t1) break;
    }
  });
  std::vector<float> out(bits.size());
  for (size_t p = 0; p < out.size(); ++p) out[p] = std::bit_cast<float>(bits[p]);
  return out;
}

}  // namespace lt
