#include "layertrace/eval/classify.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace lt {

const char* rayClassName(RayClass c) {
  switch (c) {
    case RayClass::CorrectHit: return "correct_hit";
    case RayClass::WrongHit: return "wrong_hit";
    case RayClass::FalseMiss: return "false_miss";
    case RayClass::InfoMiss: return "info_miss";
    case RayClass::CorrectMiss: return "correct_miss";
  }
  return "?";
}

glm::vec3 rayClassColor(RayClass c) {
  switch (c) {
    case RayClass::CorrectHit: return {0.1f, 0.65f, 0.15f};  // green
    case RayClass::WrongHit: return {0.9f, 0.1f, 0.1f};      // red
    case RayClass::FalseMiss: return {1.0f, 0.8f, 0.0f};     // yellow
    case RayClass::InfoMiss: return {0.15f, 0.35f, 0.95f};   // blue
    case RayClass::CorrectMiss: return {0.25f, 0.25f, 0.25f};  // grey
  }
  return glm::vec3(0.0f);
}

float sameSurfaceTolerance(const Camera& camera, float depth, float thickness) {
  return 2.0f * camera.pixelFootprint(std::max(depth, camera.near())) + thickness;
}

bool storedInLayers(const TraceHit& truth, const Camera& camera, const LayerArrays& layers) {
  if (!truth.hit) return false;
  const float depth = -truth.point.z;
  if (depth < camera.near() || depth > camera.far()) return false;
  const glm::vec2 p = camera.project(truth.point);
  if (!(p.x >= 0.0f && p.y >= 0.0f && p.x < float(camera.width()) && p.y < float(camera.height()))) return false;
  const int x = int(p.x), y = int(p.y);
  const FragmentNode* f = layers.pixel(x, y);
  for (int i = 0; i < layers.countAt(x, y); ++i)
    if (f[i].depth <= depth && depth <= f[i].back()) return true;
  // The true point lies somewhere inside its pixel, the fragments at pixel centres: accept the
  // same triangle in the pixel or a neighbour (a sliver may miss this pixel's centre).
  for (int ny = std::max(y - 1, 0); ny <= std::min(y + 1, layers.height - 1); ++ny)
    for (int nx = std::max(x - 1, 0); nx <= std::min(x + 1, layers.width - 1); ++nx) {
      const size_t base = layers.pixelIndex(nx, ny) * size_t(layers.k);
      for (int i = 0; i < layers.countAt(nx, ny); ++i)
        if (layers.triangle[base + size_t(i)] == truth.triangle) return true;
    }
  return false;
}

RayClass classifyRay(const TraceHit& tracer, const TraceHit& truth, const Camera& camera, const LayerArrays& layers,
                     float thickness) {
  if (tracer.hit) {
    if (!truth.hit) return RayClass::WrongHit;
    if (tracer.triangle == truth.triangle) return RayClass::CorrectHit;
    const float tol = sameSurfaceTolerance(camera, -truth.point.z, thickness);
    return glm::length(tracer.point - truth.point) <= tol ? RayClass::CorrectHit : RayClass::WrongHit;
  }
  if (!truth.hit) return RayClass::CorrectMiss;
  return storedInLayers(truth, camera, layers) ? RayClass::FalseMiss : RayClass::InfoMiss;
}

ClassifyObserver::ClassifyObserver(const Tracer& reference, const Camera& camera, const LayerArrays& layers, float thickness)
    : reference_(reference), camera_(camera), layers_(layers), thickness_(thickness), image_(camera.width(), camera.height()) {}

void ClassifyObserver::observe(std::span<const RayEvent> events) {
  Local& l = local_.local();
  l.rays.resize(events.size());
  l.truth.resize(events.size());
  for (size_t i = 0; i < events.size(); ++i) l.rays[i] = *events[i].ray;
  reference_.traceBatch(l.rays, l.truth, {});
  for (size_t i = 0; i < events.size(); ++i) {
    const RayEvent& e = events[i];
    const TraceHit& h = *e.hit;
    RayClass c;
    if (e.query == Query::Any && h.hit) c = l.truth[i].hit ? RayClass::CorrectHit : RayClass::WrongHit;
    else c = classifyRay(h, l.truth[i], camera_, layers_, thickness_);
    ++l.counts[size_t(c)];
    // A pixel's rays of one wave arrive together and in order: its first ray of wave 0 is the
    // first event of that pixel in the batch.
    const bool first = e.bounce == 0 && (i == 0 || events[i - 1].x != e.x || events[i - 1].y != e.y);
    if (first) image_.set(e.x, e.y, rayClassColor(c));
  }
}

std::array<uint64_t, kRayClasses> ClassifyObserver::counts() const {
  std::array<uint64_t, kRayClasses> total{};
  for (const Local& l : local_)
    for (int c = 0; c < kRayClasses; ++c) total[size_t(c)] += l.counts[size_t(c)];
  return total;
}

}  // namespace lt
