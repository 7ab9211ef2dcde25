// libFuzzer target: the Quake 3 .pk3 path (a zip archive holding a .bsp), which assimp reads
// only from a file: the bytes go to a temporary .pk3 and through loadModel, the path the CLI
// takes. Any bytes must give a scene or an InputError.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

#include <unistd.h>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  lt::setModelImportTimeout(5);  // below libFuzzer's -timeout: a stuck importer is an input error
  lt::setModelImportCrashRecovery(true);  // an importer crash is an input error too: the search goes on
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const std::string path = "/tmp/layertrace-fuzz-" + std::to_string(::getpid()) + ".pk3";
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return 0;
  const bool written = std::fwrite(data, 1, size, f) == size;
  std::fclose(f);
  if (!written) return 0;
  try {
    const lt::Scene s = lt::loadModel(path);
    (void)s;
  } catch (const lt::InputError&) {
  }
  return 0;
}
