// `layertrace bench --experiment NAME`: Hofmann et al. 2017, §6's measurements on the user's scene.
//   stride      SSR trace time and false-miss rate at strides 1–8 against HSSR and Hi-Z (Figures 10–12)
//   layers      construction time by stage for k = 1…8 (Figure 8)
//   memory      bytes by stage at 720p and 1080p (Figure 9)
//   tau         hierarchy build and trace time for τ from 1 to 128 (Figure 14)
//   resolution  cost from 640×360 to 3840×2160
//   threads     scaling from 1 thread to all cores
//   capture     raster, sort, pyramid (after the pass, and merged per tile) per thread count
//               against Embree all-hit capture of the same
//               pixel-centre rays (Embree with plain scene flags and a geometry filter)
//   warp        view synthesis (Widmer et al. 2015): holes and PSNR against the second camera's own view for
//               offsets of 0–20 % of the eye–target distance × k ∈ {1, 2, 4} × every screen tracer
//   gamma       the quad-tree's merge thresholds γ_norm × γ_dist (Widmer et al. 2015 give none): plane
//               nodes, trace time, strict classes and answers changed against no merging
//   ldc         the layered depth cube (Bürger et al. 2007) at 512² and 1K² with blocks of 4, 8, 16 texels
//               and 1 (the paper's min/max) or 4 intervals per block: construction vs tracing time
//               (Bürger et al. 2007, Table 1), memory, strict classes, beside plain Embree and HSSR on the same rays
//   simd        the vector loops on every vector target this CPU runs (AVX-512, AVX2, SSE4, scalar):
//               capture, pyramid build, HSSR trace and grid traversal, each against the best target and
//               against plain Embree on the same rays
//   frame       --frames frames of one effect (--effect, --tracer) along an orbit of the camera, as a
//               renderer draws them: on --device gpu the whole frame stays on the device, and every
//               frame is counted (wall and GPU ms, bytes each way, host waits, links, allocations,
//               dispatches, draws); DIR/frame.json holds the frames and their summary
// Every time is the median of --repeat runs on the same rays; results carry the machine, the
// build type and the date, and go to DIR/NAME.csv, DIR/NAME.json and DIR/NAME.png.
#include <algorithm>
#include <array>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <thread>

#include <unistd.h>

#include <tbb/global_control.h>

#include "layertrace/app/commands.h"
#include "layertrace/scene/surface.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/app/report.h"
#include "layertrace/render/frame_sequence.h"
#include "layertrace/eval/classify.h"
#include "layertrace/eval/image_metrics.h"
#include "layertrace/eval/oracle_observer.h"
#include "layertrace/eval/verify_layers.h"
#include "layertrace/util/error.h"
#include "layertrace/util/simd_targets.h"
#include "layertrace/util/timing.h"

#ifndef LAYERTRACE_TOOLS_DIR
#define LAYERTRACE_TOOLS_DIR "tools"
#endif
#ifndef LAYERTRACE_BUILD_TYPE
#define LAYERTRACE_BUILD_TYPE "unknown"
#endif

namespace lt {
namespace fs = std::filesystem;

std::string machine() { return machineName(); }

std::string today() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

bool runPlotScript(const std::string& scriptName, const nlohmann::json& data, const std::string& outName,
                   const std::function<void(const fs::path& scratch)>& collect) {
  const std::string script = std::string(LAYERTRACE_TOOLS_DIR) + "/" + scriptName;
  const fs::path scratch = fs::temp_directory_path() / cat("layertrace-plot-", ::getpid());
  bool plotted = false;
  std::error_code fsError;
  if (fs::exists(script) && fs::create_directories(scratch, fsError)) {
    std::ofstream((scratch / "plot.json").string()) << data.dump(2) << "\n";
    // Debian's interpreter first: python3-matplotlib is installed for it.
    const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
    const std::string cmd = python + " '" + script + "' '" + (scratch / "plot.json").string() + "' '" + (scratch / outName).string() +
                            "' >/dev/null 2>&1";
    plotted = std::system(cmd.c_str()) == 0 && fs::exists(scratch / outName);
    if (plotted) collect(scratch);
  }
  fs::remove_all(scratch, fsError);
  return plotted;
}

std::string fileBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

namespace {

/// A table of rows with named columns, written as CSV and JSON.
struct Table {
  std::vector<std::string> columns;
  std::vector<std::vector<nlohmann::json>> rows;
  std::string csv() const {
    std::ostringstream s;
    for (size_t i = 0; i < columns.size(); ++i) s << (i ? "," : "") << columns[i];
    s << "\n";
    for (const auto& r : rows) {
      for (size_t i = 0; i < r.size(); ++i) s << (i ? "," : "") << (r[i].is_string() ? r[i].get<std::string>() : r[i].dump());
      s << "\n";
    }
    return s.str();
  }
  nlohmann::json json() const {
    nlohmann::json a = nlohmann::json::array();
    for (const auto& r : rows) {
      nlohmann::json o;
      for (size_t i = 0; i < r.size(); ++i) o[columns[i]] = r[i];
      a.push_back(o);
    }
    return a;
  }
};

class Progress {
 public:
  Progress(bool quiet, std::string name, int total) : quiet_(quiet), name_(std::move(name)), total_(total) {}
  void step(const std::string& what) {
    if (!quiet_) std::cerr << "\r" << name_ << ": " << ++done_ << "/" << total_ << " " << what << "          " << std::flush;
  }
  ~Progress() {
    if (!quiet_ && done_) std::cerr << "\n";
  }

 private:
  bool quiet_;
  std::string name_;
  int total_, done_ = 0;
};

struct Classified {
  double traceMs = 0.0, iterations = 0.0, falseMiss = 0.0, correctHit = 0.0, infoMiss = 0.0, wrongHit = 0.0, correctMiss = 0.0;
};

/// Median trace time of `tracer` over the effect's rays, plus (optionally) its classification:
/// the counted pass, then the timed ones (measureTrace), as render and compare measure.
Classified measure(const Frame& frame, const Tracer& tracer, const EffectConfig& ec, int repeat, const Tracer* reference) {
  Classified c;
  ClassifyObserver classes(reference ? *reference : tracer, frame.camera, frame.layers);
  const EffectResult r = renderEffect(frame, tracer, ec, reference ? &classes : nullptr);
  c.traceMs = measureTrace(frame, tracer, ec, repeat).traceMs;
  c.iterations = r.rays ? double(r.iterationSum) / double(r.rays) : 0.0;
  if (reference) {
    const auto counts = classes.counts();
    const double n = double(std::max<uint64_t>(r.rays, 1));
    c.falseMiss = double(counts[size_t(RayClass::FalseMiss)]) / n;
    c.correctHit = double(counts[size_t(RayClass::CorrectHit)]) / n;
    c.infoMiss = double(counts[size_t(RayClass::InfoMiss)]) / n;
    c.correctMiss = double(counts[size_t(RayClass::CorrectMiss)]) / n;
    for (int k = 0; k < kRayClasses; ++k)
      if (isWrongHit(RayClass(k))) c.wrongHit += double(counts[size_t(k)]) / n;
  }
  return c;
}

}  // namespace

int runBench(const BenchOptions& o) {
  static const char* kExperiments[] = {"stride", "layers", "tau", "memory", "resolution", "threads", "warp", "capture", "gamma", "ldc", "stages", "peel", "simd", "textures", "frame"};
  if (std::find_if(std::begin(kExperiments), std::end(kExperiments), [&](const char* e) { return o.experiment == e; }) ==
      std::end(kExperiments))
    inputError("--experiment ", o.experiment.empty() ? "(none)" : o.experiment,
               ": unknown (use stride, layers, tau, memory, resolution, threads, warp, capture, gamma, ldc, stages, peel, simd, textures, frame)");
  if (o.run.device == "gpu" && o.experiment != "stages" && o.experiment != "peel" && o.experiment != "frame")
    inputError("--device gpu: bench measures the GPU with --experiment stages, peel or frame, not ", o.experiment);
  if (o.frames < 1) inputError("--frames ", o.frames, ": must be at least 1");
  // The device before the scene: a machine without one is told at once.
  std::shared_ptr<GpuContext> gpu;
  if (o.run.device == "gpu") gpu = openGpu();
  validateRepeat(o.repeat);
  validateTracerOptions(o.options);
  validateEffectConfig(o.effect);
  const std::string outDir = o.run.output;
  EffectConfig ec = o.effect;
  ec.seed = o.run.seed;

  Frame frame;
  loadFrameScene(o.run.frame, frame);
  Table t;
  const std::string& e = o.experiment;
  if (e == "stride") {
    rasterizeFrame(o.run.frame, frame);
    const BuiltTracer ref = buildReference(frame);
    t.columns = {"tracer", "stride", "trace_ms", "iterations_mean", "false_miss", "correct_hit", "relative_trace"};
    Progress p(o.run.quiet, e, 11);
    const BuiltTracer hssr = buildTracer("hssr", frame, o.options);
    p.step("hssr");
    const Classified h = measure(frame, *hssr.tracer, ec, o.repeat, ref.tracer.get());
    std::vector<std::vector<nlohmann::json>> rows;
    double stride1 = 0.0;
    for (int s = 1; s <= 8; ++s) {
      p.step(cat("ssr-layers stride ", s));
      TracerOptions to = o.options;
      to.ssr.stride = float(s);
      const BuiltTracer b = buildTracer("ssr-layers", frame, to);
      const Classified c = measure(frame, *b.tracer, ec, o.repeat, ref.tracer.get());
      if (s == 1) stride1 = c.traceMs;
      rows.push_back({"ssr-layers", s, c.traceMs, c.iterations, c.falseMiss, c.correctHit, 0.0});
    }
    rows.push_back({"hssr", 1, h.traceMs, h.iterations, h.falseMiss, h.correctHit, 0.0});
    p.step("hiz");
    const BuiltTracer hiz = buildTracer("hiz", frame, o.options);
    const Classified z = measure(frame, *hiz.tracer, ec, o.repeat, ref.tracer.get());
    rows.push_back({"hiz", 1, z.traceMs, z.iterations, z.falseMiss, z.correctHit, 0.0});
    p.step("quadtree");
    const BuiltTracer quad = buildTracer("quadtree", frame, o.options);
    const Classified q = measure(frame, *quad.tracer, ec, o.repeat, ref.tracer.get());
    rows.push_back({"quadtree", 1, q.traceMs, q.iterations, q.falseMiss, q.correctHit, 0.0});
    for (auto& r : rows) r[6] = r[2].get<double>() / stride1;  // normalised to SSR stride 1 (Figure 12)
    t.rows = rows;
  } else if (e == "layers") {
    t.columns = {"k", "raster_ms", "sort_ms", "hierarchy_ms", "fragments"};
    Progress p(o.run.quiet, e, 8);
    for (int k = 1; k <= 8; ++k) {
      p.step(cat("k = ", k));
      FrameOptions fo = o.run.frame;
      fo.layers = k;
      double raster = 0.0, sort = 0.0, hier = 0.0;
      std::vector<double> rs, ss, hs;
      rasterizeFrame(fo, frame);  // warm-up, discarded
      for (int i = 0; i < o.repeat; ++i) {
        rasterizeFrame(fo, frame);
        rs.push_back(frame.rasterMs), ss.push_back(frame.sortMs);
        hs.push_back(buildIntervalPyramid(frame.layers, frame.camera, o.options.pyramid).buildMs);
      }
      raster = median(rs), sort = median(ss), hier = median(hs);
      t.rows.push_back({k, raster, sort, hier, frame.lists.generated});
    }
  } else if (e == "memory") {
    t.columns = {"resolution", "lists_bytes", "arrays_bytes", "hierarchy_bytes", "total_bytes", "depth_complexity_mean"};
    Progress p(o.run.quiet, e, 2);
    for (auto [w, h] : {std::pair{1280, 720}, std::pair{1920, 1080}}) {
      p.step(cat(w, "x", h));
      FrameOptions fo = o.run.frame;
      fo.width = w, fo.height = h;
      Frame f;
      loadFrameScene(fo, f);
      rasterizeFrame(fo, f);
      const IntervalPyramid pyr = buildIntervalPyramid(f.layers, f.camera, o.options.pyramid);
      const size_t lists = f.lists.memoryBytes(), arrays = f.layers.memoryBytes(), hier = pyr.memoryBytes();
      t.rows.push_back({cat(w, "x", h), lists, arrays, hier, lists + arrays + hier, double(f.lists.generated) / double(w * h)});
    }
  } else if (e == "tau") {
    rasterizeFrame(o.run.frame, frame);
    t.columns = {"tau", "hierarchy_ms", "trace_ms", "iterations_mean", "intervals_level1"};
    const float taus[] = {1, 2, 4, 8, 16, 25, 32, 64, 128};
    Progress p(o.run.quiet, e, 9);
    for (float tau : taus) {
      p.step(cat("tau ", tau));
      TracerOptions to = o.options;
      to.pyramid.tau = tau;
      IntervalPyramid pyr;
      const double build = medianMs(o.repeat, [&] { pyr = buildIntervalPyramid(frame.layers, frame.camera, to.pyramid); });
      HssrConfig hc = to.hssr;
      hc.maxLevels = to.pyramid.levels;
      const HssrTracer tr(frame.camera, frame.layers, pyr, hc);
      const Classified c = measure(frame, tr, ec, o.repeat, nullptr);
      t.rows.push_back({tau, build, c.traceMs, c.iterations, pyr.levels.size() > 1 ? pyr.levels[1].intervals.size() : 0});
    }
  } else if (e == "resolution") {
    t.columns = {"resolution", "pixels", "raster_ms", "sort_ms", "hierarchy_ms", "trace_hssr_ms", "trace_ssr_layers_ms", "fragments"};
    const std::pair<int, int> sizes[] = {{640, 360}, {1280, 720}, {1920, 1080}, {2560, 1440}, {3840, 2160}};
    Progress p(o.run.quiet, e, 5);
    for (auto [w, h] : sizes) {
      p.step(cat(w, "x", h));
      FrameOptions fo = o.run.frame;
      fo.width = w, fo.height = h;
      Frame f;
      loadFrameScene(fo, f);
      std::vector<double> rs, ss;
      rasterizeFrame(fo, f);  // warm-up, discarded
      for (int i = 0; i < o.repeat; ++i) rasterizeFrame(fo, f), rs.push_back(f.rasterMs), ss.push_back(f.sortMs);
      const BuiltTracer hs = buildTracer("hssr", f, o.options);
      const double hier = medianMs(o.repeat, [&] { buildIntervalPyramid(f.layers, f.camera, o.options.pyramid); });
      const BuiltTracer sl = buildTracer("ssr-layers", f, o.options);
      const Classified a = measure(f, *hs.tracer, ec, o.repeat, nullptr), b = measure(f, *sl.tracer, ec, o.repeat, nullptr);
      t.rows.push_back({cat(w, "x", h), w * h, median(rs), median(ss), hier, a.traceMs, b.traceMs, f.lists.generated});
    }
  } else if (e == "threads") {
    t.columns = {"threads", "raster_ms", "sort_ms", "hierarchy_ms", "trace_hssr_ms", "speedup_trace"};
    const int maxThreads = int(std::thread::hardware_concurrency());
    Progress p(o.run.quiet, e, maxThreads);
    double one = 0.0;
    for (int n = 1; n <= maxThreads; ++n) {
      p.step(cat(n, " threads"));
      tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(n));
      std::vector<double> rs, ss;
      rasterizeFrame(o.run.frame, frame);  // warm-up, discarded
      for (int i = 0; i < o.repeat; ++i) rasterizeFrame(o.run.frame, frame), rs.push_back(frame.rasterMs), ss.push_back(frame.sortMs);
      const double hier = medianMs(o.repeat, [&] { buildIntervalPyramid(frame.layers, frame.camera, o.options.pyramid); });
      const BuiltTracer hs = buildTracer("hssr", frame, o.options);
      const Classified a = measure(frame, *hs.tracer, ec, o.repeat, nullptr);
      if (n == 1) one = a.traceMs;
      t.rows.push_back({n, median(rs), median(ss), hier, a.traceMs, one / a.traceMs});
    }
  }

  if (e == "capture") {
    // The pipelines on the same view: "tiles" (rasterize and sort to k in one tile-local pass,
    // the default), "tiles+lists" (the same pass also writing exact-size lists, as --verify
    // needs) and "reference" (every fragment linked into lists in a pool, then sorted). Each
    // row: warm-up discarded, medians of --repeat.
    t.columns = {"pipeline", "threads", "raster_ms", "sort_ms", "capture_ms", "pyramid_ms", "pyramid_per_tile_ms", "fragments", "mfragments_per_s",
                 "embree_allhit_ms", "embree_hits", "capture_speedup_vs_embree", "lists_bytes", "arrays_bytes", "pyramid_bytes",
                 "scratch_bytes"};
    const EmbreeScene embree(frame.scene, EmbreeScene::Mode::Capture);
    std::vector<int> counts{1};
    if (std::thread::hardware_concurrency() > 1) counts.push_back(int(std::thread::hardware_concurrency()));
    Progress p(o.run.quiet, e, int(counts.size()) * 3);
    for (int n : counts) {
      tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(n));
      uint64_t hits = 0;
      const double allHit = medianMs(o.repeat, [&] { hits = embreeCapture(frame.camera, embree); });
      for (const char* pipeline : {"tiles", "tiles+lists", "reference"}) {
        p.step(cat(pipeline, ", ", n, " threads"));
        FrameOptions fo = o.run.frame;
        fo.captureLists = std::string(pipeline) == "tiles+lists";
        fo.referenceCapture = std::string(pipeline) == "reference";
        const bool tiles = std::string(pipeline) == "tiles";
        // "tiles" also runs alternately with the pass merging levels 1… per tile
        // (FrameOptions::pyramidPerTile); that pyramid's cost is the difference of the two
        // medians — its marginal wall time. (IntervalPyramid::buildMs, the merges' own time,
        // misses that the merges and the rasterizer evict each other's cache lines: at one
        // thread it said 8.6 ms where the pass grew by 16.5 ms on FZK-Haus.)
        FrameOptions perTile = fo;
        perTile.pyramid = o.options.pyramid, perTile.pyramidPerTile = true;
        std::vector<double> rs, ss, ps;
        rasterizeFrame(fo, frame);  // warm-up, discarded
        if (tiles) rasterizeFrame(perTile, frame);
        for (int i = 0; i < o.repeat; ++i) {
          rasterizeFrame(fo, frame), rs.push_back(frame.rasterMs), ss.push_back(frame.sortMs);
          if (tiles) rasterizeFrame(perTile, frame), ps.push_back(frame.rasterMs + frame.pyramid->buildMs);
        }
        const double capture = median(rs) + median(ss);
        const double pyramidPerTile = tiles ? std::max(0.0, median(ps) - median(rs)) : 0.0;
        size_t scratchBytes = frame.capture.scratchBytes() + (tiles ? frame.pyramidTiles.scratchBytes() : 0);
        // The pyramid as the commands build it by default: levels 1… over the level 0 the
        // capture wrote (inside capture_ms), rebuilt into the same memory, as frame after frame
        // (after the per-tile variant, one more plain capture leaves the frame as fo makes it).
        if (tiles) rasterizeFrame(fo, frame);
        IntervalPyramid pyr;
        buildIntervalPyramid(frame.level0(), frame.camera, o.options.pyramid, pyr);  // warm-up, discarded
        const double pyramid = medianMs(o.repeat, [&] { buildIntervalPyramid(frame.level0(), frame.camera, o.options.pyramid, pyr); });
        const size_t pyramidBytes = pyr.memoryBytes();
        t.rows.push_back({pipeline, n, median(rs), median(ss), capture, pyramid, pyramidPerTile, frame.lists.generated,
                          double(frame.lists.generated) / capture * 1e-3, allHit, hits, allHit / capture, frame.lists.memoryBytes(),
                          frame.layers.memoryBytes(), pyramidBytes, scratchBytes});
      }
    }
  }
  if (e == "textures") {
    // What texturing costs: the same view with the scene's textures (sampled per fragment in the
    // capture and per hit in the reference, alpha tests in both) and with each texture replaced
    // by its mean colour (--textures off). Capture: warm-up discarded, medians of --repeat;
    // reference: Embree's trace of the effect's rays with its hits' shading inputs (measureTrace).
    if (!o.run.frame.textures) inputError("--experiment textures: compares --textures on with off itself (leave --textures on)");
    t.columns = {"textures", "capture_ms", "fragments", "reference_trace_ms", "capture_vs_off", "reference_vs_off", "texture_bytes",
                 "textured_materials", "cut_out_materials"};
    Progress p(o.run.quiet, e, 2);
    for (const bool on : {true, false}) {
      p.step(on ? "textures on" : "textures off");
      FrameOptions fo = o.run.frame;
      fo.textures = on;
      Frame f;
      loadFrameScene(fo, f);
      std::vector<double> cs;
      rasterizeFrame(fo, f);  // warm-up, discarded
      for (int i = 0; i < o.repeat; ++i) rasterizeFrame(fo, f), cs.push_back(f.rasterMs + f.sortMs);
      const BuiltTracer ref = buildReference(f);
      const double refMs = measureTrace(f, *ref.tracer, ec, o.repeat).traceMs;
      size_t textured = 0, cut = 0;
      for (const Material& m : f.scene.materials) {
        const uint8_t flags = surfaceFlags(f.scene, m);
        textured += (flags & kSurfaceSampled) != 0, cut += (flags & kSurfaceCutOut) != 0;
      }
      t.rows.push_back({on ? "on" : "off", median(cs), f.lists.generated, refMs, 0.0, 0.0, f.scene.textureBytes(), textured, cut});
    }
    for (auto& r : t.rows) {
      r[4] = r[1].get<double>() / t.rows[1][1].get<double>();
      r[5] = r[3].get<double>() / t.rows[1][3].get<double>();
    }
  }
  if (e == "gamma") {
    rasterizeFrame(o.run.frame, frame);
    const BuiltTracer ref = buildReference(frame);
    TracerOptions none = o.options;
    none.quadtree.gammaNorm = 0.0f, none.quadtree.gammaDist = 0.0f;  // strict "<": nothing merges
    const BuiltTracer unmerged = buildTracer("quadtree", frame, none);
    t.columns = {"gamma_norm", "gamma_dist", "plane_nodes_above_level0", "trace_ms", "iterations_mean", "correct_hit", "false_miss",
                 "changed_vs_unmerged"};
    std::vector<std::pair<float, float>> settings{{0.0f, 0.0f}};
    for (float norm : {1e-5f, 1e-4f, 1e-3f, 1e-2f})
      for (float dist : {1e-6f, 1e-5f, 1e-4f, 1e-3f}) settings.push_back({norm, dist});
    Progress p(o.run.quiet, e, int(settings.size()));
    for (auto [norm, dist] : settings) {
      p.step(cat("gamma_norm ", norm, ", gamma_dist ", dist));
      TracerOptions to = o.options;
      to.quadtree.gammaNorm = norm, to.quadtree.gammaDist = dist;
      const BuiltTracer b = buildTracer("quadtree", frame, to);
      uint64_t planes = 0;
      for (size_t l = 1; l < b.quadtree->kindCounts.size(); ++l) planes += b.quadtree->kindCounts[l][QuadNode::Plane];
      const Classified c = measure(frame, *b.tracer, ec, o.repeat, ref.tracer.get());
      MismatchObserver changed(*unmerged.tracer);
      const EffectResult r = renderEffect(frame, *b.tracer, ec, &changed);
      t.rows.push_back({norm, dist, planes, c.traceMs, c.iterations, c.correctHit, c.falseMiss,
                        double(changed.mismatches()) / double(std::max<uint64_t>(r.rays, 1))});
    }
  }
  if (e == "ldc") {
    rasterizeFrame(o.run.frame, frame);
    const BuiltTracer ref = buildReference(frame);
    t.columns = {"tracer", "resolution", "block", "block_intervals", "build_ms", "trace_ms", "memory_bytes", "samples",
                 "lost_triangles", "correct_hit", "correct_miss", "wrong_hit", "false_miss", "info_miss", "trace_vs_embree"};
    struct Setting {
      int resolution, block, intervals;
    };
    std::vector<Setting> settings;
    for (int res : {512, 1024})
      for (Setting s : {Setting{res, 4, 4}, Setting{res, 8, 4}, Setting{res, 16, 4}, Setting{res, 8, 1}}) settings.push_back(s);
    Progress p(o.run.quiet, e, int(settings.size()) + 2);
    // The baselines on the same rays: plain Embree (speed claims) and HSSR with its capture.
    p.step("embree");
    const BuiltTracer embree = buildTracer("embree", frame, o.options);
    const Classified em = measure(frame, *embree.tracer, ec, o.repeat, ref.tracer.get());
    t.rows.push_back({"embree", 0, 0, 0, embree.buildMs, em.traceMs, embree.memoryBytes, 0, 0, em.correctHit, em.correctMiss,
                      em.wrongHit, em.falseMiss, em.infoMiss, 1.0});
    p.step("hssr");
    const BuiltTracer hssr = buildTracer("hssr", frame, o.options);
    const Classified hs = measure(frame, *hssr.tracer, ec, o.repeat, ref.tracer.get());
    t.rows.push_back({"hssr", 0, 0, 0, frame.rasterMs + frame.sortMs + hssr.buildMs, hs.traceMs,
                      frame.lists.memoryBytes() + frame.layers.memoryBytes() + hssr.memoryBytes, frame.lists.generated, 0, hs.correctHit,
                      hs.correctMiss, hs.wrongHit, hs.falseMiss, hs.infoMiss, hs.traceMs / em.traceMs});
    for (const Setting& s : settings) {
      p.step(cat("ldc ", s.resolution, " block ", s.block, " intervals ", s.intervals));
      TracerOptions to = o.options;
      to.ldc.resolution = s.resolution, to.ldc.block = s.block, to.ldc.blockIntervals = s.intervals;
      std::vector<double> builds;
      BuiltTracer b = buildTracer("ldc", frame, to);  // warm-up, discarded
      for (int i = 0; i < o.repeat; ++i) {
        b = buildTracer("ldc", frame, to);
        builds.push_back(b.buildMs);
      }
      const Classified c = measure(frame, *b.tracer, ec, o.repeat, ref.tracer.get());
      t.rows.push_back({"ldc", s.resolution, s.block, s.intervals, median(builds), c.traceMs, b.memoryBytes, b.ldc->samples(),
                        b.ldc->lostTriangles(), c.correctHit, c.correctMiss, c.wrongHit, c.falseMiss, c.infoMiss, c.traceMs / em.traceMs});
    }
  }
  if (e == "warp") {
    t.columns = {"tracer", "k", "offset", "hole_fraction", "holes", "covered_pixels", "disocclusion_fraction", "holes_disoccluded",
                 "holes_outside_first_view", "psnr_db", "trace_ms"};
    const float offsets[] = {0.0f, 0.025f, 0.05f, 0.1f, 0.2f};
    const char* tracers[] = {"ssr", "ssr-layers", "hiz", "hssr", "quadtree"};
    const int ks[] = {1, 2, 4};
    Progress p(o.run.quiet, e, 3 * 5);
    std::vector<WarpReference> refs;
    std::vector<EffectConfig> warps;
    for (float offset : offsets) {
      // The second eye moves sideways (the first camera's right) by `offset` of the eye–target distance.
      EffectConfig w = ec;
      w.effect = Effect::Warp;
      const CameraDesc& d = frame.camera.desc();
      w.warpEye = frame.scene.toWorld(d.eye + glm::normalize(frame.camera.dirToWorld({1, 0, 0})) * (offset * glm::length(d.target - d.eye)));
      w.warpTarget = frame.scene.toWorld(d.target);
      refs.push_back(warpReference(frame, o.run.frame, w));
      warps.push_back(w);
    }
    for (int k : ks) {
      FrameOptions fo = o.run.frame;
      fo.layers = k;
      Frame f;
      loadFrameScene(fo, f);
      rasterizeFrame(fo, f);
      for (const char* name : tracers) {
        p.step(cat("k = ", k, ", ", name));
        const BuiltTracer b = buildTracer(name, f, o.options);  // the structure depends on k, not on the offset
        for (size_t i = 0; i < warps.size(); ++i) {
          EffectConfig w = warps[i];
          w.countRays = false;
          EffectResult r = renderEffect(f, *b.tracer, w);  // warm-up, discarded
          std::vector<double> times;
          for (int rep = 0; rep < o.repeat; ++rep) r = renderEffect(f, *b.tracer, w), times.push_back(r.traceMs);
          const WarpHoles h = countWarpHoles(refs[i], r.holes);
          t.rows.push_back({name, k, offsets[i], h.covered ? double(h.holes) / double(h.covered) : 0.0, h.holes, h.covered,
                            h.coveredInside ? double(h.disoccluded) / double(h.coveredInside) : 0.0, h.disoccluded, h.outside,
                            rmsePsnr(r.image, refs[i].image).second, median(times)});
        }
      }
    }
  }

  if (e == "stages") {
    // Every stage of a frame on the chosen device, medians of --repeat after a warm-up: capture
    // (raster, sort), the hierarchy, and the trace of each screen tracer over the same rays, with
    // plain Embree on the CPU over those rays as the baseline. On the GPU the times are GL timer
    // queries of the device's work, ray generation and shading included where the effect runs
    // on the device (shade_device "gpu"; render/effects.h EffectConfig::shadeOnDevice). There
    // ssr, ssr-layers, hiz and hssr run as resident frames (gpu/gpu_frame.h), each row timing its
    // own capture; the other tracers build over the capture read back once.
    t.columns = {"device", "tracer", "stride", "persistent", "raster_ms", "sort_ms", "hierarchy_ms", "trace_ms", "shade_ms", "shade_device", "iterations_mean",
                 "memory_bytes", "effect_bytes", "embree_trace_ms", "trace_vs_embree"};
    Progress p(o.run.quiet, e, gpu ? 12 : 11);
    p.step("capture");
    std::vector<double> rs, ss;
    auto capture = [&] {
      if (gpu) rasterizeFrameOnGpu(*gpu, o.run.frame, "lists", frame);
      else rasterizeFrame(o.run.frame, frame);
    };
    capture();  // warm-up, discarded
    for (int i = 0; i < o.repeat; ++i) capture(), rs.push_back(frame.rasterMs), ss.push_back(frame.sortMs);
    const size_t captureBytes = gpu ? frame.gpuMemoryBytes : frame.layers.memoryBytes();
    p.step("embree");
    const BuiltTracer embree = buildTracer("embree", frame, o.options);
    const double embreeMs = measure(frame, *embree.tracer, ec, o.repeat, nullptr).traceMs;
    const std::string device = o.run.device;  // the renderer string is in gpu_renderer
    struct Run {
      const char* name;
      float stride;
      bool persistent;
    };
    std::vector<Run> runs = {{"ssr", 1.0f, false}, {"ssr", 4.0f, false}, {"ssr-layers", 1.0f, false}, {"hiz", 1.0f, false}, {"hssr", 1.0f, false},
                             {"quadtree", 1.0f, false}, {"ldc", 1.0f, false}, {"grid", 1.0f, false}, {"hybrid", 1.0f, false}};
    // Hofmann et al. 2017, §5.3 and Fig. 7: HSSR with persistent threads reloading rays.
    if (gpu) runs.push_back({"hssr", 1.0f, true});
    for (const auto& [name, stride, persistent] : runs) {
      p.step(cat(name, " stride ", stride, persistent ? " persistent" : ""));
      TracerOptions to = o.options;
      to.ssr.stride = stride;
      if (gpu && (isGpuFrameTracer(name) || std::string_view(name) == "quadtree")) {
        // The resident frame: every stage on the device, nothing read back between them; its
        // own capture's times (hierarchy: the layer arrays and the pyramid, or the quad-tree
        // built from them). The cube and the grid, structures of the scene built once, are
        // timed below with their build.
        to.hssr.rayReloading = persistent;
        const ResidentStages r = measureResidentStages(o.run.frame, frame, name, to, ec, o.repeat, *gpu);
        t.rows.push_back({device, name, stride, persistent, r.rasterMs, r.sortMs, r.layersMs + r.pyramidMs, r.traceMs, r.shadeMs, "gpu",
                          r.iterationsMean, r.memoryBytes, r.effectBytes, embreeMs, r.traceMs > 0.0 ? embreeMs / r.traceMs : 0.0});
        continue;
      }
      auto build = [&] { return gpu ? buildGpuTracer(name, frame, to, *gpu) : buildTracer(name, frame, to); };
      std::vector<double> hs;
      BuiltTracer b = build();  // warm-up, discarded
      for (int i = 0; i < o.repeat; ++i) b = build(), hs.push_back(b.buildMs);
      setGpuPersistentThreads(*b.tracer, persistent);
      EffectConfig timing = ec;
      timing.countRays = false;
      timing.wholeWaves = timing.shadeOnDevice = gpu != nullptr;
      std::vector<double> trace, shade;
      bool onDevice = false;
      renderEffect(frame, *b.tracer, timing);  // warm-up, discarded
      for (int i = 0; i < o.repeat; ++i) {
        const double before = gpuTraceMs(*b.tracer);
        const EffectResult r = renderEffect(frame, *b.tracer, timing);
        trace.push_back(gpu && !r.onDevice ? gpuTraceMs(*b.tracer) - before : r.traceMs);
        shade.push_back(r.shadeMs);
        onDevice = r.onDevice;
      }
      EffectConfig counted = ec;
      counted.wholeWaves = counted.shadeOnDevice = gpu != nullptr;
      const EffectResult c = renderEffect(frame, *b.tracer, counted);
      const double ms = median(trace);
      t.rows.push_back({device, name, stride, persistent, median(rs), median(ss), median(hs), ms, median(shade), onDevice ? "gpu" : "cpu",
                        c.rays ? double(c.iterationSum) / double(c.rays) : 0.0, captureBytes + b.memoryBytes, c.deviceBytes, embreeMs,
                        ms > 0.0 ? embreeMs / ms : 0.0});
    }
  } else if (e == "peel") {
    // Hofmann et al. 2017, Fig. 8: the construction of k layers from per-pixel lists (one
    // geometry pass into a pool, then the sort) against depth peeling (a geometry pass per layer
    // on the CPU, a pass pair on the GPU), for k = 1…8; medians of --repeat after a warm-up. On
    // the GPU, GPU milliseconds (timer queries); on the CPU, wall time, and the lists are the
    // reference pipeline (the tile-local capture sorts while it rasterizes: not the paper's
    // construction).
    t.columns = {"k", "lists_raster_ms", "lists_sort_ms", "lists_ms", "peel_raster_ms", "peel_resolve_ms", "peel_ms", "peel_vs_lists",
                 "lists_bytes", "peel_bytes", "fragments"};
    Progress p(o.run.quiet, e, 8);
    for (int k = 1; k <= 8; ++k) {
      p.step(cat("k = ", k));
      FrameOptions fo = o.run.frame;
      fo.layers = k;
      double times[2][2];
      size_t bytes[2];
      uint64_t fragments = 0;
      for (int m = 0; m < 2; ++m) {
        const std::string method = m == 0 ? "lists" : "peel";
        std::vector<double> rs, ss;
        FrameOptions mo = fo;
        mo.referenceCapture = m == 0, mo.depthPeeling = m == 1;
        if (gpu) {  // resident frames: the capture stays on the device
          FrameOptions go = fo;
          go.depthPeeling = m == 1;
          const ResidentCapture r = measureResidentCapture(go, frame, o.repeat, *gpu);
          times[m][0] = r.rasterMs, times[m][1] = r.sortMs, bytes[m] = r.bytes;
          if (m == 0) fragments = r.fragments;
          continue;
        }
        rasterizeFrame(mo, frame);  // warm-up, discarded
        for (int i = 0; i < o.repeat; ++i) rasterizeFrame(mo, frame), rs.push_back(frame.rasterMs), ss.push_back(frame.sortMs);
        times[m][0] = median(rs), times[m][1] = median(ss);
        bytes[m] = frame.lists.memoryBytes() + frame.layers.memoryBytes();
        if (m == 0) fragments = frame.lists.generated;
      }
      const double lists = times[0][0] + times[0][1], peel = times[1][0] + times[1][1];
      t.rows.push_back({k, times[0][0], times[0][1], lists, times[1][0], times[1][1], peel, lists > 0.0 ? peel / lists : 0.0, bytes[0],
                        bytes[1], fragments});
    }
  }

  nlohmann::json frames;
  std::vector<std::pair<std::string, Image>> frameImages;
  if (e == "frame") {
    FrameSequenceConfig fc;
    fc.tracer = o.tracer;
    fc.tracers = o.options;
    fc.effect = ec;
    fc.effect.countRays = false;  // a renderer's frame: the counter-free marches
    fc.frames = o.frames;
    if (o.images) fc.onImage = [&](int i, const Image& img) { frameImages.emplace_back(cat("frame_", std::string(4 - std::min<size_t>(4, std::to_string(i).size()), '0'), i, ".png"), img); };
    const std::vector<FrameSample> samples = runFrameSequence(o.run.frame, frame, fc, gpu.get());
    t.columns = {"frame", "wall_ms", "gpu_ms", "capture_ms", "pyramid_ms", "trace_ms", "shade_ms", "upload_bytes", "download_bytes", "host_waits",
                 "program_links", "buffer_allocations", "dispatches", "draws", "rays", "hits", "fragments", "attempts"};
    frames = nlohmann::json::array();
    for (const FrameSample& s : samples) {
      const nlohmann::json j = frameSampleJson(s);
      frames.push_back(j);
      std::vector<nlohmann::json> row;
      for (const std::string& c : t.columns) row.push_back(j[c]);
      t.rows.push_back(row);
    }
    frames = nlohmann::json{{"frames", frames}, {"summary", frameSummary(samples)}, {"tracer", o.tracer}};
  }

  if (e == "simd") {
    // The same frame and rays on each vector target in turn (the lanes restricted to it):
    // capture (raster + sort), the pyramid's levels 1…, HSSR's trace and the grid's traversal;
    // plain Embree on the same rays in the same rounds. A warm-up round, then --repeat rounds,
    // each running every target once (so that a drift of the machine's speed falls on every
    // target alike); medians per target. Speeds are relative to the best target (the first row):
    // best time / this time.
    t.columns = {"target", "lanes", "capture_ms", "pyramid_ms", "hssr_trace_ms", "grid_trace_ms", "embree_trace_ms",
                 "capture_speed_vs_best", "pyramid_speed_vs_best", "hssr_speed_vs_best", "grid_speed_vs_best",
                 "hssr_speed_vs_embree", "grid_speed_vs_embree"};
    const std::vector<SimdTarget> targets = simdTargets();
    rasterizeFrame(o.run.frame, frame);
    const BuiltTracer embree = buildTracer("embree", frame, o.options);
    const BuiltTracer grid = buildTracer("grid", frame, o.options);
    const BuiltTracer hssr = buildTracer("hssr", frame, o.options);
    constexpr int kStages = 5;  // capture, pyramid, hssr, grid, embree
    std::vector<std::array<std::vector<double>, kStages>> times(targets.size());
    IntervalPyramid pyr;
    Frame captured;  // (the capture's own frame: the tracers keep reading `frame`'s layers)
    loadFrameScene(o.run.frame, captured);
    auto wallMs = [](auto&& f) {
      const auto start = std::chrono::steady_clock::now();
      f();
      return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    };
    Progress p(o.run.quiet, e, o.repeat + 1);
    for (int round = 0; round <= o.repeat; ++round) {
      p.step(round == 0 ? std::string("warm-up") : cat("round ", round));
      for (size_t i = 0; i < targets.size(); ++i) {
        const ScopedSimdTarget only(targets[i]);
        rasterizeFrame(o.run.frame, captured);
        const double pyramidMs = wallMs([&] { buildIntervalPyramid(frame.level0(), frame.camera, o.options.pyramid, pyr); });
        const double run[kStages] = {captured.rasterMs + captured.sortMs, pyramidMs, measureTrace(frame, *hssr.tracer, ec, 1).traceMs,
                                     measureTrace(frame, *grid.tracer, ec, 1).traceMs, measureTrace(frame, *embree.tracer, ec, 1).traceMs};
        if (round > 0)
          for (int s = 0; s < kStages; ++s) times[i][size_t(s)].push_back(run[s]);
      }
    }
    double best[kStages] = {};
    auto speed = [](double a, double b) { return b > 0.0 ? a / b : 0.0; };
    for (size_t i = 0; i < targets.size(); ++i) {
      double m[kStages];
      for (int s = 0; s < kStages; ++s) m[s] = median(times[i][size_t(s)]);
      if (i == 0) std::copy(std::begin(m), std::end(m), best);
      t.rows.push_back({targets[i].name, simdLaneCount(targets[i]), m[0], m[1], m[2], m[3], m[4], speed(best[0], m[0]), speed(best[1], m[1]),
                        speed(best[2], m[2]), speed(best[3], m[3]), speed(m[4], m[2]), speed(m[4], m[3])});
    }
  }

  nlohmann::json result;
  result["experiment"] = e;
  result["device"] = o.run.device;
  if (gpu) result["gpu"] = gpuStats(*gpu), result["gpu_renderer"] = gpu->renderer();
  result["scene"] = frame.scene.name;
  result["camera"] = frame.camera.desc().name;
  result["width"] = o.run.frame.width;
  result["height"] = o.run.frame.height;
  result["layers"] = o.run.frame.layers;
  result["effect"] = effectName(ec.effect);
  result["repeat"] = o.repeat;
  result["machine"] = machine();
  result["build_type"] = LAYERTRACE_BUILD_TYPE;
  result["date"] = today();
  result["hssr"] = {{"tau", o.options.pyramid.tau}, {"levels", o.options.pyramid.levels}, {"n_up", o.options.hssr.nUp}};
  result["preset"] = o.options.preset;
  result["parameters"] = parameterStats(o.options);
  result["rows"] = t.json();
  if (e == "frame") {
    result["tracer"] = frames["tracer"];
    result["frames"] = frames["frames"];
    result["summary"] = frames["summary"];
  }

  ensureDirectory(outDir, "-o");
  for (const auto& [name, img] : frameImages) writeImage((fs::path(outDir) / name).string(), img);
  const std::string base = (fs::path(outDir) / e).string();
  writeFileAtomic(base + ".csv", t.csv());
  writeStats(o.run.statsPath, result.dump(2));
  // The plot: python3 + matplotlib (tools/plot_bench.py); a missing Python is not an error. It
  // runs in a scratch folder (the outputs above are staged until the command succeeds), and its
  // PNG is staged beside them.
  ReportPage page;
  page.title = cat("layertrace bench ", e, ": ", frame.scene.name);
  page.table = t.csv();
  page.json = result;
  const bool plotted = runPlotScript("plot_bench.py", result, "plot.png", [&](const fs::path& scratch) {
    writeFileAtomic(base + ".png", fileBytes(scratch / "plot.png"));
    page.files.push_back({e + ".png", (scratch / "plot.png").string()});
    if (!o.report.empty()) writeReport(o.report, page);  // while the plot is still there to inline
  });
  if (!plotted && !o.report.empty()) writeReport(o.report, page);
  if (!o.run.quiet) {
    std::cout << "bench " << e << ": " << frame.scene.name << " (" << machine() << ", " << LAYERTRACE_BUILD_TYPE << ")\n"
              << t.csv() << "  wrote " << base << ".csv, .json" << (plotted ? ", .png" : " (no plot: python3/matplotlib missing)")
              << "\n";
  }
  return 0;
}

}  // namespace lt
