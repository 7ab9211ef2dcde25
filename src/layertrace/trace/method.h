// What a method tells the tracer registry about itself (pipeline/tracer_registry.h): its tracer
// names and its parameters. Each method folder (ssr/, hssr/, quadtree/, …) declares these next
// to its Config struct, so a parameter's flag, help line and default live in one place and the
// CLI, `layertrace tracers`, the viewer and the library all read them from there.
#pragma once

#include <span>
#include <string>
#include <variant>

namespace lt {

/// Where a tracer takes its answers from.
enum class TracerKind {
  Screen,           ///< the camera's k layers only (the image-space oracles apply)
  ViewIndependent,  ///< a structure built from the scene along fixed axes (layered depth cube)
  Geometric,        ///< the scene's triangles
  Hybrid,           ///< image space first, geometry for what the layers cannot know
};

/// One tracer name and what it is, for listings.
struct MethodInfo {
  const char* name;     ///< the --tracer value
  TracerKind kind;
  const char* summary;  ///< one line: what it does
  const char* paper;    ///< the paper it implements ("" for none)
};

/// One command-line parameter of a method's Config struct.
template <class Config>
struct Param {
  const char* flag;   ///< "--hssr-tau"
  const char* alias;  ///< an older spelling, still accepted but not listed ("" for none)
  const char* help;   ///< one line; the default is printed beside it
  std::variant<float Config::*, int Config::*, bool Config::*, std::string Config::*> field;
  /// The value under `--preset paper` ("25", "false"): the paper's own setting where the default
  /// ("tuned") departs from it; nullptr where the two agree.
  const char* paper = nullptr;
};

}  // namespace lt
