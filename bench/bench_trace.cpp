// One-bounce mirror reflection rays from every covered pixel of the
// FZK-Haus and am_thornish interiors (1280×720, k = 4), the same rays through every tracer:
// ssr at strides 1, 2, 4, 8; ssr-layers at strides 1, 2, 3, 4, 8; hssr (the default τ and levels, n_up 2).
// Counters: MRays/s, mean DDA iterations per ray, hit fraction; Embree (the project's scene) on
// the same rays as the baseline; the hybrid (hssr + embree, certified answers) with
// the share of rays each half answered — hybrid and Embree also on one AO ray per pixel (any
// hit, 5 % of the scene's diagonal); HSSR against Embree alternating round by round on the
// FZK-Haus, am_thornish and engine interiors (BM_HssrAgainstEmbree). Hierarchy build time is
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
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/hssr/hssr_march_lanes.h"
#include "layertrace/hssr/hssr_tracer.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/ssr/ssr_tracer.h"

namespace {

/// The HSSR passes here use the default pyramid (PyramidConfig: τ 4, 7 levels) and n_up 2.
constexpr int kLevels = lt::PyramidConfig{}.levels;

/// A uniform number in [0, 1) from a linear congruential generator (deterministic ray sets).
float uniform(uint32_t& seed) { return float((seed = seed * 1664525u + 1013904223u) >> 8) * 0x1p-24f; }

/// A cosine-distributed unit direction about the unit normal n.
glm::vec3 cosineAround(glm::vec3 n, uint32_t& seed) {
  const glm::vec3 t = glm::normalize(std::abs(n.x) > 0.5f ? glm::cross(n, {0, 1, 0}) : glm::cross(n, {1, 0, 0})), b = glm::cross(n, t);
  const float r1 = uniform(seed), r = std::sqrt(r1), phi = 6.2831853f * uniform(seed);
  return glm::normalize(t * (r * std::cos(phi)) + b * (r * std::sin(phi)) + n * std::sqrt(std::max(0.0f, 1.0f - r1)));
}

struct Setup {
  lt::Frame frame;
  std::vector<lt::Ray> rays;
  /// One ambient-occlusion ray per covered pixel, in the same order: cosine-distributed about the
  /// stored normal (turned to the eye), 5 % of the scene's diagonal long (render's default).
  std::vector<lt::Ray> aoRays;
  lt::IntervalPyramid pyramid;
};

/// Scene 0: FZK-Haus interior, 1: am_thornish hall, 2: engine interior.
Setup& setup(int scene) {
  static Setup s[3];
  static bool ready[3] = {false, false, false};
  if (!ready[scene]) {
    static const char* const files[3] = {"/scenes/fzk-haus.json", "/scenes/am-thornish.json", "/scenes/engine.json"};
    static const char* const cameras[3] = {"interior", "hall", "interior"};
    lt::FrameOptions o;
    o.scenePath = std::string(LAYERTRACE_SOURCE_DIR) + files[scene];
    o.cameraName = cameras[scene];
    s[scene].frame = lt::buildFrame(o);
    const lt::Frame& f = s[scene].frame;
    const float maxDist = f.scene.bounds().diagonal();
    uint32_t seed = 1;
    // In 8×8 pixel tiles, row by row of tiles, as the renderer lays its rays out (render/effects.cpp):
    // neighbouring rays of a batch then share cells as they do in `render` and `compare`.
    constexpr int kTile = 8;
    const int W = f.camera.width(), H = f.camera.height();
    for (int ty = 0; ty < H; ty += kTile)
      for (int tx = 0; tx < W; tx += kTile)
        for (int y = ty; y < std::min(ty + kTile, H); ++y)
          for (int x = tx; x < std::min(tx + kTile, W); ++x) {
            if (!f.layers.countAt(x, y)) continue;
            const lt::FragmentNode& fr = f.layers.pixel(x, y)[0];
            lt::Ray r;
            r.origin = f.camera.rayThrough({x + 0.5f, y + 0.5f}) * fr.depth;
            const glm::vec3 v = glm::normalize(r.origin), n = lt::decodeOctahedral(fr.normal);
            const glm::vec3 facing = glm::dot(n, v) > 0.0f ? -n : n;
            r.dir = glm::reflect(v, facing);
            r.maxDistance = maxDist;
            s[scene].rays.push_back(r);
            r.dir = cosineAround(facing, seed);
            r.maxDistance = 0.05f * maxDist;
            s[scene].aoRays.push_back(r);
          }
    s[scene].pyramid = lt::buildIntervalPyramid(f.layers, f.camera, lt::PyramidConfig{});
    ready[scene] = true;
  }
  return s[scene];
}

/// items [0, n) in batches of 256, `batch(begin, length)`, over all threads (1024 items a task):
/// how every pass here hands work to a tracer or a march.
template <class Batch>
void forBatches(size_t n, Batch&& batch) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t b = r.begin(); b < r.end(); b += 256) batch(b, std::min<size_t>(256, r.end() - b));
  });
}

/// One uncounted traceBatch pass of `tracer` over `rays` (the counter-free instantiation of the
/// tracer, trace/tracer.h).
void tracePass(const lt::Tracer& tracer, const std::vector<lt::Ray>& rays, std::vector<lt::TraceHit>& hits,
               lt::Query q = lt::Query::Closest) {
  forBatches(rays.size(), [&](size_t b, size_t len) {
    tracer.query(q, std::span<const lt::Ray>(&rays[b], len), std::span<lt::TraceHit>(&hits[b], len), {});
  });
  benchmark::DoNotOptimize(hits.data());
}

void traceAll(benchmark::State& state, const lt::Tracer& tracer, const std::vector<lt::Ray>& rays, lt::Query q = lt::Query::Closest) {
  std::vector<lt::TraceHit> hits(rays.size());
  for (auto _ : state) tracePass(tracer, rays, hits, q);
  // Counted once, outside the timing.
  std::vector<lt::RayCounters> counters(rays.size());
  tracer.query(q, rays, hits, counters);
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
  const lt::HssrTracer t(s.frame.camera, s.frame.layers, s.pyramid, lt::HssrConfig{2, kLevels});
  traceAll(state, t, s.rays);
}

/// Each round times pass(0) … pass(n − 1) on the same rays, rotating which runs first; the
/// counters `<name>_ms` are the medians (the machine is noisy, a ratio within one round is not).
template <class Pass>
std::vector<double> timeAlternating(benchmark::State& state, std::initializer_list<const char*> names, Pass&& pass) {
  const int n = int(names.size());
  std::vector<std::vector<double>> ms(static_cast<size_t>(n));
  int round = 0;
  for (auto _ : state) {
    for (int k = 0; k < n; ++k) {
      const int v = (round + k) % n;
      ms[size_t(v)].push_back(pass(v));
    }
    ++round;
  }
  std::vector<double> median;
  int v = 0;
  for (const char* name : names) {
    std::vector<double>& m = ms[size_t(v++)];
    std::sort(m.begin(), m.end());
    median.push_back(m[m.size() / 2]);
    state.counters[std::string(name) + "_ms"] = median.back();
  }
  return median;
}

/// `pass(false)` (one ray at a time) against `pass(true)` (the lanes): one_ms, lanes_ms, speedup.
template <class Pass>
void timeOneAgainstLanes(benchmark::State& state, Pass&& pass) {
  const std::vector<double> m = timeAlternating(state, {"one", "lanes"}, [&](int v) { return pass(v == 1); });
  state.counters["speedup"] = m[0] / m[1];
}

/// The HSSR march alone (segments made beforehand, no hit shading), one ray at a time
/// (hssrMarchEach) against the vector lanes (hssrMarchBatch) on the same segments.
void BM_HssrLanes(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  const lt::Frame& f = s.frame;
  std::vector<lt::ScreenSegment> segs(s.rays.size());
  for (size_t i = 0; i < segs.size(); ++i) segs[i] = lt::makeScreenSegment(f.camera, s.rays[i]);
  std::vector<lt::MarchHit> out(segs.size());
  const int W = f.camera.width(), H = f.camera.height();
  auto pass = [&](bool lanes) {
    const auto t0 = std::chrono::steady_clock::now();
    forBatches(segs.size(), [&](size_t b, size_t len) {
      const auto in = std::span<const lt::ScreenSegment>(&segs[b], len);
      const auto o = std::span<lt::MarchHit>(&out[b], len);
      if (lanes) lt::hssrMarchBatch(s.pyramid, kLevels, 2, in, W, H, o);
      else lt::hssrMarchEach(s.pyramid, kLevels, 2, in, W, H, o);
    });
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  timeOneAgainstLanes(state, pass);
  state.counters["lanes_on"] = lt::hssrLanesAvailable(s.pyramid, kLevels);
}

/// SSR (McGuire and Mara 2014) over the same rays, one ray at a time (the one-ray path of
/// TracerImpl) against the vector lanes (SsrTracer::traceBatch). Args: scene, all layers
/// (ssr-layers), stride.
void BM_SsrLanes(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  lt::SsrConfig c;
  c.allLayers = state.range(1) != 0;
  c.stride = float(state.range(2));
  const lt::SsrTracer t(s.frame.camera, s.frame.layers, c);
  std::vector<lt::TraceHit> hits(s.rays.size());
  auto pass = [&](bool lanes) {
    const auto t0 = std::chrono::steady_clock::now();
    forBatches(s.rays.size(), [&](size_t b, size_t len) {
      const auto in = std::span<const lt::Ray>(&s.rays[b], len);
      const auto o = std::span<lt::TraceHit>(&hits[b], len);
      if (lanes) t.traceBatch(in, o, {});
      else t.TracerImpl<lt::SsrTracer>::traceBatch(in, o, {});
    });
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  timeOneAgainstLanes(state, pass);
}

/// Args: scene, ray set (as BM_Hybrid).
void BM_Embree(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  const lt::EmbreeScene embree(s.frame.scene, lt::EmbreeScene::Mode::Fast);
  const lt::EmbreeTracer t("embree", s.frame.scene, s.frame.camera, embree);
  const bool ao = state.range(1) != 0;
  traceAll(state, t, ao ? s.aoRays : s.rays, ao ? lt::Query::Any : lt::Query::Closest);
}

/// HSSR (the default τ and levels, n_up 2) and plain single-ray Embree on the same rays,
/// alternating in every round (timeAlternating): the ratio `compare` reports, robust to
/// a machine whose speed drifts between runs. Arg: scene.
void BM_HssrAgainstEmbree(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  const lt::EmbreeScene embree(s.frame.scene, lt::EmbreeScene::Mode::Fast);
  const lt::EmbreeTracer e("embree", s.frame.scene, s.frame.camera, embree);
  const lt::HssrTracer h(s.frame.camera, s.frame.layers, s.pyramid, lt::HssrConfig{2, kLevels});
  std::vector<lt::TraceHit> hits(s.rays.size());
  auto pass = [&](int v) {
    const lt::Tracer& t = v == 0 ? static_cast<const lt::Tracer&>(e) : h;
    const auto t0 = std::chrono::steady_clock::now();
    tracePass(t, s.rays, hits);
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  const std::vector<double> m = timeAlternating(state, {"embree", "hssr"}, pass);
  state.counters["hssr_x_embree"] = m[0] / m[1];
}

/// Args: scene, ray set (0: the reflection rays, closest hit; 1: the AO rays, any hit).
void BM_Hybrid(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  const lt::BuiltTracer b = lt::buildTracer("hybrid", s.frame, lt::TracerOptions{});
  const auto& hybrid = dynamic_cast<const lt::HybridTracer&>(*b.tracer);
  const bool ao = state.range(1) != 0;
  traceAll(state, hybrid, ao ? s.aoRays : s.rays, ao ? lt::Query::Any : lt::Query::Closest);
  const lt::HybridStats h = hybrid.stats();
  state.counters["screen%"] = 100.0 * h.screenFraction();
  state.counters["geo%"] = 100.0 * h.geoFraction();
}

/// The irregular grid (Pérard-Gayot et al. 2017) one ray at a time against its batch queries
/// (several rays in flight), with plain single-ray Embree on the same rays in the same rounds.
/// Args: scene, ray set (0 primary, 1 AO: any hit within 5 % of the scene's diagonal, 2 diffuse;
/// both cosine-distributed from the primary hits, as `geobench`).
void BM_GridBatch(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  const lt::Scene& scene = s.frame.scene;
  const lt::Camera& cam = s.frame.camera;
  const lt::EmbreeScene embree(scene, lt::EmbreeScene::Mode::Fast);
  const lt::IrregularGrid grid(scene);
  const int set = int(state.range(1));
  const float diag = scene.bounds().diagonal();
  std::vector<lt::IrregularGrid::Query> q;
  uint32_t seed = 1;
  for (int y = 0; y < cam.height(); ++y)
    for (int x = 0; x < cam.width(); ++x) {
      const glm::vec3 o = cam.desc().eye, d = glm::normalize(cam.dirToWorld(cam.rayThrough({x + 0.5f, y + 0.5f})));
      if (set == 0) {
        q.push_back({o, d, 0.0f, 1e30f});
        continue;
      }
      const lt::GeoHit h = embree.intersect(o, d, 0.0f, 1e30f);
      if (!h.hit()) continue;
      glm::vec3 n = glm::normalize(h.ng);
      if (glm::dot(n, d) > 0.0f) n = -n;
      const glm::vec3 dir = cosineAround(n, seed);
      q.push_back({o + d * h.t, dir, 1e-4f * diag, set == 1 ? 0.05f * diag : 1e30f});
    }
  std::vector<float> answer(q.size());
  auto pass = [&](int v) {
    const auto t0 = std::chrono::steady_clock::now();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, q.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
      const std::span<const lt::IrregularGrid::Query> chunk(&q[r.begin()], r.size());
      if (v == 2) {  // the grid's batch
        if (set == 1) {
          std::vector<uint8_t> hit(r.size());
          grid.occluded(chunk, hit);
          for (size_t i = 0; i < r.size(); ++i) answer[r.begin() + i] = hit[i];
        } else {
          std::vector<lt::GeoHit> hit(r.size());
          grid.intersect(chunk, hit);
          for (size_t i = 0; i < r.size(); ++i) answer[r.begin() + i] = hit[i].t;
        }
        return;
      }
      for (size_t i = 0; i < r.size(); ++i) {  // one ray at a time: Embree, or the grid
        const lt::IrregularGrid::Query& a = chunk[i];
        if (set == 1) answer[r.begin() + i] = v == 0 ? embree.occluded(a.origin, a.dir, a.tnear, a.tfar) : grid.occluded(a.origin, a.dir, a.tnear, a.tfar);
        else answer[r.begin() + i] = (v == 0 ? embree.intersect(a.origin, a.dir, a.tnear, a.tfar) : grid.intersect(a.origin, a.dir, a.tnear, a.tfar)).t;
      }
    });
    benchmark::DoNotOptimize(answer.data());
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  const std::vector<double> m = timeAlternating(state, {"embree", "grid_one", "grid_batch"}, pass);
  state.counters["batch_speedup"] = m[1] / m[2];
  state.counters["one_x_embree"] = m[0] / m[1];
  state.counters["batch_x_embree"] = m[0] / m[2];
}

void BM_HierarchyBuild(benchmark::State& state) {
  Setup& s = setup(int(state.range(0)));
  for (auto _ : state) {
    lt::IntervalPyramid p = lt::buildIntervalPyramid(s.frame.layers, s.frame.camera, lt::PyramidConfig{});
    benchmark::DoNotOptimize(p.levels.data());
  }
  state.counters["raster_ms"] = s.frame.rasterMs;
  state.counters["sort_ms"] = s.frame.sortMs;
}

// Args: scene (0 = FZK-Haus, 1 = am_thornish), stride, all layers.
BENCHMARK(BM_Hssr)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HssrLanes)->Arg(0)->Arg(1)->Iterations(9)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrLanes)->ArgsProduct({{0, 1}, {0, 1}, {1}})->Iterations(5)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Embree)->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HssrAgainstEmbree)->DenseRange(0, 2)->Iterations(9)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Hybrid)->ArgsProduct({{0, 1}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Ssr)
    ->ArgsProduct({{0, 1}, {1, 2, 3, 4, 8}, {1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_Ssr)->ArgsProduct({{0}, {1, 2, 4, 8}, {0}})->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_GridBatch)->ArgsProduct({{0, 1}, {0, 1, 2}})->Iterations(7)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_HierarchyBuild)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
