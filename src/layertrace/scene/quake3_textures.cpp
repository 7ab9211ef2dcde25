// Quake 3's texture lookup (quake3_textures.h). The rules are ioquake3's: its file system
// (files.c: archives of a game folder sorted by name, the later searched first; names compared
// case-insensitively with '\\' as '/'), its shader scripts (tr_shader.c: ScanAndLoadShaderFiles,
// FindShaderInShaderText, ParseStage) and its image loaders (tr_image.c: R_LoadImage's
// extensions). Scripts are tokenised as the engine's COM_ParseExt does: words separated by
// white space, "quoted strings", // and /* */ comments.
#include "layertrace/scene/quake3_textures.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <filesystem>
#include <optional>
#include <set>
#include <string_view>
#include <utility>

#include "layertrace/util/error.h"

namespace lt {
namespace fs = std::filesystem;

namespace {

/// The largest entry read, image or script: far beyond any Quake 3 texture (a 4096² 32-bit TGA
/// is 64 MiB), so that an archive declaring huge sizes is not inflated into memory.
constexpr uint64_t kMaxEntryBytes = uint64_t(256) << 20;

/// A name as the game compares names: lower case, '\\' as '/'.
std::string fold(std::string_view name) {
  std::string s(name);
  for (char& c : s) c = c == '\\' ? '/' : char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// The position of a name's extension dot (after its last '/'), or npos.
size_t extensionDot(const std::string& name) {
  const size_t dot = name.rfind('.'), slash = name.rfind('/');
  return dot != std::string::npos && (slash == std::string::npos || dot > slash) ? dot : std::string::npos;
}

/// The game's path order (files.c FS_PathCmp): case-insensitive, '\\' and ':' as '/'.
bool pathLess(const std::string& a, const std::string& b) {
  const auto key = [](char c) {
    c = char(std::toupper(static_cast<unsigned char>(c)));
    return static_cast<unsigned char>(c == '\\' || c == ':' ? '/' : c);
  };
  return std::lexicographical_compare(a.begin(), a.end(), b.begin(), b.end(), [&](char x, char y) { return key(x) < key(y); });
}

/// One token of a shader script: its text and whether a line break precedes it.
struct Token {
  std::string text;
  bool newLine = false;
  int line = 1;
};

/// A shader script's tokens, read as the engine's COM_ParseExt reads them.
class Tokens {
 public:
  explicit Tokens(std::string_view text) : text_(text) {}

  std::optional<Token> next() {
    if (pushed_) return std::exchange(pushed_, std::nullopt);
    bool newLine = false;
    while (at_ < text_.size()) {
      const auto c = static_cast<unsigned char>(text_[at_]);
      if (c == '\n') newLine = true, ++line_;
      if (c <= ' ') {
        ++at_;
      } else if (text_.compare(at_, 2, "//") == 0) {
        at_ = std::min(text_.find('\n', at_), text_.size());
      } else if (text_.compare(at_, 2, "/*") == 0) {
        const size_t end = std::min(text_.find("*/", at_ + 2), text_.size());
        for (size_t i = at_; i < end; ++i) line_ += text_[i] == '\n';
        newLine = newLine || text_.substr(at_, end - at_).find('\n') != std::string_view::npos;
        at_ = std::min(end + 2, text_.size());
      } else {
        break;
      }
    }
    if (at_ >= text_.size()) return std::nullopt;
    Token t{{}, newLine, line_};
    if (text_[at_] == '"') {
      const size_t end = std::min(text_.find('"', at_ + 1), text_.size());
      t.text = text_.substr(at_ + 1, end - at_ - 1);
      at_ = std::min(end + 1, text_.size());
    } else {
      const size_t start = at_;
      while (at_ < text_.size() && static_cast<unsigned char>(text_[at_]) > ' ') ++at_;
      t.text = text_.substr(start, at_ - start);
    }
    return t;
  }
  /// The argument of a keyword: the next token when it is on the same line (else none, and the
  /// token stays to be read).
  std::optional<Token> argument() {
    std::optional<Token> t = next();
    if (t && t->newLine) pushed_ = std::move(t);
    return t && !t->newLine ? t : std::nullopt;
  }

 private:
  std::string_view text_;
  size_t at_ = 0;
  int line_ = 1;
  std::optional<Token> pushed_;
};

/// The shaders one script defines, (name, image) in the order written; "": no image. InputError
/// (with the line) when the script is malformed: a name without an opening brace or a block
/// without its closing one, for which the engine ignores the whole script.
std::vector<std::pair<std::string, std::string>> parseScript(std::string_view text) {
  std::vector<std::pair<std::string, std::string>> shaders;
  Tokens tokens(text);
  while (std::optional<Token> name = tokens.next()) {
    const std::optional<Token> open = tokens.next();
    if (!open || open->text != "{") inputError("shader \"", name->text, "\" on line ", name->line, " has no opening brace");
    std::string image;
    int depth = 1;
    bool stageDone = false;  // the current stage has named its map (an image or a $ name)
    while (depth > 0) {
      const std::optional<Token> t = tokens.next();
      if (!t) inputError("shader \"", name->text, "\" on line ", name->line, " has no closing brace");
      if (t->text == "{") {
        ++depth;
        stageDone = false;
        continue;
      }
      if (t->text == "}") {
        --depth;
        continue;
      }
      if (depth != 2 || stageDone || !image.empty()) continue;
      const std::string keyword = fold(t->text);
      std::optional<Token> map;
      if (keyword == "map" || keyword == "clampmap") {
        map = tokens.argument();
      } else if (keyword == "animmap") {  // animMap <frequency> <frame> <frame>…
        if (tokens.argument()) map = tokens.argument();
      } else if (keyword == "videomap") {
        stageDone = true;
      }
      if (!map) continue;
      stageDone = true;
      if (map->text.empty() || map->text[0] != '$') image = map->text;
    }
    shaders.emplace_back(name->text, image);
  }
  return shaders;
}

bool isPk3(const fs::path& p) { return fold(p.extension().string()) == ".pk3"; }

}  // namespace

Quake3Textures Quake3Textures::forMap(const std::string& mapPath) {
  const fs::path map(mapPath);
  const fs::path dir = map.parent_path().empty() ? fs::path(".") : map.parent_path();
  std::vector<fs::path> found;
  if (isPk3(map)) found.push_back(map);
  const auto addFolder = [&](const fs::path& folder) {
    std::error_code ec;
    for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec))
      if (isPk3(it->path()) && it->is_regular_file(ec)) found.push_back(it->path());
  };
  addFolder(dir);
  addFolder(dir / "baseoa");
  addFolder(dir / "baseq3");
  std::error_code ec;
  const fs::path absolute = fs::absolute(dir, ec);
  if (!ec && fold(absolute.filename().string()) == "maps") addFolder(absolute.parent_path());
  // Each archive once (the map's own archive is also in its folder), by file name.
  std::set<std::string> seen;
  std::vector<fs::path> archives;
  for (const fs::path& p : found) {
    std::error_code ignored;
    const fs::path canonical = fs::weakly_canonical(p, ignored);
    if (seen.insert((canonical.empty() ? p : canonical).string()).second) archives.push_back(p);
  }
  std::sort(archives.begin(), archives.end(), [](const fs::path& a, const fs::path& b) {
    const std::string na = a.filename().string(), nb = b.filename().string();
    if (pathLess(na, nb) || pathLess(nb, na)) return pathLess(na, nb);
    return a.string() < b.string();
  });
  std::vector<std::string> paths;
  for (const fs::path& p : archives) paths.push_back(p.string());
  return Quake3Textures(std::move(paths));
}

Quake3Textures::Quake3Textures(std::vector<std::string> archives) : archives_(std::move(archives)) {}

void Quake3Textures::index() {
  indexed_ = true;
  // Every archive's names, the later archive's entry replacing the earlier's (and within one
  // archive the later entry, as the engine's per-archive hash chains find it first).
  std::vector<std::vector<uint32_t>> scripts(archives_.size());  // per archive, its scripts/*.shader entries in order
  for (size_t a = 0; a < archives_.size(); ++a) {
    try {
      zips_.push_back(std::make_unique<ZipDirectory>(archives_[a]));
    } catch (const InputError& e) {
      zips_.push_back(nullptr);
      warnings_.push_back(cat(e.what(), " (archive skipped)"));
      continue;
    }
    const std::vector<ZipEntry>& entries = zips_.back()->entries;
    for (size_t n = 0; n < entries.size(); ++n) {
      if (entries[n].name.empty() || entries[n].name.back() == '/') continue;  // a folder
      std::string name = fold(entries[n].name);
      const Location where{uint32_t(a), uint32_t(n)};
      if (name.starts_with("scripts/") && name.ends_with(".shader")) scripts[a].push_back(uint32_t(n));
      files_[std::move(name)] = where;
    }
  }
  parseScripts(scripts);
}

void Quake3Textures::parseScripts(const std::vector<std::vector<uint32_t>>& scripts) {
  // The engine's list: latest archive first, each archive's scripts in directory order, each
  // name once (its first, the latest archive's). Its text is that list read backwards, and the
  // first definition of a name in it wins.
  std::vector<std::string> list;
  std::set<std::string> listed;
  for (size_t a = scripts.size(); a-- > 0;)
    for (const uint32_t n : scripts[a]) {
      std::string name = fold(zips_[a]->entries[n].name);
      if (listed.insert(name).second) list.push_back(std::move(name));
    }
  for (auto script = list.rbegin(); script != list.rend(); ++script) {
    const Location where = files_.at(*script);
    ZipDirectory& zip = *zips_[where.archive];
    const ZipEntry& entry = zip.entries[where.entry];
    const std::string source = cat(zip.path(), ":", entry.name);
    try {
      if (entry.unpacked > kMaxEntryBytes) inputError("declares ", entry.unpacked, " bytes");
      const std::vector<unsigned char> bytes = zip.contents(entry);
      for (auto& [name, image] : parseScript(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size())))
        shaders_.emplace(fold(name), std::move(image));
    } catch (const InputError& e) {
      warnings_.push_back(cat("shader script ", source, " ignored: ", e.what()));
    }
  }
}

std::optional<Quake3Textures::Location> Quake3Textures::locateImage(const std::string& name) const {
  static constexpr std::array<std::string_view, 5> kTried = {"tga", "jpg", "jpeg", "png", "bmp"};
  static constexpr std::array<std::string_view, 6> kImage = {"tga", "jpg", "jpeg", "png", "bmp", "pcx"};
  const std::string folded = fold(name);
  if (const auto it = files_.find(folded); it != files_.end()) return it->second;
  // The name less its image extension (a name such as "light_1.5" keeps its dot), each loader's in turn.
  std::string stem = folded, ext;
  if (const size_t dot = extensionDot(folded); dot != std::string::npos &&
                                               std::find(kImage.begin(), kImage.end(), folded.substr(dot + 1)) != kImage.end())
    stem = folded.substr(0, dot), ext = folded.substr(dot + 1);
  for (const std::string_view e : kTried) {
    if (e == ext) continue;  // tried as given
    if (const auto it = files_.find(cat(stem, ".", e)); it != files_.end()) return it->second;
  }
  return std::nullopt;
}

std::optional<Quake3Textures::Image> Quake3Textures::find(const std::string& shader) {
  if (!indexed_) index();
  const std::string key = fold(shader);
  auto cached = found_.find(key);
  if (cached == found_.end()) {
    // The engine looks its shader scripts up by the name less any extension.
    const size_t dot = extensionDot(key);
    const auto defined = shaders_.find(dot == std::string::npos ? key : key.substr(0, dot));
    std::optional<Location> where;
    if (defined != shaders_.end() && !defined->second.empty()) where = locateImage(defined->second);
    if (!where) where = locateImage(shader);
    cached = found_.emplace(key, where).first;
  }
  if (!cached->second) return std::nullopt;
  ZipDirectory& zip = *zips_[cached->second->archive];
  const ZipEntry& entry = zip.entries[cached->second->entry];
  try {
    if (entry.unpacked > kMaxEntryBytes) inputError("scene ", zip.path(), ": zip entry ", entry.name, " declares ", entry.unpacked, " bytes");
    return Image{entry.name, zip.contents(entry), zip.path()};
  } catch (const InputError& e) {
    warnings_.push_back(cat(e.what(), " (texture of ", shader, " skipped)"));
    cached->second = std::nullopt;  // warned once
    return std::nullopt;
  }
}

}  // namespace lt
