#include "layertrace/pipeline/gpu_tracers.h"

#include <algorithm>
#include <array>
#include <limits>
#include <string_view>

#include "layertrace/util/error.h"
#if LAYERTRACE_HAS_GPU
#include "layertrace/gpu/gpu_capture.h"
#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_frame.h"
#include "layertrace/gpu/gpu_grid.h"
#include "layertrace/gpu/gpu_grid_build.h"
#include "layertrace/gpu/gpu_hybrid.h"
#include "layertrace/gpu/gpu_ldc.h"
#include "layertrace/gpu/gpu_quadtree.h"
#include "layertrace/gpu/gpu_screen_tracer.h"
#include "layertrace/hiz/hiz_pyramid.h"
#endif

namespace lt {

namespace {
constexpr std::array<const char*, 8> kGpuTracers = {"ssr", "ssr-layers", "hiz", "hssr", "quadtree", "ldc", "grid", "hybrid"};
}


bool hasGpuTracer(const std::string& name) {
  return std::find(kGpuTracers.begin(), kGpuTracers.end(), name) != kGpuTracers.end();
}

const std::string& gpuTracerNames() {
  static const std::string names = [] {
    std::string s;
    for (const char* n : kGpuTracers) s += (s.empty() ? "" : ", ") + std::string(n);
    return s;
  }();
  return names;
}

nlohmann::json gpuFrameStats(const nlohmann::json& before, const nlohmann::json& after, double wallMs, double gpuMs) {
  nlohmann::json j = {{"frames", 1}, {"wall_ms", wallMs}, {"gpu_ms", gpuMs}};
  for (const auto& [key, value] : after.items()) j[key] = value.get<uint64_t>() - before.value(key, uint64_t(0));
  return j;
}

#if LAYERTRACE_HAS_GPU

nlohmann::json gpuActivityReading() {
  const GpuActivity a = gpuActivity();
  return {{"upload_bytes", a.uploadBytes},         {"download_bytes", a.downloadBytes}, {"host_waits", a.hostWaits},
          {"program_links", a.programLinks},       {"buffer_allocations", a.bufferAllocations},
          {"dispatches", a.dispatches},            {"draws", a.draws}};
}

bool gpuBuilt() { return true; }

std::shared_ptr<GpuContext> openGpu() { return std::make_shared<GpuContext>(); }
std::shared_ptr<GpuContext> openGpuSharing(void* eglDisplay, void* eglContext) {
  return std::make_shared<GpuContext>(GpuContext::ShareWith{eglDisplay, eglContext});
}

nlohmann::json gpuStats(const GpuContext& gpu) {
  return {{"renderer", gpu.renderer()},
          {"version", gpu.version()},
          {"software", gpu.software()},
          {"platform", gpu.platform()},
          {"subgroups", GpuScreenTracer::subgroupExtension(gpu)}};
}

void rasterizeFrameOnGpu(GpuContext& gpu, const FrameOptions& o, const std::string& capture, Frame& frame) {
  if (capture != "lists" && capture != "peel") inputError("--capture ", capture, ": unknown (use lists or peel)");
  GpuCaptureConfig c;
  c.method = capture == "peel" ? GpuCaptureMethod::Peel : GpuCaptureMethod::Lists;
  c.layers = layerConfig(o, frame);
  c.poolCapacity = o.pool;
  c.growOnOverflow = o.pool == 0;
  c.frontFacesOnly = frame.frontFacesOnly = o.frontFacesOnly;
  c.keepLists = o.captureLists;
  GpuCaptureResult r;
  captureOnGpu(gpu, frame.scene, frame.camera, c, r);
  frame.pyramid.reset();
  frame.layers = std::move(r.layers);
  frame.lists = std::move(r.lists);
  frame.intervals = std::make_shared<IntervalLayers>(makeIntervalLayers(frame.layers, frame.layers.k));
  frame.rasterMs = r.setupMs + r.rasterMs;
  frame.sortMs = r.sortMs;
  frame.raster = RasterStats{frame.rasterMs, r.overflowLost, r.passes, frame.scene.triangleCount()};
  frame.capturePipeline = "gpu-" + capture;
  frame.gpuMemoryBytes = r.memoryBytes;
  frame.geometryPasses = r.geometryPasses;
}

std::string gpuCaptureLimit(GpuContext& gpu, const Frame& frame) { return GpuCapture::limit(gpu, frame.scene); }

BuiltTracer buildGpuTracer(const std::string& name, const Frame& frame, const TracerOptions& options, GpuContext& gpu) {
  if (!hasGpuTracer(name)) inputError("--device gpu: ", name, " has no GPU version (GPU tracers: ", gpuTracerNames(), ")");
  validateTracerOptions(options);
  BuiltTracer b;
  if (name == "quadtree") {
    // Algorithms 1–2 on the device from the layers' depths; the nodes stay there.
    auto q = std::make_unique<GpuQuadtreeTracer>(gpu, frame.camera, frame.layers, options.quadtree);
    b.quadtree = std::make_unique<Quadtree>(q->summary());
    b.buildMs = b.quadtree->buildMs;
    b.memoryBytes = q->memoryBytes();
    b.tracer = std::move(q);
    return b;
  }
  if (name == "hybrid") {
    // Both halves on the GPU: the screen march over the hybrid's solid intervals (its pyramid
    // built there), the GPU grid for the rest, and the decisions between them (gpu_hybrid.h):
    // the answers are the CPU hybrid's with --hybrid-geo grid.
    HybridBuilders onGpu;
    onGpu.pyramidScreen = [&](IntervalLayers solid, const PyramidConfig& pc, const HssrConfig& hc) {
      BuiltTracer screen;
      auto t = std::make_unique<GpuScreenTracer>(gpu, frame.camera, frame.layers, solid, pc, hc);
      screen.buildMs = t->pyramid()->buildMs;
      screen.memoryBytes = t->memoryBytes();
      screen.tracer = std::move(t);
      return screen;
    };
    onGpu.part = [&](const std::string& part) { return buildGpuTracer(part, frame, options, gpu); };
    onGpu.geo = "grid";
    b = buildHybrid(frame, options, onGpu);
    const auto* grid = dynamic_cast<const GpuGridTracer*>(b.parts[1].tracer.get());
    if (grid && GpuHybridTracer::canRunOnGpu(*b.parts[0].tracer, *b.known)) {
      const auto& rules = dynamic_cast<const HybridTracer&>(*b.tracer);  // its margin and certainty, as built for the CPU
      auto h = std::make_unique<GpuHybridTracer>(gpu, frame.scene, frame.camera, frame.layers, *b.known, *b.parts[0].tracer, *grid,
                                                 rules.worldMargin(), rules.uncertainEmptySpace());
      b.memoryBytes += h->memoryBytes();
      b.tracer = std::move(h);
    }
    return b;
  }
  if (name == "grid" && options.grid.gpuBuild) {
    // Built on the GPU; a scene with alpha-tested triangles gets a CPU grid beside it for the
    // rays that meet one (the texture test).
    std::unique_ptr<IrregularGrid> cutOuts = frame.scene.anyCutOut() ? std::make_unique<IrregularGrid>(frame.scene, options.grid) : nullptr;
    GpuGridBuildStats stats;
    b = buildGpuGridOnGpu(frame, options.grid, cutOuts.get(), gpu, stats);
    b.grid = std::move(cutOuts);
    return b;
  }
  if (name == "grid") {
    // The grid built by the CPU, its packed traversal structure uploaded once, walked there.
    BuiltTracer cpu = buildTracer("grid", frame, options);
    auto g = std::make_unique<GpuGridTracer>(gpu, frame.scene, frame.camera, *cpu.grid);
    b.grid = std::move(cpu.grid);
    b.buildMs = cpu.buildMs;
    b.memoryBytes = g->memoryBytes();
    b.tracer = std::move(g);
    return b;
  }
  if (name == "ldc") {
    // The cube built by the CPU (its three LDIs rasterized here), uploaded once, traced there.
    BuiltTracer cpu = buildTracer("ldc", frame, options);
    auto l = std::make_unique<GpuLdcTracer>(gpu, frame.camera, *cpu.ldc);
    b.ldc = std::move(cpu.ldc);
    b.buildMs = cpu.buildMs;
    b.memoryBytes = l->memoryBytes();
    b.tracer = std::move(l);
    return b;
  }
  std::unique_ptr<GpuScreenTracer> t;
  if (name == "ssr" || name == "ssr-layers") {
    SsrConfig sc = options.ssr;
    sc.allLayers = name == "ssr-layers";
    t = std::make_unique<GpuScreenTracer>(gpu, frame.camera, frame.layers, sc);
  } else {
    // Level 0 uploaded, the pyramid built on the GPU (Hi-Z: the min/max pyramid, τ = ∞).
    const bool hiz = name == "hiz";
    HssrConfig hc = hiz ? hizConfig(options.pyramid.levels) : options.hssr;
    hc.maxLevels = options.pyramid.levels;
    const PyramidConfig pc = hiz ? PyramidConfig{options.pyramid.levels, std::numeric_limits<float>::infinity()} : options.pyramid;
    std::shared_ptr<IntervalLayers> level0 = frame.level0();
    if (!level0) level0 = std::make_shared<IntervalLayers>(makeIntervalLayers(frame.layers, frame.layers.k));
    t = std::make_unique<GpuScreenTracer>(gpu, frame.camera, frame.layers, *level0, pc, hc);
    // The intervals per level for the statistics, as the build counted them (the levels stay on
    // the device).
    uint64_t base = 0;
    for (uint8_t n : level0->count) base += n;
    b.levelIntervals.push_back(base);
    for (int L = 1; L < t->pyramid()->levels; ++L) b.levelIntervals.push_back(t->pyramid()->intervalCounts[size_t(L)]);
    b.buildMs = t->pyramid()->buildMs;
  }
  b.memoryBytes = t->memoryBytes();
  b.tracer = std::move(t);
  return b;
}

bool setGpuPersistentThreads(Tracer& tracer, bool on) {
  auto* g = dynamic_cast<GpuScreenTracer*>(&tracer);
  if (!g || std::string_view(g->name()).starts_with("ssr")) return false;
  g->setPersistentThreads(on);
  return true;
}

void makeGpuCurrent(const GpuContext& gpu) { gpu.makeCurrent(); }
void releaseGpu(const GpuContext& gpu) { gpu.release(); }

double gpuTraceMs(const Tracer& tracer) {
  if (const auto* h = dynamic_cast<const GpuHybridTracer*>(&tracer)) return h->totalTraceMs();
  if (const auto* h = dynamic_cast<const HybridTracer*>(&tracer))  // both halves' dispatches
    return gpuTraceMs(h->screen()) + (dynamic_cast<const Tracer*>(&h->geometry()) ? gpuTraceMs(dynamic_cast<const Tracer&>(h->geometry())) : 0.0);
  if (const auto* q = dynamic_cast<const GpuQuadtreeTracer*>(&tracer)) return q->totalTraceMs();
  if (const auto* l = dynamic_cast<const GpuLdcTracer*>(&tracer)) return l->totalTraceMs();
  if (const auto* g = dynamic_cast<const GpuGridTracer*>(&tracer)) return g->totalTraceMs();
  if (const auto* f = dynamic_cast<const GpuFrameTracer*>(&tracer)) return f->totalTraceMs();
  const auto* g = dynamic_cast<const GpuScreenTracer*>(&tracer);
  return g ? g->totalTraceMs() : 0.0;
}

BuiltTracer buildGpuGridOnGpu(const Frame& frame, const GridConfig& config, const IrregularGrid* cutOuts, GpuContext& gpu,
                              GpuGridBuildStats& stats) {
  auto built = std::make_unique<GpuGridBuild>(gpu, frame.scene, config);
  stats.cells = built->cells(), stats.cellsInitial = built->cellsInitial(), stats.refs = built->refs();
  stats.memoryBytes = built->memoryBytes(), stats.mergeRounds = built->mergeRounds(), stats.expandedFaces = built->expandedFaces();
  stats.gpuMs = built->gpuMs(), stats.wallMs = built->wallMs();
  stats.topMs = built->topMs(), stats.leavesMs = built->leavesMs(), stats.mergeMs = built->mergeMs(), stats.expandMs = built->expandMs();
  stats.packMs = built->packMs();
  BuiltTracer b;
  b.buildMs = built->wallMs();
  b.memoryBytes = built->memoryBytes();
  b.tracer = std::make_unique<GpuGridTracer>(gpu, frame.scene, frame.camera, std::move(built), cutOuts);
  return b;
}

double traceGpuGrid(const Tracer& tracer, std::span<const IrregularGrid::Query> queries, bool anyHit, std::span<GeoHit> hits) {
  const auto* g = dynamic_cast<const GpuGridTracer*>(&tracer);
  if (!g) throw InternalError("traceGpuGrid: not a GPU grid");
  g->query(queries, anyHit, hits);
  return g->lastTraceMs();
}

#else

bool gpuBuilt() { return false; }

nlohmann::json gpuActivityReading() {
  return {{"upload_bytes", 0}, {"download_bytes", 0}, {"host_waits", 0}, {"program_links", 0}, {"buffer_allocations", 0}, {"dispatches", 0}, {"draws", 0}};
}

std::shared_ptr<GpuContext> openGpu() {
  inputError("--device gpu: this build has no GPU back end (apt-get install libepoxy-dev libegl-dev glslang-tools, then rebuild)");
}
std::shared_ptr<GpuContext> openGpuSharing(void*, void*) { return openGpu(); }
nlohmann::json gpuStats(const GpuContext&) { return {}; }
void makeGpuCurrent(const GpuContext&) {}
void releaseGpu(const GpuContext&) {}
void rasterizeFrameOnGpu(GpuContext&, const FrameOptions&, const std::string&, Frame&) { openGpu(); }
std::string gpuCaptureLimit(GpuContext&, const Frame&) { return {}; }
BuiltTracer buildGpuTracer(const std::string&, const Frame&, const TracerOptions&, GpuContext&) {
  openGpu();
  return {};
}
bool setGpuPersistentThreads(Tracer&, bool) { return false; }
double gpuTraceMs(const Tracer&) { return 0.0; }
BuiltTracer buildGpuGridOnGpu(const Frame&, const GridConfig&, const IrregularGrid*, GpuContext&, GpuGridBuildStats&) {
  openGpu();
  return {};
}
double traceGpuGrid(const Tracer&, std::span<const IrregularGrid::Query>, bool, std::span<GeoHit>) {
  openGpu();
  return 0.0;
}

#endif

}  // namespace lt
