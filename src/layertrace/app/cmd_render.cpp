#include <algorithm>
#include <cctype>
#include <chrono>
#include <optional>
#include <filesystem>
#include <iostream>
#include <sstream>
#include <string>
#include <string_view>

#include "layertrace/app/commands.h"
#include "layertrace/eval/image_metrics.h"
#include "layertrace/eval/image_oracle.h"
#include "layertrace/eval/oracle_observer.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/render/frame_sequence.h"
#include "layertrace/util/error.h"
#include "layertrace/util/warning.h"

namespace lt {
namespace fs = std::filesystem;

/// Stats keys of one traced effect (`rays.*`, docs/cli.md), shared by render and compare.
nlohmann::json rayStats(const EffectResult& r, bool screen) {
  nlohmann::json j = {{"count", r.rays},
                      {"hits", r.hits},
                      {"iterations_mean", r.rays ? double(r.iterationSum) / double(r.rays) : 0.0},
                      {"iterations_p99", r.iterationsP99},
                      {"visited_pixels_mean", r.rays ? double(r.pixelSum) / double(r.rays) : 0.0},
                      {"give_ups", r.giveUps},
                      {"bent", r.bentRays},
                      {"counters", kCountersCompiled}};
  // Per visited cell at any level (the same unit for every tracer).
  if (screen) j["intervals_per_visited_pixel"] = r.iterationSum ? double(r.intervalSum) / double(r.iterationSum) : 0.0;
  return j;
}

nlohmann::json quadtreeStats(const Quadtree& t, const QuadtreeConfig& c, const EffectResult& r) {
  const double rays = r.rays ? double(r.rays) : 1.0;
  nlohmann::json perLevel = nlohmann::json::array(), itLevel = nlohmann::json::array();
  for (const auto& n : t.kindCounts) perLevel.push_back({{"empty", n[QuadNode::Empty]}, {"plane", n[QuadNode::Plane]}, {"box", n[QuadNode::Box]}});
  for (int l = 0; l < std::min(t.levelCount(), int(RayCounters::kLevels)); ++l) itLevel.push_back(double(r.levelIterations[l]) / rays);
  return {{"lambda_h", c.lambdaH},
          {"lambda_d", c.lambdaD},
          {"gamma_norm", c.gammaNorm},
          {"gamma_dist", c.gammaDist},
          {"depth_scale", t.depthScale},
          {"levels", t.levelCount()},
          {"nodes_per_level", perLevel},  // summed over the k layers
          {"iterations_per_ray_by_level", itLevel},  // the last entry holds all higher levels
          {"plane_nodes_visited_mean", double(r.planeNodeSum) / rays},
          {"box_nodes_visited_mean", double(r.boxNodeSum) / rays},
          {"empty_nodes_visited_mean", double(r.iterationSum - r.planeNodeSum - r.boxNodeSum) / rays},
          {"occlusion_hits_mean", double(r.occlusionSum) / rays}};
}

nlohmann::json ldcStats(const LayeredDepthCube& ldc, const EffectResult* r) {
  nlohmann::json views = nlohmann::json::object();
  for (const LdcView& v : ldc.views)
    views[std::string(1, "xyz"[v.axis])] = {{"width", v.width},
                                            {"height", v.height},
                                            {"triangles", v.triangles},
                                            {"samples", v.samples.size()},
                                            {"lost_triangles", v.lostTriangles},
                                            {"memory_bytes", v.memoryBytes()},
                                            {"build_ms", v.rasterMs}};
  nlohmann::json j = {{"resolution", ldc.config.resolution},
          {"block", ldc.config.block},
          {"block_intervals", ldc.config.blockIntervals},
          {"epsilon_texels", ldc.config.epsilon},
          {"texel", ldc.texel},
          {"build_ms", ldc.buildMs},
          {"memory_bytes", ldc.memoryBytes()},
          {"samples", ldc.samples()},
          // Triangles covering no texel centre of their view: each got one sample at its
          // centroid's texel (ldc.h, the centroid-texel policy).
          {"lost_triangles", ldc.lostTriangles()},
          {"degenerate_triangles", ldc.degenerateTriangles},
          {"views", views}};
  if (r) {
    const double rays = r->rays ? double(r->rays) : 1.0;
    j["blocks_per_ray"] = double(r->levelIterations[1]) / rays;
    j["texels_per_ray"] = double(r->levelIterations[0]) / rays;
    j["samples_tested_per_ray"] = double(r->intervalSum) / rays;
  }
  return j;
}

nlohmann::json hybridStats(const BuiltTracer& built, const TracerOptions& o) {
  const auto* hybrid = dynamic_cast<const HybridTracer*>(built.tracer.get());
  if (!hybrid) return nullptr;
  const HybridStats h = hybrid->stats();
  const double rays = h.rays ? double(h.rays) : 1.0;
  // On the GPU the geometric half is the grid whatever --hybrid-geo says.
  const auto* geo = dynamic_cast<const Tracer*>(&hybrid->geometry());
  const std::string geoName = geo && std::string_view(geo->name()) == "grid" ? "grid" : o.hybrid.geo;
  return {{"screen", o.hybrid.screen},
          {"geo", geoName},
          {"rays", h.rays},
          {"screen_fraction", h.screenFraction()},
          {"geo_fraction", h.geoFraction()},
          {"geo_length_mean", h.geoLengthMean()},  // of the ray's length inside the scene's bounds
          {"screen_hit_fraction", double(h.screenHits) / rays},
          {"certain_miss_fraction", double(h.certainMisses) / rays},
          {"rejected_hit_fraction", double(h.rejectedHits) / rays},  // thickness false hits caught by the exact check
          {"window_queries_per_ray", double(h.windowQueries) / rays},  // geometric windows certifying screen answers
          {"geo_queries_per_ray", h.geoQueriesPerRay()},  // windows + remainders; plain Embree: 1
          {"screen_ms", h.screenMs},  // summed over threads: the split, not wall time
          {"window_ms", h.windowMs},  // geometric windows certifying screen answers
          {"geo_ms", h.geoMs},
          {"known_space_build_ms", built.known->buildMs()},
          {"known_space_bytes", built.known->memoryBytes()}};
}

Image iterationHeat(const EffectResult& r) {
  float maxIt = 1.0f;
  for (float v : r.iterations.data) maxIt = std::max(maxIt, v);
  Image heat(r.iterations.width, r.iterations.height);
  for (int y = 0; y < heat.height; ++y)
    for (int x = 0; x < heat.width; ++x) heat.set(x, y, heatColor(std::log1p(r.iterations.at(x, y)[0]) / std::log1p(maxIt)));
  return heat;
}

void writePixelStats(const std::string& dir, const EffectResult& r) {
  ensureDirectory(dir, "--pixelstats");
  writeImage((fs::path(dir) / "iterations.exr").string(), r.iterations);
  writeImage((fs::path(dir) / "intervals.exr").string(), r.intervals);
  writeImage((fs::path(dir) / "iterations.png").string(), iterationHeat(r));
}

WarpReference warpReference(const Frame& frame, const FrameOptions& options, const EffectConfig& warp) {
  const Camera second = warpCamera(frame, warp);
  FrameOptions fo = options;
  fo.cameraName.clear();
  fo.frontFacesOnly = false;  // the truth is what the second camera sees, back faces included
  fo.eye = frame.scene.toWorld(second.desc().eye), fo.target = frame.scene.toWorld(second.desc().target);
  fo.up = second.desc().up, fo.fov = second.desc().fovY;
  Frame other = buildFrame(fo);
  other.lights = frame.lights;
  EffectConfig shade = warp;
  shade.effect = Effect::Shade;
  shade.progress = false;
  WarpReference ref;
  // Shading traces no ray: any tracer object will do; this one never sees a query.
  struct NoTracer : Tracer {
    const char* name() const override { return "none"; }
    TraceHit trace(const Ray&, RayCounters&) const override { return {}; }
  } none;
  ref.image = renderEffect(other, none, shade).image;
  ref.covered.resize(other.layers.count.size());
  ref.outsideFirst.assign(other.layers.count.size(), 0);
  const Camera& first = frame.camera;
  for (int y = 0; y < other.layers.height; ++y)
    for (int x = 0; x < other.layers.width; ++x) {
      const size_t p = other.layers.pixelIndex(x, y);
      ref.covered[p] = other.layers.count[p] > 0;
      if (!ref.covered[p]) continue;
      const glm::vec3 world = other.camera.toWorld(other.camera.rayThrough({x + 0.5f, y + 0.5f}) * other.layers.pixel(x, y)[0].depth);
      int fx, fy;
      ref.outsideFirst[p] = !first.pixelOf(first.toCamera(world), fx, fy);
    }
  return ref;
}

WarpHoles countWarpHoles(const WarpReference& ref, const std::vector<uint8_t>& holes) {
  WarpHoles h;
  for (size_t p = 0; p < holes.size(); ++p) {
    if (!ref.covered[p]) continue;
    ++h.covered;
    h.coveredInside += !ref.outsideFirst[p];
    if (!holes[p]) continue;
    ++h.holes;
    if (ref.outsideFirst[p]) ++h.outside;
    else ++h.disoccluded;
  }
  return h;
}

void validateRepeat(int repeat) {
  if (repeat < 1 || repeat > 100) inputError("--repeat ", repeat, ": must be between 1 and 100");
}

RenderOutput renderFrame(const RenderOptions& o) {
  if (!isKnownTracer(o.tracer)) inputError("--tracer ", o.tracer, ": unknown (use ", tracerNames(), ")");
  const bool screen = isScreenTracer(o.tracer);
  if (o.checkExhaustive && !screen) inputError("--check-exhaustive: needs an image-space tracer, not ", o.tracer);
  if (o.checkOracle && !screen) inputError("--check-oracle: needs an image-space tracer, not ", o.tracer);
  validateTracerOptions(o.tracers);
  validateEffectConfig(o.effect);
  validateRepeat(o.repeat);
  // The device before the scene: a machine without one is told at once.
  std::shared_ptr<GpuContext> gpu;
  if (o.run.device == "gpu") {
    if (!hasGpuTracer(o.tracer)) inputError("--tracer ", o.tracer, ": has no GPU version (with --device gpu use ", gpuTracerNames(), ")");
    gpu = openGpu();
  }
  const auto t0 = std::chrono::steady_clock::now();
  const nlohmann::json activityBefore = gpu ? gpuActivityReading() : nlohmann::json();
  FrameOptions fo = o.run.frame;
  prepareCapture(o.tracer, o.tracers, fo);
  EffectConfig ec = o.effect;
  ec.seed = o.run.seed;
  ec.progress = !o.run.quiet;
  ec.wholeWaves = gpu != nullptr;  // one dispatch per wave
  ec.shadeOnDevice = gpu != nullptr;  // rays generated and shaded on the GPU where the effect allows
  Frame frame;
  std::vector<uint8_t> png8;
  BuiltTracer built;
  EffectResult r;
  TraceTiming timed;
  double gpuMs = 0.0, countedMs = 0.0;
  nlohmann::json frameAccount, hybrid;
  std::optional<MismatchObserver> exhaustive;
  std::optional<ImageSpaceOracle> independent;
  std::optional<OracleObserver> oracleCheck;
  const auto msSinceStart = [&] { return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count(); };
  if (gpu) loadFrameScene(fo, frame);
  // The whole frame on the device where nothing needs the layers on the host: capture, sort,
  // pyramid, march and effect resident, the picture and the frame's counters read back.
  const bool resident = gpu && rendersResident(o.tracer, frame, ec) && !o.checkExhaustive && !o.checkOracle && o.run.pixelStats.empty() &&
                        gpuCaptureLimit(*gpu, frame).empty();
  if (resident) {
    ResidentRender rr = renderResident(fo, frame, o.tracer, o.tracers, ec, o.repeat, o.png8, *gpu);
    png8 = std::move(rr.srgb8);
    frame.layers.width = frame.camera.width(), frame.layers.height = frame.camera.height(), frame.layers.k = fo.layers;
    frame.lists.width = frame.camera.width(), frame.lists.height = frame.camera.height();
    frame.lists.generated = rr.fragments;
    frame.lists.stored = fo.depthPeeling ? rr.fragments : std::min(rr.fragments, rr.poolCapacity);
    frame.deviceCapture = Frame::DeviceCapture{rr.maxComplexity};
    frame.rasterMs = rr.rasterMs, frame.sortMs = rr.sortMs;
    frame.raster = RasterStats{frame.rasterMs, rr.overflowLost, rr.attempts, frame.scene.triangleCount()};
    frame.capturePipeline = fo.depthPeeling ? "gpu-peel" : "gpu-lists";
    frame.geometryPasses = fo.depthPeeling ? 2 * fo.layers : 1;
    if (rr.structure) {
      built = std::move(*rr.structure);  // a tracer of the scene: its structure and statistics
    } else {
      built.buildMs = rr.layersMs + rr.pyramidMs;
      built.memoryBytes = rr.hierarchyBytes;
      built.levelIntervals = rr.levelIntervals;
    }
    frame.gpuMemoryBytes = rr.captureBytes;
    r = std::move(rr.effect);
    gpuMs = countedMs = r.traceMs;
    frameAccount = std::move(rr.frameAccount);
    timed = {rr.timedTraceMs, rr.timedShadeMs};
  } else {
    if (gpu) {
      // The capture on the GPU too (its layers read back for the statistics and the checks),
      // unless the scene's textures exceed the GPU's storage buffers: then the CPU captures, says
      // so on stderr, and capture_pipeline in the statistics names it.
      if (const std::string why = gpuCaptureLimit(*gpu, frame); why.empty()) {
        rasterizeFrameOnGpu(*gpu, fo, fo.depthPeeling ? "peel" : "lists", frame);
      } else {
        warning(why + "; capturing on the CPU");
        rasterizeFrame(fo, frame);
      }
    } else {
      frame = buildFrame(fo);
    }
    built = gpu ? buildGpuTracer(o.tracer, frame, o.tracers, *gpu) : buildTracer(o.tracer, frame, o.tracers);
    BuiltTracer oracle;
    if (o.checkExhaustive) oracle = buildOracle(frame), exhaustive.emplace(*oracle.tracer);
    independent.emplace(frame.camera, frame.layers);
    oracleCheck.emplace(*independent);
    ObserverList observers;
    if (exhaustive) observers.add(&*exhaustive);
    if (o.checkOracle) observers.add(&*oracleCheck);
    r = renderEffect(frame, *built.tracer, ec, observers.empty() ? nullptr : &observers);
    // the counted pass's dispatches: the marches alone, or with the origin rule's passes where
    // the effect ran on the device
    gpuMs = !gpu ? 0.0 : r.onDevice ? r.traceMs : gpuTraceMs(*built.tracer);
    countedMs = r.traceMs;
    // The first frame's accounting: capture, structure and the counted effect (uploads, links and
    // allocations included: a resident frame's steady state is bench --experiment frame's).
    if (gpu)
      frameAccount = gpuFrameStats(activityBefore, gpuActivityReading(), msSinceStart(),
                                   frame.rasterMs + frame.sortMs + built.buildMs + r.traceMs + (r.onDevice ? r.shadeMs : 0.0));
    if (built.known) hybrid = hybridStats(built, o.tracers);  // of the counted pass alone
    timed = measureTrace(frame, *built.tracer, ec, o.repeat);  // as compare and bench measure it
  }
  r.traceMs = timed.traceMs;
  const double totalMs = msSinceStart();

  nlohmann::json stats = frameStats(frame);
  stats["tracer"] = built.tracer ? std::string(built.tracer->name()) : o.tracer;
  stats["effect"] = effectName(ec.effect);
  stats["threads"] = o.run.threads;
  stats["bounces"] = ec.bounces;
  stats["timings_ms"]["hierarchy"] = built.buildMs;
  stats["timings_ms"]["trace"] = r.traceMs;  // inside the tracer's batch calls: median of --repeat passes without counters
  stats["timings_ms"]["trace_counted"] = countedMs;  // the counted pass (the counters' cost included)
  stats["timings_ms"]["shade"] = timed.shadeMs;  // ray generation, shading, bookkeeping (the timed passes)
  stats["timings_ms"]["total"] = totalMs;
  stats["device"] = o.run.device;
  if (gpu) {
    // GL timer queries of the trace dispatches. With the effect on the device (gpu.shading
    // "gpu"), `trace` and `shade` above are timer queries too; otherwise `trace` adds the rays'
    // upload and the answers' download, and `shade` is the CPU's. On a software rasterizer
    // (gpu.software) these are CPU times.
    stats["timings_ms"]["gpu_trace"] = gpuMs;
    stats["gpu"] = gpuStats(*gpu);
    stats["gpu"]["shading"] = r.onDevice ? "gpu" : "cpu";
    // true: capture, pyramid, march and effect stayed on the device as one frame, and only the
    // picture and the frame's counters were read back (gpu.frame counts it)
    stats["gpu"]["resident"] = resident;
    stats["gpu"]["frame"] = frameAccount;
    if (r.onDevice) stats["memory_bytes"]["gpu_effect"] = r.deviceBytes;  // the effect's buffers on the GPU
    stats["gpu_renderer"] = gpu->renderer();
  }
  stats["memory_bytes"]["hierarchy"] = built.memoryBytes;
  stats["rays"] = rayStats(r, screen);
  if (exhaustive) stats["rays"]["exhaustive_mismatch"] = exhaustive->mismatches();
  if (o.checkOracle) {
    stats["rays"]["oracle_mismatch"] = oracleCheck->mismatches();
    stats["rays"]["oracle_ambiguous"] = oracleCheck->ambiguous();
  }
  stats["preset"] = o.tracers.preset;
  stats["parameters"] = parameterStats(o.tracers);
  if ((built.pyramid || !built.levelIntervals.empty()) && o.tracer == "hssr") {
    stats["hssr"] = {{"tau", o.tracers.pyramid.tau}, {"levels", o.tracers.pyramid.levels}, {"n_up", o.tracers.hssr.nUp}};
    nlohmann::json perLevel = nlohmann::json::array();
    if (built.pyramid) {
      const IntervalPyramid& p = *built.pyramid;
      uint64_t base = 0;
      for (uint8_t n : p.base->count) base += n;
      perLevel.push_back(base);
      for (size_t l = 1; l < p.levels.size(); ++l) perLevel.push_back(p.levels[l].intervals.size());
    } else {
      for (uint64_t n : built.levelIntervals) perLevel.push_back(n);  // counted on the GPU
    }
    stats["hssr"]["intervals_per_level"] = perLevel;
    // Where the traversal spends its steps (a proxy for time per level: one iteration = one
    // visited cell, and every cell costs about the same).
    nlohmann::json itLevel = nlohmann::json::array();
    for (int l = 0; l < std::min(o.tracers.pyramid.levels, int(RayCounters::kLevels)); ++l)
      itLevel.push_back(r.rays ? double(r.levelIterations[l]) / double(r.rays) : 0.0);
    stats["hssr"]["iterations_per_ray_by_level"] = itLevel;
  }

  if (built.quadtree) stats["quadtree"] = quadtreeStats(*built.quadtree, o.tracers.quadtree, r);
  if (built.known) stats["hybrid"] = hybrid;
  if (built.ldc) stats["ldc"] = ldcStats(*built.ldc, &r);

  std::optional<Image> direct;
  if (ec.effect == Effect::Warp) {
    // The truth of view synthesis: the second camera's own rasterization, shaded with the same
    // lights. Holes are counted where that view sees a surface and the warp found none.
    const Camera second = warpCamera(frame, ec);
    WarpReference ref = warpReference(frame, o.run.frame, ec);
    direct = std::move(ref.image);
    const WarpHoles h = countWarpHoles(ref, r.holes);
    const uint64_t covered = h.covered, holes = h.holes, allHoles = uint64_t(std::count(r.holes.begin(), r.holes.end(), 1));
    const auto [rmse, psnr] = rmsePsnr(r.image, *direct);
    stats["warp"] = {{"eye", worldStats(frame.scene, second.desc().eye)},
                     {"target", worldStats(frame.scene, second.desc().target)},
                     {"covered_pixels", covered},  {"holes", holes},
                     {"hole_fraction", covered ? double(holes) / double(covered) : 0.0},
                     {"holes_total", allHoles},    {"psnr_db", psnr},
                     {"rmse", rmse},
                     {"holes_outside_first_view", h.outside},
                     {"holes_disoccluded", h.disoccluded},
                     {"disocclusion_fraction", h.coveredInside ? double(h.disoccluded) / double(h.coveredInside) : 0.0}};
  }
  std::ostringstream summary;
  summary << "render: " << frame.scene.name << " " << frame.camera.width() << "x" << frame.camera.height() << " " << stats["tracer"].get<std::string>() << " "
          << effectName(ec.effect) << ": " << r.rays << " rays, " << r.hits << " hits, " << stats["rays"]["iterations_mean"].get<double>()
          << " iterations/ray; raster " << frame.rasterMs << " ms, sort " << frame.sortMs << " ms, hierarchy " << built.buildMs
          << " ms, trace " << r.traceMs << " ms, shade " << timed.shadeMs << " ms";
  if (gpu) summary << "; on " << gpu->renderer() << ": GPU trace " << gpuMs << " ms";
  if (exhaustive) summary << "; exhaustive mismatches " << exhaustive->mismatches();
  if (o.checkOracle) summary << "; oracle mismatches " << oracleCheck->mismatches() << " (ambiguous " << oracleCheck->ambiguous() << ")";
  if (direct)
    summary << "; warp holes " << stats["warp"]["holes"].get<uint64_t>() << " of " << stats["warp"]["covered_pixels"].get<uint64_t>()
            << " covered pixels, PSNR " << stats["warp"]["psnr_db"].get<double>() << " dB against the direct view";
  return {std::move(r), std::move(png8), std::move(direct), std::move(stats), summary.str()};
}

int runRender(const RenderOptions& o) {
  const std::string out = o.run.output;
  std::string ext = fs::path(out).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext != ".png" && ext != ".exr") inputError("-o ", out, ": render writes .png or .exr");
  RenderOptions options = o;
  options.png8 = ext == ".png";
  const RenderOutput rendered = renderFrame(options);
  if (!o.run.pixelStats.empty()) writePixelStats(o.run.pixelStats, rendered.result);
  if (fs::path(out).has_parent_path()) ensureDirectory(fs::path(out).parent_path().string(), "-o");
  if (!rendered.png8.empty()) writePngBytes(out, rendered.stats["width"].get<int>(), rendered.stats["height"].get<int>(), 3, rendered.png8.data());
  else writeImage(out, rendered.result.image);
  if (rendered.direct)
    writeImage((fs::path(out).parent_path() / (fs::path(out).stem().string() + "_direct" + ext)).string(), *rendered.direct);
  writeStats(o.run.statsPath, rendered.stats.dump(2));
  if (!o.run.quiet) std::cout << rendered.summary << "\n  wrote " << out << "\n";
  return 0;
}

}  // namespace lt
