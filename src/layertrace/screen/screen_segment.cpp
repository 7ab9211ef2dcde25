#include "layertrace/screen/screen_segment.h"

#include <algorithm>
#include <cmath>

namespace lt {

ScreenSegment makeScreenSegment(const Camera& camera, const Ray& ray) {
  ScreenSegment seg;
  const float nearZ = -camera.near();
  if (ray.origin.z > nearZ) return seg;  // origin behind the near plane
  // seed 001: clip to the near plane.
  const float len = (ray.origin.z + ray.dir.z * ray.maxDistance > nearZ) ? (nearZ - ray.origin.z) / ray.dir.z : ray.maxDistance;
  const glm::vec3 end = ray.origin + ray.dir * std::max(len, 0.0f);
  seg.k0 = 1.0f / -ray.origin.z;
  seg.k1 = 1.0f / -end.z;
  seg.p0 = camera.project(ray.origin);
  seg.p1 = camera.project(end);
  // Clip the end to the viewport (the G3D version does, the published listing does not).
  const float W = float(camera.width()), H = float(camera.height());
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
    seg.p1 = seg.p0 + d * tEnd;
    seg.k1 = seg.k0 + (seg.k1 - seg.k0) * tEnd;
  }
  seg.valid = std::isfinite(seg.p1.x) && std::isfinite(seg.p1.y) && seg.k1 > 0.0f;
  return seg;
}

}  // namespace lt
