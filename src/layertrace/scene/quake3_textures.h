// Quake 3's texture lookup: the image a map's shader name stands for, found the way the game
// (ioquake3, which OpenArena runs on) finds it over its .pk3 archives. A map names shaders
// ("textures/base_wall/concrete"); a shader script (scripts/*.shader) may define one, and its
// first stage's image is the texture; a shader no script defines is the image of its own name.
// Internal to scene/: the model loader's Quake 3 materials.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "layertrace/scene/zip_archive.h"

namespace lt {

/// Quake 3's lookup of the image a map's shader name stands for, over the game's .pk3 archives.
/// Names compare as the game compares them: case-insensitively, '\\' as '/'. Rules:
///  - An archive later in the search list wins over an earlier one, for images and scripts alike.
///  - Shader scripts are the scripts/*.shader entries of all archives (one script name read from
///    the latest archive holding it). A shader defined in several scripts keeps the definition
///    ioquake3 keeps: scripts listed latest archive first (each archive's in its directory order)
///    and read in the reverse of that list, the first definition read winning.
///  - A shader's image is the map, clampMap or first animMap frame of its first stage that names
///    an image ($lightmap, $whiteimage and other $ names name none). A defined shader without
///    one, or whose image no archive holds, and a shader no script defines, are the image of the
///    shader's own name.
///  - An image name is looked for as given, then with its image extension (.tga, .jpg, .jpeg,
///    .png, .bmp, .pcx; none: the name whole) replaced by .tga, .jpg, .jpeg, .png and .bmp in
///    turn, as ioquake3's image loaders try them (less .pcx, which nothing here decodes).
/// The archives' directories are read and the scripts parsed once, at the first find(); an
/// archive that cannot be read is skipped with a warning (warnings()), never failing the lookup.
/// Only the names are kept: an entry's bytes are inflated when a find() returns it. Not safe to
/// share between threads (find() fills caches).
class Quake3Textures {
 public:
  /// The archives searched for a map at `mapPath` (.pk3 or .bsp): the map's own archive (if a .pk3),
  /// every .pk3 in the map's folder, every .pk3 in a `baseoa` or `baseq3` folder beside the map,
  /// and for a map in a `maps` folder (a game folder's maps/) every .pk3 of the folder above;
  /// archives sorted by file name (case-insensitively, as the game does), later archives searched first.
  /// Folders that do not exist add nothing.
  static Quake3Textures forMap(const std::string& mapPath);
  /// `archives`: the .pk3 files to search, in search order last first.
  explicit Quake3Textures(std::vector<std::string> archives);

  struct Image {
    std::string name;                  ///< the entry found ("textures/base_wall/concrete.jpg"), for messages
    std::vector<unsigned char> bytes;  ///< the encoded image: tga, jpg, png or bmp bytes
    std::string archive;               ///< the archive holding it
  };
  /// The encoded image of shader `shader` ("textures/base_wall/concrete"), or nullopt when no
  /// archive holds it. Where an image lies is looked up once per shader; its bytes are read
  /// from the archive at every call.
  std::optional<Image> find(const std::string& shader);

  /// The archives searched (the constructor's list, skipped ones included).
  size_t archiveCount() const { return archives_.size(); }
  const std::vector<std::string>& archives() const { return archives_; }
  /// One line per archive skipped, shader script ignored or entry that could not be read, so far.
  std::vector<std::string> warnings() const { return warnings_; }

 private:
  struct Location {
    uint32_t archive = 0, entry = 0;
  };
  void index();
  void parseScripts(const std::vector<std::vector<uint32_t>>& scripts);
  std::optional<Location> locateImage(const std::string& name) const;

  std::vector<std::string> archives_;
  bool indexed_ = false;
  std::vector<std::unique_ptr<ZipDirectory>> zips_;          ///< per archive; null when skipped
  std::unordered_map<std::string, Location> files_;          ///< folded name → the latest archive's entry
  std::unordered_map<std::string, std::string> shaders_;     ///< folded shader name → its image ("": none)
  std::unordered_map<std::string, std::optional<Location>> found_;  ///< folded shader name → its image's entry
  std::vector<std::string> warnings_;
};

}  // namespace lt
