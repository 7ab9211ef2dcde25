#include "layertrace/raster/fragment.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace lt {

namespace {

glm::vec2 signNotZero(glm::vec2 v) { return {v.x >= 0.0f ? 1.0f : -1.0f, v.y >= 0.0f ? 1.0f : -1.0f}; }

float fromSnorm16(uint32_t bits) { return std::max(float(int16_t(uint16_t(bits))) / 32767.0f, -1.0f); }

float srgbEncode(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

const std::array<float, 256>& srgbDecodeTable() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) {
      const float v = float(i) / 255.0f;
      t[size_t(i)] = v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
    }
    return t;
  }();
  return table;
}

}  // namespace

glm::vec3 decodeOctahedral(uint32_t packed) {
  const glm::vec2 p(fromSnorm16(packed & 0xFFFFu), fromSnorm16(packed >> 16));
  glm::vec3 n(p.x, p.y, 1.0f - std::abs(p.x) - std::abs(p.y));
  if (n.z < 0.0f) {
    const glm::vec2 q = (1.0f - glm::abs(glm::vec2(n.y, n.x))) * signNotZero(glm::vec2(n.x, n.y));
    n.x = q.x;
    n.y = q.y;
  }
  return n / std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
}

uint32_t packAlbedoSpec(glm::vec3 albedo, float specular) {
  auto q = [](float v) { return uint32_t(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f)); };
  return q(srgbEncode(albedo.x)) | (q(srgbEncode(albedo.y)) << 8) | (q(srgbEncode(albedo.z)) << 16) | (q(specular) << 24);
}

glm::vec3 unpackAlbedo(uint32_t packed) {
  const auto& t = srgbDecodeTable();
  return {t[packed & 0xFFu], t[(packed >> 8) & 0xFFu], t[(packed >> 16) & 0xFFu]};
}

float unpackSpecular(uint32_t packed) { return float(packed >> 24) / 255.0f; }

}  // namespace lt
