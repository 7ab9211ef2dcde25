#include "layertrace/util/image.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include <ImfArray.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>

#include <stb_image.h>  // (the implementation: stb_image_impl.cpp)
#include <stb_image_write.h>

#include "layertrace/util/error.h"

namespace lt {
namespace fs = std::filesystem;

namespace {

std::string extensionOf(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

float linearToSrgb(float v) {
  v = std::clamp(v, 0.0f, 1.0f);
  return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

float srgbToLinear(float v) {
  return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

}  // namespace

uint8_t encodeChannel8(float v, bool srgb) {
  v = srgb ? linearToSrgb(v) : std::clamp(v, 0.0f, 1.0f);
  return static_cast<unsigned char>(std::lround(v * 255.0f));
}

void encode8(const Image& image, bool srgb, int outChannels, std::vector<uint8_t>& bytes) {
  bytes.resize(size_t(image.width) * size_t(image.height) * size_t(outChannels));
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      for (int c = 0; c < outChannels; ++c)
        bytes[(size_t(y) * size_t(image.width) + size_t(x)) * size_t(outChannels) + size_t(c)] =
            encodeChannel8(image.at(x, y)[std::min(c, image.channels - 1)], srgb);
}

std::array<float, 255> srgb8Thresholds() {
  // For each code c ≥ 1, the smallest float in [0, 1] that encodes to c or more: a binary search
  // over the bit patterns of the non-negative floats, which are ordered as the floats are.
  std::array<float, 255> t{};
  const uint32_t one = std::bit_cast<uint32_t>(1.0f);
  for (int c = 1; c <= 255; ++c) {
    uint32_t lo = 0, hi = one;  // encodeChannel8(1) = 255 ≥ c
    while (lo < hi) {
      const uint32_t mid = lo + (hi - lo) / 2;
      if (encodeChannel8(std::bit_cast<float>(mid), true) >= c) hi = mid;
      else lo = mid + 1;
    }
    t[size_t(c - 1)] = std::bit_cast<float>(lo);
  }
  return t;
}

void stageOrRename(const std::string& tmp, const std::string& path);

namespace {

std::string tempNameFor(const std::string& path) {
  return cat(path, ".tmp.", ::getpid());
}

void renameIntoPlace(const std::string& tmp, const std::string& path) {
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    inputError("output ", path, ": cannot write (", ec.message(), ")");
  }
}

OutputStage* currentStage = nullptr;  // commands write their outputs from one thread

/// Writes `tmp`; errors name `path`, the file the user asked for.
void writePng(const std::string& tmp, const std::string& path, const Image& image, bool srgb) {
  const int outChannels = image.channels == 1 ? 1 : 3;
  std::vector<uint8_t> bytes;
  encode8(image, srgb, outChannels, bytes);
  if (!stbi_write_png(tmp.c_str(), image.width, image.height, outChannels, bytes.data(),
                      image.width * outChannels))
    inputError("output ", path, ": cannot write PNG");
}

void writeExr(const std::string& tmp, const Image& image) {
  static const char* names[4] = {"R", "G", "B", "A"};
  Imf::Header header(image.width, image.height);
  const bool grey = image.channels == 1;
  const int n = std::min(image.channels, 4);
  Imf::FrameBuffer fb;
  const size_t xs = sizeof(float) * size_t(image.channels);
  for (int c = 0; c < n; ++c) {
    const char* name = grey ? "Y" : names[c];
    header.channels().insert(name, Imf::Channel(Imf::FLOAT));
    fb.insert(name, Imf::Slice(Imf::FLOAT, (char*)(image.data.data() + c), xs, xs * size_t(image.width)));
  }
  Imf::OutputFile file(tmp.c_str(), header);
  file.setFrameBuffer(fb);
  file.writePixels(image.height);
}

}  // namespace

void writeFileAtomic(const std::string& path, const std::string& bytes) {
  const std::string tmp = tempNameFor(path);
  {
    std::ofstream out(tmp, std::ios::binary);
    if (!out) inputError("output ", path, ": cannot open for writing");
    out.write(bytes.data(), std::streamsize(bytes.size()));
    if (!out) {
      out.close();
      std::error_code ec;
      fs::remove(tmp, ec);
      inputError("output ", path, ": write failed");
    }
  }
  stageOrRename(tmp, path);
}

void writeImage(const std::string& path, const Image& image, bool srgb) {
  const std::string ext = extensionOf(path);
  if (ext != ".png" && ext != ".exr")
    inputError("output ", path, ": unknown image extension \"", ext, "\" (use .png or .exr)");
  LT_CHECK(image.width > 0 && image.height > 0, image.width, "x", image.height);
  const std::string tmp = tempNameFor(path) + ext;  // keep the extension for the writers
  try {
    if (ext == ".png")
      writePng(tmp, path, image, srgb);
    else
      writeExr(tmp, image);
  } catch (const InputError&) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw;
  } catch (const std::exception& e) {
    std::error_code ec;
    fs::remove(tmp, ec);
    inputError("output ", path, ": cannot write (", e.what(), ")");
  }
  stageOrRename(tmp, path);
}

void writePngBytes(const std::string& path, int width, int height, int channels, const uint8_t* bytes) {
  if (extensionOf(path) != ".png") inputError("output ", path, ": expected a .png file");
  const std::string tmp = tempNameFor(path);
  if (!stbi_write_png(tmp.c_str(), width, height, channels, bytes, width * channels)) {
    std::error_code ec;
    fs::remove(tmp, ec);
    inputError("output ", path, ": cannot write PNG");
  }
  stageOrRename(tmp, path);
}

Image readImage(const std::string& path, bool srgb) {
  const std::string ext = extensionOf(path);
  if (ext == ".png") {
    int w = 0, h = 0, c = 0;
    unsigned char* px = stbi_load(path.c_str(), &w, &h, &c, 0);
    if (!px) inputError("image ", path, ": cannot read PNG (", stbi_failure_reason(), ")");
    Image image(w, h, c);
    for (size_t i = 0; i < image.data.size(); ++i) {
      const float v = float(px[i]) / 255.0f;
      image.data[i] = srgb ? srgbToLinear(v) : v;
    }
    stbi_image_free(px);
    return image;
  }
  if (ext == ".exr") {
    try {
      Imf::InputFile file(path.c_str());
      const Imath::Box2i dw = file.header().dataWindow();
      const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
      const bool grey = file.header().channels().findChannel("Y") != nullptr;
      Image image(w, h, grey ? 1 : 3);
      Imf::FrameBuffer fb;
      const size_t xs = sizeof(float) * size_t(image.channels);
      char* base = (char*)(image.data.data()) - (size_t(dw.min.x) + size_t(dw.min.y) * size_t(w)) * xs;
      const char* names[3] = {"R", "G", "B"};
      for (int c = 0; c < image.channels; ++c)
        fb.insert(grey ? "Y" : names[c], Imf::Slice(Imf::FLOAT, base + size_t(c) * sizeof(float), xs, xs * size_t(w)));
      file.setFrameBuffer(fb);
      file.readPixels(dw.min.y, dw.max.y);
      return image;
    } catch (const std::exception& e) {
      inputError("image ", path, ": cannot read EXR (", e.what(), ")");
    }
  }
  inputError("image ", path, ": unknown image extension \"", ext, "\"");
}

namespace {

// DirectDraw Surface (.dds), which stb_image does not read: the top level of an uncompressed
// RGB(A) surface or of a DXT1, DXT3 or DXT5 (BC1–BC3) compressed one, as Microsoft's DDS
// documentation ("DDS_HEADER", "Block compression") lays them out. Other formats (DX10 headers,
// BC4–BC7, cube maps' other faces) decode to nothing.
uint32_t le32At(const uint8_t* p) { return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24; }

/// The 4 × 4 texels of a BC1 colour block (RGBA, row-major) at `b`; `fourColours` forces the
/// 4-colour mode (DXT3 and DXT5 colour blocks), otherwise c0 <= c1 selects 3 colours and
/// transparent black.
void decodeColourBlock(const uint8_t* b, bool fourColours, uint8_t out[16][4]) {
  const uint32_t c0 = uint32_t(b[0]) | uint32_t(b[1]) << 8, c1 = uint32_t(b[2]) | uint32_t(b[3]) << 8;
  auto expand = [](uint32_t c, int channel) {
    const uint32_t v = channel == 0 ? (c >> 11) & 31u : channel == 1 ? (c >> 5) & 63u : c & 31u;
    return channel == 1 ? (v << 2) | (v >> 4) : (v << 3) | (v >> 2);
  };
  uint8_t palette[4][4];
  for (int ch = 0; ch < 3; ++ch) {
    const uint32_t a = expand(c0, ch), z = expand(c1, ch);
    palette[0][ch] = uint8_t(a), palette[1][ch] = uint8_t(z);
    if (fourColours || c0 > c1) {
      palette[2][ch] = uint8_t((2 * a + z) / 3), palette[3][ch] = uint8_t((a + 2 * z) / 3);
    } else {
      palette[2][ch] = uint8_t((a + z) / 2), palette[3][ch] = 0;
    }
  }
  palette[0][3] = palette[1][3] = palette[2][3] = 255;
  palette[3][3] = fourColours || c0 > c1 ? 255 : 0;
  const uint32_t indices = le32At(b + 4);
  for (int i = 0; i < 16; ++i) std::memcpy(out[i], palette[(indices >> (2 * i)) & 3u], 4);
}

std::optional<Rgba8Image> decodeDds(const uint8_t* data, size_t size, const std::string& source) {
  if (size < 128 || std::memcmp(data, "DDS ", 4) != 0 || le32At(data + 4) != 124) return std::nullopt;
  const uint32_t height = le32At(data + 12), width = le32At(data + 16);
  const uint32_t pfFlags = le32At(data + 80), bits = le32At(data + 88);
  if (width == 0 || height == 0) return std::nullopt;
  if (width > uint32_t(kMaxImageSide) || height > uint32_t(kMaxImageSide))
    inputError("texture ", source, ": ", width, "×", height, " pixels, more than the limit of ", kMaxImageSide, " per side");
  Rgba8Image image;
  image.width = int(width), image.height = int(height);
  const uint8_t* body = data + 128;
  const size_t available = size - 128;
  // The pixels are allocated only once the data is known to hold them (a header alone may ask for 1 GiB).
  auto allocate = [&] { image.pixels.assign(size_t(width) * height * 4, 255); };
  if (pfFlags & 0x4u) {  // DDPF_FOURCC: block-compressed
    const uint32_t fourcc = le32At(data + 84);
    const int kind = fourcc == le32At(reinterpret_cast<const uint8_t*>("DXT1")) ? 1
                   : fourcc == le32At(reinterpret_cast<const uint8_t*>("DXT3")) ? 3
                   : fourcc == le32At(reinterpret_cast<const uint8_t*>("DXT5")) ? 5 : 0;
    if (kind == 0) return std::nullopt;
    const size_t blockBytes = kind == 1 ? 8 : 16, bw = (width + 3) / 4, bh = (height + 3) / 4;
    if (available / blockBytes < bw * bh) return std::nullopt;
    allocate();
    for (size_t by = 0; by < bh; ++by)
      for (size_t bx = 0; bx < bw; ++bx) {
        const uint8_t* b = body + (by * bw + bx) * blockBytes;
        uint8_t texels[16][4];
        decodeColourBlock(kind == 1 ? b : b + 8, kind != 1, texels);
        if (kind == 3) {
          for (int i = 0; i < 16; ++i) texels[i][3] = uint8_t(((b[i / 2] >> (4 * (i % 2))) & 15u) * 17u);
        } else if (kind == 5) {
          const uint32_t a0 = b[0], a1 = b[1];
          uint32_t alpha[8] = {a0, a1};
          for (uint32_t k = 1; k <= 6; ++k)
            alpha[k + 1] = a0 > a1 ? ((7 - k) * a0 + k * a1) / 7 : k <= 4 ? ((5 - k) * a0 + k * a1) / 5 : (k == 5 ? 0u : 255u);
          uint64_t indices = 0;
          for (int k = 0; k < 6; ++k) indices |= uint64_t(b[2 + k]) << (8 * k);
          for (int i = 0; i < 16; ++i) texels[i][3] = uint8_t(alpha[(indices >> (3 * i)) & 7u]);
        }
        for (int i = 0; i < 16; ++i) {
          const size_t x = bx * 4 + size_t(i % 4), y = by * 4 + size_t(i / 4);
          if (x < width && y < height) std::memcpy(&image.pixels[(y * width + x) * 4], texels[i], 4);
        }
      }
    return image;
  }
  if (!(pfFlags & 0x40u) || (bits != 24 && bits != 32)) return std::nullopt;  // DDPF_RGB, 24 or 32 bits
  const size_t bytes = bits / 8;
  if (available / bytes / width < height) return std::nullopt;
  allocate();
  const uint32_t masks[4] = {le32At(data + 92), le32At(data + 96), le32At(data + 100), (pfFlags & 0x1u) ? le32At(data + 104) : 0u};
  for (size_t p = 0; p < size_t(width) * height; ++p) {
    uint32_t v = 0;
    for (size_t k = 0; k < bytes; ++k) v |= uint32_t(body[p * bytes + k]) << (8 * k);
    for (int c = 0; c < 4; ++c) {
      if (masks[c] == 0) continue;
      const int shift = std::countr_zero(masks[c]);
      const uint64_t max = masks[c] >> shift, value = (v & masks[c]) >> shift;
      image.pixels[p * 4 + size_t(c)] = uint8_t((value * 255u + max / 2) / max);
    }
  }
  return image;
}

}  // namespace

std::optional<Rgba8Image> decodeRgba8(const uint8_t* data, size_t size, const std::string& source) {
  if (size >= 4 && std::memcmp(data, "DDS ", 4) == 0) return decodeDds(data, size, source);
  if (size == 0 || size > size_t(INT32_MAX)) return std::nullopt;
  int w = 0, h = 0, c = 0;
  if (!stbi_info_from_memory(data, int(size), &w, &h, &c) || w <= 0 || h <= 0) return std::nullopt;
  if (w > kMaxImageSide || h > kMaxImageSide)
    inputError("texture ", source, ": ", w, "×", h, " pixels, more than the limit of ", kMaxImageSide, " per side");
  unsigned char* px = stbi_load_from_memory(data, int(size), &w, &h, &c, 4);
  if (!px) return std::nullopt;
  Rgba8Image image;
  image.width = w, image.height = h;
  image.pixels.assign(px, px + size_t(w) * size_t(h) * 4);
  stbi_image_free(px);
  return image;
}


glm::vec3 heatColor(float t) {
  t = std::clamp(t, 0.0f, 1.0f);
  static const glm::vec3 stops[5] = {{0.0f, 0.0f, 0.6f}, {0.0f, 0.7f, 1.0f}, {0.1f, 0.8f, 0.1f},
                                     {1.0f, 0.9f, 0.0f}, {0.9f, 0.0f, 0.0f}};
  const float s = t * 4.0f;
  const int i = std::min(int(s), 3);
  const float f = s - float(i);
  return stops[i] * (1.0f - f) + stops[i + 1] * f;
}

std::string encodePng(const Image& image, bool srgb) {
  const int outChannels = image.channels == 1 ? 1 : 3;
  std::vector<uint8_t> bytes;
  encode8(image, srgb, outChannels, bytes);
  std::string png;
  auto append = [](void* context, void* data, int size) { static_cast<std::string*>(context)->append(static_cast<const char*>(data), size_t(size)); };
  if (!stbi_write_png_to_func(append, &png, image.width, image.height, outChannels, bytes.data(), image.width * outChannels))
    throw InternalError("PNG encoding failed");
  return png;
}

void stageOrRename(const std::string& tmp, const std::string& path) {
  if (!currentStage) return renameIntoPlace(tmp, path);
  // A file written twice in one command: its temporary name is the same, so the later content
  // replaced the earlier one there; stage it once.
  std::erase_if(currentStage->files_, [&](const auto& f) { return f.second == path; });
  currentStage->files_.emplace_back(tmp, path);
}

bool createOutputDirectory(const std::string& dir) {
  std::error_code ec;
  fs::path top;  // the outermost folder this call creates
  for (fs::path p = fs::absolute(dir, ec); !ec && !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    top = p;
    if (p == p.parent_path()) break;
  }
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir, ec)) return false;
  if (currentStage && !top.empty()) currentStage->createdDirs_.push_back(top.string());
  return true;
}

OutputStage::OutputStage() : outer_(currentStage) { currentStage = this; }

OutputStage::~OutputStage() {
  rollback();
  currentStage = outer_;
}

void OutputStage::commit() {
  for (size_t i = 0; i < files_.size(); ++i) {
    std::error_code ec;
    fs::rename(files_[i].first, files_[i].second, ec);
    if (ec) {
      const std::string path = files_[i].second, why = ec.message();
      files_.erase(files_.begin(), files_.begin() + std::ptrdiff_t(i));  // these are in place
      inputError("output ", path, ": cannot write (", why, ")");
    }
  }
  files_.clear();
  createdDirs_.clear();
}

void OutputStage::rollback() noexcept {
  std::error_code ec;
  for (const auto& f : files_) fs::remove(f.first, ec);
  for (auto it = createdDirs_.rbegin(); it != createdDirs_.rend(); ++it) fs::remove_all(*it, ec);
  files_.clear();
  createdDirs_.clear();
}

}  // namespace lt
