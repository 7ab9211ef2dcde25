#include "layertrace/pipeline/tracer_factory.h"

#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/raster/unsampled.h"
#include "layertrace/util/error.h"

namespace lt {

void validateTracerOptions(const TracerOptions& o) {
  if (!(o.ssr.stride >= 1.0f && o.ssr.stride <= 4096.0f)) inputError("--stride ", o.ssr.stride, ": must be between 1 and 4096 pixels");
  if (!(o.ssr.jitter >= 0.0f && o.ssr.jitter <= 1.0f)) inputError("--jitter ", o.ssr.jitter, ": must be in [0, 1]");
  if (o.ssr.maxSteps < 0) inputError("--max-steps ", o.ssr.maxSteps, ": must be >= 0");
  if (o.hssr.nUp < 1) inputError("--n-up ", o.hssr.nUp, ": must be >= 1");
  if (!(o.grid.lambda1 > 0.0f)) inputError("--lambda1 ", o.grid.lambda1, ": must be positive");
  if (!(o.grid.lambda2 > 0.0f)) inputError("--lambda2 ", o.grid.lambda2, ": must be positive");
  if (o.pyramid.levels < 1 || o.pyramid.levels > 16) inputError("--levels ", o.pyramid.levels, ": must be between 1 and 16");
  if (!(o.pyramid.tau > 0.0f && std::isfinite(o.pyramid.tau))) inputError("--tau ", o.pyramid.tau, ": must be positive and finite");
  validateQuadtreeConfig(o.quadtree);
  validateLdcConfig(o.ldc);
  if (o.hybridScreen != "hssr" && o.hybridScreen != "hiz" && o.hybridScreen != "quadtree" && o.hybridScreen != "ldc")
    inputError("--hybrid-screen ", o.hybridScreen, ": unknown (use hssr, hiz, quadtree or ldc)");
  if (o.hybridGeo != "embree" && o.hybridGeo != "embree-robust" && o.hybridGeo != "grid")
    inputError("--hybrid-geo ", o.hybridGeo, ": unknown (use embree, embree-robust or grid)");
}

namespace {
/// The frame's pyramid: over the level 0 the capture wrote, or from the k-layer arrays.
std::shared_ptr<IntervalPyramid> makePyramid(const Frame& frame, const PyramidConfig& config) {
  if (std::shared_ptr<IntervalPyramid> built = frame.pyramidFor(config)) return built;  // built by the capture, tile by tile
  auto p = std::make_shared<IntervalPyramid>();
  if (std::shared_ptr<IntervalLayers> level0 = frame.level0()) buildIntervalPyramid(std::move(level0), frame.camera, config, *p);
  else buildIntervalPyramid(frame.layers, frame.camera, config, *p);
  return p;
}
}  // namespace

bool isScreenTracer(const std::string& n) {
  return n == "ssr" || n == "ssr-layers" || n == "hiz" || n == "hssr" || n == "quadtree";
}
bool isKnownTracer(const std::string& n) { return isScreenTracer(n) || n == "ldc" || n == "hybrid" || n == "embree" || n == "grid"; }

BuiltTracer buildTracer(const std::string& name, const Frame& frame, const TracerOptions& o) {
  BuiltTracer b;
  if (name == "hssr") {
    b.pyramid = makePyramid(frame, o.pyramid);
    b.buildMs = b.pyramid->buildMs;
    b.memoryBytes = b.pyramid->memoryBytes();
    HssrConfig hc = o.hssr;
    hc.maxLevels = o.pyramid.levels;
    b.tracer = std::make_unique<HssrTracer>(frame.camera, frame.layers, *b.pyramid, hc);
  } else if (name == "hiz") {
    b.pyramid = std::make_unique<IntervalPyramid>(buildHizPyramid(frame.layers, frame.camera, o.pyramid.levels));
    b.buildMs = b.pyramid->buildMs;
    b.memoryBytes = b.pyramid->memoryBytes();
    b.tracer = std::make_unique<HssrTracer>(frame.camera, frame.layers, *b.pyramid, hizConfig(o.pyramid.levels));
  } else if (name == "quadtree") {
    b.quadtree = std::make_unique<Quadtree>(buildQuadtree(frame.layers, frame.camera, o.quadtree));
    b.buildMs = b.quadtree->buildMs;
    b.memoryBytes = b.quadtree->memoryBytes();
    b.tracer = std::make_unique<QuadtreeTracer>(frame.camera, frame.layers, *b.quadtree);
  } else if (name == "ldc") {
    b.ldc = std::make_unique<LayeredDepthCube>(buildLdc(frame.scene, o.ldc));
    b.buildMs = b.ldc->buildMs;
    b.memoryBytes = b.ldc->memoryBytes();
    b.tracer = std::make_unique<LdcTracer>(frame.camera, *b.ldc);
  } else if (name == "ssr" || name == "ssr-layers") {
    SsrConfig sc = o.ssr;
    sc.allLayers = name == "ssr-layers";
    b.tracer = std::make_unique<SsrTracer>(frame.camera, frame.layers, sc);
  } else if (name == "embree") {
    b.embree = std::make_unique<EmbreeScene>(frame.scene, EmbreeScene::Mode::Fast);
    b.buildMs = b.embree->buildMs();
    b.memoryBytes = b.embree->memoryBytes();
    b.tracer = makeEmbreeTracer(frame.scene, frame.camera, *b.embree);
  } else if (name == "grid") {
    b.grid = std::make_unique<IrregularGrid>(frame.scene, o.grid);
    b.buildMs = b.grid->stats().buildMs;
    b.memoryBytes = b.grid->memoryBytes();
    b.tracer = makeGridTracer(frame.scene, frame.camera, *b.grid);
  } else if (name == "hybrid") {
    validateTracerOptions(o);
    // Triangles thinner than a pixel that cross pixels unstored end those pixels' knowledge; the
    // nearest depth any triangle has inside a pixel starts its solid intervals.
    const UnsampledDepths unsampled = unsampledDepths(frame.scene, frame.camera, frame.layers, kHybridLastThicknessPx);
    const CaptureCoverage coverage{frame.layers, frame.lists.complexity, frame.frontFacesOnly, unsampled.unsampled, unsampled.nearest};
    const bool pyramidScreen = o.hybridScreen == "hssr" || o.hybridScreen == "hiz";
    if (pyramidScreen) {
      // HSSR or Hi-Z over the solid intervals: one march answers rule 3 and the surfaces.
      BuiltTracer screen;
      const auto start = std::chrono::steady_clock::now();
      IntervalLayers solid = solidIntervals(frame.camera, coverage, kHybridLastThicknessPx);
      const bool hiz = o.hybridScreen == "hiz";
      const PyramidConfig pc = hiz ? PyramidConfig{o.pyramid.levels, std::numeric_limits<float>::infinity()} : o.pyramid;
      screen.pyramid = std::make_unique<IntervalPyramid>(buildIntervalPyramid(std::move(solid), frame.camera, pc));
      screen.buildMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
      screen.memoryBytes = screen.pyramid->memoryBytes();
      HssrConfig hc = hiz ? hizConfig(o.pyramid.levels) : o.hssr;
      hc.maxLevels = o.pyramid.levels;
      screen.tracer = std::make_unique<HssrTracer>(frame.camera, frame.layers, *screen.pyramid, hc);
      b.parts.push_back(std::move(screen));
    } else {
      b.parts.push_back(buildTracer(o.hybridScreen, frame, o));
    }
    // embree-robust: Embree with RTC_SCENE_FLAG_ROBUST, the reference `compare` grades against
    // (watertight at shared edges and vertices, where plain Embree lets rays through: on a closed
    // sphere, 8–13 % of rays aimed exactly at its vertices and edge points). Every answer the
    // hybrid returns comes from its geometric half, so with it the hybrid answers as the
    // reference does, at the robust kernels' cost.
    const bool robust = o.hybridGeo == "embree-robust";
    b.parts.push_back(robust ? buildReference(frame) : buildTracer(o.hybridGeo, frame, o));
    // Embree as the geometric half traces closest hits in 16-wide packets: the hybrid hands it
    // whole batches (windows, then remainders) of rays from neighbouring pixels, and the answers
    // are Embree's bit for bit (TraceInterface.EmbreePacketsAnswerAsSingleRays). Measured on
    // FZK-Haus / engine one-bounce reflections: windows 1.5–2.2×, remainders 1.4–1.6× faster.
    if (o.hybridGeo == "embree" || robust)
      b.parts.back().tracer = std::make_unique<EmbreePacketTracer>(frame.scene, frame.camera, *b.parts.back().embree);
    // The layered depth cube knows the whole scene box (the hybrid does not ask the camera's
    // known space, so only its cheap frustum part is built).
    const bool ldc = o.hybridScreen == "ldc";
    b.known = std::make_unique<KnownSpace>(frame.camera, coverage, frame.scene.bounds(), pyramidScreen || ldc);
    b.buildMs = b.parts[0].buildMs + b.parts[1].buildMs + b.known->buildMs();
    b.memoryBytes = b.parts[0].memoryBytes + b.parts[1].memoryBytes + b.known->memoryBytes();
    // The margin is the diagonal of a sample's widened texel, (1 + 2ε)·√3 texels (2.6 at the
    // default ε): where the ray meets the sample's plane inside it, the surface the sample stands
    // for is crossed within that distance unless the ray grazes it (then the hit is rejected).
    const float worldMargin = ldc ? (1.0f + 2.0f * o.ldc.epsilon) * std::sqrt(3.0f) * b.parts[0].ldc->texel : 0.0f;
    // The quad-tree marches thin planes, not solid intervals, and the LDC samples surfaces in
    // texels that can miss a thin one: what they call empty is not certain (the LDC's wrong hits
    // on the real views, 0.05–0.15 %, were surfaces its texels missed before a certified hit).
    const auto* geo = dynamic_cast<const GeoHitQueries*>(b.parts[1].tracer.get());
    if (!geo) throw InternalError("hybrid: the geometric tracer answers no segment queries");
    b.tracer = std::make_unique<HybridTracer>(frame.scene, frame.camera, frame.layers, *b.known, *b.parts[0].tracer, *geo,
                                              worldMargin, o.hybridScreen == "quadtree" || ldc);
  } else {
    inputError("--tracer ", name, ": unknown (use ", kTracerNames, ")");
  }
  return b;
}

BuiltTracer buildReference(const Frame& frame) {
  BuiltTracer b;
  b.embree = std::make_unique<EmbreeScene>(frame.scene, EmbreeScene::Mode::Robust);
  b.buildMs = b.embree->buildMs();
  b.memoryBytes = b.embree->memoryBytes();
  b.tracer = makeEmbreeTracer(frame.scene, frame.camera, *b.embree);
  return b;
}

BuiltTracer buildOracle(const Frame& frame) {
  BuiltTracer b;
  b.pyramid = makePyramid(frame, PyramidConfig{1, 25.0f});
  b.tracer = std::make_unique<HssrTracer>(frame.camera, frame.layers, *b.pyramid, HssrConfig{1, 1});
  return b;
}

}  // namespace lt
