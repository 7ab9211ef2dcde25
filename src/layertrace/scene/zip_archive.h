// Zip archives (Quake 3's .pk3 files) read without trusting them: the central directory and
// every entry are found through offsets that are checked against the file before they are
// followed. Internal to scene/: the model loader's archive checks (load_model.cpp) and Quake 3's
// texture lookup (quake3_textures.h) read archives through it. Every failure is an InputError
// naming the file.
#pragma once

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

namespace lt {

/// The little-endian numbers of zip headers (and Quake 3 maps).
inline uint32_t le32(const unsigned char* p) { return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24; }
inline uint16_t le16(const unsigned char* p) { return uint16_t(p[0] | p[1] << 8); }

/// One entry of a zip central directory.
struct ZipEntry {
  std::string name;
  uint16_t method = 0;
  uint64_t packed = 0, unpacked = 0, localHeader = 0;
};

/// A zip archive's central directory, read without trusting it: every offset is checked
/// against the file before it is followed. The file stays open for contents().
class ZipDirectory {
 public:
  /// Reads the central directory; InputError naming `path` when it cannot be opened or is no
  /// well-formed zip archive.
  explicit ZipDirectory(const std::string& path);

  /// Reads `n` bytes at `offset`, or fails naming what was being read.
  std::vector<unsigned char> read(uint64_t offset, uint64_t n, const char* what);

  /// The entry's bytes, inflated (stored and deflated entries; the only methods .pk3 files use).
  std::vector<unsigned char> contents(const ZipEntry& z);

  const std::string& path() const { return path_; }

  std::vector<ZipEntry> entries;

 private:
  std::string path_;
  std::ifstream in_;
  uint64_t size_ = 0;
};

}  // namespace lt
