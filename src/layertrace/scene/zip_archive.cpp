// The zip reader of zip_archive.h: the end-of-central-directory record, the central directory,
// local headers and entry data, each checked to lie inside the file; deflated entries inflated
// through zlib into exactly their declared size.
#include "layertrace/scene/zip_archive.h"

#include <algorithm>

#include <zlib.h>

#include "layertrace/util/error.h"
#include "layertrace/util/memory.h"

namespace lt {

ZipDirectory::ZipDirectory(const std::string& path) : path_(path), in_(path, std::ios::binary | std::ios::ate) {
  if (!in_) inputError("scene ", path, ": cannot open");
  size_ = uint64_t(in_.tellg());
  // The end-of-central-directory record lies in the last 64 KiB + 22 bytes.
  const uint64_t tailSize = std::min<uint64_t>(size_, 65557);
  const std::vector<unsigned char> tail = read(size_ - tailSize, tailSize, "end record");
  const unsigned char* e = nullptr;
  for (size_t i = tail.size() >= 22 ? tail.size() - 22 + 1 : 0; i-- > 0 && !e;)
    if (le32(&tail[i]) == 0x06054b50u) e = &tail[i];
  if (!e) inputError("scene ", path, ": not a zip archive (no end of central directory)");
  const uint64_t count = le16(e + 10), cdSize = le32(e + 12), cdOffset = le32(e + 16);
  if (cdOffset + cdSize > size_) inputError("scene ", path, ": zip central directory lies beyond the end of the file");
  const std::vector<unsigned char> cd = read(cdOffset, cdSize, "central directory");
  size_t at = 0;
  for (uint64_t n = 0; n < count; ++n) {
    if (at + 46 > cd.size() || le32(&cd[at]) != 0x02014b50u) inputError("scene ", path, ": malformed zip central directory");
    const unsigned char* h = &cd[at];
    const size_t nameLength = le16(h + 28);
    if (at + 46 + nameLength > cd.size()) inputError("scene ", path, ": malformed zip central directory");
    ZipEntry z;
    z.name.assign(reinterpret_cast<const char*>(h + 46), nameLength);
    // ZIP64 markers (0xFFFFFFFF) count as the largest size they stand for.
    z.method = le16(h + 10), z.packed = le32(h + 20), z.unpacked = le32(h + 24), z.localHeader = le32(h + 42);
    if (z.unpacked == 0xFFFFFFFFu) z.unpacked = uint64_t(1) << 32;
    entries.push_back(std::move(z));
    at += 46 + nameLength + le16(h + 30) + le16(h + 32);
  }
}

std::vector<unsigned char> ZipDirectory::read(uint64_t offset, uint64_t n, const char* what) {
  if (offset > size_ || n > size_ - offset) inputError("scene ", path_, ": the zip ", what, " lies beyond the end of the file");
  std::vector<unsigned char> bytes(n);
  in_.clear();
  in_.seekg(std::streamoff(offset));
  if (!in_.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(n))) inputError("scene ", path_, ": cannot read the zip ", what);
  return bytes;
}

std::vector<unsigned char> ZipDirectory::contents(const ZipEntry& z) {
  const std::vector<unsigned char> local = read(z.localHeader, 30, "local header");
  if (le32(local.data()) != 0x04034b50u) inputError("scene ", path_, ": malformed zip local header of ", z.name);
  const std::vector<unsigned char> packed = read(z.localHeader + 30 + le16(&local[26]) + le16(&local[28]), z.packed, "entry data");
  if (z.method == 0) return packed;
  if (z.method != 8) inputError("scene ", path_, ": zip entry ", z.name, " uses compression method ", z.method);
  checkAllocation(cat("scene ", path_, ": zip entry ", z.name), z.unpacked);
  std::vector<unsigned char> out(z.unpacked);
  z_stream zs{};
  if (inflateInit2(&zs, -MAX_WBITS) != Z_OK) throw InternalError("zlib: inflateInit2 failed");
  zs.next_in = const_cast<unsigned char*>(packed.data()), zs.avail_in = uInt(packed.size());
  zs.next_out = out.data(), zs.avail_out = uInt(out.size());
  const int rc = inflate(&zs, Z_FINISH);
  const uint64_t produced = zs.total_out;
  inflateEnd(&zs);
  if (rc != Z_STREAM_END || produced != z.unpacked)
    inputError("scene ", path_, ": zip entry ", z.name, " does not inflate to its declared ", z.unpacked, " bytes");
  return out;
}

}  // namespace lt
