#include "layertrace/eval/classify.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace lt {

const char* rayClassName(RayClass c) {
  switch (c) {
    case RayClass::CorrectHit: return "correct_hit";
    case RayClass::WrongHitThickness: return "wrong_hit_thickness";
    case RayClass::WrongHitUnstored: return "wrong_hit_unstored";
    case RayClass::WrongHitOther: return "wrong_hit_other";
    case RayClass::FalseMiss: return "false_miss";
    case RayClass::OriginPixelMiss: return "origin_pixel_miss";
    case RayClass::InfoMiss: return "info_miss";
    case RayClass::CorrectMiss: return "correct_miss";
  }
  return "?";
}

glm::vec3 rayClassColor(RayClass c) {
  switch (c) {
    case RayClass::CorrectHit: return {0.1f, 0.65f, 0.15f};          // green
    case RayClass::WrongHitThickness: return {0.9f, 0.1f, 0.1f};     // red
    case RayClass::WrongHitUnstored: return {0.55f, 0.0f, 0.25f};    // dark red
    case RayClass::WrongHitOther: return {0.95f, 0.3f, 0.75f};       // pink
    case RayClass::FalseMiss: return {1.0f, 0.8f, 0.0f};             // yellow
    case RayClass::OriginPixelMiss: return {0.0f, 0.85f, 0.85f};     // cyan
    case RayClass::InfoMiss: return {0.15f, 0.35f, 0.95f};           // blue
    case RayClass::CorrectMiss: return {0.25f, 0.25f, 0.25f};        // grey
  }
  return glm::vec3(0.0f);
}

float depthTolerance(const Camera& camera, glm::vec3 p, glm::vec3 dir, glm::vec3 n) {
  const float z = -p.z;
  const float footprint = camera.pixelFootprint(z);
  // The ray: depth per pixel of screen motion, d(depth)/dt over |d(screen)/dt|, where the
  // screen motion of a point moving by dir at depth z is focal/z × |dir_xy + p_xy/z · dir_z|.
  const glm::vec2 lateral = glm::vec2(dir.x, dir.y) - glm::vec2(p.x, p.y) / p.z * dir.z;
  const float screen = glm::length(lateral) / footprint;
  const float rayPerPixel = screen > 1e-12f ? std::abs(dir.z) / screen : std::numeric_limits<float>::infinity();
  // The stored surface: a plane with normal n seen along the pixel ray r changes depth by
  // footprint · |n_xy| / |n · r| per pixel (at most 20 footprints: grazing surfaces).
  const glm::vec3 r = p / z;
  const float nr = std::abs(glm::dot(n, r));
  const float surfacePerPixel = footprint * std::min(20.0f, nr > 0.0f ? glm::length(glm::vec2(n.x, n.y)) / nr : 20.0f);
  return 1.5f * (rayPerPixel + surfacePerPixel);
}

namespace {

/// Does the true hit's depth lie in fragment f's interval widened by δ (the rules in the header)?
bool inWidenedInterval(const FragmentNode& f, const TraceHit& truth, glm::vec3 dir, const Camera& camera) {
  const float delta = depthTolerance(camera, truth.point, dir, decodeOctahedral(f.normal)), z = -truth.point.z;
  return f.depth - delta <= z && z <= f.back() + delta;
}

/// A hit on no camera layer is as close to the true one as a screen tracer's must be: within 1.5
/// pixel footprints across the ray and along it, where a surface seen at a grazing angle (true
/// normal n) may add up to 20 footprints — the screen rules' δ, measured at the true point's
/// distance from the eye so that it also applies off screen.
bool withinOnePixel(glm::vec3 reported, const TraceHit& truth, glm::vec3 dir, const Camera& camera) {
  const float footprint = camera.pixelFootprint(std::max(glm::length(truth.point), camera.near()));
  const glm::vec3 diff = reported - truth.point;
  const float along = glm::dot(diff, dir), across = glm::length(diff - dir * along);
  const float cosine = std::abs(glm::dot(dir, truth.normal));
  const float slope = std::min(20.0f, cosine > 0.0f ? 1.0f / cosine : 20.0f);
  return across <= 1.5f * footprint && std::abs(along) <= 1.5f * footprint * slope;
}

}  // namespace

bool storedInLayers(const TraceHit& truth, glm::vec3 dir, const Camera& camera, const LayerArrays& layers) {
  int x, y;
  if (!truth.hit || !camera.pixelOf(truth.point, x, y)) return false;
  for (int ny = std::max(y - 1, 0); ny <= std::min(y + 1, layers.height - 1); ++ny)
    for (int nx = std::max(x - 1, 0); nx <= std::min(x + 1, layers.width - 1); ++nx) {
      const size_t base = layers.pixelIndex(nx, ny) * size_t(layers.k);
      for (int i = 0; i < layers.countAt(nx, ny); ++i)
        if (layers.triangle[base + size_t(i)] == truth.triangle) return true;
    }
  const FragmentNode* f = layers.pixel(x, y);
  for (int i = 0; i < layers.countAt(x, y); ++i)
    if (inWidenedInterval(f[i], truth, dir, camera)) return true;
  return false;
}

RayClass classifyRay(const Ray& ray, const TraceHit& tracer, const TraceHit& truth, Query query, const Camera& camera,
                     const LayerArrays& layers) {
  int ox = -1, oy = -1, tx = -1, ty = -1;
  camera.pixelOf(ray.origin, ox, oy);
  const bool truthOnScreen = truth.hit && camera.pixelOf(truth.point, tx, ty);
  const bool inOriginPixel = truthOnScreen && tx == ox && ty == oy;
  if (tracer.hit) {
    if (query == Query::Any) return truth.hit ? RayClass::CorrectHit : RayClass::WrongHitThickness;
    if (tracer.layer < 0 && truth.hit) {  // a hit on no camera layer (geometric tracers, ldc)
      const float tr = glm::length(tracer.point - ray.origin), tt = glm::length(truth.point - ray.origin);
      if (truth.triangle == tracer.triangle || std::abs(tr - tt) <= 1e-4f * std::max(tr, tt)) return RayClass::CorrectHit;
      if (withinOnePixel(tracer.point, truth, ray.dir, camera)) return RayClass::CorrectHit;
    }
    if (tracer.layer >= 0 && truthOnScreen && std::abs(tx - tracer.x) <= 1 && std::abs(ty - tracer.y) <= 1) {
      if (truth.triangle == tracer.triangle) return RayClass::CorrectHit;
      if (inWidenedInterval(layers.pixel(tracer.x, tracer.y)[tracer.layer], truth, ray.dir, camera)) return RayClass::CorrectHit;
    }
    const float tReported = glm::dot(tracer.point - ray.origin, ray.dir);
    const float tTrue = truth.hit ? glm::dot(truth.point - ray.origin, ray.dir) : std::numeric_limits<float>::infinity();
    if (tTrue > tReported) return RayClass::WrongHitThickness;
    if (inOriginPixel) return RayClass::OriginPixelMiss;
    return storedInLayers(truth, ray.dir, camera, layers) ? RayClass::WrongHitOther : RayClass::WrongHitUnstored;
  }
  if (!truth.hit) return RayClass::CorrectMiss;
  if (inOriginPixel) return RayClass::OriginPixelMiss;
  return storedInLayers(truth, ray.dir, camera, layers) ? RayClass::FalseMiss : RayClass::InfoMiss;
}

ClassifyObserver::ClassifyObserver(const Tracer& reference, const Camera& camera, const LayerArrays& layers)
    : reference_(reference), camera_(camera), layers_(layers), image_(camera.width(), camera.height()) {}

void ClassifyObserver::observe(std::span<const RayEvent> events) {
  Local& l = local_.local();
  l.rays.resize(events.size());
  l.truth.resize(events.size());
  for (size_t i = 0; i < events.size(); ++i) l.rays[i] = *events[i].ray;
  reference_.query(Query::Closest, l.rays, l.truth, {});  // (the origin rule of the graded answers)
  for (size_t i = 0; i < events.size(); ++i) {
    const RayEvent& e = events[i];
    const RayClass c = classifyRay(*e.ray, *e.hit, l.truth[i], e.query, camera_, layers_);
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
