// libFuzzer target: model ingestion from memory (scene/load_model.cpp) — assimp's importer for a
// format chosen by the first byte, then our mesh checks, normals, bounds and (for .bsp) the
// Quake 3 fix-up. Any bytes must give a scene or an InputError.
#include <cstddef>
#include <cstdint>
#include <iterator>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"

namespace {
// The formats of the fetched scenes and the common ones assimp reads from memory.
const char* const kFormats[] = {"obj", "ply", "stl", "off", "gltf", "glb", "dae", "fbx", "3ds", "ifc",
                                "x",   "ac",  "ase", "ms3d", "lwo", "smd", "nff", "md2", "md3", "bsp"};
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  lt::setModelImportTimeout(5);  // below libFuzzer's -timeout: a stuck importer is an input error
  lt::setModelImportCrashRecovery(true);  // an importer crash is an input error too: the search goes on
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const char* format = kFormats[data[0] % std::size(kFormats)];
  try {
    const lt::Scene s = lt::loadModelFromMemory(data + 1, size - 1, format, "fuzz-model");
    (void)s;
  } catch (const lt::InputError&) {
  }
  return 0;
}
