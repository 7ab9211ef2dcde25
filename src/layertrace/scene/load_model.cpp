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
#include "layertrace/scene/quake3_textures.h"
#include "layertrace/scene/zip_archive.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"
#include "layertrace/util/memory.h"
#include "layertrace/util/warning.h"

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

/// The most bytes a scene's decoded textures (with their mip chains) may take.
constexpr uint64_t kMaxTextureBytes = uint64_t(2) << 30;

/// The textures of a model, decoded once each into scene.textures (makeTexture builds the mip
/// chain): embedded in the model (assimp's "*N", or by file name) or a file beside it
/// (`modelDir`; none for a model read from memory). A texture that is missing or does not decode
/// is reported in one warning line and has no index (-1); one over kMaxImageSide per side, or
/// past kMaxTextureBytes for the scene, is refused (InputError).
class TextureLoader {
 public:
  TextureLoader(const aiScene* as, std::string modelDir, std::string source, Scene& scene)
      : as_(as), dir_(std::move(modelDir)), source_(std::move(source)), scene_(scene) {}

  int32_t operator()(const std::string& name) {
    const auto [it, added] = cache_.try_emplace(name, -1);
    if (added) it->second = load(name);
    return it->second;
  }

  /// Decodes an encoded image (`label` names it in messages).
  int32_t decode(const std::string& label, const uint8_t* data, size_t size) {
    const std::optional<Rgba8Image> image = decodeRgba8(data, size, label);
    if (!image) {
      warning(cat("scene ", source_, ": texture ", label, " does not decode (PNG, JPEG, TGA, BMP and DDS are read); its material keeps its colour"));
      return -1;
    }
    return add(label, image->width, image->height, image->pixels.data());
  }

  const Texture& texture(int32_t index) const { return *scene_.textures[size_t(index)]; }

  int32_t add(const std::string& label, int width, int height, const uint8_t* rgba) {
    bytes_ += uint64_t(width) * uint64_t(height) * 4 * 4 / 3 + 4;  // the chain: at most 4/3 of level 0
    if (bytes_ > kMaxTextureBytes)
      inputError("scene ", source_, ": its textures take more than the budget of ", kMaxTextureBytes >> 20, " MiB (at ", label, ")");
    checkAllocation(cat("texture ", label), uint64_t(width) * uint64_t(height) * 8);
    scene_.textures.push_back(std::make_shared<const Texture>(makeTexture(label, width, height, rgba)));
    return int32_t(scene_.textures.size() - 1);
  }

 private:
  int32_t load(const std::string& name) {
    if (const aiTexture* t = as_->GetEmbeddedTexture(name.c_str())) {
      if (!t->pcData) return -1;
      if (t->mHeight == 0) return decode(name, reinterpret_cast<const uint8_t*>(t->pcData), t->mWidth);
      if (t->mWidth > uint32_t(kMaxImageSide) || t->mHeight > uint32_t(kMaxImageSide))
        inputError("texture ", name, ": ", t->mWidth, "×", t->mHeight, " pixels, more than the limit of ", kMaxImageSide, " per side");
      std::vector<uint8_t> rgba;  // raw texels: ARGB8888 as b, g, r, a bytes
      const size_t n = size_t(t->mWidth) * size_t(t->mHeight);
      rgba.reserve(4 * n);
      for (size_t i = 0; i < n; ++i) rgba.insert(rgba.end(), {t->pcData[i].r, t->pcData[i].g, t->pcData[i].b, t->pcData[i].a});
      return add(name, int(t->mWidth), int(t->mHeight), rgba.data());
    }
    const std::string missing = cat("scene ", source_, ": texture ", name, " not found");
    if (dir_.empty()) return warning(missing + " (a model read from memory has no folder)"), -1;
    std::string file = name;
    std::replace(file.begin(), file.end(), '\\', '/');
    const fs::path path = fs::path(file).is_absolute() ? fs::path(file) : fs::path(dir_) / file;
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) return warning(cat(missing, " (", path.string(), "); its material keeps its colour")), -1;
    const uintmax_t size = fs::file_size(path, ec);
    if (ec || size > (uintmax_t(256) << 20))
      return warning(cat("scene ", source_, ": texture ", path.string(), " is over 256 MiB; its material keeps its colour")), -1;
    std::ifstream in(path, std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return decode(path.string(), bytes.data(), bytes.size());
  }

  const aiScene* as_;
  std::string dir_, source_;
  Scene& scene_;
  uint64_t bytes_ = 0;
  std::map<std::string, int32_t> cache_;
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

TextureWrap wrapMode(const aiMaterial* am, aiTextureType type, bool u) {
  int mode = aiTextureMapMode_Wrap;
  if (!getNumber(am, u ? _AI_MATKEY_MAPPINGMODE_U_BASE : _AI_MATKEY_MAPPINGMODE_V_BASE, unsigned(type), 0, mode)) return TextureWrap::Repeat;
  return mode == aiTextureMapMode_Clamp || mode == aiTextureMapMode_Decal ? TextureWrap::Clamp
         : mode == aiTextureMapMode_Mirror                                 ? TextureWrap::Mirror
                                                                           : TextureWrap::Repeat;
}

Material convertMaterial(const aiMaterial* am, TextureLoader& textures, const Scene& scene) {
  Material m;
  if (const auto name = materialString(am, AI_MATKEY_NAME)) m.name = *name;
  aiColor4D c;
  bool haveColor = false;
  if (getNumber(am, AI_MATKEY_BASE_COLOR, c) || getNumber(am, AI_MATKEY_COLOR_DIFFUSE, c)) {
    m.albedo = glm::clamp(glm::vec3(c.r, c.g, c.b), 0.0f, 1.0f);
    haveColor = true;
  }
  aiTextureType type = aiTextureType_BASE_COLOR;
  std::optional<std::string> tex = materialString(am, AI_MATKEY_TEXTURE(aiTextureType_BASE_COLOR, 0));
  if (!tex) type = aiTextureType_DIFFUSE, tex = materialString(am, AI_MATKEY_TEXTURE(aiTextureType_DIFFUSE, 0));
  if (tex && !tex->empty()) {
    // The texture multiplies the colour factor (glTF's base colour factor, OBJ's Kd; white when
    // the material gives none). One that cannot be read leaves the factor alone (a warning says so).
    m.baseTexture = textures(*tex);
    if (m.baseTexture >= 0) {
      if (!haveColor) m.albedo = glm::vec3(1.0f);
      m.wrapU = wrapMode(am, type, true), m.wrapV = wrapMode(am, type, false);
      // Alpha test: glTF's MASK with its cut-off (0.5 by default); glTF's OPAQUE (its default)
      // and BLEND (layertrace draws blending opaque) ignore alpha; a material of a format
      // without alpha modes whose texture's alpha is 1-bit is a cut-out at 0.5.
      const std::optional<std::string> mode = materialString(am, "$mat.gltf.alphaMode", 0, 0);
      float cutoff = 0.5f;
      if (mode == "MASK") {
        if (getNumber(am, "$mat.gltf.alphaCutoff", 0, 0, cutoff) && std::isfinite(cutoff)) m.alphaCutoff = std::clamp(cutoff, 0.0f, 1.0f);
        else m.alphaCutoff = 0.5f;
      } else if (!mode && scene.textures[size_t(m.baseTexture)]->binaryAlpha) {
        m.alphaCutoff = 0.5f;
      }
    }
  }
  if (const std::optional<std::string> spec = materialString(am, AI_MATKEY_TEXTURE(aiTextureType_SPECULAR, 0)); spec && !spec->empty())
    m.specularTexture = textures(*spec);
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

}  // namespace

namespace {

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

/// A Quake 3 surface without its texture: coloured by its key, so that surfaces stay distinguishable.
Material quake3Untextured(const std::string& key) {
  Material m{key};
  m.albedo = colorFromName(key), m.specular = 0.1f;
  return m;
}

/// The materials of a Quake 3 map's faces, from assimp's keys "texture.lightmap": the texture
/// record's shader name resolved to its image over the game's archives (Quake3Textures), and the
/// face's lightmap (a map's lightmaps hold light at half intensity: the engine's default
/// overbright shift doubles them, and so does this). A shader whose image is not found is
/// coloured by its name (reportArchiveWarnings says which, in one line).
class Quake3Materials {
 public:
  Quake3Materials(const Quake3Patches& map, const std::string& path, TextureLoader& loader)
      : map_(map), path_(path), loader_(loader), archives_(Quake3Textures::forMap(path)) {}

  Material operator()(const std::string& key) {
    Material m = quake3Untextured(key);
    const size_t dot = key.find('.');
    long texture = -1, lightmap = -1;
    try {
      texture = std::stol(key.substr(0, dot));
      if (dot != std::string::npos) lightmap = std::stol(key.substr(dot + 1));
    } catch (const std::exception&) {
      return m;  // not a key of assimp's: nothing to look up
    }
    if (texture >= 0 && size_t(texture) < map_.shaders.size()) {
      const std::string& shader = map_.shaders[size_t(texture)];
      m.name = shader;
      const auto [it, added] = images_.try_emplace(shader, -1);
      if (added) {
        if (const std::optional<Quake3Textures::Image> image = archives_.find(shader))
          it->second = loader_.decode(image->archive + ":" + image->name, image->bytes.data(), image->bytes.size());
        else
          missing_.push_back(shader);
      }
      if (it->second >= 0) {
        m.baseTexture = it->second, m.albedo = glm::vec3(1.0f);
        if (loader_.texture(it->second).binaryAlpha) m.alphaCutoff = 0.5f;
      }
    }
    const size_t lightmaps = map_.lightmaps.size() / kLightmapBytes;
    if (lightmap >= 0 && size_t(lightmap) < lightmaps) {
      const auto [it, added] = lightmaps_.try_emplace(lightmap, -1);
      if (added) {
        std::vector<uint8_t> rgba(size_t(kLightmapSide) * kLightmapSide * 4, 255);
        const unsigned char* src = &map_.lightmaps[size_t(lightmap) * kLightmapBytes];
        for (size_t i = 0; i < size_t(kLightmapSide) * kLightmapSide; ++i)
          for (int c = 0; c < 3; ++c) rgba[4 * i + size_t(c)] = uint8_t(std::min(2 * int(src[3 * i + size_t(c)]), 255));
        it->second = loader_.add(cat(path_, ": lightmap ", lightmap), kLightmapSide, kLightmapSide, rgba.data());
      }
      m.lightmap = it->second;
    }
    return m;
  }

  /// Archives skipped and scripts ignored while looking images up, one warning line each, and
  /// one line for the shaders whose image was not found (the first few named).
  void reportArchiveWarnings() const {
    for (const std::string& w : archives_.warnings()) warning(cat("scene ", path_, ": ", w));
    if (missing_.empty()) return;
    std::string names;
    for (size_t i = 0; i < std::min<size_t>(missing_.size(), 3); ++i) names += (i ? ", " : "") + missing_[i];
    warning(cat("scene ", path_, ": no image for ", missing_.size(), " of ", images_.size(), " shaders (", names, missing_.size() > 3 ? ", …" : "",
                ") in ", archives_.archiveCount(), " archives; they are coloured by their names"));
  }

 private:
  static constexpr int kLightmapSide = 128;
  static constexpr size_t kLightmapBytes = size_t(kLightmapSide) * kLightmapSide * 3;
  const Quake3Patches& map_;
  std::string path_;
  TextureLoader& loader_;
  Quake3Textures archives_;
  std::map<std::string, int32_t> images_;
  std::map<long, int32_t> lightmaps_;
  std::vector<std::string> missing_;
};

/// Appends a Quake 3 map's tessellated curved surfaces, transformed by `m`, each in the material
/// `materialFor` gives its key (the one made for assimp's faces of the same key, or a new one).
void addPatches(Scene& scene, const Quake3Patches& p, const glm::mat4& m, const std::function<uint32_t(const std::string&)>& materialFor) {
  std::vector<uint32_t> material(p.keys.size());
  for (size_t k = 0; k < p.keys.size(); ++k) material[k] = materialFor(p.keys[k]);
  const glm::mat3 nm = glm::inverseTranspose(glm::mat3(m));
  const bool mirrored = glm::determinant(glm::mat3(m)) < 0.0f;  // keeps each triangle's front side (convertScene)
  const auto base = uint32_t(scene.positions.size());
  for (size_t v = 0; v < p.positions.size(); ++v) {
    scene.positions.push_back(glm::vec3(m * glm::vec4(p.positions[v], 1.0f)));
    scene.normals.push_back(nm * p.normals[v]);  // zero length → derived from faces in finalize()
    scene.texcoords.push_back(p.texcoords[v]);
    scene.lightmapCoords.push_back(p.lightmapCoords[v]);
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
  TextureLoader textures(as, modelDir, path, scene);
  std::optional<Quake3Materials> q3materials;
  if (q3 && patches) q3materials.emplace(*patches, path, textures);
  std::map<std::string, uint32_t> q3keys;  // assimp's material key → the scene's material (patches share them)
  for (unsigned i = 0; i < as->mNumMaterials; ++i) {
    if (q3) {
      const std::optional<std::string> key = materialString(as->mMaterials[i], AI_MATKEY_NAME);
      q3keys.emplace(key.value_or(""), uint32_t(scene.materials.size()));
      scene.materials.push_back(q3materials ? (*q3materials)(key.value_or("")) : quake3Untextured(key.value_or("")));
      continue;
    }
    scene.materials.push_back(convertMaterial(as->mMaterials[i], textures, scene));
  }
  if (scene.materials.empty()) scene.materials.push_back(Material{"default"});
  bool uv = false;  // whether any mesh has texture coordinates

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
        const aiVector3D st = mesh->mTextureCoords[0] ? mesh->mTextureCoords[0][v] : aiVector3D(0.0f);
        const aiVector3D lm = mesh->mTextureCoords[1] ? mesh->mTextureCoords[1][v] : aiVector3D(0.0f);
        scene.texcoords.push_back(q3 ? quake3TexCoord({st.x, st.y}) : glm::vec2(st.x, st.y));
        if (q3) scene.lightmapCoords.push_back(quake3TexCoord({lm.x, lm.y}));
      }
      uv = uv || mesh->mTextureCoords[0];
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
  if (patches && !patches->triangles.empty()) addPatches(scene, *patches, transform * toGlm(as->mRootNode->mTransformation), [&](const std::string& key) {
      const auto [it, added] = q3keys.try_emplace(key, uint32_t(scene.materials.size()));
      if (added) scene.materials.push_back(q3materials ? (*q3materials)(key) : quake3Untextured(key));
      return it->second;
    });
  if (q3materials) q3materials->reportArchiveWarnings();
  // Texture coordinates only where a material has a texture to map.
  const bool textured = std::any_of(scene.materials.begin(), scene.materials.end(), [](const Material& m) {
    return m.baseTexture >= 0 || m.specularTexture >= 0 || m.lightmap >= 0;
  });
  // A model whose meshes have no texture coordinates cannot map its textures: each material
  // takes its textures' mean colour instead (flattenTextures).
  if (textured && !uv && !(patches && !patches->triangles.empty())) flattenTextures(scene);
  if (!textured) scene.texcoords.clear(), scene.lightmapCoords.clear();

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
