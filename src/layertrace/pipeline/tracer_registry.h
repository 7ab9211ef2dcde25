// The tracer registry: every method's name, parameters and builder, read by the CLI, `layertrace
// tracers`, the viewer and the library. A method declares its name and parameters in its own
// folder (trace/method.h); this file binds them to TracerOptions and builds the tracer for a frame.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <span>
#include <string_view>
#include <variant>
#include <vector>

#include <nlohmann/json.hpp>

#include "layertrace/geometry/embree_method.h"
#include "layertrace/geometry/embree_scene.h"
#include "layertrace/grid/grid_method.h"
#include "layertrace/hiz/hiz_method.h"
#include "layertrace/hssr/hssr_method.h"
#include "layertrace/hybrid/hybrid_method.h"
#include "layertrace/hybrid/hybrid_tracer.h"
#include "layertrace/ldc/ldc_method.h"
#include "layertrace/pipeline/frame.h"
#include "layertrace/quadtree/quadtree_method.h"
#include "layertrace/ssr/ssr_method.h"

namespace lt {

/// The hybrid's HSSR / Hi-Z intervals (known_space.h solidIntervals): the last stored surface of
/// a complete pixel is this many pixel footprints deep.
inline constexpr float kHybridLastThicknessPx = 20.0f;

/// Every method's parameters, one Config per method folder. Each field's flag, help line and
/// default live in that folder (its *_method.h); tracerParams() binds them to this struct.
struct TracerOptions {
  SsrConfig ssr;
  PyramidConfig pyramid;
  HssrConfig hssr;
  GridConfig grid;
  QuadtreeConfig quadtree;
  LdcConfig ldc;
  HybridConfig hybrid;
  std::string preset = "tuned";  ///< the preset these started from (applyPreset), for the statistics
};

/// Throws InputError naming the flag for any invalid value, whichever tracer will run.
void validateTracerOptions(const TracerOptions& options);

/// A method parameter bound to its field of TracerOptions.
using ParamRef = std::variant<float*, int*, bool*, std::string*>;
struct TracerParam {
  const char* group;  ///< the method folder that declares it: "ssr", "hssr", …
  const char* flag;   ///< "--hssr-tau"
  const char* alias;  ///< older spelling, accepted but not listed ("" for none)
  const char* help;
  std::function<ParamRef(TracerOptions&)> field;  ///< the field it sets in a TracerOptions
  const char* paper = nullptr;  ///< its value under --preset paper (nullptr: the default is the paper's)
};
/// Every method parameter, grouped by method, in listing order.
std::span<const TracerParam> tracerParams();
/// The current value of a parameter in `options`, as the CLI prints it ("4", "true", "hssr").
std::string paramValue(const TracerParam& param, const TracerOptions& options);
/// Sets a parameter from its text ("25", "0.12", "true"); InputError naming the flag for a value
/// of the wrong type.
void setParamValue(const TracerParam& param, TracerOptions& options, const std::string& value);

/// The parameter presets: "tuned" (the defaults: what measured fastest here, with the same
/// answers) and "paper" (every method with its paper's parameters and rules, as published).
inline constexpr const char* kPresetNames[] = {"tuned", "paper"};
/// Sets every parameter the preset `name` gives (TracerParam::paper for "paper"; the defaults for
/// "tuned") except those `keep` returns true for (the ones a user set explicitly).
/// InputError for an unknown preset.
void applyPreset(std::string_view name, TracerOptions& options, const std::function<bool(const TracerParam&)>& keep = {});
/// The options of preset `name` from the defaults.
TracerOptions presetOptions(std::string_view name);
/// Every parameter's value by flag without its dashes ({"hssr-tau": 4, …}): the statistics'
/// "parameters" object.
nlohmann::json parameterStats(const TracerOptions& options);

struct BuiltTracer;
struct Frame;
/// One tracer of the registry: what it is, which parameter groups it reads, how to build it.
struct TracerEntry {
  MethodInfo info;
  std::vector<const char*> groups;  ///< parameter groups it reads (TracerParam::group)
  BuiltTracer (*build)(const Frame& frame, const TracerOptions& options);
  /// What the capture builds for this tracer while it rasterizes (HSSR: its interval pyramid,
  /// tile by tile, Frame::pyramid), asked for in the frame's options; null for none.
  void (*prepareCapture)(const TracerOptions& options, FrameOptions& frame) = nullptr;
  /// Where it reads only some parameters of its groups: their flags (Hi-Z reads the HSSR
  /// group's level count alone); empty: every parameter of its groups.
  std::vector<const char*> only = {};
  /// Whether it reads `param` (what `layertrace tracers` lists under it).
  bool reads(const TracerParam& param) const;
};
/// Asks the capture for what the tracer `name` can have built with it (TracerEntry::prepareCapture).
void prepareCapture(std::string_view name, const TracerOptions& options, FrameOptions& frame);
/// Every tracer: ssr, ssr-layers, hiz, hssr, quadtree, ldc, hybrid, embree, embree-robust, grid.
std::span<const TracerEntry> tracerRegistry();
/// The entry named `name`, or null.
const TracerEntry* findTracer(std::string_view name);
/// "ssr, ssr-layers, …": the names, for messages.
const std::string& tracerNames();
/// A tracer that answers from the camera's layers alone (the exhaustive oracle applies to it).
bool isScreenTracer(const std::string& name);
bool isKnownTracer(const std::string& name);

struct BuiltTracer {
  std::unique_ptr<Tracer> tracer;
  std::shared_ptr<IntervalPyramid> pyramid;  ///< hssr, hiz (hssr: may be the frame's, Frame::pyramid)
  std::unique_ptr<Quadtree> quadtree;        ///< quadtree
  std::unique_ptr<LayeredDepthCube> ldc;     ///< ldc
  std::unique_ptr<EmbreeScene> embree;       ///< embree
  std::unique_ptr<IrregularGrid> grid;       ///< grid
  std::unique_ptr<KnownSpace> known;         ///< hybrid: where the layers' knowledge ends
  std::vector<BuiltTracer> parts;            ///< hybrid: its screen and geometric tracers
  double buildMs = 0.0;                      ///< hierarchy / BVH construction
  size_t memoryBytes = 0;                    ///< the structure's bytes
  /// hssr, hiz on the GPU: the intervals per pyramid level ([0]: level 0's) as the device counted
  /// them (the pyramid itself stays there; `pyramid` is null).
  std::vector<uint64_t> levelIntervals;
};

/// Builds the registry's tracer `name` for `frame`; InputError for an unknown name.
BuiltTracer buildTracer(const std::string& name, const Frame& frame, const TracerOptions& options);

/// How the hybrid's halves are made: on the CPU by buildTracer, on the GPU by the GPU tracers
/// (gpu_tracers.h). Its decisions (known_space.h) are the same either way.
struct HybridBuilders {
  /// HSSR or Hi-Z over the hybrid's solid intervals (known_space.h solidIntervals).
  std::function<BuiltTracer(IntervalLayers solid, const PyramidConfig& pyramid, const HssrConfig& march)> pyramidScreen;
  /// Another screen half (quadtree, ldc) or the geometric half, by its registry name.
  std::function<BuiltTracer(const std::string& name)> part;
  /// The geometric half's name in place of --hybrid-geo (empty: the option's).
  std::string geo;
};
/// The hybrid of `options.hybrid` with halves made by `build`.
BuiltTracer buildHybrid(const Frame& frame, const TracerOptions& options, const HybridBuilders& build);

/// The geometric ground truth of classification: Embree in robust (watertight) mode. The
/// "embree" tracer of buildTracer is the fast baseline (default scene flags) that speed claims
/// are measured against.
BuiltTracer buildReference(const Frame& frame);

/// The exhaustive image-space oracle (hssr traversal with one level).
BuiltTracer buildOracle(const Frame& frame);

}  // namespace lt
