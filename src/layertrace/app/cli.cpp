// layertrace — the command-line interface of DESIGN.md (app/cli.h).
// Exit status: 0 success, 2 bad input (one line naming the input and value), 1 internal error.
#include "layertrace/app/cli.h"

#include <cmath>
#include <limits>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <tuple>

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include "layertrace/app/commands.h"
#include "layertrace/app/view_session.h"
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
  std::string maxMemory;            ///< --max-memory
};

void addFrameOptions(CLI::App* app, lt::RunOptions& run, RawFrameOptions& raw) {
  lt::FrameOptions& f = run.frame;
  app->add_option("SCENE", f.scenePath, "JSON scene file or any model file assimp reads")->required();
  app->add_option("--camera", f.cameraName, "named camera of the scene (default: its first, else auto-framed)");
  app->add_option("--eye", raw.eye, "camera position x,y,z (overrides --camera)");
  app->add_option("--target", raw.target, "camera target x,y,z");
  app->add_option("--up", raw.up, "camera up vector x,y,z");
  app->add_option("--fov", raw.fov, "vertical field of view in degrees (default: the camera's)");
  app->add_option("--width", f.width, "image width in pixels")->capture_default_str();
  app->add_option("--height", f.height, "image height in pixels")->capture_default_str();
  app->add_option("--layers", f.layers, "layers k kept per pixel, 1..16")->capture_default_str();
  app->add_option("--thickness", raw.thickness, "fixed fragment z-thickness in scene units (default: --thickness-px)");
  app->add_option("--thickness-px", raw.thicknessPx,
                  lt::cat("fragment z-thickness in pixel footprints at the fragment's depth (default ", lt::kDefaultThicknessPx, ")"));
  app->add_option("--min-separation", f.minSeparation, "minimum depth separation of kept layers (0 = off)")->capture_default_str();
  app->add_flag("--adaptive-thickness", f.adaptiveThickness, "merge fragments that start inside the previous kept interval (seed 000 §4.2)");
  app->add_flag("--front-faces-only", f.frontFacesOnly, "capture only triangles facing the camera (layers = nearest front surfaces)");
  app->add_option("--pool", f.pool, "fragment pool capacity (0 = automatic, grows on overflow)")->capture_default_str()->check(CLI::NonNegativeNumber);
  app->add_option("--max-memory", raw.maxMemory, "refuse, before allocating, any structure that would take the process past this size, e.g. 4G (default: the memory available)");
  app->add_option("--light", raw.lights, "add a point light x,y,z[,intensity] (repeatable; default light: above the eye)");
  app->add_option("--threads", run.threads, "worker threads (0 = all cores)")->capture_default_str();
  app->add_option("--seed", run.seed, "random seed")->capture_default_str()->check(CLI::NonNegativeNumber);
  app->add_option("--stats", run.statsPath, "write statistics JSON to this file");
  app->add_option("--pixelstats", run.pixelStats, "write per-pixel counter images to this folder");
  app->add_option("-o,--output", run.output, "output image (render) or folder");
  app->add_flag("--quiet", run.quiet, "no progress or summary output");
}

void addGridOptions(CLI::App* app, lt::GridConfig& g) {
  app->add_option("--lambda1", g.lambda1, "grid: top-level density (seed 003)")->capture_default_str();
  app->add_option("--lambda2", g.lambda2, "grid: second-level density (seed 003)")->capture_default_str();
  app->add_flag("--partial-expansion,!--no-partial-expansion", g.partialExpansion,
                "grid: also expand into neighbours whose swept part holds only shared primitives (default on)");
}

void addLdcOptions(CLI::App* app, lt::LdcConfig& c) {
  app->add_option("--ldc-resolution", c.resolution, "ldc: texels along the scene box's longest axis (seed 004: 512, 1024)")->capture_default_str();
  app->add_option("--ldc-block", c.block, "ldc: coarse block edge in texels (seed 004 §1.3)")->capture_default_str();
  app->add_option("--ldc-block-intervals", c.blockIntervals, "ldc: depth intervals per block (1 = seed 004's min/max)")->capture_default_str();
  app->add_option("--ldc-epsilon", c.epsilon, "ldc: hit tolerance in texels (a sample's patch is widened by this much)")->capture_default_str();
}

void addTracerOptions(CLI::App* app, lt::TracerOptions& t) {
  app->add_option("--stride", t.ssr.stride, "ssr: pixels per step")->capture_default_str();
  app->add_option("--jitter", t.ssr.jitter, "ssr: start offset in strides, [0,1]")->capture_default_str();
  app->add_option("--max-steps", t.ssr.maxSteps, "ssr: step limit (0 = to the viewport edge)")->capture_default_str();
  app->add_option("--tau", t.pyramid.tau, "hssr: merge threshold in pixel footprints")->capture_default_str();
  app->add_option("--levels", t.pyramid.levels, "hssr: pyramid levels incl. level 0")->capture_default_str();
  app->add_option("--n-up", t.hssr.nUp, "hssr: cells without overlap before ascending (sooner on entering a new parent cell)")->capture_default_str();
  app->add_option("--lambda-h", t.quadtree.lambdaH, "quadtree: zero one-sided depth derivatives above this (seed 002 Alg. 1)")->capture_default_str();
  app->add_option("--lambda-d", t.quadtree.lambdaD, "quadtree: Laplacian discontinuity threshold (seed 002 Alg. 1)")->capture_default_str();
  app->add_option("--gamma-norm", t.quadtree.gammaNorm, "quadtree: merge planes whose normals differ by less (1 - dot)")->capture_default_str();
  app->add_option("--gamma-dist", t.quadtree.gammaDist, "quadtree: merge planes within this relative depth")->capture_default_str();
  app->add_option("--hybrid-screen", t.hybridScreen, "hybrid: the screen tracer (hssr, hiz, quadtree, ldc)")->capture_default_str();
  app->add_option("--hybrid-geo", t.hybridGeo, "hybrid: the geometric tracer for what the layers do not know (embree, embree-robust, grid)")->capture_default_str();
  addLdcOptions(app, t.ldc);
  addGridOptions(app, t.grid);
}

void addEffectOptions(CLI::App* app, lt::EffectConfig& e, std::string& effectName, RawFrameOptions& raw) {
  app->add_option("--effect", effectName, "shade | reflection | refraction | ao | shadow | warp")->capture_default_str();
  app->add_option("--warp-eye", raw.warpEye, "warp: the second camera's eye x,y,z (world space)");
  app->add_option("--warp-target", raw.warpTarget, "warp: the second camera's target x,y,z (default: the first camera's)");
  app->add_option("--bounces", e.bounces, "reflection bounces")->capture_default_str();
  app->add_option("--ao-samples", e.aoSamples, "AO rays per pixel")->capture_default_str();
  app->add_option("--ao-radius", e.aoRadius, "AO ray length (0 = 5% of the scene diagonal)")->capture_default_str();
  app->add_option("--max-distance", e.maxDistance, "ray length (0 = the scene diagonal)")->capture_default_str();
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
  for (const std::string& l : raw.lights) {
    const auto v = parseNumbers("--light", l, 3, 4);
    f.lights.push_back({v[0], v[1], v[2], v.size() == 4 ? v[3] : 1.0});
  }
  if (run.threads < 0) inputError("--threads ", run.threads, ": must be >= 0");
}

}  // namespace

namespace lt {

namespace {
ViewRunner viewRunner = nullptr;
}  // namespace

void setViewRunner(ViewRunner runner) { viewRunner = runner; }

int runCli(int argc, const char* const* argv, CliMode mode) {
  CLI::App app{"layertrace: image-space ray tracing of secondary effects through multi-layer fragment buffers"};
  app.require_subcommand(1);
  app.set_help_all_flag("--help-all", "help for every subcommand");

  lt::LayersOptions layers;
  RawFrameOptions layersRaw;
  CLI::App* layersCmd = app.add_subcommand("layers", "capture fragments, write layer images + depth-complexity map");
  addFrameOptions(layersCmd, layers.run, layersRaw);
  layersCmd->add_flag("--verify", layers.verify, "compare every pixel's fragment list with Embree all-hit primary rays");

  lt::RenderOptions render;
  RawFrameOptions renderRaw;
  std::string effectName = "reflection";
  CLI::App* renderCmd = app.add_subcommand("render", "image of one effect traced with one tracer");
  addFrameOptions(renderCmd, render.run, renderRaw);
  renderCmd->add_option("--tracer", render.tracer, "ssr | ssr-layers | hiz | hssr | quadtree | ldc | hybrid | embree | grid")->capture_default_str();
  addEffectOptions(renderCmd, render.effect, effectName, renderRaw);
  addTracerOptions(renderCmd, render.tracers);
  renderCmd->add_flag("--check-exhaustive", render.checkExhaustive, "trace every ray with the exhaustive oracle too; count differences");
  renderCmd->add_flag("--check-oracle", render.checkOracle,
                      "trace every ray with the independent image-space oracle too; count differences (rays.oracle_mismatch)");

  lt::CompareOptions compare;
  RawFrameOptions compareRaw;
  std::string compareEffect = "reflection", compareTracers = "ssr,ssr-layers,hssr";
  CLI::App* compareCmd = app.add_subcommand("compare", "same rays through several tracers + Embree: accuracy and cost table");
  addFrameOptions(compareCmd, compare.run, compareRaw);
  compareCmd->add_option("--tracers", compareTracers, "comma list of ssr, ssr-layers, hiz, hssr, quadtree, ldc, hybrid, embree, grid")->capture_default_str();
  addEffectOptions(compareCmd, compare.effect, compareEffect, compareRaw);
  addTracerOptions(compareCmd, compare.options);
  compareCmd->add_option("--report", compare.report, "also write an HTML report (one self-contained page) to this folder");
  // compare checks every image-space ray against the exhaustive oracle anyway (exhaustive_mismatch
  // per tracer); the flag is accepted so that the tracer options of DESIGN.md work everywhere.
  compareCmd->add_flag("--check-exhaustive")
      ->description("accepted for symmetry with render: compare always checks image-space rays against the exhaustive oracle");
  compareCmd->add_flag("--check-oracle", compare.checkOracle,
                       "also check every image-space ray against the independent oracle (slow; oracle_mismatch)");

  lt::BenchOptions bench;
  RawFrameOptions benchRaw;
  CLI::App* benchCmd = app.add_subcommand("bench", "the papers' experiments: stride|layers|tau|memory|resolution|threads|capture|warp|gamma|ldc");
  addFrameOptions(benchCmd, bench.run, benchRaw);
  benchCmd->add_option("--experiment", bench.experiment, "stride | layers | tau | memory | resolution | threads | capture | warp | gamma | ldc")->required();
  benchCmd->add_option("--repeat", bench.repeat, "runs per measurement (the median is reported)")->capture_default_str();
  addTracerOptions(benchCmd, bench.options);
  benchCmd->add_option("--report", bench.report, "also write an HTML report to this folder");

  lt::GeobenchOptions geobench;
  RawFrameOptions geobenchRaw;
  CLI::App* geobenchCmd = app.add_subcommand("geobench", "geometric tracers (grid vs embree): build, memory, MRays/s, agreement");
  addFrameOptions(geobenchCmd, geobench.run, geobenchRaw);
  addGridOptions(geobenchCmd, geobench.grid);
  geobenchCmd->add_option("--repeat", geobench.repeat, "runs per timing (the median is reported)")->capture_default_str();
  geobenchCmd->add_flag("--sweep", geobench.sweep, "also sweep lambda1 x lambda2: build time vs traversal time");

  lt::LdcOptions ldc;
  RawFrameOptions ldcRaw;
  CLI::App* ldcCmd = app.add_subcommand("ldc", "build the layered depth cube (seed 004): per-axis depth complexity and albedo images");
  addFrameOptions(ldcCmd, ldc.run, ldcRaw);
  addLdcOptions(ldcCmd, ldc.ldc);

  lt::ViewOptions view;
  RawFrameOptions viewRaw;
  std::string viewEffect = "reflection";
  CLI::App* viewCmd = app.add_subcommand("view", "interactive viewer: fly through the scene, switch tracers and overlays live");
  addFrameOptions(viewCmd, view.render.run, viewRaw);
  viewCmd->add_option("--tracer", view.render.tracer, "ssr | ssr-layers | hiz | hssr | quadtree | ldc | hybrid | embree | grid")->capture_default_str();
  addEffectOptions(viewCmd, view.render.effect, viewEffect, viewRaw);
  addTracerOptions(viewCmd, view.render.tracers);
  viewCmd->add_option("--frames", view.frames, "render this many full frames without input, then exit (scripted mode)")->capture_default_str();
  viewCmd->add_option("--screenshot", view.screenshot, "scripted mode: write the last traced image (without the UI) to this PNG");
  viewCmd->add_option("--screenshot-ui", view.screenshotUi, "scripted mode: write the whole window of the last frame to this PNG");
  viewCmd->add_option("--overlay", view.overlay, "image | classes (strict classes vs Embree) | iterations | layer | complexity")->capture_default_str();

  std::string names;
  bool known = false;
  for (const CLI::App* sub : app.get_subcommands({})) {
    names += (names.empty() ? "" : ", ") + sub->get_name();
    known = known || (argc > 1 && sub->get_name() == argv[1]);
  }
  if (argc > 1 && argv[1][0] != '-' && !known) {
    std::cerr << "layertrace: unknown subcommand \"" << argv[1] << "\" (use one of: " << names << ")\n";
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::string msg = e.what();
    std::replace(msg.begin(), msg.end(), '\n', ' ');
    std::cerr << "layertrace: " << msg << "\n";
    return 2;
  }

  try {
    std::unique_ptr<tbb::global_control> threads;
    // Converts the raw vector options and applies --threads for the subcommand that ran.
    auto prepare = [&](lt::RunOptions& run, const RawFrameOptions& raw) {
      finishFrameOptions(run, raw);
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
        if (cmd->parsed()) prepare(*run, *raw), lt::validateFrameOptions(run->frame);
      if (compareCmd->parsed()) finishEffectOptions(compare.effect, compareEffect, compareRaw), lt::validateEffectConfig(compare.effect);
      if (renderCmd->parsed()) finishEffectOptions(render.effect, effectName, renderRaw), lt::validateEffectConfig(render.effect);
      if (renderCmd->parsed()) lt::validateTracerOptions(render.tracers);
      if (viewCmd->parsed()) {
        finishEffectOptions(view.render.effect, viewEffect, viewRaw), lt::validateEffectConfig(view.render.effect);
        lt::validateTracerOptions(view.render.tracers), lt::validateViewOptions(view);
      }
      if (compareCmd->parsed()) lt::validateTracerOptions(compare.options);
      if (benchCmd->parsed()) lt::validateTracerOptions(bench.options);
      if (ldcCmd->parsed()) lt::validateLdcConfig(ldc.ldc);
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
    if (benchCmd->parsed()) {
      prepare(bench.run, benchRaw);
      return done(lt::runBench(bench));
    }
    if (compareCmd->parsed()) {
      prepare(compare.run, compareRaw);
      finishEffectOptions(compare.effect, compareEffect, compareRaw);
      compare.tracers = splitList(compareTracers);
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
      return done(lt::runRender(render));
    }
  } catch (const lt::InputError& e) {
    std::cerr << "layertrace: " << e.what() << "\n";
    return 2;
  } catch (const lt::InternalError& e) {
    std::cerr << "layertrace: internal error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "layertrace: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "layertrace: internal error: " << e.what() << "\n";
    return 1;
  }
  return 1;
}

}  // namespace lt
