// Scene loading. SCENE on the command line is either a JSON scene file (see scenes/README.md for
// its format) or any model file assimp reads; Quake 3 archives (.pk3) and maps (.bsp) get the
// fix-up described in load_model.cpp. Every failure is an InputError naming the file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "layertrace/scene/scene.h"

struct aiMaterial;

namespace lt {

/// Loads a JSON scene or a model file, chosen by extension (.json → JSON scene), and
/// recentre()s it: a scene far from the origin comes back with Scene::origin set.
Scene loadScene(const std::string& path);

/// Loads one model file through assimp, transformed by `transform`.
Scene loadModel(const std::string& path, const glm::mat4& transform = glm::mat4(1.0f));

/// A string property of an assimp material (`key`, `semantic`, `index` as assimp's AI_MATKEY_*
/// macros give them), read from its bytes: assimp's own getter asserts that the stored string
/// ends in a zero byte and aborts the process when it does not, and some importers store strings
/// without one (assimp 5.2.5's MDL7 reader: `broadleavedtreeD.mdl` of assimp's test models).
/// Here the length is clamped to the property's bytes and the string ends at
/// its first zero byte; a property that is not a string is absent.
std::optional<std::string> materialString(const aiMaterial* material, const char* key, unsigned semantic, unsigned index);
/// Whether a material property is a number assimp's number getters read: one stored as a string
/// is not. assimp 5.2.5 parses such a string after asserting (aborting) that it ends in a zero
/// byte, and then never succeeds: one number fails, several throw (it does not skip the space
/// between them). False for an absent property too.
bool readableNumber(const aiMaterial* material, const char* key, unsigned semantic, unsigned index);

/// An import that runs longer than this is stopped and reported as a malformed model (one line,
/// status 2); 0 = no limit. Large models import in seconds; an importer stuck in a loop never
/// returns (assimp 5.2.5's PLY reader on some malformed headers).
inline constexpr unsigned kDefaultImportTimeoutSeconds = 300;
void setModelImportTimeout(unsigned seconds);
/// Off (the default): an importer that crashes ends the process with one line and exit status 2.
/// On: the crash unwinds out of the import as an InputError, so the process goes on (a fuzzer
/// searching past assimp's crashes); the crashed importer's memory is then leaked.
void setModelImportCrashRecovery(bool on);

/// A zip archive (.pk3) whose entries declare more than this in total, or an entry over 64 MiB
/// that expands more than 1000-fold, is refused before assimp inflates it (zip bombs).
inline constexpr uint64_t kMaxArchiveBytes = uint64_t(4) << 30;
/// InputError naming `path` when its central directory breaks the limits above or is malformed.
void checkArchiveSizes(const std::string& path, uint64_t maxTotalBytes);
/// checkArchiveSizes, then every .bsp inside the archive through validateQuake3Bsp (InputError
/// naming the archive and the map); one read of the central directory, each map inflated once.
/// Returns the bytes of the map assimp's importer reads from the archive (empty: none).
std::vector<unsigned char> checkQuake3Archive(const std::string& path, uint64_t maxTotalBytes);
/// InputError naming `name` unless `data` is a Quake 3 map (IBSP 46) whose lump directory lies
/// inside the file and whose faces index existing vertices, mesh vertices, textures and
/// lightmaps — what assimp's Q3BSP importer reads without checking (scene/quake3_bsp.cpp).
void validateQuake3Bsp(const unsigned char* data, size_t size, const std::string& name);

/// The curved surfaces of a Quake 3 map, which assimp 5.2's importer drops (am_thornish loses 520,
/// its arches and columns): every face of type 2 is a grid of width × height control points
/// (both odd), (width − 1)/2 × (height − 1)/2 biquadratic Bézier patches sharing their border
/// rows. Each grid is tessellated whole, so patches that share a border share its vertices.
struct Quake3Patches {
  std::vector<glm::vec3> positions, normals;  ///< map coordinates; normals interpolated from the control points'
  std::vector<glm::uvec3> triangles;          ///< counter-clockwise seen from the side the normals point to
  std::vector<uint32_t> triKey;               ///< per triangle, an index into keys
  /// The names assimp's importer gives the faces' materials: "texture.lightmap" (its createKey).
  std::vector<std::string> keys;
  /// Per vertex: texture and lightmap coordinates (quake3TexCoord).
  std::vector<glm::vec2> texcoords, lightmapCoords;
  /// The whole map's, not only the patches': the shader name of each texture record ("texture" in
  /// a key indexes it), and the lightmaps, 128 × 128 RGB8 each, rows top-down.
  std::vector<std::string> shaders;
  std::vector<unsigned char> lightmaps;
};
/// A Quake 3 texture or lightmap coordinate (s, t; t grows down the image) in the scene's
/// convention (texture.h: v grows up the image).
glm::vec2 quake3TexCoord(glm::vec2 st);
/// `data` must pass validateQuake3Bsp (checked again). `tolerance`: the largest distance (map
/// units) between a patch and its triangles, where 64 segments per patch side reach it.
Quake3Patches tessellateQuake3Patches(const unsigned char* data, size_t size, float tolerance);

/// InputError naming `name` when an OFF file's header (the first 4 KiB of `data`) declares more
/// vertices or faces than `size` bytes of text can hold: assimp's OFF importer would otherwise
/// reserve memory for them (assimp's own test file OutOfMemory.off, 353 535 235 358 vertices in
/// 309 bytes, ran for 85 s before the importer died).
void validateOffHeader(const char* data, size_t size, const std::string& name);

/// Loads a model from memory through assimp; `formatHint` is the file extension without the dot
/// ("obj", "glb", …), `source` names the input in error messages. A Quake 3 archive comes back as
/// assimp reads it, without the curved surfaces loadModel adds.
Scene loadModelFromMemory(const void* data, size_t size, const std::string& formatHint, const std::string& source);

/// Loads a JSON scene file composing models, shapes, materials, lights and cameras.
Scene loadJsonScene(const std::string& path);

/// Parses a JSON scene from text; `baseDir` resolves relative model paths, `source` names the
/// input in error messages.
Scene parseJsonScene(const std::string& text, const std::string& baseDir, const std::string& source);

// Built-in shapes (JSON "box", "sphere", "quad"), with outward normals, one material (index 0).
Scene makeBox(glm::vec3 lo, glm::vec3 hi);
Scene makeSphere(glm::vec3 center, float radius, int segments);
/// A parallelogram corner, corner+u, corner+u+v, corner+v (two triangles).
Scene makeQuad(glm::vec3 corner, glm::vec3 u, glm::vec3 v);

/// Applies an affine transform to positions and (inverse-transpose) to normals.
void transformScene(Scene& scene, const glm::mat4& m);

}  // namespace lt
