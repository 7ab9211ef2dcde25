// layertrace — the command-line interface (app/cli.h; docs/cli.md lists every flag).
// Exit status: 0 success, 2 bad input (one line naming the input and value), 1 internal error.
#include "layertrace/app/cli.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <tuple>

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include "layertrace/app/commands.h"
#include "layertrace/app/view_session.h"
#include "layertrace/app/version.h"
#include "layertrace/util/error.h"
#include "layertrace/util/image.h"

namespace {

using lt::inputError;

/// Numbers in double (a position far from the origin keeps its precision until the scene's
/// origin is subtracted: Scene::fromWorld), each within float range.
std::vector<double> parseNumbers(const std::string& option, const std::string& text, size_t minCount, size_t maxCount) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      size_t used = 0;
      const double f = std::stod(item, &used);
      if (used != item.size() || !std::isfinite(f)) throw std::invalid_argument(item);
      if (std::abs(f) > double(std::numeric_limits<float>::max())) throw std::out_of_range(item);
      v.push_back(f);
    } catch (const std::out_of_range&) {
      inputError(option, " ", text, ": \"", item, "\" is out of range");
    } catch (const std::exception&) {
      inputError(option, " ", text, ": \"", item, "\" is not a number");
    }
  }
  if (v.size() < minCount || v.size() > maxCount)
    inputError(option, " ", text, ": expected ", minCount == maxCount ? std::to_string(minCount) : lt::cat(minCount, " or ", maxCount),
               " comma-separated numbers");
  return v;
}

glm::dvec3 parseVec3(const std::string& option, const std::string& text) {
  const auto v = parseNumbers(option, text, 3, 3);
  return {v[0], v[1], v[2]};
}

float parseFloat(const std::string& option, const std::string& text) { return float(parseNumbers(option, text, 1, 1)[0]); }

/// Raw strings of the vector options, converted after parsing so errors name the option.
struct RawFrameOptions {
  std::string eye, target, up;
  std::vector<std::string> lights;
  std::string fov, thickness, thicknessPx;  ///< parsed when given: 0 is a value, not "unset"
  std::string warpEye, warpTarget;  ///< --warp-eye / --warp-target (effect options)
  std::string belowSurface = "mirror";  ///< --below-surface mirror|bend
  std::string maxMemory;            ///< --max-memory
  std::string textures = "on";      ///< --textures on|off
};

void addFrameOptions(CLI::App* app, lt::RunOptions& run, RawFrameOptions& raw, const char* outputHelp) {
  lt::FrameOptions& f = run.frame;
  app->add_option("-o,--output", run.output, outputHelp);
  app->add_option("SCENE", f.scenePath, "JSON scene file or any model file assimp reads")->required();
  app->add_option("--camera", f.cameraName, "named camera of the scene (default: its first, else auto-framed)");
  app->add_option("--eye", raw.eye, "camera position x,y,z (overrides --camera)");
  app->add_option("--target", raw.target, "camera target x,y,z");
  app->add_option("--up", raw.up, "camera up vector x,y,z");
  app->add_option("--fov", raw.fov, "vertical field of view in degrees (default: the camera's)")->type_name("FLOAT");
  app->add_option("--width", f.width, "image width in pixels")->capture_default_str();
  app->add_option("--height", f.height, "image height in pixels")->capture_default_str();
  app->add_option("--layers", f.layers, "layers k kept per pixel, 1..16")->capture_default_str();
  app->add_option("--thickness", raw.thickness, "fixed fragment z-thickness in scene units (default: --thickness-px)")->type_name("FLOAT");
  app->add_option("--thickness-px", raw.thicknessPx,
                  lt::cat("fragment z-thickness in pixel footprints at the fragment's depth (default ", lt::kDefaultThicknessPx, ")"));
  app->add_option("--min-separation", f.minSeparation, "minimum depth separation of kept layers (0 = off)")->capture_default_str();
  app->add_flag("--adaptive-thickness", f.adaptiveThickness, "merge fragments that start inside the previous kept interval (Hofmann et al. 2017, §4.2)");
  app->add_flag("--front-faces-only", f.frontFacesOnly, "capture only triangles facing the camera (layers = nearest front surfaces)");
  app->add_option("--textures", raw.textures, "map textures and alpha cut-outs per fragment and hit (on), or give each material its textures' mean colour (off)")
      ->capture_default_str()
      ->check(CLI::IsMember({"on", "off"}));
  app->add_flag("--lightmaps", f.lightmaps, "multiply the albedo by the level's lightmaps (Quake 3 maps)");
  app->add_option("--pool", f.pool, "fragment pool capacity (0 = automatic, grows on overflow)")->capture_default_str()->check(CLI::NonNegativeNumber);
  app->add_option("--max-memory", raw.maxMemory, "refuse, before allocating, any structure that would take the process past this size, e.g. 4G (default: the memory available)");
  app->add_option("--light", raw.lights, "add a point light x,y,z[,intensity] (repeatable; default light: above the eye)");
  app->add_option("--threads", run.threads, "worker threads (0 = all cores)")->capture_default_str();
  app->add_option("--seed", run.seed, "random seed")->capture_default_str()->check(CLI::NonNegativeNumber);
  app->add_option("--stats", run.statsPath, "write the statistics JSON here instead of beside the main output");
  app->add_option("--pixelstats", run.pixelStats,
                  "write per-pixel counter images to this folder (default: beside the main output; render, compare, layers)")
      ->expected(0, 1);
  app->add_flag("--quiet", run.quiet, "no progress or summary output");
}

/// An on/off switch: `flag` turns it on, `--no-` and the rest of its name off. The help names
/// the default and the off spelling, which is not listed apart (CLI11 would show a negated
/// name's value, "{false}", beside it). `hidden`: an older spelling, not in the help.
void addSwitch(CLI::App* app, const std::string& flag, bool& field, const std::string& help, bool hidden = false) {
  const std::string off = "--no-" + flag.substr(2);
  CLI::Option* on = app->add_flag(flag, field, help + (field ? lt::cat(" (default on; ", off, " turns it off)") : " (default off)"));
  app->add_flag_callback(off, [&field] { field = false; })->group("");
  if (hidden) on->group("");
}

/// A registry parameter's flag, bound to its field in `options`; its older spelling, if any, is a
/// hidden alias bound to the same field.
void addParam(CLI::App* app, const lt::TracerParam& p, lt::TracerOptions& options) {
  const std::string help = lt::cat(p.group, ": ", p.help);
  std::visit(
      [&](auto* field) {
        if constexpr (std::is_same_v<decltype(field), bool*>) {
          addSwitch(app, p.flag, *field, help);
          if (*p.alias) addSwitch(app, p.alias, *field, help, true);
        } else {
          app->add_option(p.flag, *field, help)->capture_default_str();
          if (*p.alias) app->add_option(p.alias, *field)->group("");
        }
      },
      p.field(options));
}

/// The registry's parameters of `groups` (every group when empty), bound to `t`, and --preset.
void addTracerOptions(CLI::App* app, lt::TracerOptions& t, std::initializer_list<std::string_view> groups = {}) {
  app->add_option("--preset", t.preset,
                  "parameter preset: tuned (the defaults) or paper (every method with its paper's parameters and rules; "
                  "flags given beside it still apply)")
      ->capture_default_str();
  for (const lt::TracerParam& p : lt::tracerParams())
    if (groups.size() == 0 || std::find(groups.begin(), groups.end(), p.group) != groups.end()) addParam(app, p, t);
}

/// Applies the --preset of `cmd` to `t`: every parameter the preset sets, except those given on
/// the command line (under their name or their older spelling).
void finishPreset(const CLI::App* cmd, lt::TracerOptions& t) {
  lt::applyPreset(t.preset, t, [cmd](const lt::TracerParam& p) {
    for (const char* flag : {p.flag, p.alias})
      if (*flag)
        for (const std::string& name : {std::string(flag), "--no-" + std::string(flag + 2)})  // a switch's off spelling too
          if (const CLI::Option* o = cmd->get_option_no_throw(name); o && o->count() > 0) return true;
    return false;
  });
}

void addEffectOptions(CLI::App* app, lt::EffectConfig& e, std::string& effectName, RawFrameOptions& raw) {
  app->add_option("--effect", effectName, "shade | reflection | refraction | ao | shadow | warp")->capture_default_str();
  app->add_option("--warp-eye", raw.warpEye, "warp: the second camera's eye x,y,z (world space)");
  app->add_option("--warp-target", raw.warpTarget, "warp: the second camera's target x,y,z (default: the first camera's)");
  app->add_option("--bounces", e.bounces, "reflection bounces")->capture_default_str();
  app->add_option("--ao-samples", e.aoSamples, "AO rays per pixel")->capture_default_str();
  app->add_option("--ao-radius", e.aoRadius, "AO ray length (0 = 5% of the scene diagonal)")->capture_default_str();
  app->add_option("--max-distance", e.maxDistance, "ray length (0 = the scene diagonal)")->capture_default_str();
  app->add_option("--below-surface", raw.belowSurface, "a secondary ray below the geometric surface it leaves (smooth normals on a flat face): mirror (about the geometric plane) | bend (to graze it)")->capture_default_str();
}

std::vector<std::string> splitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

void finishEffectOptions(lt::EffectConfig& e, const std::string& effectName, const RawFrameOptions& raw) {
  e.effect = lt::parseEffect(effectName);
  if (!raw.warpEye.empty()) e.warpEye = parseVec3("--warp-eye", raw.warpEye);
  if (!raw.warpTarget.empty()) e.warpTarget = parseVec3("--warp-target", raw.warpTarget);
  if (raw.belowSurface != "mirror" && raw.belowSurface != "bend") lt::inputError("--below-surface ", raw.belowSurface, ": unknown (use mirror or bend)");
  e.mirrorBelowSurface = raw.belowSurface == "mirror";
}

void finishFrameOptions(lt::RunOptions& run, const RawFrameOptions& raw) {
  lt::setMemoryLimit(raw.maxMemory.empty() ? 0 : lt::parseByteSize("--max-memory", raw.maxMemory));
  lt::FrameOptions& f = run.frame;
  if (!raw.eye.empty()) f.eye = parseVec3("--eye", raw.eye);
  if (!raw.target.empty()) f.target = parseVec3("--target", raw.target);
  if (!raw.up.empty()) f.up = glm::vec3(parseVec3("--up", raw.up));
  if (!raw.fov.empty()) f.fov = parseFloat("--fov", raw.fov);
  if (!raw.thickness.empty()) f.thickness = parseFloat("--thickness", raw.thickness);
  if (!raw.thicknessPx.empty()) f.thicknessPx = parseFloat("--thickness-px", raw.thicknessPx);
  f.textures = raw.textures == "on";
  for (const std::string& l : raw.lights) {
    const auto v = parseNumbers("--light", l, 3, 4);
    f.lights.push_back({v[0], v[1], v[2], v.size() == 4 ? v[3] : 1.0});
  }
  if (run.threads < 0) inputError("--threads ", run.threads, ": must be >= 0");
}

/// --device: where the tracers run.
void addDeviceOption(CLI::App* cmd, lt::RunOptions& run) {
  cmd->add_option("--device", run.device,
                  "where the tracers run: cpu, or gpu (OpenGL 4.5 compute shaders through headless EGL; every tracer but embree and embree-robust)")
      ->capture_default_str()
      ->check(CLI::IsMember({"cpu", "gpu"}));
}

/// Options every subcommand accepts (one shared command line) that some commands have no use
/// for: naming one there prints a warning instead of passing in silence.
void warnUnused(const CLI::App& cmd) {
  static const std::map<std::string, std::vector<std::string>> unused = {
      {"layers", {"--light", "--seed"}},
      {"geobench", {"--layers", "--thickness", "--thickness-px", "--min-separation", "--adaptive-thickness", "--front-faces-only",
                    "--pool", "--light", "--pixelstats"}},
      {"ldc", {"--camera", "--eye", "--target", "--up", "--fov", "--width", "--height", "--layers", "--thickness", "--thickness-px",
               "--min-separation", "--adaptive-thickness", "--front-faces-only", "--pool", "--light", "--seed", "--pixelstats"}},
      {"bench", {"--pixelstats"}},
      {"view", {"--stats", "--pixelstats"}},
  };
  const auto it = unused.find(cmd.get_name());
  if (it == unused.end()) return;
  for (const std::string& option : it->second)
    if (const CLI::Option* o = cmd.get_option_no_throw(option); o && o->count() > 0)
      std::cerr << "layertrace: warning: " << cmd.get_name() << " does not use " << option << "; it is ignored\n";
}

/// The one output convention: -o is the main output (render: an image, default out/render.png;
/// every other command: a folder, default out/<command>); the statistics go beside it, to
/// <image stem>.json or <folder>/<command>.json, unless --stats names a file; --pixelstats and
/// --report without a folder write to <image stem>_pixelstats/ and into the output folder.
void resolveOutputs(lt::RunOptions& run, const std::string& command, bool pixelStatsAsked, std::string* report, bool reportAsked) {
  namespace fs = std::filesystem;
  const bool image = command == "render";
  if (run.output.empty()) run.output = image ? "out/render.png" : "out/" + command;
  const fs::path out(run.output);
  const std::string prefix = image ? (out.parent_path() / out.stem()).string() : (out / command).string();
  if (run.statsPath.empty()) run.statsPath = prefix + ".json";
  if (pixelStatsAsked && run.pixelStats.empty()) run.pixelStats = image ? prefix + "_pixelstats" : (out / "pixelstats").string();
  if (report && reportAsked && report->empty()) *report = run.output;
}

}  // namespace

namespace lt {

namespace {
ViewRunner viewRunner = nullptr;
}  // namespace

void setViewRunner(ViewRunner runner) { viewRunner = runner; }

namespace {

/// runCli's work; with `parsed`, render and compare stop after their checks and hand their
/// options over, and bad input is thrown rather than printed.
int runCliImpl(int argc, const char* const* argv, CliMode mode, CliCommand* parsed) {
  CLI::App app{"layertrace: image-space ray tracing of secondary effects through multi-layer fragment buffers"};
  app.require_subcommand(0, 1);
  app.set_help_all_flag("--help-all", "help for every subcommand");
  bool showVersion = false;
  app.add_flag("--version", showVersion, "print the version, the commit and the enabled features, then exit");
  CLI::App* tracersCmd = app.add_subcommand("tracers", "list every tracer and effect with its parameters and defaults");

  lt::LayersOptions layers;
  RawFrameOptions layersRaw;
  CLI::App* layersCmd = app.add_subcommand("layers", "capture fragments, write layer images + depth-complexity map");
  addFrameOptions(layersCmd, layers.run, layersRaw, "output folder (default out/layers; statistics in layers.json)");
  addDeviceOption(layersCmd, layers.run);
  layersCmd->add_option("--capture", layers.capture, "lists (every fragment in per-pixel lists, sorted to k) or peel (depth peeling: k geometry passes, no fragment stored)")
      ->capture_default_str()
      ->check(CLI::IsMember({"lists", "peel"}));
  layersCmd->add_flag("--verify", layers.verify, "compare every pixel's fragment list with Embree all-hit primary rays");

  lt::RenderOptions render;
  RawFrameOptions renderRaw;
  std::string effectName = "reflection";
  CLI::App* renderCmd = app.add_subcommand("render", "image of one effect traced with one tracer");
  addFrameOptions(renderCmd, render.run, renderRaw, "output image, .png or .exr (default out/render.png; statistics beside it in render.json)");
  addDeviceOption(renderCmd, render.run);
  renderCmd->add_option("--tracer", render.tracer, "ssr | ssr-layers | hiz | hssr | quadtree | ldc | hybrid | embree | embree-robust | grid")->capture_default_str();
  addEffectOptions(renderCmd, render.effect, effectName, renderRaw);
  addTracerOptions(renderCmd, render.tracers);
  renderCmd->add_option("--repeat", render.repeat, "timed passes of the trace without counters, after the counted pass (the warm-up); the trace time is their median")->capture_default_str();
  renderCmd->add_flag("--check-exhaustive", render.checkExhaustive, "trace every ray with the exhaustive oracle too; count differences");
  renderCmd->add_flag("--check-oracle", render.checkOracle,
                      "trace every ray with the independent image-space oracle too; count differences (rays.oracle_mismatch)");

  lt::CompareOptions compare;
  RawFrameOptions compareRaw;
  std::string compareEffect = "reflection", compareTracers = "ssr,ssr-layers,hssr";
  CLI::App* compareCmd = app.add_subcommand("compare", "same rays through several tracers + Embree: accuracy and cost table");
  addFrameOptions(compareCmd, compare.run, compareRaw, "output folder (default out/compare; statistics in compare.json)");
  addDeviceOption(compareCmd, compare.run);
  compareCmd->add_option("--tracers", compareTracers, "comma list of ssr, ssr-layers, hiz, hssr, quadtree, ldc, hybrid, embree, embree-robust, grid")->capture_default_str();
  addEffectOptions(compareCmd, compare.effect, compareEffect, compareRaw);
  addTracerOptions(compareCmd, compare.options);
  compareCmd->add_option("--report", compare.report, "also write an HTML report (one self-contained page) to this folder (default: the output folder)")
      ->expected(0, 1);
  compareCmd->add_option("--repeat", compare.repeat, "timed passes of the trace without counters, after the counted pass (the warm-up); the trace time is their median")->capture_default_str();
  addSwitch(compareCmd, "--check-exhaustive", compare.checkExhaustive,
            "check every image-space ray against the exhaustive oracle (exhaustive_mismatch)");
  compareCmd->add_flag("--check-oracle", compare.checkOracle,
                       "also check every image-space ray against the independent oracle (slow; oracle_mismatch)");

  lt::BenchOptions bench;
  RawFrameOptions benchRaw;
  std::string benchEffect = "reflection";
  CLI::App* benchCmd = app.add_subcommand("bench", "the papers' experiments: stride|layers|tau|memory|resolution|threads|capture|warp|gamma|ldc|stages|peel|simd|textures|frame");
  addFrameOptions(benchCmd, bench.run, benchRaw, "output folder (default out/bench; EXPERIMENT.json, .csv and .png)");
  addDeviceOption(benchCmd, bench.run);
  benchCmd->add_option("--experiment", bench.experiment, "stride | layers | tau | memory | resolution | threads | capture | warp | gamma | ldc | stages (every stage on --device cpu or gpu) | peel (per-pixel lists against depth peeling, k = 1..8, on --device cpu or gpu) | simd (capture, pyramid, HSSR and grid on every vector target of this CPU) | textures (capture and reference with the textures against --textures off) | frame (--frames frames of one effect along an orbit of the camera, each counted: wall and GPU ms, bytes each way, host waits, links, allocations, dispatches)")->required();
  addEffectOptions(benchCmd, bench.effect, benchEffect, benchRaw);
  benchCmd->add_option("--tracer", bench.tracer, "frame: the tracer (on --device gpu: hssr, hiz, exhaustive, ssr or ssr-layers)")->capture_default_str();
  benchCmd->add_option("--frames", bench.frames, "frame: frames along the orbit (the summary is the median of those after the first)")->capture_default_str();
  benchCmd->add_flag("--images", bench.images, "frame: also read back and write each frame's picture (frame_NNNN.png)");
  benchCmd->add_option("--repeat", bench.repeat, "timed runs of each measured time; the median is reported")->capture_default_str();
  addTracerOptions(benchCmd, bench.options);
  benchCmd->add_option("--report", bench.report, "also write an HTML report to this folder (default: the output folder)")->expected(0, 1);

  lt::ReproduceOptions reproduce;
  int reproduceWidth = 0, reproduceHeight = 0;
  CLI::App* reproduceCmd = app.add_subcommand(
      "reproduce", "the five papers' hardware-independent results under --preset paper and tuned, on the real scenes: one Markdown page");
  reproduceCmd->add_option("SCENES", reproduce.scenes,
                           "scene files, each optionally SCENE:CAMERA (default: the default scene and the fetched real scenes; "
                           "with --quick the default scene)");
  reproduceCmd->add_option("-o,--output", reproduce.run.output, "output folder: reproduction.md and reproduction/ (plots, JSON); default out/reproduce");
  reproduceCmd->add_flag("--quick", reproduce.quick, "the default scene at 640x360, one timed run (under a minute); exit 1 if a claim's outcome differs from the documented one");
  reproduceCmd->add_option("--width", reproduceWidth, "image width (default 1280, --quick 640)");
  reproduceCmd->add_option("--height", reproduceHeight, "image height (default 720, --quick 360)");
  reproduceCmd->add_option("--repeat", reproduce.repeat, "timed runs of each measured time; the median is reported")->capture_default_str();
  reproduceCmd->add_option("--threads", reproduce.run.threads, "worker threads (0 = all cores)")->capture_default_str();
  reproduceCmd->add_option("--seed", reproduce.run.seed, "random seed")->capture_default_str()->check(CLI::NonNegativeNumber);
  reproduceCmd->add_flag("--quiet", reproduce.run.quiet, "no progress or summary output");
  reproduceCmd->add_option("--device", reproduce.run.device,
                           "cpu, or gpu: also time the construction against k (lists and depth peeling) on the GPU")
      ->capture_default_str()
      ->check(CLI::IsMember({"cpu", "gpu"}));

  lt::GeobenchOptions geobench;
  RawFrameOptions geobenchRaw;
  CLI::App* geobenchCmd = app.add_subcommand("geobench", "geometric tracers (grid vs embree): build, memory, MRays/s, agreement");
  addFrameOptions(geobenchCmd, geobench.run, geobenchRaw, "output folder (default out/geobench; statistics in geobench.json)");
  addTracerOptions(geobenchCmd, geobench.tracers, {"grid"});
  addDeviceOption(geobenchCmd, geobench.run);
  geobenchCmd->add_option("--repeat", geobench.repeat, "timed runs of each measured time; the median is reported")->capture_default_str();
  geobenchCmd->add_flag("--sweep", geobench.sweep, "also sweep lambda1 x lambda2: build time vs traversal time");

  lt::LdcOptions ldc;
  RawFrameOptions ldcRaw;
  CLI::App* ldcCmd = app.add_subcommand("ldc", "build the layered depth cube (Bürger et al. 2007): per-axis depth complexity and albedo images");
  addFrameOptions(ldcCmd, ldc.run, ldcRaw, "output folder (default out/ldc; statistics in ldc.json)");
  addTracerOptions(ldcCmd, ldc.tracers, {"ldc"});

  lt::ViewOptions view;
  RawFrameOptions viewRaw;
  std::string viewEffect = "reflection";
  CLI::App* viewCmd = app.add_subcommand("view", "interactive viewer: fly through the scene, switch tracers and overlays live");
  addFrameOptions(viewCmd, view.render.run, viewRaw, "scripted mode: write the last traced image (without the UI) to this PNG");
  viewCmd->add_option("--tracer", view.render.tracer, "ssr | ssr-layers | hiz | hssr | quadtree | ldc | hybrid | embree | embree-robust | grid")->capture_default_str();
  addDeviceOption(viewCmd, view.render.run);
  addEffectOptions(viewCmd, view.render.effect, viewEffect, viewRaw);
  addTracerOptions(viewCmd, view.render.tracers);
  viewCmd->add_option("--frames", view.frames, "render this many full frames without input, then exit (scripted mode)")->capture_default_str();
  viewCmd->add_option("--screenshot", view.render.run.output)->group("");  // the older spelling of -o
  viewCmd->add_option("--screenshot-ui", view.screenshotUi, "scripted mode: write the whole window of the last frame to this PNG");
  viewCmd->add_flag("--hide-panel", view.hidePanel, "start with the panel hidden: the window shows the picture alone (H shows it)");
  viewCmd->add_option("--overlay", view.overlay, "image | classes (strict classes vs Embree) | iterations | layer | complexity")->capture_default_str();

  std::string names;
  bool known = false;
  for (const CLI::App* sub : app.get_subcommands({})) {
    names += (names.empty() ? "" : ", ") + sub->get_name();
    known = known || (argc > 1 && sub->get_name() == argv[1]);
  }
  if (argc > 1 && argv[1][0] != '-' && !known) {
    const std::string msg = lt::cat("unknown subcommand \"", argv[1], "\" (use one of: ", names, ")");
    if (parsed) throw lt::InputError(msg);
    std::cerr << "layertrace: " << msg << "\n";
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    if (parsed) throw lt::InputError("--help: not a command to run");
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    if (parsed) throw lt::InputError("--help-all: not a command to run");
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::string msg = e.what();
    std::replace(msg.begin(), msg.end(), '\n', ' ');
    if (parsed) throw lt::InputError(msg);
    std::cerr << "layertrace: " << msg << "\n";
    return 2;
  }
  if (parsed && !renderCmd->parsed() && !compareCmd->parsed()) throw lt::InputError("only render and compare can be parsed to options");

  if (showVersion) {
    std::cout << versionText(viewRunner != nullptr);
    return 0;
  }
  if (tracersCmd->parsed()) {
    std::cout << tracersText();
    return 0;
  }
  if (app.get_subcommands().empty() && argc <= 1) {
    std::cout << app.help();  // no arguments at all: what the tool does and how to ask it
    return 0;
  }
  if (app.get_subcommands().empty()) {
    std::cerr << "layertrace: a subcommand is required (use one of: " << names << "; --help for more)\n";
    return 2;
  }
  try {
    for (auto [cmd, options] : {std::pair{renderCmd, &render.tracers}, std::pair{compareCmd, &compare.options},
                                std::pair{benchCmd, &bench.options}, std::pair{geobenchCmd, &geobench.tracers},
                                std::pair{ldcCmd, &ldc.tracers}, std::pair{viewCmd, &view.render.tracers}})
      if (cmd->parsed()) finishPreset(cmd, *options);
    std::unique_ptr<tbb::global_control> threads;
    // Converts the raw vector options and applies --threads for the subcommand that ran.
    auto prepare = [&](lt::RunOptions& run, const RawFrameOptions& raw) {
      finishFrameOptions(run, raw);
      const CLI::App* cmd = app.get_subcommands().front();
      const std::string name = cmd->get_name();
      // A refused value is the one line a bad command prints: check the frame options before
      // warning about the ones this command ignores.
      lt::validateFrameOptions(run.frame);
      if (mode == CliMode::Run) warnUnused(*cmd);
      std::string* report = name == "compare" ? &compare.report : name == "bench" ? &bench.report : nullptr;
      if (name == "view") {
        view.screenshot = run.output;  // -o is the screenshot of scripted mode; nothing else is written
      } else {
        // bench's statistics are its experiment's table: <folder>/<experiment>.json beside the .csv.
        if (name == "bench" && run.statsPath.empty())
          run.statsPath = (std::filesystem::path(run.output.empty() ? "out/bench" : run.output) / bench.experiment).string() + ".json";
        const auto asked = [cmd](const char* option) {
          const CLI::Option* o = cmd->get_option_no_throw(option);
          return o && o->count() > 0;
        };
        resolveOutputs(run, name, asked("--pixelstats"), report, asked("--report"));
      }
      if (run.threads > 0 && mode == CliMode::Run)
        threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(run.threads));
    };
    if (mode == CliMode::ParseOnly) {
      // Everything that needs no scene: the conversions above and the option checks each
      // command makes before loading anything.
      for (auto [cmd, run, raw] : {std::tuple{layersCmd, &layers.run, &layersRaw}, std::tuple{geobenchCmd, &geobench.run, &geobenchRaw},
                                   std::tuple{benchCmd, &bench.run, &benchRaw}, std::tuple{compareCmd, &compare.run, &compareRaw},
                                   std::tuple{renderCmd, &render.run, &renderRaw}, std::tuple{ldcCmd, &ldc.run, &ldcRaw},
                                   std::tuple{viewCmd, &view.render.run, &viewRaw}})
        if (cmd->parsed()) prepare(*run, *raw);
      if (compareCmd->parsed()) finishEffectOptions(compare.effect, compareEffect, compareRaw), lt::validateEffectConfig(compare.effect);
      if (renderCmd->parsed()) finishEffectOptions(render.effect, effectName, renderRaw), lt::validateEffectConfig(render.effect);
      if (renderCmd->parsed()) lt::validateTracerOptions(render.tracers);
      if (viewCmd->parsed()) {
        finishEffectOptions(view.render.effect, viewEffect, viewRaw), lt::validateEffectConfig(view.render.effect);
        lt::validateTracerOptions(view.render.tracers), lt::validateViewOptions(view);
      }
      if (compareCmd->parsed()) lt::validateTracerOptions(compare.options);
      if (benchCmd->parsed()) lt::validateTracerOptions(bench.options), finishEffectOptions(bench.effect, benchEffect, benchRaw), lt::validateEffectConfig(bench.effect);
      if (ldcCmd->parsed()) lt::validateLdcConfig(ldc.tracers.ldc);
      return 0;
    }
    // A command's files appear together when it succeeds, or not at all (the viewer, which saves
    // while it runs, writes directly).
    std::optional<lt::OutputStage> stage;
    if (!viewCmd->parsed()) stage.emplace();
    auto done = [&stage](int status) {
      if (status == 0 && stage) stage->commit();
      return status;
    };
    if (layersCmd->parsed()) {
      prepare(layers.run, layersRaw);
      return done(lt::runLayers(layers));
    }
    if (ldcCmd->parsed()) {
      prepare(ldc.run, ldcRaw);
      return done(lt::runLdc(ldc));
    }
    if (geobenchCmd->parsed()) {
      prepare(geobench.run, geobenchRaw);
      return done(lt::runGeobench(geobench));
    }
    if (reproduceCmd->parsed()) {
      reproduce.run.frame.width = reproduceWidth ? reproduceWidth : reproduce.quick ? 640 : 1280;
      reproduce.run.frame.height = reproduceHeight ? reproduceHeight : reproduce.quick ? 360 : 720;
      lt::validateFrameOptions(reproduce.run.frame);
      for (int i = 0; i < argc; ++i) reproduce.commandLine += (i ? " " : "") + std::string(i ? argv[i] : "layertrace");
      if (reproduce.run.threads > 0)
        threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(reproduce.run.threads));
      // A claim that does not hold (status 1 with --quick) still leaves the page that says which.
      const int status = lt::runReproduce(reproduce);
      if (stage) stage->commit();
      return status;
    }
    if (benchCmd->parsed()) {
      prepare(bench.run, benchRaw);
      finishEffectOptions(bench.effect, benchEffect, benchRaw);
      return done(lt::runBench(bench));
    }
    if (compareCmd->parsed()) {
      prepare(compare.run, compareRaw);
      finishEffectOptions(compare.effect, compareEffect, compareRaw);
      compare.tracers = splitList(compareTracers);
      if (parsed) {
        lt::validateEffectConfig(compare.effect);
        parsed->name = "compare";
        parsed->compare = compare;
        return 0;
      }
      return done(lt::runCompare(compare));
    }
    if (viewCmd->parsed()) {
      prepare(view.render.run, viewRaw);
      finishEffectOptions(view.render.effect, viewEffect, viewRaw);
      lt::validateViewOptions(view);
      if (!viewRunner)
        lt::inputError("view: this build has no viewer (configure with GLFW, OpenGL and Dear ImGui: apt-get install libglfw3-dev "
                       "libimgui-dev, then rebuild; -DLAYERTRACE_VIEWER=ON)");
      return viewRunner(view);
    }
    if (renderCmd->parsed()) {
      prepare(render.run, renderRaw);
      finishEffectOptions(render.effect, effectName, renderRaw);
      if (parsed) {
        lt::validateEffectConfig(render.effect);
        parsed->name = "render";
        parsed->render = render;
        return 0;
      }
      return done(lt::runRender(render));
    }
  } catch (const lt::InputError& e) {
    if (parsed) throw;
    std::cerr << "layertrace: " << e.what() << "\n";
    return 2;
  } catch (const lt::InternalError& e) {
    if (parsed) throw;
    std::cerr << "layertrace: internal error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    if (parsed) throw;
    std::cerr << "layertrace: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    if (parsed) throw;
    std::cerr << "layertrace: internal error: " << e.what() << "\n";
    return 1;
  }
  return 1;
}

}  // namespace

int runCli(int argc, const char* const* argv, CliMode mode) { return runCliImpl(argc, argv, mode, nullptr); }

CliCommand parseCli(int argc, const char* const* argv) {
  CliCommand command;
  runCliImpl(argc, argv, CliMode::Run, &command);
  return command;
}

}  // namespace lt
