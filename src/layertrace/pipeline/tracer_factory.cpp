#include "layertrace/pipeline/tracer_factory.h"

#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/util/error.h"

namespace lt {

void validateTracerOptions(const TracerOptions& o) {
  if (!(o.ssr.stride >= 1.0f)) inputError("--stride ", o.ssr.stride, ": must be >= 1");
  if (!(o.ssr.jitter >= 0.0f && o.ssr.jitter <= 1.0f)) inputError("--jitter ", o.ssr.jitter, ": must be in [0, 1]");
  if (o.ssr.maxSteps < 0) inputError("--max-steps ", o.ssr.maxSteps, ": must be >= 0");
  if (o.hssr.nUp < 1) inputError("--n-up ", o.hssr.nUp, ": must be >= 1");
  if (!(o.grid.lambda1 > 0.0f)) inputError("--lambda1 ", o.grid.lambda1, ": must be positive");
  if (!(o.grid.lambda2 > 0.0f)) inputError("--lambda2 ", o.grid.lambda2, ": must be positive");
  if (o.pyramid.levels < 1 || o.pyramid.levels > 16) inputError("--levels ", o.pyramid.levels, ": must be between 1 and 16");
  if (!(o.pyramid.tau > 0.0f)) inputError("--tau ", o.pyramid.tau, ": must be positive");
  validateQuadtreeConfig(o.quadtree);
}

bool isScreenTracer(const std::string& n) {
  return n == "ssr" || n == "ssr-layers" || n == "hiz" || n == "hssr" || n == "quadtree";
}
bool isKnownTracer(const std::string& n) { return isScreenTracer(n) || n == "embree" || n == "grid"; }

BuiltTracer buildTracer(const std::string& name, const Frame& frame, const TracerOptions& o) {
  BuiltTracer b;
  if (name == "hssr") {
    b.pyramid = std::make_unique<IntervalPyramid>(buildIntervalPyramid(frame.layers, frame.camera, o.pyramid));
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
  b.pyramid = std::make_unique<IntervalPyramid>(buildIntervalPyramid(frame.layers, frame.camera, PyramidConfig{1, 25.0f}));
  b.tracer = std::make_unique<HssrTracer>(frame.camera, frame.layers, *b.pyramid, HssrConfig{1, 1});
  return b;
}

}  // namespace lt
