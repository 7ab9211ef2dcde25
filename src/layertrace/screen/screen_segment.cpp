#include "layertrace/screen/screen_segment.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace lt {

ScreenSegment makeScreenSegment(const Camera& camera, const Ray& ray) {
  ScreenSegment seg;
  seg.clippedStart = !ray.startsOnSurface;
  const float nearZ = -camera.near();
  glm::vec3 origin = ray.origin;
  float maxDistance = ray.maxDistance;
  if (origin.z > nearZ) {
    // Behind the near plane: start where the ray crosses it, if it ever does.
    if (!(ray.dir.z < 0.0f)) return seg;
    const float t = (nearZ - origin.z) / ray.dir.z;
    if (!(t < maxDistance)) return seg;
    origin += ray.dir * t;
    origin.z = nearZ;
    maxDistance -= t;
    seg.clippedStart = seg.startOutside = true;
  }
  // McGuire and Mara 2014: clip to the near plane.
  const float len = (origin.z + ray.dir.z * maxDistance > nearZ) ? (nearZ - origin.z) / ray.dir.z : maxDistance;
  seg.clippedEnd = len < maxDistance;
  const glm::vec3 end = origin + ray.dir * std::max(len, 0.0f);
  seg.k0 = 1.0f / -origin.z;
  seg.k1 = 1.0f / -end.z;
  seg.p0 = camera.project(origin);
  seg.p1 = camera.project(end);
  const float W = float(camera.width()), H = float(camera.height());
  if (!(seg.p0.x >= 0.0f && seg.p0.y >= 0.0f && seg.p0.x <= W && seg.p0.y <= H)) {
    // Off-screen start: move it to where the 2D segment enters the viewport (Liang–Barsky).
    float tA = 0.0f, tB = 1.0f;
    const glm::vec2 d = seg.p1 - seg.p0;
    for (int a = 0; a < 2; ++a) {
      const float hi = a == 0 ? W : H;
      if (d[a] == 0.0f) {
        if (seg.p0[a] < 0.0f || seg.p0[a] > hi) return seg;
        continue;
      }
      const float t0 = (0.0f - seg.p0[a]) / d[a], t1 = (hi - seg.p0[a]) / d[a];
      tA = std::max(tA, std::min(t0, t1));
      tB = std::min(tB, std::max(t0, t1));
    }
    if (!(tA <= tB)) return seg;
    seg.p0 = glm::clamp(seg.p0 + d * tA, glm::vec2(0.0f), glm::vec2(W, H));
    seg.k0 = seg.k0 + (seg.k1 - seg.k0) * tA;
    seg.clippedStart = seg.startOutside = true;
  }
  // Clip the end to the viewport (the G3D version does, the published listing does not).
  float tEnd = 1.0f;
  const glm::vec2 d = seg.p1 - seg.p0;
  auto limit = [&](float p, float dp, float lo, float hi) {
    if (dp > 0.0f && p + dp > hi) tEnd = std::min(tEnd, (hi - p) / dp);
    if (dp < 0.0f && p + dp < lo) tEnd = std::min(tEnd, (lo - p) / dp);
  };
  limit(seg.p0.x, d.x, 0.0f, W);
  limit(seg.p0.y, d.y, 0.0f, H);
  tEnd = std::max(tEnd, 0.0f);
  if (tEnd < 1.0f) {
    seg.clippedEnd = true;
    seg.p1 = seg.p0 + d * tEnd;
    seg.k1 = seg.k0 + (seg.k1 - seg.k0) * tEnd;
  }
  seg.valid = std::isfinite(seg.p1.x) && std::isfinite(seg.p1.y) && seg.k1 > 0.0f;
  return seg;
}

float rayParamAt(const Camera& camera, const Ray& ray, const ScreenSegment& seg, float s) {
  const glm::vec3 p = camera.rayThrough(seg.pointAt(s)) * seg.depthAt(s);
  return std::clamp(glm::dot(p - ray.origin, ray.dir), 0.0f, ray.maxDistance);
}

float ScreenSegment::pixelParam(float pixels) const {
  const glm::vec2 d = p1 - p0;
  return pixels / std::max({std::abs(d.x), std::abs(d.y), 1e-6f});
}

namespace {

/// Liang–Barsky: the screen parameters where the 2D segment enters and leaves pixel (x, y)'s
/// square.
glm::vec2 pixelParams(const ScreenSegment& seg, int x, int y) {
  const glm::vec2 d = seg.p1 - seg.p0;
  float sIn = 0.0f, sOut = 1.0f;
  for (int a = 0; a < 2; ++a) {
    const float lo = float(a == 0 ? x : y), hi = lo + 1.0f;
    if (d[a] == 0.0f) continue;
    const float s0 = (lo - seg.p0[a]) / d[a], s1 = (hi - seg.p0[a]) / d[a];
    sIn = std::max(sIn, std::min(s0, s1));
    sOut = std::min(sOut, std::max(s0, s1));
  }
  return {sIn, sOut};
}

/// The ray parameter `m` (screen parameter) after the segment leaves a pixel at sOut.
float paramAfter(const Camera& camera, const Ray& ray, const ScreenSegment& seg, float sOut, float m) {
  return !seg.clippedEnd && sOut + m >= 1.0f ? ray.maxDistance : rayParamAt(camera, ray, seg, std::clamp(sOut + m, 0.0f, 1.0f));
}

}  // namespace

float rayParamAfterPixel(const Camera& camera, const Ray& ray, const ScreenSegment& seg, int x, int y, float margin) {
  if (!seg.valid) return ray.maxDistance;
  return paramAfter(camera, ray, seg, pixelParams(seg, x, y).y, seg.pixelParam(margin));
}

ParamSpan rayParamsAroundPixel(const Camera& camera, const Ray& ray, const ScreenSegment& seg, int x, int y, float margin) {
  if (!seg.valid) return {0.0f, ray.maxDistance};
  const glm::vec2 s = pixelParams(seg, x, y);
  const float m = seg.pixelParam(margin);
  return {rayParamAt(camera, ray, seg, std::clamp(s.x - m, 0.0f, 1.0f)), paramAfter(camera, ray, seg, s.y, m)};
}

}  // namespace lt
