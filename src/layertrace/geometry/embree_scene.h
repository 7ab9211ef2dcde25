// Embree 3 over the scene's triangles: the geometric ground truth of layertrace.
//
// Embree wants flush-to-zero / denormals-are-zero in every thread that calls it;
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

/// What one geometric query did (optional out-parameter of every query).
struct TraversalCounts {
  uint32_t steps = 0;    ///< cells visited (grid); 1 per query (Embree)
  uint32_t tests = 0;    ///< ray–triangle tests (grid; Embree does not say)
  uint32_t giveUps = 0;  ///< 1 when a step cap ended the traversal before the ray did
};

class EmbreeScene {
 public:
  /// Fast: Embree's default scene flags (no robust mode, no filter function), HIGH build
  /// quality — the baseline every speed claim is measured against. Robust:
  /// RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION — watertight, and able to
  /// collect all hits (allHits): the ground truth of classification, capture checks and verify.
  /// Capture: default scene flags with a geometry-level filter that collects every hit — the
  /// plain baseline of all-hit capture (allHits), no robust mode, no scene filter flag.
  enum class Mode { Fast, Robust, Capture };
  explicit EmbreeScene(const Scene& scene, Mode mode = Mode::Robust);
  Mode mode() const { return mode_; }
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  /// Closest hit with t in (tnear, tfar] (Embree's rule: tnear < t ≤ tfar); `counts` (if
  /// given) gets one step: one BVH query.
  GeoHit intersect(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts = nullptr) const;
  /// Any hit with t in (tnear, tfar]; `counts` as for intersect.
  bool occluded(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, TraversalCounts* counts = nullptr) const;
  /// Closest hits of n rays with one tnear/tfar, traced `width` (4, 8 or 16) at a time with
  /// rtcIntersect4/8/16 (the last packet masked) — the packet baseline of geobench.
  void intersectPackets(const glm::vec3* origins, const glm::vec3* dirs, size_t n, float tnear, float tfar, int width,
                        GeoHit* out) const;
  /// The same with each ray's own (tnear, tfar], 16 at a time (rtcIntersect16).
  void intersectPackets(const glm::vec3* origins, const glm::vec3* dirs, const float* tnear, const float* tfar, size_t n,
                        GeoHit* out) const;
  /// Any hit of n rays, each with its own (tnear, tfar], 16 at a time (rtcOccluded16).
  void occludedPackets(const glm::vec3* origins, const glm::vec3* dirs, const float* tnear, const float* tfar, size_t n,
                       bool* out) const;
  /// Every hit along the ray with t in (tnear, tfar], sorted by t, each triangle once (with
  /// HIGH build quality Embree may report a triangle twice). Robust and Capture modes.
  void allHits(glm::vec3 origin, glm::vec3 dir, float tnear, float tfar, std::vector<GeoHit>& out) const;

  double buildMs() const { return buildMs_; }
  size_t memoryBytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double buildMs_ = 0.0;
  Mode mode_ = Mode::Robust;
};

}  // namespace lt
