// The command line of DESIGN.md: subcommands render, layers, compare, bench, geobench.
#pragma once

namespace lt {

enum class CliMode {
  Run,        ///< parse, check and run the subcommand
  ParseOnly,  ///< parse and check every option that needs no scene, then return (fuzzing)
};

/// Parses `argv` and runs the subcommand. Returns the exit status: 0 success, 2 bad input (one
/// line on stderr naming the input and the value), 1 internal error.
int runCli(int argc, const char* const* argv, CliMode mode = CliMode::Run);

}  // namespace lt
