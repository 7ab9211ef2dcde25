#include "layertrace/scene/texture.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace lt {
namespace {

const std::array<float, 256>& decodeTable() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) {
      const double v = double(i) / 255.0;
      t[size_t(i)] = float(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
    }
    return t;
  }();
  return table;
}

/// threshold[c]: the linear value of sRGB (c + 0.5) / 255, where code c + 1 starts.
const std::array<float, 255>& thresholdTable() {
  static const std::array<float, 255> table = [] {
    std::array<float, 255> t{};
    for (int i = 0; i < 255; ++i) {
      const double v = (double(i) + 0.5) / 255.0;
      t[size_t(i)] = float(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
    }
    return t;
  }();
  return table;
}

uint32_t channel(uint32_t texel, int c) { return (texel >> (8 * c)) & 0xFFu; }

/// Wraps integer texel coordinate i into [0, n).
int wrapIndex(int i, int n, TextureWrap mode) {
  switch (mode) {
    case TextureWrap::Clamp:
      return std::clamp(i, 0, n - 1);
    case TextureWrap::Mirror: {
      const int period = 2 * n;
      int m = i % period;
      if (m < 0) m += period;
      return m < n ? m : period - 1 - m;
    }
    case TextureWrap::Repeat:
    default: {
      if ((n & (n - 1)) == 0) return i & (n - 1);  // a power of two: the same texel without a division
      const int m = i % n;
      return m < 0 ? m + n : m;
    }
  }
}

/// A texture coordinate kept where texel indices fit an int (|t| < 1024 times a side of at most
/// 2^14); beyond it, moved exactly by a multiple of 2 (a period of Repeat and of Mirror) to
/// ±[1022, 1026] (Clamp sees the same edge). NaN and infinities read 0.
float tame(float t) {
  if (std::abs(t) < 1024.0f) return t;
  return std::isfinite(t) ? std::copysign(1024.0f, t) + std::fmod(t, 2.0f) : 0.0f;
}

glm::vec4 texelLinear(uint32_t texel) {
  const auto& d = decodeTable();
  return {d[channel(texel, 0)], d[channel(texel, 1)], d[channel(texel, 2)], float(channel(texel, 3)) / 255.0f};
}

glm::vec4 sampleBilinear(const Texture& t, int level, glm::vec2 uv, TextureWrap wu, TextureWrap wv) {
  const Texture::Level& L = t.levels[size_t(level)];
  const float x = tame(uv.x) * float(L.width) - 0.5f, y = (1.0f - tame(uv.y)) * float(L.height) - 0.5f;
  const float fx = std::floor(x), fy = std::floor(y);
  const float ax = x - fx, ay = y - fy;
  const int x0 = int(fx), y0 = int(fy);
  const int xa = wrapIndex(x0, L.width, wu), xb = wrapIndex(x0 + 1, L.width, wu);
  const int ya = wrapIndex(y0, L.height, wv), yb = wrapIndex(y0 + 1, L.height, wv);
  const uint32_t* row0 = &t.texels[L.offset + size_t(ya) * size_t(L.width)];
  const uint32_t* row1 = &t.texels[L.offset + size_t(yb) * size_t(L.width)];
  const glm::vec4 top = texelLinear(row0[xa]) * (1.0f - ax) + texelLinear(row0[xb]) * ax;
  const glm::vec4 bottom = texelLinear(row1[xa]) * (1.0f - ax) + texelLinear(row1[xb]) * ax;
  return top * (1.0f - ay) + bottom * ay;
}

}  // namespace

float srgb8ToLinear(uint32_t c) { return decodeTable()[std::min<uint32_t>(c, 255u)]; }

float srgb8Threshold(uint32_t c) { return thresholdTable()[std::min<uint32_t>(c, 254u)]; }

namespace {

constexpr int kBuckets = 4096;

/// Per bucket [b / 4096, (b + 1) / 4096) of linear values, the code of its lower end: where
/// linearToSrgb8's walk starts (a bucket spans less than one code step but at the very bottom,
/// where it spans 0.8 codes).
const std::array<uint8_t, kBuckets>& bucketStart() {
  static const std::array<uint8_t, kBuckets> table = [] {
    std::array<uint8_t, kBuckets> b{};
    const auto& t = thresholdTable();
    for (int i = 0; i < kBuckets; ++i)
      b[size_t(i)] = uint8_t(std::upper_bound(t.begin(), t.end(), float(i) / float(kBuckets)) - t.begin());
    return b;
  }();
  return table;
}

}  // namespace

uint32_t linearToSrgb8(float v) {
  if (!(v > 0.0f)) return 0u;
  if (v >= 1.0f) return 255u;
  // The number of thresholds ≤ v (upper_bound over them), found from the bucket's first code:
  // thresholds rise, and the bucket's lower end is ≤ v, so the walk only goes up.
  const auto& t = thresholdTable();
  uint32_t code = bucketStart()[size_t(v * float(kBuckets))];
  while (code < 255u && t[code] <= v) ++code;
  return code;
}

Texture makeTexture(std::string name, int width, int height, const uint8_t* rgba) {
  Texture t;
  t.name = std::move(name);
  size_t total = 0;
  for (int w = width, h = height;; w = std::max(w / 2, 1), h = std::max(h / 2, 1)) {
    t.levels.push_back({w, h, total});
    total += size_t(w) * size_t(h);
    if (w == 1 && h == 1) break;
  }
  t.texels.resize(total);
  bool anyZero = false, binary = true;
  for (size_t i = 0; i < size_t(width) * size_t(height); ++i) {
    const uint8_t* p = rgba + 4 * i;
    t.texels[i] = uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
    anyZero = anyZero || p[3] == 0;
    binary = binary && (p[3] == 0 || p[3] == 255);
  }
  t.binaryAlpha = binary && anyZero;
  t.texelsLog2 = 0.5f * std::log2(float(width) * float(height));
  double acc[4] = {0.0, 0.0, 0.0, 0.0};
  for (size_t i = 0; i < size_t(width) * size_t(height); ++i) {
    const glm::vec4 v = texelLinear(t.texels[i]);
    for (int c = 0; c < 4; ++c) acc[c] += double(v[c]);
  }
  const double n = double(width) * double(height);
  t.meanLinear = glm::vec4(float(acc[0] / n), float(acc[1] / n), float(acc[2] / n), float(acc[3] / n));
  // Each level from the one above: the linear-space mean of the texels it covers (2 × 2, or
  // 1 × 2 / 2 × 1 where a side is already 1; an odd side's last row or column is left out).
  for (size_t l = 1; l < t.levels.size(); ++l) {
    const Texture::Level& src = t.levels[l - 1];
    const Texture::Level& dst = t.levels[l];
    const int sx = src.width > 1 ? 2 : 1, sy = src.height > 1 ? 2 : 1;
    for (int y = 0; y < dst.height; ++y)
      for (int x = 0; x < dst.width; ++x) {
        glm::vec4 sum(0.0f);
        for (int j = 0; j < sy; ++j)
          for (int i = 0; i < sx; ++i)
            sum += texelLinear(t.texels[src.offset + size_t(y * sy + j) * size_t(src.width) + size_t(x * sx + i)]);
        const glm::vec4 m = sum / float(sx * sy);
        const uint32_t a = uint32_t(std::lround(std::clamp(m.w, 0.0f, 1.0f) * 255.0f));
        t.texels[dst.offset + size_t(y) * size_t(dst.width) + size_t(x)] =
            linearToSrgb8(m.x) | linearToSrgb8(m.y) << 8 | linearToSrgb8(m.z) << 16 | a << 24;
      }
  }
  return t;
}

glm::vec4 sampleTrilinear(const Texture& texture, glm::vec2 uv, float lod, TextureWrap wrapU, TextureWrap wrapV) {
  if (texture.levels.empty()) return glm::vec4(1.0f);
  const int last = int(texture.levels.size()) - 1;
  if (!(lod > 0.0f)) return sampleBilinear(texture, 0, uv, wrapU, wrapV);  // magnified (or NaN)
  if (lod >= float(last)) return sampleBilinear(texture, last, uv, wrapU, wrapV);
  const int l0 = int(lod);
  const float f = lod - float(l0);
  const glm::vec4 a = sampleBilinear(texture, l0, uv, wrapU, wrapV);
  if (f == 0.0f) return a;
  return a * (1.0f - f) + sampleBilinear(texture, l0 + 1, uv, wrapU, wrapV) * f;
}

float alphaNearest(const Texture& texture, glm::vec2 uv, TextureWrap wrapU, TextureWrap wrapV) {
  if (texture.levels.empty()) return 1.0f;
  const Texture::Level& L = texture.levels[0];
  const int x = wrapIndex(int(std::floor(tame(uv.x) * float(L.width))), L.width, wrapU);
  const int y = wrapIndex(int(std::floor((1.0f - tame(uv.y)) * float(L.height))), L.height, wrapV);
  return float(channel(texture.texels[L.offset + size_t(y) * size_t(L.width) + size_t(x)], 3)) / 255.0f;
}

}  // namespace lt
