#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include <tbb/enumerable_thread_specific.h>

#include "layertrace/app/commands.h"
#include "layertrace/app/report.h"
#include "layertrace/eval/classify.h"
#include "layertrace/eval/image_metrics.h"
#include "layertrace/eval/image_oracle.h"
#include "layertrace/eval/oracle_observer.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/pipeline/gpu_tracers.h"
#include "layertrace/render/frame_sequence.h"
#if LAYERTRACE_HAS_GPU
#include "layertrace/gpu/gpu_frame.h"
#endif
#include "layertrace/util/error.h"

namespace lt {
namespace fs = std::filesystem;

namespace {

/// Every ray a pass traced, with the answer (screen tracers: the hit fragment), for tracing the
/// same rays again on the GPU.
/// Every traced ray with its answer and its query (closest or any hit), from every thread.
struct RecordedRay {
  Ray ray;
  TraceHit hit;
  Query query;
};
class RayRecorder : public RayObserver {
 public:
  void observe(std::span<const RayEvent> events) override {
    auto& mine = perThread_.local();
    for (const RayEvent& e : events) mine.push_back({*e.ray, *e.hit, e.query});
  }
  std::vector<RecordedRay> take() {
    std::vector<RecordedRay> all;
    for (auto& v : perThread_) all.insert(all.end(), v.begin(), v.end()), v.clear();
    return all;
  }

 private:
  tbb::enumerable_thread_specific<std::vector<RecordedRay>> perThread_;
};

/// The GPU version of tracer `name` on the rays `recorded` traced on the CPU, each asked as the
/// CPU asked it (closest or any hit): the share whose answer is the same fragment (or a miss on
/// both), the GPU time, the mean iterations per ray. The screen tracers of the resident frame
/// (hssr, hiz, exhaustive, ssr, ssr-layers) march over layers captured and a pyramid built on
/// the GPU (gpu/gpu_frame.h), so that the agreement covers the whole GPU frame; the others trace
/// the CPU's layers, uploaded.
nlohmann::json gpuAgreement(const std::string& name, const FrameOptions& frameOptions, const Frame& frame, const TracerOptions& options,
                            GpuContext& gpu, const std::vector<RecordedRay>& recorded) {
  BuiltTracer built;
#if LAYERTRACE_HAS_GPU
  std::unique_ptr<GpuFrame> resident;
  if (isGpuFrameTracer(name)) {
    resident = makeResidentFrame(gpu, frameOptions, frame, name, options);
    resident->build(frame.camera, layerConfig(frameOptions, frame));
    built.tracer = std::make_unique<GpuFrameTracer>(*resident, "resident");
    built.memoryBytes = resident->hierarchyBytes();
  }
#else
  (void)frameOptions;
#endif
  if (!built.tracer) built = buildGpuTracer(name, frame, options, gpu);
  uint64_t same = 0, iterations = 0;
  for (const Query q : {Query::Closest, Query::Any}) {
    std::vector<Ray> rays;
    std::vector<const TraceHit*> want;
    for (const RecordedRay& r : recorded)
      if (r.query == q) rays.push_back(r.ray), want.push_back(&r.hit);
    std::vector<TraceHit> hits(rays.size());
    std::vector<RayCounters> counters(rays.size());
    built.tracer->query(q, rays, hits, counters);
    for (size_t i = 0; i < rays.size(); ++i) {
      const TraceHit& c = *want[i];
      const TraceHit& g = hits[i];
      same += c.hit ? g.hit && g.x == c.x && g.y == c.y && g.layer == c.layer : !g.hit;
      iterations += counters[i].iterations;
    }
  }
  const double traceMs = gpuTraceMs(*built.tracer);
  const double n = double(std::max<size_t>(recorded.size(), 1));
  return {{"agreement", recorded.empty() ? 1.0 : double(same) / n},
          {"trace_ms", traceMs},
          {"iterations_mean", double(iterations) / n},
          {"memory_bytes", built.memoryBytes}};
}

/// Images side by side at half resolution (nearest of each 2×2 block's average).
Image sideBySide(const std::vector<const Image*>& images) {
  const int w = (images[0]->width + 1) / 2, h = (images[0]->height + 1) / 2;
  Image out(w * int(images.size()), h);
  for (size_t k = 0; k < images.size(); ++k)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        glm::vec3 c(0.0f);
        int n = 0;
        for (int dy = 0; dy < 2; ++dy)
          for (int dx = 0; dx < 2; ++dx)
            if (2 * x + dx < images[k]->width && 2 * y + dy < images[k]->height) c += images[k]->rgb(2 * x + dx, 2 * y + dy), ++n;
        out.set(int(k) * w + x, y, c / float(n));
      }
  return out;
}

}  // namespace

CompareOutput compareFrame(const CompareOptions& o) {
  if (o.tracers.empty()) inputError("--tracers: empty list");
  for (const std::string& t : o.tracers)
    if (!isKnownTracer(t)) inputError("--tracers ", t, ": unknown (use ", tracerNames(), ")");
  for (size_t i = 0; i < o.tracers.size(); ++i)
    if (std::find(o.tracers.begin(), o.tracers.begin() + std::ptrdiff_t(i), o.tracers[i]) != o.tracers.begin() + std::ptrdiff_t(i))
      inputError("--tracers ", o.tracers[i], ": listed twice");
  validateTracerOptions(o.options);
  validateEffectConfig(o.effect);
  // --device gpu: every tracer with a GPU version traces the CPU's rays again there.
  std::shared_ptr<GpuContext> gpu;
  if (o.run.device == "gpu") {
    if (std::none_of(o.tracers.begin(), o.tracers.end(), hasGpuTracer))
      inputError("--device gpu: none of --tracers has a GPU version (", gpuTracerNames(), ")");
    gpu = openGpu();
  }
  FrameOptions fo = o.run.frame;
  for (const std::string& name : o.tracers) prepareCapture(name, o.options, fo);
  Frame frame = buildFrame(fo);
  EffectConfig ec = o.effect;
  ec.seed = o.run.seed;
  ec.progress = !o.run.quiet;

  validateRepeat(o.repeat);
  const BuiltTracer reference = buildTracer("embree", frame, o.options);  // the timing baseline
  const BuiltTracer truth = buildReference(frame);                         // the ground truth of the classes
  EffectConfig refConfig = ec;
  refConfig.countRays = false;  // the baseline: the counter-free instantiation, as every tracer is timed
  EffectResult ref = renderEffect(frame, *reference.tracer, refConfig);  // (also the warm-up of its timing)
  ref.traceMs = measureTrace(frame, *reference.tracer, refConfig, o.repeat).traceMs;
  // The packet baseline on the same rays: 16-wide rtcIntersect16 over each batch (any-hit rays
  // of AO and shadows stay one at a time).
  const EmbreePacketTracer packets(frame.scene, frame.camera, *reference.embree);
  EffectResult packet = renderEffect(frame, packets, refConfig);
  packet.traceMs = measureTrace(frame, packets, refConfig, o.repeat).traceMs;
  const BuiltTracer oracle = buildOracle(frame);
  const ImageSpaceOracle independent(frame.camera, frame.layers);

  nlohmann::json stats = frameStats(frame);
  stats["effect"] = effectName(ec.effect);
  stats["bounces"] = ec.bounces;
  stats["threads"] = o.run.threads;
  stats["tracers"] = o.tracers;
  stats["device"] = o.run.device;
  stats["preset"] = o.options.preset;
  stats["parameters"] = parameterStats(o.options);
  if (gpu) stats["gpu"] = gpuStats(*gpu), stats["gpu_renderer"] = gpu->renderer();
  stats["reference"] = {{"tracer", "embree"},
                        {"trace_ms", ref.traceMs},
                        {"build_ms", reference.buildMs},
                        {"rays", ref.rays},
                        {"packet16_trace_ms", packet.traceMs},
                        {"packet16_traced_rmse", rmsePsnr(packet.traced, ref.traced).first},  // 0: the same answers
                        {"flags", "default scene flags, HIGH build quality, rtcIntersect1/rtcOccluded1 per ray"},
                        {"ground_truth", "embree RTC_SCENE_FLAG_ROBUST"}};
  std::vector<std::pair<std::string, Image>> images;
  std::vector<EffectResult> results;
  std::vector<Image> classImages;
  for (const std::string& name : o.tracers) {
    const BuiltTracer built = buildTracer(name, frame, o.options);
    const bool screen = isScreenTracer(name);
    // The counted pass, watched by the oracle and the reference for the per-ray verdicts; then
    // the timed passes over the same rays without counters (medianTraceMs: the counted pass is
    // their warm-up).
    MismatchObserver exhaustive(*oracle.tracer);
    ClassifyObserver classes(*truth.tracer, frame.camera, frame.layers);
    ObserverList observers;
    observers.add(&classes);
    OracleObserver oracleCheck(independent);
    if (screen && o.checkExhaustive) observers.add(&exhaustive);
    if (screen && o.checkOracle) observers.add(&oracleCheck);
    RayRecorder recorded;
    const bool onGpu = gpu && hasGpuTracer(name);
    if (onGpu) observers.add(&recorded);
    EffectResult r = renderEffect(frame, *built.tracer, ec, &observers);
    const nlohmann::json hybrid = hybridStats(built, o.options);  // of the counted pass alone
    const TraceTiming timed = measureTrace(frame, *built.tracer, ec, o.repeat);
    r.traceMs = timed.traceMs;
    if (!o.run.pixelStats.empty()) writePixelStats((fs::path(o.run.pixelStats) / name).string(), r);
    const auto [rmse, psnr] = rmsePsnr(r.image, ref.image);
    const auto [rmseTraced, psnrTraced] = rmsePsnr(r.traced, ref.traced);
    nlohmann::json t;
    const double rays = double(std::max<uint64_t>(r.rays, 1));
    const auto counts = classes.counts();
    double wrong = 0.0;
    for (int c = 0; c < kRayClasses; ++c) {
      t[rayClassName(RayClass(c))] = double(counts[size_t(c)]) / rays;
      if (isWrongHit(RayClass(c))) wrong += double(counts[size_t(c)]) / rays;
    }
    t["wrong_hit"] = wrong;  // = wrong_hit_thickness + wrong_hit_unstored + wrong_hit_other
    if (screen) {
      if (o.checkExhaustive) t["exhaustive_mismatch"] = exhaustive.mismatches();
      if (o.checkOracle) {
        t["oracle_mismatch"] = oracleCheck.mismatches();
        t["oracle_ambiguous"] = oracleCheck.ambiguous();
      }
    }
    t["psnr_db"] = psnr;
    t["rmse"] = rmse;
    t["psnr_traced_db"] = psnrTraced;
    t["rmse_traced"] = rmseTraced;
    t["trace_ms"] = r.traceMs;
    t["shade_ms"] = timed.shadeMs;
    t["hierarchy_ms"] = built.buildMs;
    t["memory_bytes"] = built.memoryBytes;
    t["iterations_mean"] = r.rays ? double(r.iterationSum) / double(r.rays) : 0.0;
    t["rays"] = rayStats(r, screen);
    if (!hybrid.is_null()) t["hybrid"] = hybrid;
    if (built.ldc) t["ldc"] = ldcStats(*built.ldc, &r);
    if (onGpu) {
      const nlohmann::json g = gpuAgreement(name, o.run.frame, frame, o.options, *gpu, recorded.take());
      t["gpu_agreement"] = g["agreement"];
      t["gpu_trace_ms"] = g["trace_ms"];
      t["gpu_iterations_mean"] = g["iterations_mean"];
      t["gpu_memory_bytes"] = g["memory_bytes"];
    }
    stats["compare"][name] = t;
    images.emplace_back(name + ".png", r.image);
    images.emplace_back(name + "_traced.png", r.traced);
    images.emplace_back(name + "_classes.png", classes.classImage());
    classImages.push_back(classes.classImage());
    results.push_back(std::move(r));
  }
  images.emplace_back("reference.png", ref.image);
  images.emplace_back("reference_traced.png", ref.traced);
  std::vector<const Image*> row{&ref.image};
  for (const EffectResult& r : results) row.push_back(&r.image);
  images.emplace_back("side_by_side.png", sideBySide(row));
  std::vector<const Image*> classRow;
  for (const Image& c : classImages) classRow.push_back(&c);
  images.emplace_back("classes_side_by_side.png", sideBySide(classRow));

  // The table.
  std::ostringstream table;
  table << std::left << std::setw(12) << "tracer" << std::right;
  for (const char* h : {"correct", "wr-thick", "wr-unst", "wr-other", "falsemiss", "origin", "infomiss", "corrmiss", "oracle≠",
                        "PSNR dB", "PSNR tr", "trace ms", "iter/ray"})
    table << std::setw(11) << h;
  table << "\n";
  for (const std::string& name : o.tracers) {
    const nlohmann::json& t = stats["compare"][name];
    table << std::left << std::setw(12) << name << std::right << std::fixed;
    for (int c = 0; c < kRayClasses; ++c) {  // shares of no rays are not 0 %: a dash
      if (ref.rays == 0) table << std::setw(11) << "-";
      else table << std::setw(10) << std::setprecision(2) << 100.0 * t[rayClassName(RayClass(c))].get<double>() << "%";
    }
    table << std::setw(11)
          << (t.contains("oracle_mismatch")       ? std::to_string(t["oracle_mismatch"].get<uint64_t>())
              : t.contains("exhaustive_mismatch") ? std::to_string(t["exhaustive_mismatch"].get<uint64_t>()) + "ᵉ"
                                                  : "-");
    table << std::setw(11) << std::setprecision(2) << t["psnr_db"].get<double>() << std::setw(11) << t["psnr_traced_db"].get<double>()
          << std::setw(11) << std::setprecision(1)
          << t["trace_ms"].get<double>() << std::setw(11) << std::setprecision(1) << t["iterations_mean"].get<double>() << "\n";
  }

  CompareOutput out;
  out.table = table.str();
  out.title = cat("layertrace compare: ", frame.scene.name, " — ", effectName(ec.effect));
  std::ostringstream summary;
  summary << "compare: " << frame.scene.name << " " << frame.camera.width() << "x" << frame.camera.height() << " " << effectName(ec.effect)
          << ", reference embree (" << ref.rays << " rays, " << ref.traceMs << " ms; 16-wide packets " << packet.traceMs << " ms)\n";
  if (ref.rays == 0)
    summary << "  no rays: no covered pixel of this view casts " << effectName(ec.effect)
            << " rays (nothing in view, or no surface with the material the effect needs)\n";
  if (gpu) {
    summary << "  the same rays on " << gpu->renderer() << (gpu->software() ? " (a CPU rasterizer: its times are CPU times)" : "") << ":";
    for (const std::string& name : o.tracers)
      if (const nlohmann::json& t = stats["compare"][name]; t.contains("gpu_agreement"))
        summary << " " << name << " " << std::fixed << std::setprecision(2) << 100.0 * t["gpu_agreement"].get<double>() << " % agree, "
                << std::setprecision(2) << t["gpu_trace_ms"].get<double>() << " ms;";
    summary << "\n";
  }
  out.summary = summary.str();
  out.stats = std::move(stats);
  out.images = std::move(images);
  return out;
}

int runCompare(const CompareOptions& o) {
  const std::string outDir = o.run.output;
  const CompareOutput c = compareFrame(o);
  ensureDirectory(outDir, "-o");
  for (const auto& [name, image] : c.images) writeImage((fs::path(outDir) / name).string(), image);
  writeStats(o.run.statsPath, c.stats.dump(2));
  if (!o.report.empty()) {
    ReportPage page;
    page.title = c.title;
    page.table = c.table;
    page.json = c.stats;
    for (const auto& [name, image] : c.images) page.images.push_back({name, &image});
    writeReport(o.report, page);
  }
  if (!o.run.quiet)
    std::cout << c.summary << c.table << "  wrote " << c.images.size() << " images to " << outDir << " and the statistics to " << o.run.statsPath
              << "\n";
  return 0;
}

}  // namespace lt
