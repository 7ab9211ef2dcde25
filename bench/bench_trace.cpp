// Issues 3 §6 and 4 §6: one-bounce mirror reflection rays from every covered pixel of the
// FZK-Haus and am_thornish interiors (1280×720, k = 4), the same rays through every tracer:
// ssr at strides 1, 2, 4, 8; ssr-layers at strides 1, 2, 3, 4, 8; hssr (τ 25, 5 levels, n_up 2).
// Counters: MRays/s, mean DDA iterations per ray, hit fraction; Embree (the project's scene) on
// the same rays as the baseline; the hybrid (issue 15: hssr + embree, certified answers) with
// the share of rays each half answered. Hierarchy build time is
// measured beside raster and sort.
#include <algorithm>
#include <chrono>
#include <span>

#include <benchmark/benchmark.h>
#include <glm/geometric.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "layertrace/geometry/geometric_tracer.h"
#include "layertrace/pipeline/frame.h"
#include "layertrace/pipeline/tracer_factory.h"
#include "layertrace/screen/hssr_march_lanes.h"
#include "layertrace/screen/hssr_tracer.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/screen/ssr_tracer.h"

namespace {

struct Setup {
  lt::Frame frame;
  std::vector<lt::Ray> rays;
  lt::IntervalPyramid pyramid;
};

Setup& setup(int scene) {
  static Setup s[2];
  static bool ready[2] = {false, false};
  if (!ready[scene]) {
    lt::FrameOptions o;
    o.scenePath = std::string(LAYERTRACE_SOURCE_DIR) + (scene == 0 ? "/scenes/fzk-haus.json" : "/scenes/am-thornish.json");
    o.cameraName = scene == 0 ? "interior" : "hall";
    s[scene].frame = lt::buildFrame(o);
    const lt::Frame& f = s[scene].frame;
    const float maxDist = f.scene.bounds().diagonal();
    for (int y = 0; y < f.camera.height(); ++y)
      for (int x = 0; x < f.camera.width(); ++x) {
        if (!f.layers.countAt(x, y)) continue;
        const lt::FragmentNode& fr = f.layers.pixel(x, y)[0];
        lt::Ray r;
        r.origin = f.camera.rayThrough({x + 0.5f, y + 0.5f}) * fr.depth;
        const glm::vec3 v = glm::normalize(r.origin), n = lt::decodeOctahedral(fr.normal);
        r.dir = glm::reflect(v, glm::dot(n, v) > 0.0f ? -n : n);
        r.maxDistance = maxDist;
        s[scene].rays.push_back(r);
      }
    s[scene].pyramid = lt::buildIntervalPyramid(f.layers, f.camera, lt::PyramidConfig{5, 25.0f});
    ready[scene] = true;
  }
  return s[scene];
}

void traceAll(benchmark::State& state, const lt::Tracer& tracer, const std::vector<lt::Ray>& rays) {
  // Timed: batches of 256 rays through traceBatch without counters (the counter-free
  // instantiation of the tracer, trace/tracer.h).
  std::vector<lt::TraceHit> hits(rays.size());
  for (auto _ : state) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t b = r.begin(); b < r.end(); b += 256) {
        const size_t len = std::min<size_t>(256, r.end() - b);
        tracer.traceBatch(std::span<const lt::Ray>(&rays[b], len), std::span<lt::TraceHit>(&hits[b], len), {});
      }
    });
    benchmark::DoNotOptimize(hits.data());
  }
  // Counted once, outside the timing.
  std::vector<lt::RayCounters> counters(rays.size());
  tracer.traceBatch(rays, hits, counters);
  uint64_t iterations = 0, hit = 0;
  for (size_t i = 0; i < rays.size(); ++i) iterations += counters[i].iterations, hit += hits[i].hit;
  state.counters["MRays/s"] = benchmark::Counter(double(rays.size()) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["iter/ray"] = double(iterations) / double(rays.size());
  state.counters["hit%"] = 100.0 * double(hit) / double(rays.size());
}

void BM_Ssr(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  lt::SsrConfig c;
  c.stride = float(state.range(1));
  c.allLayers = state.range(2) != 0;
  const lt::SsrTracer t(s.frame.camera, s.frame.layers, c);
  traceAll(state, t, s.rays);
}

void BM_Hssr(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  const lt::HssrTracer t(s.frame.camera, s.frame.layers, s.pyramid, lt::HssrConfig{2, 5});
  traceAll(state, t, s.rays);
}

/// Each round times `pass(false)` (one ray at a time) and `pass(true)` (the lanes) on the same
/// rays, alternating which runs first; the counters are the medians and their ratio (the
/// machine is noisy, a ratio within one round is not).
template <class Pass>
void timeOneAgainstLanes(benchmark::State& state, Pass&& pass) {
  std::vector<double> one, lanes;
  for (auto _ : state) {
    const bool lanesFirst = one.size() % 2 == 1;
    if (lanesFirst) lanes.push_back(pass(true));
    one.push_back(pass(false));
    if (!lanesFirst) lanes.push_back(pass(true));
  }
  std::sort(one.begin(), one.end());
  std::sort(lanes.begin(), lanes.end());
  state.counters["one_ms"] = one[one.size() / 2];
  state.counters["lanes_ms"] = lanes[lanes.size() / 2];
  state.counters["speedup"] = one[one.size() / 2] / lanes[lanes.size() / 2];
}

/// The HSSR march alone (segments made beforehand, no hit shading), one ray at a time
/// (hssrMarchEach) against the AVX-512 lanes (hssrMarchBatch) on the same segments.
void BM_HssrLanes(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  const lt::Frame& f = s.frame;
  std::vector<lt::ScreenSegment> segs(s.rays.size());
  for (size_t i = 0; i < segs.size(); ++i) segs[i] = lt::makeScreenSegment(f.camera, s.rays[i]);
  std::vector<lt::MarchHit> out(segs.size());
  const int W = f.camera.width(), H = f.camera.height();
  auto pass = [&](bool lanes) {
    const auto t0 = std::chrono::steady_clock::now();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, segs.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t b = r.begin(); b < r.end(); b += 256) {
        const size_t len = std::min<size_t>(256, r.end() - b);
        const auto in = std::span<const lt::ScreenSegment>(&segs[b], len);
        const auto o = std::span<lt::MarchHit>(&out[b], len);
        if (lanes) lt::hssrMarchBatch(s.pyramid, 5, 2, in, W, H, o);
        else lt::hssrMarchEach(s.pyramid, 5, 2, in, W, H, o);
      }
    });
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  timeOneAgainstLanes(state, pass);
  state.counters["lanes_on"] = lt::hssrLanesAvailable(s.pyramid, 5);
}

/// SSR (seed 001) over the same rays, one ray at a time (the one-ray path of TracerImpl) against
/// the AVX-512 lanes (SsrTracer::traceBatch). Args: scene, all layers (ssr-layers), stride.
void BM_SsrLanes(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  lt::SsrConfig c;
  c.allLayers = state.range(1) != 0;
  c.stride = float(state.range(2));
  const lt::SsrTracer t(s.frame.camera, s.frame.layers, c);
  std::vector<lt::TraceHit> hits(s.rays.size());
  auto pass = [&](bool lanes) {
    const auto t0 = std::chrono::steady_clock::now();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, s.rays.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t b = r.begin(); b < r.end(); b += 256) {
        const size_t len = std::min<size_t>(256, r.end() - b);
        const auto in = std::span<const lt::Ray>(&s.rays[b], len);
        const auto o = std::span<lt::TraceHit>(&hits[b], len);
        if (lanes) t.traceBatch(in, o, {});
        else t.TracerImpl<lt::SsrTracer>::traceBatch(in, o, {});
      }
    });
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  timeOneAgainstLanes(state, pass);
}

void BM_Embree(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  const lt::EmbreeScene embree(s.frame.scene, lt::EmbreeScene::Mode::Fast);
  const lt::EmbreeTracer t("embree", s.frame.scene, s.frame.camera, embree);
  traceAll(state, t, s.rays);
}

void BM_Hybrid(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  const lt::BuiltTracer b = lt::buildTracer("hybrid", s.frame, lt::TracerOptions{});
  const auto& hybrid = dynamic_cast<const lt::HybridTracer&>(*b.tracer);
  traceAll(state, hybrid, s.rays);
  const lt::HybridStats h = hybrid.stats();
  state.counters["screen%"] = 100.0 * h.screenFraction();
  state.counters["geo%"] = 100.0 * h.geoFraction();
}

void BM_HierarchyBuild(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  for (auto _ : state) {
    lt::IntervalPyramid p = lt::buildIntervalPyramid(s.frame.layers, s.frame.camera, lt::PyramidConfig{5, 25.0f});
    benchmark::DoNotOptimize(p.levels.data());
  }
  state.counters["raster_ms"] = s.frame.rasterMs;
  state.counters["sort_ms"] = s.frame.sortMs;
}

// Args: scene (0 = FZK-Haus, 1 = am_thornish), stride, all layers.
BENCHMARK(BM_Hssr)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HssrLanes)->Arg(0)->Arg(1)->Iterations(9)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrLanes)->ArgsProduct({{0, 1}, {0, 1}, {1}})->Iterations(5)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Embree)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Hybrid)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Ssr)
    ->ArgsProduct({{0, 1}, {1, 2, 3, 4, 8}, {1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_Ssr)->ArgsProduct({{0}, {1, 2, 4, 8}, {0}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HierarchyBuild)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
