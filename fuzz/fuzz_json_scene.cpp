// libFuzzer target: JSON scene files (scene/load_json.cpp). Any bytes must give a scene or an
// InputError naming the input — never a crash, a leak, an out-of-bounds access or a hang.
// Model paths resolve against a folder that does not exist, so every "model" entry fails cleanly.
#include <cstddef>
#include <cstdint>
#include <string>

#include "layertrace/scene/load.h"
#include "layertrace/util/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const lt::Scene s = lt::parseJsonScene(text, "/nonexistent-layertrace-fuzz", "fuzz.json");
    (void)s;
  } catch (const lt::InputError&) {
  }
  return 0;
}
