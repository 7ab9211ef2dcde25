#include "layertrace/util/image.h"

#include <algorithm>
#include <cmath>
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

#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#define STBI_ONLY_JPEG  // model textures (meanColorOfEncoded)
#define STBI_ONLY_TGA
#define STBI_ONLY_BMP
#include <stb_image.h>
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

void encode8(const Image& image, bool srgb, int outChannels, std::vector<uint8_t>& bytes) {
  bytes.resize(size_t(image.width) * size_t(image.height) * size_t(outChannels));
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      for (int c = 0; c < outChannels; ++c) {
        float v = image.at(x, y)[std::min(c, image.channels - 1)];
        v = srgb ? linearToSrgb(v) : std::clamp(v, 0.0f, 1.0f);
        bytes[(size_t(y) * size_t(image.width) + size_t(x)) * size_t(outChannels) + size_t(c)] =
            static_cast<unsigned char>(std::lround(v * 255.0f));
      }
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

glm::vec3 meanColorOfPixels(const uint8_t* pixels, size_t count, int channels) {
  float linear[256];
  for (int v = 0; v < 256; ++v) linear[v] = srgbToLinear(float(v) / 255.0f);
  double sum[3] = {0.0, 0.0, 0.0};
  for (size_t i = 0; i < count; ++i)
    for (int c = 0; c < 3; ++c) sum[c] += linear[pixels[i * size_t(channels) + size_t(c)]];
  const double n = count ? double(count) : 1.0;
  return glm::vec3(float(sum[0] / n), float(sum[1] / n), float(sum[2] / n));
}

std::optional<Rgba8Image> decodeRgba8(const uint8_t* data, size_t size, const std::string& source) {
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

std::optional<glm::vec3> meanColorOfEncoded(const uint8_t* data, size_t size, uint64_t maxPixels) {
  if (size == 0 || size > size_t(INT32_MAX)) return std::nullopt;
  int w = 0, h = 0, c = 0;
  // The header first: a small file can declare a huge image.
  if (!stbi_info_from_memory(data, int(size), &w, &h, &c) || w <= 0 || h <= 0 || uint64_t(w) * uint64_t(h) > maxPixels) return std::nullopt;
  unsigned char* px = stbi_load_from_memory(data, int(size), &w, &h, &c, 3);
  if (!px) return std::nullopt;
  const glm::vec3 mean = meanColorOfPixels(px, size_t(w) * size_t(h), 3);
  stbi_image_free(px);
  return mean;
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
