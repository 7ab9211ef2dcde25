// libFuzzer target: command-line parsing (app/cli.h) with argv from bytes (NUL-separated, at most
// 32 arguments), in ParseOnly mode: every option conversion and every check that needs no scene.
// Any argv must end in status 0 or 2 (bad input, one line) — never a crash or status 1.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "layertrace/app/cli.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<std::string> args{"layertrace"};
  std::string cur;
  for (size_t i = 0; i < size && args.size() < 32; ++i) {
    if (data[i] == 0) {
      args.push_back(cur), cur.clear();
    } else {
      cur += char(data[i]);
    }
  }
  if (!cur.empty() && args.size() < 32) args.push_back(cur);
  std::vector<const char*> argv;
  for (const std::string& a : args) argv.push_back(a.c_str());
  const int status = lt::runCli(int(argv.size()), argv.data(), lt::CliMode::ParseOnly);
  if (status != 0 && status != 2) std::abort();  // an internal error on an option is a bug
  return 0;
}
