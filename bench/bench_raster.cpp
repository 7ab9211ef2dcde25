// Raster + sort (list pipeline, and tile-local capture) at 1280×720, k = 4, on the FZK-Haus
// interior, with 1 and 2 threads, beside Embree collecting the same fragments with all-hit primary
// rays. Reports ms per frame (Google Benchmark's time) and million fragments per second (counter
// "Mfrag/s").
#include <cstdlib>
#include <filesystem>

#include <benchmark/benchmark.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "layertrace/pipeline/frame.h"
#include "layertrace/geometry/embree_scene.h"
#include "layertrace/hssr/interval_pyramid.h"

namespace {

/// The FZK-Haus interior, or the view named by LT_BENCH_SCENE=scene.json[:camera] (another
/// scene's numbers from the same benchmarks).
lt::Frame& fzk() {
  static lt::Frame frame = [] {
    lt::FrameOptions o;
    o.scenePath = std::string(LAYERTRACE_SOURCE_DIR) + "/scenes/fzk-haus.json";
    o.cameraName = "interior";
    if (const char* view = std::getenv("LT_BENCH_SCENE")) {
      const std::string v = view;
      const size_t colon = v.rfind(':');
      o.scenePath = v.substr(0, colon);
      o.cameraName = colon == std::string::npos ? "" : v.substr(colon + 1);
    }
    lt::Frame f;
    lt::loadFrameScene(o, f);
    return f;
  }();
  return frame;
}

void BM_RasterSort(benchmark::State& state) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(state.range(0)));
  lt::Frame& f = fzk();
  uint64_t fragments = 0;
  for (auto _ : state) {
    lt::FragmentLists lists = lt::rasterize(f.scene, f.camera);
    lt::LayerConfig lc{4, f.thickness};
    lc.thicknessPerDepth = f.thicknessPerDepth;
    lt::LayerArrays layers = lt::sortAndTruncate(lists, lc);
    benchmark::DoNotOptimize(layers.count.data());
    fragments = lists.generated;
  }
  state.counters["Mfrag/s"] = benchmark::Counter(double(fragments) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["fragments"] = double(fragments);
}

/// The FZK interior's k = 4 layers, captured tile by tile into memory the caller keeps.
struct TileCaptured {
  lt::LayerCapture capture;
  lt::LayerArrays layers;
  std::vector<uint32_t> complexity;
  lt::CaptureStats stats;
  void run(const lt::Frame& f) {
    lt::LayerConfig lc{4, f.thickness};
    lc.thicknessPerDepth = f.thicknessPerDepth;
    capture.capture(f.scene, f.camera, lt::RasterConfig{}, lc, layers, complexity, &stats);
  }
};

// The tile-local capture, buffers reused from iteration to iteration as in animation.
void BM_TileCapture(benchmark::State& state) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(state.range(0)));
  lt::Frame& f = fzk();
  TileCaptured c;
  for (auto _ : state) {
    c.run(f);
    benchmark::DoNotOptimize(c.layers.count.data());
  }
  const lt::CaptureStats& st = c.stats;
  state.counters["Mfrag/s"] = benchmark::Counter(double(st.generated) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["setup_ms"] = st.setupMs;
  state.counters["tiles_ms"] = st.tilesMs;
}

// The interval pyramid over the captured layers (Hofmann et al. 2017, §4.3), 5 levels, τ = 25:
// levels 1… over the level 0 the capture wrote, rebuilt in place as the pipeline does frame after
// frame.
void BM_Pyramid(benchmark::State& state) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(state.range(0)));
  lt::Frame& f = fzk();
  TileCaptured c;
  c.run(f);
  const auto level0 = std::make_shared<lt::IntervalLayers>(lt::makeIntervalLayers(c.layers, c.layers.k));
  lt::IntervalPyramid p;
  for (auto _ : state) {
    lt::buildIntervalPyramid(level0, f.camera, lt::PyramidConfig{}, p);
    benchmark::DoNotOptimize(p.levels.back().cells.data());
  }
}

// The frame's capture as the commands run it (level 0 written per tile), without (0) and with (1)
// levels 1… merged per tile (FrameOptions::pyramid, what hssr reads): the difference of the two
// is the per-tile pyramid's wall time, and its scaling from 1 to 2 threads.
void BM_FrameCapture(benchmark::State& state) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(state.range(0)));
  lt::Frame& f = fzk();
  lt::FrameOptions o;
  o.width = f.camera.width(), o.height = f.camera.height();
  if (state.range(1)) o.pyramid = lt::PyramidConfig{};
  lt::rasterizeFrame(o, f);  // warm-up: sizes every buffer
  for (auto _ : state) {
    lt::rasterizeFrame(o, f);
    benchmark::DoNotOptimize(f.layers.count.data());
  }
  if (f.pyramid) state.counters["pyramid_ms"] = f.pyramid->buildMs;
}

void BM_EmbreeAllHits(benchmark::State& state) {
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, size_t(state.range(0)));
  lt::Frame& f = fzk();
  static lt::EmbreeScene embree(f.scene);
  const lt::Camera& cam = f.camera;
  std::atomic<uint64_t> fragments{0};
  for (auto _ : state) {
    fragments = 0;
    tbb::parallel_for(tbb::blocked_range<int>(0, cam.height(), 8), [&](const tbb::blocked_range<int>& r) {
      std::vector<lt::GeoHit> hits;
      uint64_t n = 0;
      for (int y = r.begin(); y != r.end(); ++y)
        for (int x = 0; x < cam.width(); ++x) {
          embree.allHits(cam.desc().eye, cam.dirToWorld(cam.rayThrough({x + 0.5f, y + 0.5f})), cam.near(), cam.far(), hits);
          n += hits.size();
        }
      fragments += n;
    });
  }
  state.counters["Mfrag/s"] = benchmark::Counter(double(fragments) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["fragments"] = double(fragments);
}

BENCHMARK(BM_RasterSort)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
BENCHMARK(BM_TileCapture)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
BENCHMARK(BM_Pyramid)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
BENCHMARK(BM_FrameCapture)->Args({1, 0})->Args({1, 1})->Args({2, 0})->Args({2, 1})->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);
BENCHMARK(BM_EmbreeAllHits)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(1.0);

}  // namespace

BENCHMARK_MAIN();
