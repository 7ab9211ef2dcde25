// The 16-byte fragment node of Hofmann et al. 2017, §4.1 (Figure 3, left and centre).
//
//   depth       32-bit float, positive linear eye-space depth (see camera.h)
//   normal      camera-space normal, octahedral encoding [Meyer et al. 2010], 2 × 16-bit snorm
//   albedoSpec  albedo RGB8 (sRGB-encoded, like an SRGB8 texture) + 8-bit specular weight
//   next        in a fragment list: index of the next node (kNullIndex ends the list);
//               in a layer array (after sorting, Figure 3 centre): the fragment's z-thickness
//               as float bits, so the fragment's interval is [depth, depth + thickness].
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <type_traits>

#include <glm/common.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace lt {

inline constexpr uint32_t kNullIndex = 0xFFFFFFFFu;

/// Trivially constructible on purpose: pools of nodes are written before they are read.
struct FragmentNode {
  float depth;
  uint32_t normal;
  uint32_t albedoSpec;
  uint32_t next;

  float thickness() const { return std::bit_cast<float>(next); }
  void setThickness(float t) { next = std::bit_cast<uint32_t>(t); }
  float back() const { return depth + thickness(); }
};
static_assert(sizeof(FragmentNode) == 16, "Hofmann et al. 2017, §4.1: one node is 128 bits");
static_assert(std::is_trivial_v<FragmentNode>);

/// std::lround for |v| < 2^23, inline (the rasterizer rounds two values per fragment, and the
/// library call was 5 % of capture): v - trunc(v) is exact, and halves round away from zero.
inline long roundHalfAway(float v) {
  const float t = std::trunc(v), r = v - t;
  return long(t) + long(r >= 0.5f) - long(r <= -0.5f);
}

/// Octahedral normal vector encoding, two 16-bit signed-normalised values packed in 32 bits.
inline uint32_t encodeOctahedral(glm::vec3 n) {
  auto snorm16 = [](float v) { return uint32_t(uint16_t(int16_t(roundHalfAway(std::clamp(v, -1.0f, 1.0f) * 32767.0f)))); };
  const float l1 = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
  if (!(l1 > 0.0f)) return snorm16(0.0f) | (snorm16(0.0f) << 16);  // degenerate: decodes to +z
  float px = n.x / l1, py = n.y / l1;
  if (n.z < 0.0f) {
    const float ox = (1.0f - std::abs(py)) * (px >= 0.0f ? 1.0f : -1.0f);
    const float oy = (1.0f - std::abs(px)) * (py >= 0.0f ? 1.0f : -1.0f);
    px = ox, py = oy;
  }
  return snorm16(px) | (snorm16(py) << 16);
}
glm::vec3 decodeOctahedral(uint32_t packed);

/// Packs linear albedo (encoded to sRGB 8 bit) and a specular weight in [0,1].
uint32_t packAlbedoSpec(glm::vec3 albedo, float specular);
glm::vec3 unpackAlbedo(uint32_t packed);
float unpackSpecular(uint32_t packed);

}  // namespace lt
