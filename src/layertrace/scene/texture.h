// Material textures: decoded once per scene into RGBA8 mip chains, sampled trilinearly.
//
// Colour channels are stored sRGB-encoded (as an SRGB8_ALPHA8 texture holds them) and filtered
// in linear space; alpha is linear. Texture coordinates follow assimp's convention: (0, 0) is
// the image's bottom-left corner, v grows upwards, so image row y = (1 - v) · height.
//
// Layer: scene/. Includes util/ only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec4.hpp>

namespace lt {

/// How texture coordinates outside [0, 1) map into the image (a material's, per axis).
enum class TextureWrap : uint8_t { Repeat, Clamp, Mirror };

/// An image and its mip chain: level i + 1 halves level i's sides (rounded down, at least 1), each
/// texel the linear-space mean of the (up to) 2 × 2 texels it covers.
struct Texture {
  struct Level {
    int width = 0, height = 0;
    size_t offset = 0;  ///< index of its first texel in `texels`
  };
  std::string name;            ///< the file or archive entry it came from, for messages
  std::vector<Level> levels;   ///< level 0 first
  std::vector<uint32_t> texels;  ///< RGBA8, red in the low byte; rows top-down per level
  /// Every texel's alpha is 0 or 255 and some are 0: an alpha-tested (1-bit) cut-out texture.
  bool binaryAlpha = false;
  /// log2 of level 0's texels per unit of texture coordinate (the geometric mean of its sides):
  /// the texture's term of the mip level.
  float texelsLog2 = 0.0f;

  int width() const { return levels.empty() ? 0 : levels[0].width; }
  int height() const { return levels.empty() ? 0 : levels[0].height; }
  size_t bytes() const { return texels.size() * sizeof(uint32_t); }
  /// The mean colour and alpha of level 0, linear (computed once, in double precision).
  glm::vec4 mean() const { return meanLinear; }
  glm::vec4 meanLinear{1.0f};
};

/// Builds the texture and its mip chain from `width` × `height` RGBA8 pixels (row 0 at the top).
Texture makeTexture(std::string name, int width, int height, const uint8_t* rgba);

/// Linear RGBA at `uv`, filtered trilinearly between the two mip levels around `lod` (0: level
/// 0's texel spacing; clamped to the chain).
glm::vec4 sampleTrilinear(const Texture& texture, glm::vec2 uv, float lod, TextureWrap wrapU, TextureWrap wrapV);

/// The alpha of level 0's texel nearest `uv`, in [0, 1]: what the alpha test reads. It is the same
/// texel from every direction and distance, so a cut-out's holes are geometry every tracer sees
/// alike (the rasterizer, Embree's filter, the grid).
float alphaNearest(const Texture& texture, glm::vec2 uv, TextureWrap wrapU, TextureWrap wrapV);

/// The sRGB 8-bit code nearest (in sRGB space) to linear value `v` (clamped to [0, 1]), exact
/// and without pow: the number of the 255 decision thresholds (srgb8Threshold) at or below v,
/// found by a table of 4096 buckets and a step or two (texture_test checks it against the search).
uint32_t linearToSrgb8(float v);
/// The linear value of sRGB code `c` (0…255).
float srgb8ToLinear(uint32_t c);
/// The linear value where linearToSrgb8 moves from code `c` to c + 1 (c in 0…254).
float srgb8Threshold(uint32_t c);

}  // namespace lt
