// The command line: subcommands render, layers, compare, bench, geobench, ldc, view, tracers (docs/cli.md).
#pragma once

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

}  // namespace lt
