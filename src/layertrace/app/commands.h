// The subcommands of the CLI (docs/cli.md), as library functions: main() only parses options.
//
// Layer: app/ is the CLI only — the subcommands, option handling, reports. It may include every
// layer; nothing under src/layertrace/ outside app/ includes it.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "layertrace/pipeline/frame.h"
#include "layertrace/util/image.h"

namespace lt {

/// Options every subcommand has beside the frame's.
/// Throws InputError unless 1 ≤ repeat ≤ 100 (--repeat of render, compare and bench).
void validateRepeat(int repeat);

struct RunOptions {
  FrameOptions frame;
  std::string output;      ///< -o: the image (render), the screenshot (view) or the output folder (every other command)
  std::string statsPath;   ///< --stats FILE.json (default: beside the main output, app/cli.cpp resolveOutputs)
  std::string pixelStats;  ///< render --pixelstats [DIR]
  int threads = 0;         ///< --threads; 0 = all cores
  uint64_t seed = 1;       ///< --seed
  bool quiet = false;      ///< --quiet
  std::string device = "cpu";  ///< --device cpu|gpu (render, compare): where the tracers run
};

struct LayersOptions {
  RunOptions run;
  bool verify = false;  ///< --verify against Embree all-hit primary rays (and, on the GPU, the CPU's capture)
  std::string capture = "lists";  ///< --capture lists|peel (--device gpu)
};

/// `layertrace layers`: per-layer albedo/normal/depth images, depth-complexity map, stats.
int runLayers(const LayersOptions& options);

/// Writes `json` to `path` atomically (pretty-printed), if `path` is not empty.
void writeStats(const std::string& path, const std::string& json);

/// The depth-complexity map of a width × height buffer of fragment counts (row-major): a heat
/// image (black = none, blue = 1, red = the maximum) and the raw counts (one channel, for EXR).
struct ComplexityImages {
  Image heat, counts;
  uint32_t max = 1;
};
ComplexityImages depthComplexityImages(int width, int height, const std::vector<uint32_t>& counts);

/// The albedo of every pixel's `layer`-th stored fragment (black where it has fewer).
Image layerAlbedo(const LayerArrays& layers, int layer);
/// Creates `dir` (and parents); InputError naming the option if impossible.
void ensureDirectory(const std::string& dir, const std::string& option);

/// "AMD EPYC 9R14, 2 threads": the CPU model and thread count every measured table carries.
std::string machine();
/// The current UTC time, ISO 8601 ("2026-12-06T05:20:00Z").
std::string today();
/// Runs `python3 tools/SCRIPT DATA.json SCRATCH/OUT` in a scratch folder and, if it wrote OUT,
/// hands the folder to `collect` (which stages what it wants) before removing it. A missing
/// Python or matplotlib is not an error: false, nothing collected.
bool runPlotScript(const std::string& script, const nlohmann::json& data, const std::string& out,
                   const std::function<void(const std::filesystem::path& scratch)>& collect);
/// A file's bytes ("" if it cannot be read).
std::string fileBytes(const std::filesystem::path& path);

}  // namespace lt

#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/render/effects.h"

namespace lt {

struct RenderOptions {
  RunOptions run;
  std::string tracer = "hssr";  ///< one of tracerNames()
  EffectConfig effect;
  TracerOptions tracers;
  bool checkExhaustive = false;  ///< trace every ray with the exhaustive oracle too
  bool checkOracle = false;      ///< trace every ray with the independent image-space oracle too
  int repeat = 3;                ///< --repeat: timed passes after the counted one; the trace time is their median
  /// The picture is for a PNG: a resident GPU frame reads it back as 8-bit sRGB codes
  /// (RenderOutput::png8) instead of floats. Set by runRender.
  bool png8 = false;
};

/// What `render` computes, before it writes anything.
struct RenderOutput {
  EffectResult result;         ///< the image (unless png8 holds it) and the per-pixel counters
  std::vector<uint8_t> png8;   ///< RenderOptions::png8 on a resident GPU frame: the PNG's RGB bytes, row 0 first
  std::optional<Image> direct;  ///< view synthesis: the second camera's own rendering
  nlohmann::json stats;        ///< the statistics file's contents
  std::string summary;         ///< the console line
};
/// The work of `render` without its files: the checks, the frame, the tracer, the effect and
/// the statistics.
RenderOutput renderFrame(const RenderOptions& options);
/// `layertrace render`: one effect traced with one tracer → image, stats, per-pixel counters.
int runRender(const RenderOptions& options);

/// `layertrace view`: the render options plus the scripted mode of tests and figures.
struct ViewOptions {
  RenderOptions render;
  int frames = 0;            ///< --frames N: render N full frames without input, then exit (0 = interactive)
  std::string screenshot;    ///< --screenshot PNG: the traced image of the last frame (no UI)
  std::string screenshotUi;  ///< --screenshot-ui PNG: the whole window of the last frame
  std::string overlay = "image";  ///< --overlay: image | classes | iterations | layer | complexity
  bool hidePanel = false;    ///< --hide-panel: the window shows the picture alone (H toggles the panel)
};

struct CompareOptions {
  RunOptions run;
  std::vector<std::string> tracers = {"ssr", "ssr-layers", "hssr"};  ///< --tracers, comma list
  EffectConfig effect;
  TracerOptions options;
  std::string report;  ///< --report DIR: one HTML page with images and the table
  bool checkExhaustive = true;  ///< --check-exhaustive (default on): every image-space ray against the exhaustive oracle
  bool checkOracle = false;  ///< --check-oracle: every image-space ray against the independent oracle too
  int repeat = 3;            ///< --repeat: timed passes per tracer after its counted one; the median is reported
};

struct BenchOptions {
  RunOptions run;
  std::string experiment;  ///< stride | layers | tau | memory | resolution | threads
  int repeat = 3;          ///< runs per measurement; the median is reported
  EffectConfig effect;     ///< one-bounce reflections from every pixel, as in Hofmann et al. 2017, §6
  TracerOptions options;
  std::string report;      ///< --report DIR
  std::string tracer = "hssr";  ///< --tracer: the frame experiment's tracer
  int frames = 30;              ///< --frames: the frame experiment's frames
  bool images = false;          ///< --images: the frame experiment writes each frame's picture
};

/// `layertrace bench`: the HSSR paper's experiments (Hofmann et al. 2017, §6) on your scene → CSV, JSON, PNG plot.
int runBench(const BenchOptions& options);

/// `layertrace reproduce`: the papers' hardware-independent results under both presets.
struct ReproduceOptions {
  RunOptions run;
  std::vector<std::string> scenes;  ///< SCENE or SCENE:CAMERA; empty: kReproduceScenes (--quick: the default scene)
  bool quick = false;               ///< --quick: the default scene at a small size; exit 1 if a claim fails
  int repeat = 3;                   ///< timed runs per time (median)
  std::string commandLine;          ///< as typed, for the page's header
};
/// The scenes of the full run: the default scene and the fetched real scenes (scripts/fetch-scenes.sh),
/// relative to the source tree.
inline const std::vector<std::string> kReproduceScenes = {"scenes/default.json", "scenes/fzk-haus.json:interior",
                                                          "scenes/am-thornish.json:hall", "scenes/engine.json:interior"};
/// Writes OUT/reproduction.md, OUT/reproduction/*.png and reproduction.json; 0, or 1 when --quick
/// and a paper's claim does not hold.
int runReproduce(const ReproduceOptions& options);

struct GeobenchOptions {
  RunOptions run;
  TracerOptions tracers;  ///< only the grid's parameters are read
  int repeat = 3;      ///< runs per timing; the median is reported
  bool sweep = false;  ///< also sweep λ1 × λ2 (build time vs traversal time)
};

/// `layertrace geobench`: the geometric tracers (grid vs Embree) on the same rays.
int runGeobench(const GeobenchOptions& options);

/// The `rays.*` stats of one traced effect (render and compare).
nlohmann::json rayStats(const EffectResult& r, bool screenTracer);
/// The per-pixel iteration heat map of --pixelstats (log scale, blue → red).
Image iterationHeat(const EffectResult& r);
/// Writes iterations.exr/.png and intervals.exr to `dir` (--pixelstats).
void writePixelStats(const std::string& dir, const EffectResult& r);
/// The `quadtree` stats block: thresholds, nodes per level and kind, visits per kind.
nlohmann::json quadtreeStats(const Quadtree& tree, const QuadtreeConfig& config, const EffectResult& r);

/// The `ldc` stats block: build time, memory and samples per axis, lost triangles; with a traced
/// effect also blocks, texels and samples visited per ray.
nlohmann::json ldcStats(const LayeredDepthCube& ldc, const EffectResult* r);

struct LdcOptions {
  RunOptions run;
  TracerOptions tracers;  ///< only the layered depth cube's parameters are read
};

/// `layertrace ldc`: builds the layered depth cube (Bürger et al. 2007) of a scene and writes per axis its
/// depth-complexity map and first-layer albedo, and the `ldc` stats.
int runLdc(const LdcOptions& options);

/// The `hybrid` stats block (screen_fraction, geo_fraction, geo_length_mean) of the
/// tracer's runs since its last reset; null for any other tracer.
nlohmann::json hybridStats(const BuiltTracer& built, const TracerOptions& options);

/// The truth of view synthesis (Effect::Warp): the second camera's own rasterization of the
/// scene, shaded with `frame`'s lights, and per pixel whether it sees a surface.
struct WarpReference {
  Image image;
  std::vector<uint8_t> covered;  ///< the second camera sees a surface here
  /// ... and that surface lies outside the first camera's view (off its screen, or in front of
  /// its near plane): no layer can hold it, whatever k. Holes elsewhere are disocclusions.
  std::vector<uint8_t> outsideFirst;
};

/// Holes of a warp against its reference: all holes on covered pixels, and those split into
/// outside-the-first-view and disoccluded.
struct WarpHoles {
  uint64_t covered = 0, holes = 0, outside = 0, disoccluded = 0, coveredInside = 0;
};
WarpHoles countWarpHoles(const WarpReference& ref, const std::vector<uint8_t>& holes);
WarpReference warpReference(const Frame& frame, const FrameOptions& options, const EffectConfig& warp);

/// What `compare` computes, before it writes anything.
struct CompareOutput {
  nlohmann::json stats;  ///< compare.json
  std::vector<std::pair<std::string, Image>> images;  ///< file name → image
  std::string title, table, summary;  ///< the report's title, the console table and the lines above it
};
/// The work of `compare` without its files.
CompareOutput compareFrame(const CompareOptions& options);
/// `layertrace compare`: the same rays through several tracers and Embree → accuracy and cost.
int runCompare(const CompareOptions& options);

}  // namespace lt
