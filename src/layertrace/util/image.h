// Float images and their files. Images are chosen by extension (.png, .exr) and always written
// through a temporary file and a rename, so no partial file is ever left behind.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

namespace lt {

/// A row-major float image, row 0 at the top, `channels` interleaved floats per pixel.
struct Image {
  int width = 0;
  int height = 0;
  int channels = 3;
  std::vector<float> data;

  Image() = default;
  Image(int w, int h, int c = 3, float fill = 0.0f)
      : width(w), height(h), channels(c), data(size_t(w) * size_t(h) * size_t(c), fill) {}

  float* at(int x, int y) { return &data[(size_t(y) * size_t(width) + size_t(x)) * size_t(channels)]; }
  const float* at(int x, int y) const {
    return &data[(size_t(y) * size_t(width) + size_t(x)) * size_t(channels)];
  }
  void set(int x, int y, glm::vec3 c) {
    float* p = at(x, y);
    for (int i = 0; i < channels && i < 3; ++i) p[i] = c[i];
  }
  glm::vec3 rgb(int x, int y) const {
    const float* p = at(x, y);
    return channels >= 3 ? glm::vec3(p[0], p[1], p[2]) : glm::vec3(p[0]);
  }
};

/// Writes `.png` (linear values encoded to sRGB 8 bit; set `srgb=false` for data images) or
/// `.exr` (32-bit float, linear). Throws InputError for an unknown extension or unwritable path.
void writeImage(const std::string& path, const Image& image, bool srgb = true);

/// The 8-bit encoding writeImage uses for PNG (sRGB when `srgb`, else clamped), `outChannels`
/// (1 or 3) per pixel, row 0 first — also what the viewer shows.
void encode8(const Image& image, bool srgb, int outChannels, std::vector<uint8_t>& bytes);
/// encode8's code of one channel value.
uint8_t encodeChannel8(float v, bool srgb);
/// The sRGB encoding of encode8 as 255 thresholds: a value's code is the number of thresholds at
/// or below it (for every float; NaN has code 0). The GPU encodes with them (its pow is not
/// libm's), to the CPU's codes bit for bit.
std::array<float, 255> srgb8Thresholds();
/// Writes 8-bit pixels (row 0 at the top) as a PNG, atomically.
void writePngBytes(const std::string& path, int width, int height, int channels, const uint8_t* bytes);
/// Reads `.png` (decoded back to linear when `srgb`) or `.exr`. Used by round-trip tests.
Image readImage(const std::string& path, bool srgb = true);

/// A decoded 8-bit RGBA image, row 0 at the top.
struct Rgba8Image {
  int width = 0, height = 0;
  std::vector<uint8_t> pixels;  ///< width × height × 4 bytes
};
/// The largest side of an image decodeRgba8 accepts.
inline constexpr int kMaxImageSide = 16384;
/// Decodes an encoded PNG, JPEG, TGA or BMP image (stb_image) or a DDS surface (uncompressed
/// RGB(A), DXT1, DXT3 or DXT5; its top level) in memory to RGBA8 (no alpha channel: 255).
/// Nothing when it does not decode. Throws InputError naming `source` and both sides when the
/// header declares a side over kMaxImageSide (the header is read before any pixel is decoded).
std::optional<Rgba8Image> decodeRgba8(const uint8_t* data, size_t size, const std::string& source);

/// Writes `bytes` to `path` through `path.tmp.<pid>` and a rename.
void writeFileAtomic(const std::string& path, const std::string& bytes);
/// An image as the bytes of a PNG file (sRGB 8 bit when `srgb`), written nowhere.
std::string encodePng(const Image& image, bool srgb = true);

/// Creates `dir` and its missing parents; false if it cannot. Inside an OutputStage the folders
/// it created are removed again if the stage ends without commit.
bool createOutputDirectory(const std::string& dir);

/// All or nothing for a command's outputs. While a stage lives, the writers above write each
/// file to its temporary name as always but leave it there; commit() renames them all into
/// place. A stage destroyed without commit — the command failed — removes the temporary files
/// and the folders createOutputDirectory made, so a failed command leaves nothing behind, even
/// when its last output is the one that cannot be written (DESIGN: no partial output).
class OutputStage {
 public:
  OutputStage();
  ~OutputStage();
  OutputStage(const OutputStage&) = delete;
  OutputStage& operator=(const OutputStage&) = delete;
  /// Renames every staged file into place (InputError naming the file if one cannot be).
  void commit();

 private:
  friend void stageOrRename(const std::string& tmp, const std::string& path);
  friend bool createOutputDirectory(const std::string& dir);
  void rollback() noexcept;
  std::vector<std::pair<std::string, std::string>> files_;  ///< (temporary, final)
  std::vector<std::string> createdDirs_;
  OutputStage* outer_;
};

/// Maps t in [0,1] to a perceptual heat colour (blue → cyan → green → yellow → red).
glm::vec3 heatColor(float t);

}  // namespace lt
