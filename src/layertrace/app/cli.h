// The command line: subcommands render, layers, compare, bench, geobench, ldc, view, tracers (docs/cli.md).
#pragma once

#include <string>

#include "layertrace/app/commands.h"

namespace lt {

enum class CliMode {
  Run,        ///< parse, check and run the subcommand
  ParseOnly,  ///< parse and check every option that needs no scene, then return (fuzzing)
};

struct ViewOptions;
/// The interactive viewer (`layertrace view`) lives outside the library (apps/viewer/, GLFW +
/// OpenGL + Dear ImGui); a binary that has it registers it here before runCli. Without it
/// `view` exits with status 2 and says how to build it.
using ViewRunner = int (*)(const ViewOptions&);
void setViewRunner(ViewRunner runner);

/// Parses `argv` and runs the subcommand. Returns the exit status: 0 success, 2 bad input (one
/// line on stderr naming the input and the value), 1 internal error.
int runCli(int argc, const char* const* argv, CliMode mode = CliMode::Run);

/// The checked options of a `render` or `compare` command line, for a caller that runs the
/// command itself (the Python package): the same parsing, presets, defaults and checks as
/// runCli, without running, writing or printing anything.
struct CliCommand {
  std::string name;  ///< "render" or "compare"
  RenderOptions render;
  CompareOptions compare;
};
/// Throws InputError with the line runCli would print (without its "layertrace: " prefix) for
/// bad input, and for any subcommand other than render and compare.
CliCommand parseCli(int argc, const char* const* argv);

}  // namespace lt
