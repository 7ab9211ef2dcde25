// The one question every tracer answers (DESIGN.md): given a camera-space ray and a maximum
// distance, which stored surface does it hit first, if any? Screen-space tracers answer from
// the layer arrays; geometric tracers (Embree) from the triangles. Effects use only this.
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

namespace lt {

struct ScreenRay {
  glm::vec3 origin{0.0f};  ///< camera space, on a visible surface
  glm::vec3 dir{0.0f, 0.0f, -1.0f};  ///< camera space, unit length
  float maxDistance = 1e30f;
};

/// The surface hit: enough to shade it and to start the next bounce.
struct TraceHit {
  bool hit = false;
  int x = -1, y = -1;     ///< pixel of the hit fragment (screen tracers); projected pixel or -1 (geometric)
  int layer = -1;         ///< layer index of the hit fragment (screen tracers)
  glm::vec3 point{0.0f};  ///< camera-space hit point
  glm::vec3 normal{0.0f, 0.0f, 1.0f};  ///< camera-space shading normal (as stored; not flipped)
  uint32_t albedoSpec = 0;            ///< packed albedo + specular (fragment format)
  uint32_t triangle = 0xFFFFFFFFu;     ///< scene triangle (material lookup, evaluation)
};

/// Per-ray traversal counters (hssr-pitfalls §10: one iteration = one visited cell at any level
/// for HSSR, one step for SSR; intervals counted at every visited cell).
struct RayCounters {
  static constexpr int kLevels = 8;  ///< per-level counts kept for levels 0..7 (higher ones go to 7)
  uint32_t iterations = 0;
  uint32_t intervals = 0;
  uint32_t pixels = 0;  ///< visited level-0 pixels (screen tracers)
  uint32_t levelIterations[kLevels] = {};  ///< HSSR: visited cells per pyramid level
};

class Tracer {
 public:
  virtual ~Tracer() = default;
  virtual const char* name() const = 0;
  virtual TraceHit trace(const ScreenRay& ray, RayCounters& counters) const = 0;
};

}  // namespace lt
