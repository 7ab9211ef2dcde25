// Embree 3 over the scene's triangles: the geometric ground truth of layertrace.
//
// Embree wants flush-to-zero / denormals-are-zero in every thread that calls it (DATA.md);
// every query method sets them, so callers from any TBB worker are safe.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/vec3.hpp>

#include "layertrace/scene/scene.h"

namespace lt {

struct GeoHit {
  float t = 0.0f;                  ///< ray parameter of the hit
  uint32_t triangle = 0xFFFFFFFFu;  ///< scene triangle index; 0xFFFFFFFF = miss
  glm::vec3 ng{0.0f};              ///< geometric normal (unnormalised, Embree's orientation)
  bool hit() const { return triangle != 0xFFFFFFFFu; }
};

class EmbreeScene {
 public:
  explicit EmbreeScene(const Scene& scene);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  /// Closest hit with t in [tnear, tfar]; `steps` (if given) is set to 1: one BVH query.
  GeoHit intersect(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, uint32_t* steps = nullptr) const;
  /// Any hit with t in [tnear, tfar]; `steps` as for intersect.
  bool occluded(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, uint32_t* steps = nullptr) const;
  /// Every hit along the ray with t in [tnear, tfar], sorted by t, each triangle once (with
  /// HIGH build quality Embree may report a triangle twice).
  void allHits(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, std::vector<GeoHit>& out) const;

  double buildMs() const { return buildMs_; }
  size_t memoryBytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double buildMs_ = 0.0;
};

/// Sets flush-to-zero and denormals-are-zero for the calling thread.
void enableFlushDenormals();

}  // namespace lt
