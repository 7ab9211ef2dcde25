// libFuzzer target: the texture path of a model's materials. The bytes are an encoded image
// (PNG, JPEG, TGA, BMP or DDS, as a model embeds or names them): decoded, its mip chain built and
// sampled at coordinates, levels and wrap modes taken from the input's first bytes. Any bytes
// must give a texture, nothing (undecodable) or an InputError (over the size limit).
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>

#include "layertrace/scene/texture.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  float probe[3] = {0.5f, 0.5f, 0.0f};  // u, v, lod
  uint8_t modes = 0;
  if (size >= 13) {
    std::memcpy(probe, data, 12);
    modes = data[12];
  }
  try {
    const std::optional<lt::Rgba8Image> image = lt::decodeRgba8(data, size, "fuzz");
    if (!image) return 0;
    if (uint64_t(image->width) * uint64_t(image->height) > (uint64_t(1) << 16)) return 0;  // decoded; a larger chain only takes time
    const lt::Texture t = lt::makeTexture("fuzz", image->width, image->height, image->pixels.data());
    const auto wrapU = lt::TextureWrap(modes % 3), wrapV = lt::TextureWrap((modes / 3) % 3);
    const glm::vec4 s = lt::sampleTrilinear(t, {probe[0], probe[1]}, probe[2], wrapU, wrapV);
    const float a = lt::alphaNearest(t, {probe[0], probe[1]}, wrapU, wrapV);
    if (!(a >= 0.0f && a <= 1.0f) || !(s.w >= 0.0f && s.w <= 1.0f + 1e-6f)) __builtin_trap();
  } catch (const lt::InputError&) {
  }
  return 0;
}
