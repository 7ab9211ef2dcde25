#include <chrono>
#include <filesystem>
#include <iostream>
#include <memory>

#include "layertrace/app/commands.h"
#include "layertrace/geometry/embree_tracer.h"
#include "layertrace/util/error.h"

namespace lt {
namespace fs = std::filesystem;

int runRender(const RenderOptions& o) {
  const std::string out = o.run.output.empty() ? "out/render.png" : o.run.output;
  const std::string ext = fs::path(out).extension().string();
  if (ext != ".png" && ext != ".exr") inputError("-o ", out, ": render writes .png or .exr");
  const bool screen = o.tracer == "ssr" || o.tracer == "ssr-layers" || o.tracer == "hssr";
  if (!screen && o.tracer != "embree") inputError("--tracer ", o.tracer, ": unknown (use ssr, ssr-layers, hssr, embree)");
  if (o.checkExhaustive && !screen) inputError("--check-exhaustive: needs an image-space tracer, not ", o.tracer);
  // Every tracer option is checked, whichever tracer runs: a bad value is never silently unused.
  if (!(o.ssr.stride >= 1.0f)) inputError("--stride ", o.ssr.stride, ": must be >= 1");
  if (!(o.ssr.jitter >= 0.0f && o.ssr.jitter <= 1.0f)) inputError("--jitter ", o.ssr.jitter, ": must be in [0, 1]");
  if (o.ssr.maxSteps < 0) inputError("--max-steps ", o.ssr.maxSteps, ": must be >= 0");
  if (o.hssr.nUp < 1) inputError("--n-up ", o.hssr.nUp, ": must be >= 1");
  if (o.pyramid.levels < 1 || o.pyramid.levels > 16) inputError("--levels ", o.pyramid.levels, ": must be between 1 and 16");
  if (!(o.pyramid.tau > 0.0f)) inputError("--tau ", o.pyramid.tau, ": must be positive");
  if (o.effect.bounces < 1 || o.effect.bounces > 16) inputError("--bounces ", o.effect.bounces, ": must be between 1 and 16");
  const auto t0 = std::chrono::steady_clock::now();
  Frame frame = buildFrame(o.run.frame);

  // Build the tracer's structure.
  std::unique_ptr<Tracer> tracer;
  std::unique_ptr<EmbreeScene> embree;
  IntervalPyramid pyramid, oraclePyramid;
  double hierarchyMs = 0.0;
  if (o.tracer == "hssr") {
    pyramid = buildIntervalPyramid(frame.layers, frame.camera, o.pyramid);
    hierarchyMs = pyramid.buildMs;
    tracer = std::make_unique<HssrTracer>(frame.camera, frame.layers, pyramid, o.hssr);
  } else if (o.tracer == "embree") {
    embree = std::make_unique<EmbreeScene>(frame.scene);
    hierarchyMs = embree->buildMs();
    tracer = std::make_unique<EmbreeTracer>(frame.scene, frame.camera, *embree);
  } else {
    SsrConfig sc = o.ssr;
    sc.allLayers = o.tracer == "ssr-layers";
    tracer = std::make_unique<SsrTracer>(frame.camera, frame.layers, sc);
  }
  std::unique_ptr<HssrTracer> oracle;
  if (o.checkExhaustive) {
    oraclePyramid = buildIntervalPyramid(frame.layers, frame.camera, PyramidConfig{1, o.pyramid.tau});
    oracle = std::make_unique<HssrTracer>(frame.camera, frame.layers, oraclePyramid, HssrConfig{1, 1});
  }
  EffectConfig ec = o.effect;
  ec.seed = o.run.seed;
  const EffectResult r = renderEffect(frame, *tracer, ec, oracle.get());
  const double totalMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

  nlohmann::json stats = frameStats(frame);
  stats["tracer"] = tracer->name();
  stats["effect"] = effectName(ec.effect);
  stats["threads"] = o.run.threads;
  stats["bounces"] = ec.bounces;
  stats["timings_ms"]["hierarchy"] = hierarchyMs;
  stats["timings_ms"]["trace"] = r.traceMs;  // rays and the shading of their hits, interleaved
  stats["timings_ms"]["shade"] = 0.0;         // included in trace (shading happens per hit)
  stats["timings_ms"]["total"] = totalMs;
  stats["memory_bytes"]["hierarchy"] = o.tracer == "hssr" ? pyramid.memoryBytes() : embree ? embree->memoryBytes() : 0;
  stats["rays"] = {{"count", r.rays},
                   {"hits", r.hits},
                   {"iterations_mean", r.rays ? double(r.iterationSum) / double(r.rays) : 0.0},
                   {"iterations_p99", r.iterationsP99},
                   // per visited cell at any level (hssr-pitfalls §10: the same unit for every tracer)
                   {"intervals_per_visited_pixel", r.iterationSum ? double(r.intervalSum) / double(r.iterationSum) : 0.0},
                   {"visited_pixels_mean", r.rays ? double(r.pixelSum) / double(r.rays) : 0.0}};
  if (o.checkExhaustive) stats["rays"]["exhaustive_mismatch"] = r.exhaustiveMismatch;
  if (o.tracer == "hssr") {
    stats["hssr"] = {{"tau", o.pyramid.tau}, {"levels", o.pyramid.levels}, {"n_up", o.hssr.nUp}};
    nlohmann::json perLevel = nlohmann::json::array();
    uint64_t base = 0;
    for (uint8_t n : pyramid.base.count) base += n;
    perLevel.push_back(base);
    for (size_t l = 1; l < pyramid.levels.size(); ++l) perLevel.push_back(pyramid.levels[l].intervals.size());
    stats["hssr"]["intervals_per_level"] = perLevel;
    // Where the traversal spends its steps (a proxy for time per level: one iteration = one
    // visited cell, and every cell costs about the same).
    nlohmann::json itLevel = nlohmann::json::array();
    for (int l = 0; l < std::min(o.pyramid.levels, int(RayCounters::kLevels)); ++l)
      itLevel.push_back(r.rays ? double(r.levelIterations[l]) / double(r.rays) : 0.0);
    stats["hssr"]["iterations_per_ray_by_level"] = itLevel;
  }
  if (!screen) stats["rays"].erase("intervals_per_visited_pixel");

  if (!o.run.pixelStats.empty()) {
    ensureDirectory(o.run.pixelStats, "--pixelstats");
    writeImage((fs::path(o.run.pixelStats) / "iterations.exr").string(), r.iterations);
    writeImage((fs::path(o.run.pixelStats) / "intervals.exr").string(), r.intervals);
    float maxIt = 1.0f;
    for (float v : r.iterations.data) maxIt = std::max(maxIt, v);
    Image heat(r.iterations.width, r.iterations.height);
    for (int y = 0; y < heat.height; ++y)
      for (int x = 0; x < heat.width; ++x) heat.set(x, y, heatColor(std::log1p(r.iterations.at(x, y)[0]) / std::log1p(maxIt)));
    writeImage((fs::path(o.run.pixelStats) / "iterations.png").string(), heat);
  }
  if (fs::path(out).has_parent_path()) ensureDirectory(fs::path(out).parent_path().string(), "-o");
  writeImage(out, r.image);
  writeStats(o.run.statsPath, stats.dump(2));
  if (!o.run.quiet) {
    std::cout << "render: " << frame.scene.name << " " << frame.camera.width() << "x" << frame.camera.height() << " "
              << tracer->name() << " " << effectName(ec.effect) << ": " << r.rays << " rays, " << r.hits << " hits, "
              << stats["rays"]["iterations_mean"].get<double>() << " iterations/ray; raster " << frame.rasterMs
              << " ms, sort " << frame.sortMs << " ms, hierarchy " << hierarchyMs << " ms, trace " << r.traceMs << " ms";
    if (o.checkExhaustive) std::cout << "; exhaustive mismatches " << r.exhaustiveMismatch;
    std::cout << "\n  wrote " << out << "\n";
  }
  return 0;
}

}  // namespace lt
