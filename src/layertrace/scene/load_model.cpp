// Model files through assimp, with the Quake 3 fix-up described in docs/data.md.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <vector>

#include <csetjmp>
#include <csignal>
#include <cstdio>
#include <cstring>

#include <fcntl.h>
#include <unistd.h>

#include <zlib.h>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/version.h>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <glm/gtc/matrix_inverse.hpp>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"
#include "layertrace/util/memory.h"

namespace lt {
namespace fs = std::filesystem;

namespace {

glm::mat4 toGlm(const aiMatrix4x4& m) {
  // assimp is row-major, glm column-major.
  return glm::mat4(m.a1, m.b1, m.c1, m.d1, m.a2, m.b2, m.c2, m.d2, m.a3, m.b3, m.c3, m.d3, m.a4, m.b4, m.c4, m.d4);
}

/// A stable, pleasant colour from a texture name: models whose materials only name textures
/// that cannot be read (Quake 3 maps, missing files) still get distinguishable surfaces.
glm::vec3 colorFromName(const std::string& name) {
  const size_t h = std::hash<std::string>{}(name);
  const float hue = float(h % 360u) / 60.0f;
  const float x = 1.0f - std::abs(std::fmod(hue, 2.0f) - 1.0f);
  glm::vec3 c = hue < 1 ? glm::vec3(1, x, 0) : hue < 2 ? glm::vec3(x, 1, 0) : hue < 3 ? glm::vec3(0, 1, x)
              : hue < 4 ? glm::vec3(0, x, 1) : hue < 5 ? glm::vec3(x, 0, 1) : glm::vec3(1, 0, x);
  return 0.25f + 0.5f * c;  // muted: keep albedo well inside (0, 1)
}

/// The mean colours of the textures a model's materials name, each decoded once: embedded in the
/// model (assimp's "*N", or by file name) or a file beside it (`modelDir`; none for a model read
/// from memory). A texture that is missing or does not decode has no colour.
class TextureColours {
 public:
  TextureColours(const aiScene* as, std::string modelDir) : as_(as), dir_(std::move(modelDir)) {}

  std::optional<glm::vec3> operator()(const std::string& name) {
    const auto [it, added] = cache_.try_emplace(name);
    if (added) it->second = decode(name);
    return it->second;
  }

 private:
  std::optional<glm::vec3> decode(const std::string& name) const {
    if (const aiTexture* t = as_->GetEmbeddedTexture(name.c_str())) {
      if (!t->pcData) return std::nullopt;
      if (t->mHeight == 0) return meanColorOfEncoded(reinterpret_cast<const uint8_t*>(t->pcData), t->mWidth);
      std::vector<uint8_t> rgb;  // raw texels: ARGB8888 as b, g, r, a bytes
      const size_t n = size_t(t->mWidth) * size_t(t->mHeight);
      rgb.reserve(3 * n);
      for (size_t i = 0; i < n; ++i) rgb.insert(rgb.end(), {t->pcData[i].r, t->pcData[i].g, t->pcData[i].b});
      return meanColorOfPixels(rgb.data(), n, 3);
    }
    if (dir_.empty()) return std::nullopt;
    std::string file = name;
    std::replace(file.begin(), file.end(), '\\', '/');
    const fs::path path = fs::path(file).is_absolute() ? fs::path(file) : fs::path(dir_) / file;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) return std::nullopt;
    const uintmax_t size = fs::file_size(path, ec);
    if (ec || size > (uintmax_t(256) << 20)) return std::nullopt;
    std::ifstream in(path, std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return meanColorOfEncoded(bytes.data(), bytes.size());
  }

  const aiScene* as_;
  std::string dir_;
  std::map<std::string, std::optional<glm::vec3>> cache_;
};

}  // namespace

std::optional<std::string> materialString(const aiMaterial* am, const char* key, unsigned semantic, unsigned index) {
  for (unsigned i = 0; i < am->mNumProperties; ++i) {
    const aiMaterialProperty* p = am->mProperties[i];
    if (!p || p->mSemantic != semantic || p->mIndex != index || std::strcmp(p->mKey.C_Str(), key) != 0) continue;
    if (p->mType != aiPTI_String || !p->mData || p->mDataLength < sizeof(uint32_t)) return std::nullopt;
    uint32_t length = 0;  // aiString's layout in a property: a 32-bit length, the bytes, a zero byte
    std::memcpy(&length, p->mData, sizeof length);
    const char* chars = p->mData + sizeof length;
    const size_t stored = std::min<size_t>(length, p->mDataLength - sizeof length);
    return std::string(chars, std::find(chars, chars + stored, '\0'));
  }
  return std::nullopt;
}

bool readableNumber(const aiMaterial* am, const char* key, unsigned semantic, unsigned index) {
  const aiMaterialProperty* p = nullptr;
  return aiGetMaterialProperty(am, key, semantic, index, &p) == AI_SUCCESS && p && p->mType != aiPTI_String;
}

namespace {

/// am->Get for numbers, where readableNumber.
template <class T>
bool getNumber(const aiMaterial* am, const char* key, unsigned semantic, unsigned index, T& out) {
  return readableNumber(am, key, semantic, index) && am->Get(key, semantic, index, out) == AI_SUCCESS;
}

Material convertMaterial(const aiMaterial* am, TextureColours& textures) {
  Material m;
  if (const auto name = materialString(am, AI_MATKEY_NAME)) m.name = *name;
  aiColor4D c;
  bool haveColor = false;
  if (getNumber(am, AI_MATKEY_BASE_COLOR, c) || getNumber(am, AI_MATKEY_COLOR_DIFFUSE, c)) {
    m.albedo = glm::clamp(glm::vec3(c.r, c.g, c.b), 0.0f, 1.0f);
    haveColor = true;
  }
  std::optional<std::string> tex = materialString(am, AI_MATKEY_TEXTURE(aiTextureType_BASE_COLOR, 0));
  if (!tex) tex = materialString(am, AI_MATKEY_TEXTURE(aiTextureType_DIFFUSE, 0));
  if (tex && !tex->empty()) {
    // A texture multiplies the colour (glTF's base colour factor, OBJ's Kd; usually white): one
    // albedo per material, so its mean colour stands for it. One that cannot be read gets a
    // colour derived from its name, so that surfaces stay distinguishable.
    if (const std::optional<glm::vec3> mean = textures(*tex)) m.albedo = glm::clamp((haveColor ? m.albedo : glm::vec3(1.0f)) * *mean, 0.0f, 1.0f);
    else if (!haveColor || m.albedo == glm::vec3(1.0f)) m.albedo = colorFromName(*tex);
  }
  aiColor4D s;
  if (getNumber(am, AI_MATKEY_COLOR_SPECULAR, s))
    m.specular = std::clamp(0.2126f * s.r + 0.7152f * s.g + 0.0722f * s.b, 0.0f, 1.0f);
  float shin = 0.0f;
  if (getNumber(am, AI_MATKEY_SHININESS, shin) && shin > 0.0f) m.shininess = std::min(shin, 1024.0f);
  float opacity = 1.0f;
  if (getNumber(am, AI_MATKEY_OPACITY, opacity) && opacity < 0.999f && opacity >= 0.0f)
    m.transmission = 1.0f - opacity;  // glass in IFC/OBJ files: refracts with ior 1.5
  float ior = 0.0f;
  if (getNumber(am, AI_MATKEY_REFRACTI, ior) && ior >= 1.0f && ior <= 4.0f) m.ior = ior;
  return m;
}

/// The accumulated transform of node `n` (identity for none).
glm::mat4 nodeTransform(const aiNode* n) {
  glm::mat4 chain(1.0f);
  for (; n; n = n->mParent) chain = toGlm(n->mTransformation) * chain;
  return chain;
}

bool isQuake3(const std::string& ext) { return ext == ".pk3" || ext == ".bsp"; }

// Some of assimp's importers abort (ai_assert) or crash on malformed files. While one runs, a
// fatal signal means "this model file is malformed": report it like any bad input (one line,
// status 2 — nothing has been written yet) instead of dying. Outside the import the default
// handlers stay, so our own bugs are never masked.
// The same holds for an importer that never finishes (assimp 5.2.5's PLY reader loops forever
// on some malformed headers — found by fuzz/fuzz_model.cpp): an alarm stops the import after
// gImportTimeout seconds.
char gImportPath[1024];
int gStderr = 2;  // the real stderr while the importer's own stderr chatter is silenced
unsigned gImportTimeout = kDefaultImportTimeoutSeconds;

bool gRecoverFromCrash = false;  // setModelImportCrashRecovery
// With recovery on, the process must survive an importer crash: jump back to the import and
// report the file as malformed (the aborted importer's memory is lost).
sigjmp_buf gImportJump;

extern "C" void importCrashed(int signal) {
  if (gRecoverFromCrash) siglongjmp(gImportJump, 1);
  static const char head[] = "layertrace: scene ";
  static const char crashed[] = ": the model importer crashed on this file (malformed model)\n";
  static const char hung[] = ": the model importer did not finish in time (malformed model?)\n";
  const char* tail = signal == SIGALRM ? hung : crashed;
  ssize_t ignored = ::write(gStderr, head, sizeof head - 1);
  ignored = ::write(gStderr, gImportPath, std::strlen(gImportPath));
  ignored = ::write(gStderr, tail, std::strlen(tail));
  (void)ignored;
  ::_exit(2);
}

class ImportGuard {
 public:
  explicit ImportGuard(const std::string& path) {
    std::strncpy(gImportPath, path.c_str(), sizeof gImportPath - 1);
    struct sigaction sa {};
    sa.sa_handler = importCrashed;
    sigemptyset(&sa.sa_mask);
    for (int i = 0; i < kCount; ++i) sigaction(kSignals[i], &sa, &old_[i]);
    ::alarm(gImportTimeout);
    // assimp prints assertion text to stderr before aborting: keep our error to one line. Some
    // importers also chatter on stdout (the Ogre reader's "Skeleton is not a valid root"), which
    // --quiet promises to keep silent.
    std::fflush(stdout);
    std::fflush(stderr);
    savedOut_ = ::dup(1);
    saved_ = ::dup(2);
    const int devnull = ::open("/dev/null", O_WRONLY);
    if (savedOut_ >= 0 && devnull >= 0) ::dup2(devnull, 1);
    if (saved_ >= 0 && devnull >= 0) {
      ::dup2(devnull, 2);
      gStderr = saved_;
    }
    if (devnull >= 0) ::close(devnull);
  }
  ~ImportGuard() {
    std::fflush(stdout);
    std::fflush(stderr);
    if (savedOut_ >= 0) {
      ::dup2(savedOut_, 1);
      ::close(savedOut_);
    }
    if (saved_ >= 0) {
      ::dup2(saved_, 2);
      ::close(saved_);
    }
    gStderr = 2;
    ::alarm(0);
    for (int i = 0; i < kCount; ++i) sigaction(kSignals[i], &old_[i], nullptr);
  }
  ImportGuard(const ImportGuard&) = delete;
  ImportGuard& operator=(const ImportGuard&) = delete;

 private:
  static constexpr int kCount = 5;
  static constexpr int kSignals[kCount] = {SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGALRM};
  struct sigaction old_[kCount];
  int saved_ = -1;
  int savedOut_ = -1;
};

/// The importer settings of every model: post-processing for meshes, raw reads for Quake 3
/// (assimp 5.2.5's Q3BSP importer never fills face indices, and post-processing trips over that;
/// read raw and rebuild the triangles in convertScene).
unsigned configureImporter(Assimp::Importer& importer, bool q3) {
  importer.SetPropertyFloat(AI_CONFIG_PP_GSN_MAX_SMOOTHING_ANGLE, 60.0f);
  importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
  return q3 ? 0u
            : aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_GenSmoothNormals |
                  aiProcess_SortByPType;  // our reader checks indices itself; assimp's validation rejects files with an empty mesh
}

/// Destroys an importer under the import guard too: some importers build scenes that crash
/// assimp's own destructor (assimp 5.2.5's 3MF reader on its test model cube_gears_prod_req.3mf:
/// "free(): invalid pointer" in aiScene::~aiScene, found by a sweep of assimp's models), which is
/// as much a malformed model as a crash while reading.
struct GuardedImporterDelete {
  std::string source;
  void operator()(Assimp::Importer* importer) const {
    const ImportGuard guard(source);
    if (sigsetjmp(gImportJump, 1) != 0) return;  // crashed (recovery on): leaked, as in guardedImport
    delete importer;
  }
};
using ImporterPtr = std::unique_ptr<Assimp::Importer, GuardedImporterDelete>;

ImporterPtr makeImporter(const std::string& source) { return ImporterPtr(new Assimp::Importer, GuardedImporterDelete{source}); }

/// assimp before 5.4 lets its 3MF importer hand the scene the package's embedded textures (a
/// thumbnail, which most 3MF writers add) and then delete them with the package: the scene's
/// texture pointers dangle, and its destructor frees them a second time ("free(): invalid
/// pointer" on assimp's own test model cube_gears_prod_req.3mf; fixed upstream in 5.4.0, "Remove
/// double delete"). Drop that array before anything reads it. Our materials lose nothing: a 3MF
/// thumbnail is no material's texture, and a texture that cannot be found gives the material's
/// own colour. Recognised by the extension (or the format hint from memory), which is how assimp
/// chooses the importer first.
void dropDanglingTextures(const aiScene* scene, const std::string& ext) {
  const bool doubleDeletes = aiGetVersionMajor() < 5 || (aiGetVersionMajor() == 5 && aiGetVersionMinor() < 4);
  if (!scene || ext != ".3mf" || !doubleDeletes) return;
  auto* owned = const_cast<aiScene*>(scene);  // NOLINT: the importer owns it; we repair what it left behind
  delete[] owned->mTextures;                  // the array is the scene's; its elements are already freed
  owned->mTextures = nullptr;
  owned->mNumTextures = 0;
}

/// Runs `read` under the import guard and repairs what the importer of `ext` (".obj", lower case)
/// leaves behind (dropDanglingTextures); InputError naming `source` when it fails or crashes.
/// `importer` is owned by the caller; with crash recovery on (setModelImportCrashRecovery) a crashed import leaves it leaked (its
/// state is not safe to destroy).
template <class Read>
const aiScene* guardedImport(ImporterPtr& importer, const std::string& source, const std::string& ext, Read&& read) {
  const aiScene* as = nullptr;
  {
    const ImportGuard guard(source);
    if (sigsetjmp(gImportJump, 1) != 0) {  // crashed, recovery on
      importer.release();  // NOLINT: deliberately leaked, see above
      inputError("scene ", source, ": the model importer crashed on this file (malformed model)");
    }
    as = read();
    dropDanglingTextures(as, ext);
  }
  if (!as || !as->mRootNode) {
    std::string why = importer->GetErrorString();
    std::replace(why.begin(), why.end(), '\n', ' ');
    inputError("scene ", source, ": cannot load model (", why.empty() ? "unknown format" : why, ")");
  }
  return as;
}

/// `ext`: the file's extension, lower case with its dot (".obj"), which decides the importer's quirks.
/// `modelDir`: where the model's texture files are looked for (empty: nowhere, a model read from memory).
Scene convertScene(const aiScene* as, const std::string& path, const std::string& name, const std::string& ext, const glm::mat4& transform,
                   const std::string& modelDir, const Quake3Patches* patches = nullptr);

uint32_t le32(const unsigned char* p) { return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24; }
uint16_t le16(const unsigned char* p) { return uint16_t(p[0] | p[1] << 8); }

}  // namespace

namespace {

/// One entry of a zip central directory.
struct ZipEntry {
  std::string name;
  uint16_t method = 0;
  uint64_t packed = 0, unpacked = 0, localHeader = 0;
};

/// A zip archive's central directory, read without trusting it: every offset is checked
/// against the file before it is followed.
class ZipDirectory {
 public:
  explicit ZipDirectory(const std::string& path) : path_(path), in_(path, std::ios::binary | std::ios::ate) {
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

  /// Reads `n` bytes at `offset`, or fails naming what was being read.
  std::vector<unsigned char> read(uint64_t offset, uint64_t n, const char* what) {
    if (offset > size_ || n > size_ - offset) inputError("scene ", path_, ": the zip ", what, " lies beyond the end of the file");
    std::vector<unsigned char> bytes(n);
    in_.clear();
    in_.seekg(std::streamoff(offset));
    if (!in_.read(reinterpret_cast<char*>(bytes.data()), std::streamsize(n))) inputError("scene ", path_, ": cannot read the zip ", what);
    return bytes;
  }

  /// The entry's bytes, inflated (stored and deflated entries; the only methods .pk3 files use).
  std::vector<unsigned char> contents(const ZipEntry& z) {
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

  std::vector<ZipEntry> entries;

 private:
  std::string path_;
  std::ifstream in_;
  uint64_t size_ = 0;
};

bool endsWithBsp(const std::string& name) {
  if (name.size() < 4) return false;
  std::string ext = name.substr(name.size() - 4);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return std::tolower(ch); });
  return ext == ".bsp";
}

void checkSizes(const ZipDirectory& zip, const std::string& path, uint64_t maxTotalBytes) {
  uint64_t total = 0;
  for (size_t n = 0; n < zip.entries.size(); ++n) {
    const ZipEntry& z = zip.entries[n];
    total += z.unpacked;
    if (z.unpacked > (uint64_t(64) << 20) && z.unpacked / std::max<uint64_t>(z.packed, 1) > 1000)
      inputError("scene ", path, ": zip entry ", n, " expands ", z.unpacked, " bytes from ", z.packed, " (a zip bomb?)");
  }
  if (total > maxTotalBytes)
    inputError("scene ", path, ": archive declares ", total, " bytes uncompressed, more than the limit of ", maxTotalBytes);
}

/// The map assimp's importer reads from an archive (Q3BSPFileImporter::findFirstMapInArchive):
/// over the entries with data, by name with '\\' as '/' and leading '.' and '/' removed
/// (ZipArchiveIOSystem's SimplifyFilename, a repeated name keeping its first entry), in byte
/// order (its std::map), the first whose extension is "bsp" in any case and whose name contains
/// "maps/" and ".bsp". None when there is none.
const ZipEntry* importersMap(const ZipDirectory& zip) {
  std::map<std::string, const ZipEntry*> names;
  for (const ZipEntry& z : zip.entries) {
    if (z.unpacked == 0) continue;
    std::string name = z.name;
    std::replace(name.begin(), name.end(), '\\', '/');
    name.erase(0, std::min(name.find_first_not_of("./"), name.size()));
    names.emplace(name, &z);
  }
  for (const auto& [name, z] : names)
    if (endsWithBsp(name) && name.find("maps/") != std::string::npos && name.find(".bsp") != std::string::npos) return z;
  return nullptr;
}

/// Every .bsp of the archive through validateQuake3Bsp, each inflated once; returns the bytes of
/// the map the importer reads (importersMap), empty when there is none.
std::vector<unsigned char> checkMaps(ZipDirectory& zip, const std::string& path) {
  const ZipEntry* read = importersMap(zip);
  std::vector<unsigned char> map;
  for (const ZipEntry& z : zip.entries)
    if (endsWithBsp(z.name)) {
      std::vector<unsigned char> bsp = zip.contents(z);
      validateQuake3Bsp(bsp.data(), bsp.size(), path + ":" + z.name);
      if (&z == read) map = std::move(bsp);
    }
  return map;
}

/// The largest distance between a Quake 3 patch and its triangles, in map units — our choice (the
/// format leaves it to the engine, whose default is 4): every Quake 3 map has the same unit,
/// about an inch, and at 1 unit a curve stays within a pixel of its triangles from a few metres.
constexpr float kPatchTolerance = 1.0f;

}  // namespace

void checkArchiveSizes(const std::string& path, uint64_t maxTotalBytes) { checkSizes(ZipDirectory(path), path, maxTotalBytes); }

std::vector<unsigned char> checkQuake3Archive(const std::string& path, uint64_t maxTotalBytes) {
  ZipDirectory zip(path);
  checkSizes(zip, path, maxTotalBytes);
  return checkMaps(zip, path);
}

void setModelImportTimeout(unsigned seconds) { gImportTimeout = seconds; }
void setModelImportCrashRecovery(bool on) { gRecoverFromCrash = on; }

void validateOffHeader(const char* data, size_t size, const std::string& name) {
  // The header: an optional keyword (OFF, COFF, NOFF, STOFF, 4OFF…), comments (#), then
  // "vertices faces [edges]" — on the keyword's line, the next lines, or split between them
  // (assimp reads "OFF5555…\n3" as 5555… vertices and 3 faces: fuzz_model). A vertex takes at
  // least 6 bytes of text ("0 0 0\n"), a face 8 ("3 0 1 2\n"). Anything that does not parse is
  // left to assimp.
  std::istringstream in(std::string(data, std::min<size_t>(size, 4096)));
  std::string line;
  std::vector<double> counts;
  bool first = true;
  while (counts.size() < 2 && std::getline(in, line)) {
    const size_t start = line.find_first_not_of(" \t\r");
    if (start == std::string::npos || line[start] == '#') continue;
    if (first && !std::isdigit(static_cast<unsigned char>(line[start]))) {  // the keyword; counts may follow it
      const size_t off = line.find("OFF");
      if (off == std::string::npos) return;
      line = line.substr(off + 3);
    }
    first = false;
    std::istringstream tokens(line);
    std::string token;
    while (counts.size() < 2 && tokens >> token) {
      size_t used = 0;
      double v = 0.0;
      try {
        v = std::stod(token, &used);
      } catch (const std::exception&) {
        return;  // no number (std::stod also throws beyond double's range: assimp's to judge)
      }
      counts.push_back(v);  // a number's leading digits, as assimp's strtoul10 reads them ("1111(100")
    }
  }
  if (counts.size() < 2) return;
  const double vertices = counts[0], faces = counts[1];
  // A count beyond 2^64 is said as a double (converting it would be undefined: fuzz_model).
  const auto said = [](double count) { return count < 1e19 ? cat(uint64_t(std::max(count, 0.0))) : cat(count); };
  if (vertices * 6.0 + faces * 8.0 > double(size))
    inputError("scene ", name, ": the OFF header declares ", said(vertices), " vertices and ", said(faces), " faces, more than its ", size,
               " bytes can hold (malformed model)");
}

Scene loadModel(const std::string& path, const glm::mat4& transform) {
  std::error_code ec;
  if (!fs::exists(path, ec)) inputError("scene ", path, ": file not found");
  if (!fs::is_regular_file(path, ec)) inputError("scene ", path, ": not a regular file");
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return std::tolower(ch); });
  const bool q3 = isQuake3(ext);
  // assimp inflates archive entries into memory: refuse what declares more than it could hold.
  std::vector<unsigned char> map;  // a Quake 3 map, for the curved surfaces assimp drops
  if (ext == ".pk3") map = checkQuake3Archive(path, kMaxArchiveBytes);
  if (ext == ".off") {
    std::ifstream in(path, std::ios::binary);
    std::string head(4096, '\0');
    in.read(head.data(), std::streamsize(head.size()));
    head.resize(size_t(in.gcount()));
    validateOffHeader(head.data(), head.size() < 4096 ? head.size() : size_t(fs::file_size(path, ec)), path);
  }
  if (ext == ".bsp") {
    std::ifstream in(path, std::ios::binary);
    map.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    validateQuake3Bsp(map.data(), map.size(), path);
  }
  ImporterPtr importer = makeImporter(path);
  const unsigned flags = configureImporter(*importer, q3);
  const aiScene* as = guardedImport(importer, path, ext, [&] { return importer->ReadFile(path, flags); });
  const fs::path parent = fs::path(path).parent_path();
  const std::string modelDir = parent.empty() ? std::string(".") : parent.string();  // texture files are looked for beside the model
  const Quake3Patches patches = map.empty() ? Quake3Patches{} : tessellateQuake3Patches(map.data(), map.size(), kPatchTolerance);
  return convertScene(as, path, fs::path(path).stem().string(), ext, transform, modelDir, &patches);
}

Scene loadModelFromMemory(const void* data, size_t size, const std::string& formatHint, const std::string& source) {
  std::string hint = formatHint;
  std::transform(hint.begin(), hint.end(), hint.begin(), [](unsigned char ch) { return std::tolower(ch); });
  const bool q3 = isQuake3("." + hint);
  if (hint == "off") validateOffHeader(static_cast<const char*>(data), size, source);
  ImporterPtr importer = makeImporter(source);
  const unsigned flags = configureImporter(*importer, q3);
  const aiScene* as =
      guardedImport(importer, source, "." + hint, [&] { return importer->ReadFileFromMemory(data, size, flags, hint.c_str()); });
  return convertScene(as, source, source, "." + hint, glm::mat4(1.0f), "");
}

namespace {

/// Appends a Quake 3 map's tessellated curved surfaces, transformed by `m`, each in the material
/// assimp made for the same key (it makes one for every key, patches' too; one it did not make
/// is added, coloured by its name as the others are).
void addPatches(Scene& scene, const Quake3Patches& p, const glm::mat4& m) {
  std::vector<uint32_t> material(p.keys.size());
  for (size_t k = 0; k < p.keys.size(); ++k) {
    const auto it = std::find_if(scene.materials.begin(), scene.materials.end(), [&](const Material& x) { return x.name == p.keys[k]; });
    material[k] = uint32_t(it - scene.materials.begin());
    if (it == scene.materials.end()) {
      Material added{p.keys[k]};
      added.albedo = colorFromName(added.name), added.specular = 0.1f;
      scene.materials.push_back(added);
    }
  }
  const glm::mat3 nm = glm::inverseTranspose(glm::mat3(m));
  const bool mirrored = glm::determinant(glm::mat3(m)) < 0.0f;  // keeps each triangle's front side (convertScene)
  const auto base = uint32_t(scene.positions.size());
  for (size_t v = 0; v < p.positions.size(); ++v) {
    scene.positions.push_back(glm::vec3(m * glm::vec4(p.positions[v], 1.0f)));
    scene.normals.push_back(nm * p.normals[v]);  // zero length → derived from faces in finalize()
  }
  for (size_t t = 0; t < p.triangles.size(); ++t) {
    const glm::uvec3 c = p.triangles[t] + base;
    scene.triangles.push_back(mirrored ? glm::uvec3(c.x, c.z, c.y) : c);
    scene.triMaterial.push_back(material[p.triKey[t]]);
  }
}

Scene convertScene(const aiScene* as, const std::string& path, const std::string& name, const std::string& ext, const glm::mat4& transform,
                   const std::string& modelDir, const Quake3Patches* patches) {
  const bool q3 = isQuake3(ext);
  Scene scene;
  scene.name = name;
  TextureColours textures(as, modelDir);
  for (unsigned i = 0; i < as->mNumMaterials; ++i) {
    Material m = convertMaterial(as->mMaterials[i], textures);
    // Quake 3 surfaces are textured shaders without colours: colour them by shader name.
    if (q3) m.albedo = colorFromName(m.name), m.specular = 0.1f;
    scene.materials.push_back(m);
  }
  if (scene.materials.empty()) scene.materials.push_back(Material{"default"});

  std::function<void(const aiNode*, const glm::mat4&)> visit = [&](const aiNode* node, const glm::mat4& parent) {
    const glm::mat4 m = parent * toGlm(node->mTransformation);
    const glm::mat3 nm = glm::inverseTranspose(glm::mat3(m));
    // A mirroring transform (negative determinant) turns counter-clockwise into clockwise:
    // swapping two corners keeps each triangle's front face the side it was (otherwise mirrored
    // objects would be captured inside out with --front-faces-only).
    const bool mirrored = glm::determinant(glm::mat3(m)) < 0.0f;
    const int second = mirrored ? 2 : 1, third = mirrored ? 1 : 2;
    for (unsigned k = 0; k < node->mNumMeshes && node->mMeshes; ++k) {
      if (node->mMeshes[k] >= as->mNumMeshes) continue;
      const aiMesh* mesh = as->mMeshes[node->mMeshes[k]];
      if (!mesh || !mesh->mVertices) continue;
      const auto base = uint32_t(scene.positions.size());
      for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
        const aiVector3D p = mesh->mVertices[v];
        scene.positions.push_back(glm::vec3(m * glm::vec4(p.x, p.y, p.z, 1.0f)));
        glm::vec3 n(0.0f);
        if (mesh->mNormals) {
          const aiVector3D an = mesh->mNormals[v];
          n = nm * glm::vec3(an.x, an.y, an.z);
        }
        scene.normals.push_back(n);  // zero length → derived from faces in finalize()
      }
      const uint32_t material = mesh->mMaterialIndex < scene.materials.size() ? mesh->mMaterialIndex : 0;
      if (q3) {
        // Consecutive vertices form triangles; Quake 3 winds front faces clockwise.
        for (uint32_t t = 0; t + 2 < mesh->mNumVertices; t += 3) {
          scene.triangles.push_back({base + t, base + t + uint32_t(third), base + t + uint32_t(second)});
          scene.triMaterial.push_back(material);
        }
        continue;
      }
      for (unsigned f = 0; f < mesh->mNumFaces && mesh->mFaces; ++f) {
        const aiFace& face = mesh->mFaces[f];
        if (face.mNumIndices != 3 || !face.mIndices) continue;  // points and lines are not surfaces
        bool ok = true;
        for (int c = 0; c < 3; ++c) ok = ok && face.mIndices[c] < mesh->mNumVertices;
        if (!ok) inputError("scene ", path, ": face index out of range in mesh ", node->mMeshes[k]);
        scene.triangles.push_back({base + face.mIndices[0], base + face.mIndices[second], base + face.mIndices[third]});
        scene.triMaterial.push_back(material);
      }
    }
    for (unsigned c = 0; c < node->mNumChildren && node->mChildren; ++c)
      if (node->mChildren[c]) visit(node->mChildren[c], m);
  };
  visit(as->mRootNode, transform);
  if (patches && !patches->triangles.empty()) addPatches(scene, *patches, transform * toGlm(as->mRootNode->mTransformation));

  // Cameras and point lights placed by their nodes.
  for (unsigned i = 0; i < as->mNumCameras; ++i) {
    const aiCamera* ac = as->mCameras[i];
    const aiNode* node = as->mRootNode->FindNode(ac->mName);
    const glm::mat4 m = transform * nodeTransform(node);
    CameraDesc cd;
    cd.name = ac->mName.length ? ac->mName.C_Str() : cat("camera", i);
    glm::vec3 pos(ac->mPosition.x, ac->mPosition.y, ac->mPosition.z);
    // assimp 5.2's glTF 2 importer (Debian 12's) also copies the camera node's translation into
    // mPosition, which is relative to that node: the translation counted twice (assimp issue
    // #5054, fixed in 5.3 where mPosition is 0). A glTF camera's position is its node's.
    if ((ext == ".gltf" || ext == ".glb") && node &&
        pos == glm::vec3(node->mTransformation.a4, node->mTransformation.b4, node->mTransformation.c4))
      pos = glm::vec3(0.0f);
    const glm::vec3 look(ac->mLookAt.x, ac->mLookAt.y, ac->mLookAt.z);
    cd.eye = glm::vec3(m * glm::vec4(pos, 1.0f));
    cd.target = glm::vec3(m * glm::vec4(pos + look, 1.0f));
    cd.up = glm::normalize(glm::vec3(m * glm::vec4(ac->mUp.x, ac->mUp.y, ac->mUp.z, 0.0f)));
    const float aspect = ac->mAspect > 0.0f ? ac->mAspect : 16.0f / 9.0f;
    if (ac->mHorizontalFOV > 0.0f)
      cd.fovY = glm::degrees(2.0f * std::atan(std::tan(ac->mHorizontalFOV * 0.5f) / aspect));
    if (cd.fovY > 0.0f && cd.fovY < 180.0f && glm::length(cd.target - cd.eye) > 0.0f) scene.cameras.push_back(cd);
  }
  for (unsigned i = 0; i < as->mNumLights; ++i) {
    const aiLight* al = as->mLights[i];
    if (al->mType != aiLightSource_POINT) continue;
    const glm::mat4 m = transform * nodeTransform(as->mRootNode->FindNode(al->mName));
    scene.lights.push_back({glm::vec3(m * glm::vec4(al->mPosition.x, al->mPosition.y, al->mPosition.z, 1.0f)),
                            glm::vec3(al->mColorDiffuse.r, al->mColorDiffuse.g, al->mColorDiffuse.b)});
  }
  scene.finalize(path);
  return scene;
}

}  // namespace

}  // namespace lt
