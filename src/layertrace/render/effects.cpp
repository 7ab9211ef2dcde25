#include "layertrace/render/effects.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "layertrace/screen/fragment_hit.h"
#if LAYERTRACE_HAS_GPU
#include "layertrace/gpu/gpu_effects.h"
#include "layertrace/render/gpu_effect_params.h"
#endif
#include "layertrace/util/timing.h"
#include "layertrace/util/error.h"
#include "layertrace/util/progress.h"
#include "layertrace/util/parallel.h"

namespace lt {

Effect parseEffect(const std::string& name) {
  if (name == "shade") return Effect::Shade;
  if (name == "reflection") return Effect::Reflection;
  if (name == "refraction") return Effect::Refraction;
  if (name == "ao") return Effect::AO;
  if (name == "shadow") return Effect::Shadow;
  if (name == "warp") return Effect::Warp;
  inputError("--effect ", name, ": unknown (use shade, reflection, refraction, ao, shadow, warp)");
}

const char* effectName(Effect e) {
  switch (e) {
    case Effect::Shade: return "shade";
    case Effect::Reflection: return "reflection";
    case Effect::Refraction: return "refraction";
    case Effect::AO: return "ao";
    case Effect::Shadow: return "shadow";
    case Effect::Warp: return "warp";
  }
  return "?";
}

void validateEffectConfig(const EffectConfig& config) {
  if (config.bounces < 1 || config.bounces > 16) inputError("--bounces ", config.bounces, ": must be between 1 and 16");
  if (config.aoSamples < 1 || config.aoSamples > 4096) inputError("--ao-samples ", config.aoSamples, ": must be between 1 and 4096");
  if (!(config.aoRadius >= 0.0f && std::isfinite(config.aoRadius))) inputError("--ao-radius ", config.aoRadius, ": must be >= 0 and finite");
  if (!(config.maxDistance >= 0.0f && std::isfinite(config.maxDistance)))
    inputError("--max-distance ", config.maxDistance, ": must be >= 0 and finite");
  if (config.effect == Effect::Warp && !config.warpEye) inputError("--effect warp: needs --warp-eye x,y,z");
  for (const auto& v : {config.warpEye, config.warpTarget})
    if (v && !std::isfinite(v->x + v->y + v->z)) inputError("--warp-eye/--warp-target ", v->x, ",", v->y, ",", v->z, ": not finite");
}

Camera warpCamera(const Frame& frame, const EffectConfig& config) {
  const Camera& first = frame.camera;
  CameraDesc d = first.desc();
  d.name = "warp";
  if (config.warpEye) d.eye = frame.scene.fromWorld(*config.warpEye);
  if (config.warpTarget) d.target = frame.scene.fromWorld(*config.warpTarget);
  const glm::dvec3 eye = frame.scene.toWorld(d.eye);
  if (!std::isfinite(d.eye.x + d.eye.y + d.eye.z + d.target.x + d.target.y + d.target.z))
    inputError("--warp-eye/--warp-target ", eye.x, ",", eye.y, ",", eye.z, ": out of range");
  if (!(glm::length(d.target - d.eye) > 0.0f)) inputError("--warp-eye ", eye.x, ",", eye.y, ",", eye.z, ": equals the target");
  d.near = first.near(), d.far = first.far();
  return Camera(d, first.width(), first.height());
}

namespace {

constexpr int kHistogramMax = 1 << 16;
constexpr size_t kBatchRays = 256;   ///< rays per traceBatch call
constexpr size_t kBandRays = 4096;   ///< rays in flight per thread and wave (keeps buffers in L2)
constexpr int kTile = 8;             ///< rays are laid out in kTile × kTile pixel tiles

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

/// The effect's ray lengths with their scene-dependent defaults: reflection and refraction rays
/// cross the scene (its diagonal), AO rays 5 % of it, and a shadow ray stops 1e-4 of it short
/// of its light.
struct RayLengths {
  float maxDistance, aoRadius, eps;
};
RayLengths rayLengths(const Frame& f, const EffectConfig& c) {
  const float diag = f.scene.bounds().diagonal();
  return {c.maxDistance > 0.0f ? c.maxDistance : diag, c.aoRadius > 0.0f ? c.aoRadius : 0.05f * diag, 1e-4f * diag};
}

/// View synthesis: the second camera, its eye in the first camera's space, and its rays' length
/// (long enough to cross the scene from wherever the eye is).
struct WarpRays {
  Camera camera;
  glm::vec3 origin{0.0f};
  float maxDistance = 1.0f;
};
WarpRays warpRays(const Frame& f, const EffectConfig& c) {
  WarpRays w;
  w.camera = warpCamera(f, c);
  w.origin = f.camera.toCamera(w.camera.desc().eye);
  w.maxDistance = 2.0f * f.scene.bounds().diagonal() + glm::length(w.camera.desc().eye - f.scene.bounds().center());
  return w;
}

/// The smallest iteration count that at least 99 % of the `rays` do not exceed.
template <class Count>
uint64_t percentile99(const std::vector<Count>& histogram, uint64_t rays) {
  uint64_t seen = 0;
  for (size_t i = 0; i < histogram.size(); ++i) {
    seen += histogram[i];
    if (rays && double(seen) >= 0.99 * double(rays)) return i;
  }
  return 0;
}

struct Accum {
  uint64_t rays = 0, hits = 0, it = 0, iv = 0, px = 0, fr = 0, giveUps = 0, bent = 0;
  uint64_t planes = 0, boxes = 0, occlusions = 0;
  uint64_t level[RayCounters::kLevels] = {};
  std::vector<uint64_t> histogram;
  double traceMs = 0.0, busyMs = 0.0;  ///< time inside tracer calls / processing bands
};

struct Surface {
  glm::vec3 p{0.0f}, n{0.0f};  ///< camera space; n faces the viewer of this surface
  glm::vec3 ng{0.0f};          ///< camera-space geometric normal, on the viewer's side
  glm::vec3 albedo{0.0f};
  float specular = 0.0f;
  const Material* material = nullptr;
  uint32_t triangle = kNoTriangle;  ///< the scene triangle: rays leaving it never answer with it
};

/// One pixel's path between waves: the effect's state machine (see effects.h).
struct PathState {
  int x = 0, y = 0;
  bool done = true;        ///< issues no more rays; `result` is final
  Surface s;               ///< the surface the next ray leaves from
  glm::vec3 v{0.0f};       ///< view direction at the front surface
  glm::vec3 incoming{0.0f};  ///< reflection: the direction arriving at s
  glm::vec3 colour{0.0f}, weight{1.0f};  ///< reflection: accumulated colour and path weight
  glm::vec3 dir{0.0f};     ///< the direction of the ray in flight, as computed (unnormalised)
  glm::vec3 result{0.0f};
  glm::vec3 traced{0.0f};  ///< what the rays brought back, unweighted by materials (EffectResult::traced)
  // Refraction: the front surface's reflection and what is seen through it.
  float fresnel = 0.0f;
  glm::vec3 reflected{0.0f};  ///< the colour the reflection ray brought back
  glm::vec3 through{0.0f}, out{0.0f};
  Surface back;
  float it = 0.0f, iv = 0.0f;  ///< counters summed over the pixel's rays
  uint32_t bent = 0;             ///< rays bent out of the geometric surface (keepOutside)
  bool hole = false;             ///< warp: the ray found nothing
  uint32_t first = 0, count = 0;  ///< the pixel's rays in the current wave's dense arrays
};

/// A thread's buffers for one band of pixels, reused across bands and waves.
struct Band {
  // Pool vectors (util/default_init.h): a whole-wave band holds the whole frame, and huge pages
  // cut its first-touch page faults.
  PoolVector<PathState> states;
  PoolVector<Ray> rays;           ///< the wave's rays, dense, in tile order
  std::vector<uint16_t> samples;  ///< each ray's index among its pixel's rays of the wave
  PoolVector<TraceHit> hits;
  PoolVector<RayCounters> counters;
  std::vector<RayEvent> events;
  PoolVector<Ray> denseRays;           ///< whole waves: the rays emitted per pixel, compacted
  std::vector<uint16_t> denseSamples;
};

class Renderer {
 public:
  Renderer(const Frame& f, const Tracer& t, const EffectConfig& c, RayObserver* observer)
      : f_(f), tracer_(t), config_(c), observer_(observer) {
    for (const PointLight& l : f.lights) lights_.push_back({f.camera.toCamera(l.position), l.intensity});
    const RayLengths lengths = rayLengths(f, c);
    maxDist_ = lengths.maxDistance, aoRadius_ = lengths.aoRadius, eps_ = lengths.eps;
    query_ = c.effect == Effect::AO || c.effect == Effect::Shadow ? Query::Any : Query::Closest;
    if (c.effect == Effect::Warp) {
      const WarpRays w = warpRays(f, c);
      warp_ = w.camera, warpOrigin_ = w.origin, warpMax_ = w.maxDistance;
    }
  }

  /// Bands of up to one 8×8 tile (fewer pixels when each pixel has many rays) are processed
  /// by the worker threads independently, each wave by wave; the time inside the tracer calls
  /// is attributed to `traceMs` as its share of the workers' busy time, times the wall time.
  EffectResult run() {
    const int W = f_.camera.width(), H = f_.camera.height();
    EffectResult res;
    res.image = Image(W, H);
    res.traced = Image(W, H);
    if (config_.effect == Effect::Warp) res.holes.assign(size_t(W) * size_t(H), 0);
    res.iterations = Image(W, H, 1);
    res.intervals = Image(W, H, 1);
    const std::vector<uint32_t> order = tileOrder(W, H);
    const size_t bandPixels = config_.wholeWaves ? std::max<size_t>(order.size(), 1)
                                                 : std::clamp<size_t>(kBandRays / size_t(maxRaysPerPixel()), 1, size_t(kTile * kTile));
    const size_t bands = (order.size() + bandPixels - 1) / bandPixels;
    Progress progress(cat(tracer_.name(), " ", effectName(config_.effect)), order.size(), config_.progress);
    tbb::enumerable_thread_specific<Band> bandBuffers;
    const auto start = Clock::now();
    auto runBands = [&](const tbb::blocked_range<size_t>& r) {
      Band& band = bandBuffers.local();
      Accum& a = accums_.local();
      if (a.histogram.empty() && config_.countRays) a.histogram.assign(kHistogramMax + 1, 0);
      const auto t0 = Clock::now();
      for (size_t b = r.begin(); b != r.end(); ++b) {
        const size_t p0 = b * bandPixels, n = std::min(bandPixels, order.size() - p0);
        // (the whole frame is one band with EffectConfig::wholeWaves: its pixels start and
        // finish in parallel)
        band.states.resize(n);
        auto begin1 = [&](size_t i) {
          band.states[i] = PathState{};
          begin(band.states[i], int(order[p0 + i] % uint32_t(W)), int(order[p0 + i] / uint32_t(W)));
        };
        auto finish1 = [&](size_t i) {
          const PathState& st = band.states[i];
          res.image.set(st.x, st.y, st.result);
          res.traced.set(st.x, st.y, st.traced);
          if (!res.holes.empty()) res.holes[size_t(st.y) * size_t(W) + size_t(st.x)] = st.hole;
          res.iterations.at(st.x, st.y)[0] = st.it;
          res.intervals.at(st.x, st.y)[0] = st.iv;
        };
        if (config_.wholeWaves) parallelFor(size_t(0), n, begin1);
        else for (size_t i = 0; i < n; ++i) begin1(i);
        for (int wave = 0; config_.wholeWaves ? traceWholeWave(wave, band, a) : traceWave(wave, band, a); ++wave) {
        }
        for (const PathState& st : band.states) a.bent += st.bent;
        if (config_.wholeWaves) parallelFor(size_t(0), n, finish1);
        else for (size_t i = 0; i < n; ++i) finish1(i);
        progress.add(n);
      }
      a.busyMs += msSince(t0);
    };
    if (config_.wholeWaves) runBands(tbb::blocked_range<size_t>(0, bands, 1));
    else parallelFor(tbb::blocked_range<size_t>(0, bands, 1), runBands);
    const double wall = msSince(start);
    double traceMs = 0.0, busyMs = 0.0;
    for (const Accum& a : accums_) traceMs += a.traceMs, busyMs += a.busyMs;
    res.traceMs = busyMs > 0.0 ? wall * traceMs / busyMs : 0.0;
    res.shadeMs = wall - res.traceMs;
    gather(res);
    return res;
  }

 private:
  /// Pixels in 8×8 tiles (tiles row by row, pixels row by row inside a tile).
  static std::vector<uint32_t> tileOrder(int W, int H) {
    std::vector<uint32_t> order;
    order.reserve(size_t(W) * size_t(H));
    for (int ty = 0; ty < H; ty += kTile)
      for (int tx = 0; tx < W; tx += kTile)
        for (int y = ty; y < std::min(ty + kTile, H); ++y)
          for (int x = tx; x < std::min(tx + kTile, W); ++x) order.push_back(uint32_t(y) * uint32_t(W) + uint32_t(x));
    return order;
  }

  int maxRaysPerPixel() const {
    switch (config_.effect) {
      case Effect::AO: return config_.aoSamples;
      case Effect::Shadow: return std::max(1, int(lights_.size()));
      case Effect::Refraction: return 2;
      default: return 1;
    }
  }

  /// One wave of a band: every active pixel emits its rays, they are traced in batches, each
  /// pixel consumes its answers. Returns false when no pixel had a ray left.
  bool traceWave(int wave, Band& band, Accum& a) const {
    const size_t n = band.states.size();
    const size_t R = size_t(maxRaysPerPixel());
    // Each pixel emits at most R rays, written straight after the previous pixel's.
    band.rays.resize(n * R);
    band.samples.resize(n * R);
    size_t total = 0;
    for (size_t i = 0; i < n; ++i) {
      PathState& st = band.states[i];
      st.first = uint32_t(total);
      st.count = 0;
      if (st.done) continue;
      for (size_t j = 0; j < R; ++j) band.samples[total + j] = uint16_t(j);
      st.count = emit(wave, st, &band.rays[total], &band.samples[total]);
      total += st.count;
      if (st.count == 0) consume(wave, st, nullptr, nullptr);  // e.g. shadows with every light behind the surface
    }
    if (total == 0) return false;
    band.hits.resize(total);
    band.counters.assign(config_.countRays ? total : 0, RayCounters{});
    // Trace: the only part timed as tracing.
    const auto t0 = Clock::now();
    const size_t batch = config_.wholeWaves ? total : kBatchRays;
    for (size_t b = 0; b < total; b += batch) {
      const size_t len = std::min(batch, total - b);
      const std::span<RayCounters> c = band.counters.empty() ? std::span<RayCounters>() : std::span<RayCounters>(&band.counters[b], len);
      tracer_.query(query_, std::span<const Ray>(&band.rays[b], len), std::span<TraceHit>(&band.hits[b], len), c);
    }
    a.traceMs += msSince(t0);
    // Consume, count and let the observer see the answers.
    band.events.clear();
    for (size_t i = 0; i < n; ++i) answer(wave, band.states[i], band.rays.data(), band.samples.data(), band, a, band.events);
    if (observer_ && !band.events.empty()) observer_->observe(band.events);
    return true;
  }

  /// A pixel's rays of the wave (at st.first in `rays`, `samples` and the band's answers):
  /// counted into `a`, recorded for the observer, then consumed by the pixel's path.
  void answer(int wave, PathState& st, const Ray* rays, const uint16_t* samples, const Band& band, Accum& a,
              std::vector<RayEvent>& events) const {
    if (st.count == 0) return;
    for (uint32_t j = st.first; j < st.first + st.count; ++j) {
      count(st, band.hits[j], config_.countRays ? &band.counters[j] : nullptr, a);
      if (observer_) events.push_back(RayEvent{&rays[j], &band.hits[j], st.x, st.y, wave, int(samples[j]), query_});
    }
    consume(wave, st, &band.hits[st.first], &samples[st.first]);
  }

  /// traceWave for the whole frame in one tracer call (EffectConfig::wholeWaves): the pixels
  /// emit and consume in parallel (each into its own R slots, then compacted in pixel order, so
  /// the tracer sees the rays traceWave would give it, in the same order), the trace runs on the
  /// calling thread.
  bool traceWholeWave(int wave, Band& band, Accum& a) {
    const size_t n = band.states.size();
    const size_t R = size_t(maxRaysPerPixel());
    band.rays.resize(n * R);
    band.samples.resize(n * R);
    parallelFor(size_t(0), n, [&](size_t i) {
      PathState& st = band.states[i];
      st.count = 0;
      if (st.done) return;
      for (size_t j = 0; j < R; ++j) band.samples[i * R + j] = uint16_t(j);
      st.count = emit(wave, st, &band.rays[i * R], &band.samples[i * R]);
      if (st.count == 0) consume(wave, st, nullptr, nullptr);
    });
    size_t total = 0;
    for (PathState& st : band.states) st.first = uint32_t(total), total += st.count;
    if (total == 0) return false;
    band.denseRays.resize(total);
    band.denseSamples.resize(total);
    parallelFor(size_t(0), n, [&](size_t i) {
      const PathState& st = band.states[i];
      std::copy_n(&band.rays[i * R], st.count, &band.denseRays[st.first]);
      std::copy_n(&band.samples[i * R], st.count, &band.denseSamples[st.first]);
    });
    band.hits.resize(total);
    band.counters.assign(config_.countRays ? total : 0, RayCounters{});
    const auto t0 = Clock::now();
    tracer_.query(query_, band.denseRays, band.hits, band.counters);
    a.traceMs += msSince(t0);
    parallelFor(tbb::blocked_range<size_t>(0, n, 4096), [&](const tbb::blocked_range<size_t>& r) {
      Accum& mine = accums_.local();
      if (mine.histogram.empty() && config_.countRays) mine.histogram.assign(kHistogramMax + 1, 0);
      std::vector<RayEvent> events;
      for (size_t i = r.begin(); i != r.end(); ++i)
        answer(wave, band.states[i], band.denseRays.data(), band.denseSamples.data(), band, mine, events);
      if (observer_ && !events.empty()) observer_->observe(events);
    });
    return true;
  }

  static void count(PathState& st, const TraceHit& h, const RayCounters* c, Accum& a) {
    ++a.rays;
    a.hits += h.hit;
    if (!c) return;
    a.it += c->iterations, a.iv += c->intervals, a.px += c->pixels, a.fr += c->fragments, a.giveUps += c->giveUps;
    a.planes += c->planeNodes, a.boxes += c->boxNodes, a.occlusions += c->occlusions;
    for (int l = 0; l < RayCounters::kLevels; ++l) a.level[l] += c->levelIterations[l];
    ++a.histogram[std::min<uint32_t>(c->iterations, kHistogramMax)];
    st.it += float(c->iterations), st.iv += float(c->intervals);
  }

  void gather(EffectResult& res) {
    std::vector<uint64_t> histogram(kHistogramMax + 1, 0);
    for (const Accum& a : accums_) {
      res.rays += a.rays, res.hits += a.hits, res.iterationSum += a.it, res.intervalSum += a.iv, res.pixelSum += a.px;
      res.fragmentSum += a.fr, res.giveUps += a.giveUps;
      res.planeNodeSum += a.planes, res.boxNodeSum += a.boxes, res.occlusionSum += a.occlusions;
      res.bentRays += a.bent;
      for (int l = 0; l < RayCounters::kLevels; ++l) res.levelIterations[l] += a.level[l];
      for (size_t i = 0; i < a.histogram.size(); ++i) histogram[i] += a.histogram[i];
    }
    if (config_.countRays) res.iterationsP99 = percentile99(histogram, res.rays);
  }

  Surface surfaceOf(const TraceHit& h, glm::vec3 incoming) const {
    Surface s;
    s.p = h.point;
    s.triangle = h.triangle;
    s.n = glm::dot(h.normal, incoming) > 0.0f ? -h.normal : h.normal;
    s.ng = s.n;
    if (h.triangle < f_.scene.triangles.size()) {
      const glm::uvec3 t = f_.scene.triangles[h.triangle];
      const glm::vec3 a = f_.scene.positions[t.x];
      const glm::vec3 g = glm::cross(f_.scene.positions[t.y] - a, f_.scene.positions[t.z] - a);
      if (glm::dot(g, g) > 0.0f) s.ng = glm::normalize(f_.camera.dirToCamera(g));
      if (glm::dot(s.ng, incoming) > 0.0f) s.ng = -s.ng;
    }
    s.albedo = unpackAlbedo(h.albedoSpec);
    s.specular = unpackSpecular(h.albedoSpec);
    s.material = &f_.scene.materials[h.triangle < f_.scene.triMaterial.size() ? f_.scene.triMaterial[h.triangle] : 0];
    return s;
  }

  glm::vec3 light(const Surface& s, glm::vec3 incoming, int lightIndex) const {
    const auto& [pos, intensity] = lights_[size_t(lightIndex)];
    const glm::vec3 toL = pos - s.p;
    const float d2 = std::max(glm::dot(toL, toL), 1e-12f);
    const glm::vec3 l = toL / std::sqrt(d2);
    const float ndl = glm::dot(s.n, l);
    if (ndl <= 0.0f) return glm::vec3(0.0f);
    const glm::vec3 hv = glm::normalize(l - incoming);
    const float e = s.material->shininess;
    const float spec = s.specular * (e + 8.0f) / 8.0f * std::pow(std::max(0.0f, glm::dot(s.n, hv)), e);
    return intensity / d2 * (s.albedo * ndl + glm::vec3(spec));
  }

  glm::vec3 local(const Surface& s, glm::vec3 incoming) const {
    glm::vec3 c = 0.05f * s.albedo;
    for (int i = 0; i < int(lights_.size()); ++i) c += light(s, incoming, i);
    return c;
  }

  /// A secondary ray leaving surface `s` (never answered with s's own triangle: Tracer::query).
  static Ray ray(const Surface& s, glm::vec3 d, float maxDist) {
    Ray r{s.p, glm::normalize(d), maxDist};
    r.originTriangle = s.triangle;
    return r;
  }

  /// A secondary ray leaving surface s must leave on the outside of its geometric surface.
  /// Interpolated (shading) normals can send a reflection or an AO sample into or along the
  /// triangle it starts on — a flat wall with smooth vertex normals reflects half its rays into
  /// itself; a geometric tracer then passes through the wall, an image-space tracer hits the
  /// wall it started from. Such a direction is mirrored about the geometric plane (d − 2(d·n_g)n_g:
  /// it leaves at the angle it would have entered) and counted (`rays.bent`). Measured on a box
  /// room with smooth corner normals, a view along one wall (tests/origin_rule_test.cpp; 320×180,
  /// one bounce, HSSR, with the origin rule of Tracer::query): 71 % of the reflections are below
  /// the wall; bent up to graze it, 20 % of the rays are correct hits and 65 % false misses (image
  /// space cannot follow a ray skimming a surface); mirrored, 79 % and 3 %, wrong hits 0.9 % both
  /// ways (without the origin rule: 75 % bent, 9.5 % mirrored). A direction that stays within kMinElevation
  /// of the plane after that (or every one, with mirrorBelowSurface off) is bent up to
  /// kMinElevation above it, as production ray tracers do.
  static constexpr float kMinElevation = 0.01f;  ///< sine of the smallest angle above the plane (0.57°)
  glm::vec3 keepOutside(glm::vec3 dir, const Surface& s, uint32_t& bent) const {
    glm::vec3 d = glm::normalize(dir);
    float e = glm::dot(d, s.ng);
    if (e >= kMinElevation) return dir;
    ++bent;
    if (config_.mirrorBelowSurface && e < 0.0f) {
      d -= 2.0f * e * s.ng;
      e = -e;
      if (e >= kMinElevation) return d;
    }
    return d + s.ng * (kMinElevation - e);
  }

  /// The pixel's front surface; pixels without fragments show the environment and trace nothing.
  void begin(PathState& st, int x, int y) const {
    st.x = x, st.y = y;
    if (config_.effect == Effect::Warp) {  // pixels of the second camera: no surface to start from
      st.done = false;
      return;
    }
    const LayerArrays& L = f_.layers;
    if (L.countAt(x, y) == 0) {
      st.result = st.traced = f_.scene.environment;
      st.done = true;
      return;
    }
    const TraceHit front = fragmentHit(f_.camera, L, x, y, 0);
    st.v = glm::normalize(front.point);
    st.s = surfaceOf(front, st.v);
    st.incoming = st.v;
    st.done = false;
    if (config_.effect == Effect::Shade || (config_.effect == Effect::Refraction && st.s.material->transmission <= 0.0f))
      st.result = st.traced = local(st.s, st.v), st.done = true;
  }

  /// Reflection, one bounce's start: blend in the surface's own light, continue the mirror path.
  Ray reflectFrom(PathState& st) const {
    const float m = st.s.material->mirror;
    st.colour += st.weight * (1.0f - m) * local(st.s, st.incoming);
    st.weight *= m;
    st.dir = keepOutside(glm::reflect(st.incoming, st.s.n), st.s, st.bent);
    return ray(st.s, st.dir, maxDist_);
  }

  /// Writes the pixel's rays of `wave` to `out` (at most maxRaysPerPixel; `samples` holds each
  /// slot's index and may be overwritten with another sample id); returns how many.
  uint32_t emit(int wave, PathState& st, Ray* out, uint16_t* samples) const {
    switch (config_.effect) {
      case Effect::Shade: return 0;
      case Effect::Reflection: out[0] = reflectFrom(st); return 1;
      case Effect::Warp: {
        // The second camera's primary ray through this pixel, in the first camera's space.
        st.dir = glm::normalize(f_.camera.dirToCamera(warp_.dirToWorld(warp_.rayThrough({float(st.x) + 0.5f, float(st.y) + 0.5f}))));
        out[0] = Ray{warpOrigin_, st.dir, warpMax_};
        out[0].startsOnSurface = false;  // an eye, not a surface: its first pixel counts
        return 1;
      }
      case Effect::Shadow: {
        uint32_t n = 0;
        for (int i = 0; i < int(lights_.size()); ++i) {
          const glm::vec3 toL = lights_[size_t(i)].first - st.s.p;
          const float d = glm::length(toL);
          if (glm::dot(toL, st.s.n) <= 0.0f) continue;  // facing away: dark without a ray
          samples[n] = uint16_t(i);  // the light's index
          out[n++] = ray(st.s, toL, std::max(d - eps_, 0.0f));
        }
        return n;
      }
      case Effect::AO: {
        // One splitmix64 stream per pixel: deterministic for any thread count, and cheap to
        // seed (a Mersenne Twister per pixel would cost more than its rays).
        uint64_t state = config_.seed * 0x9E3779B97F4A7C15ull + uint64_t(st.y) * 65537ull + uint64_t(st.x);
        auto u = [&state] {
          uint64_t z = (state += 0x9E3779B97F4A7C15ull);
          z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
          z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
          return float((z ^ (z >> 31)) >> 40) * (1.0f / 16777216.0f);  // 24 bits → [0, 1)
        };
        const glm::vec3 n = st.s.n;
        const glm::vec3 t = glm::normalize(std::abs(n.x) > 0.5f ? glm::cross(n, {0, 1, 0}) : glm::cross(n, {1, 0, 0}));
        const glm::vec3 bt = glm::cross(n, t);
        for (int k = 0; k < config_.aoSamples; ++k) {
          const float r1 = u(), r2 = u(), r = std::sqrt(r1), phi = 2.0f * glm::pi<float>() * r2;
          const glm::vec3 d = t * (r * std::cos(phi)) + bt * (r * std::sin(phi)) + n * std::sqrt(std::max(0.0f, 1.0f - r1));
          out[k] = ray(st.s, keepOutside(d, st.s, st.bent), aoRadius_);
        }
        return uint32_t(config_.aoSamples);
      }
      case Effect::Refraction: {
        if (wave == 0) {
          // Enter (air → ior), travel to the back surface (a deeper layer), leave (ior → air).
          const Material& m = *st.s.material;
          const float cosi = -glm::dot(st.v, st.s.n);
          const float f0 = std::pow((1.0f - m.ior) / (1.0f + m.ior), 2.0f);
          st.fresnel = f0 + (1.0f - f0) * std::pow(1.0f - std::clamp(cosi, 0.0f, 1.0f), 5.0f);
          out[0] = reflectFrom(st);  // st.dir keeps its direction for consume
          st.out = glm::refract(st.v, st.s.n, 1.0f / m.ior);
          st.through = f_.scene.environment;
          if (glm::dot(st.out, st.out) == 0.0f) return 1;
          out[1] = ray(st.s, st.out, maxDist_);
          return 2;
        }
        out[0] = ray(st.back, st.out, maxDist_);  // wave 1: leaving the transmissive back surface
        return 1;
      }
    }
    return 0;
  }

  /// Takes the answers to the pixel's rays of `wave`.
  void consume(int wave, PathState& st, const TraceHit* h, const uint16_t* samples) const {
    switch (config_.effect) {
      case Effect::Shade: break;
      case Effect::Warp:
        st.hole = !h[0].hit;
        st.result = st.traced = h[0].hit ? local(surfaceOf(h[0], st.dir), st.dir) : f_.scene.environment;
        st.done = true;
        return;
      case Effect::Reflection: {
        if (!h[0].hit) {
          st.result = st.colour + st.weight * f_.scene.environment;
          st.traced = f_.scene.environment;
          st.done = true;
          return;
        }
        st.s = surfaceOf(h[0], st.dir);
        st.incoming = st.dir;
        if (wave + 1 == config_.bounces) {
          st.traced = local(st.s, st.incoming);
          st.result = st.colour + st.weight * st.traced;
          st.done = true;
        }
        return;
      }
      case Effect::Shadow: {
        glm::vec3 c = 0.05f * st.s.albedo;
        for (uint32_t j = 0; j < st.count; ++j)
          if (!h[j].hit) c += light(st.s, st.v, samples[j]);
        st.result = st.traced = c;
        st.done = true;
        return;
      }
      case Effect::AO: {
        int open = 0;
        for (uint32_t j = 0; j < st.count; ++j) open += !h[j].hit;
        st.result = st.traced = glm::vec3(float(open) / float(std::max(1, config_.aoSamples)));
        st.done = true;
        return;
      }
      case Effect::Refraction: {
        if (wave == 0) {
          st.reflected = h[0].hit ? st.colour + st.weight * local(surfaceOf(h[0], st.dir), st.dir)
                                  : st.colour + st.weight * f_.scene.environment;
          if (st.count == 2 && h[1].hit) {
            const glm::vec3 dir = st.out;
            st.back = surfaceOf(h[1], dir);
            glm::vec3 out = glm::refract(glm::normalize(dir), st.back.n,
                                         st.back.material->transmission > 0.0f ? st.back.material->ior : 1.0f);
            if (glm::dot(out, out) == 0.0f) out = glm::reflect(glm::normalize(dir), st.back.n);  // total internal reflection
            if (st.back.material->transmission <= 0.0f) {
              st.through = local(st.back, dir);  // the refracted ray met an opaque surface
            } else {
              st.out = out;
              return;  // wave 1 leaves the back surface
            }
          }
        } else {
          st.through = h[0].hit ? local(surfaceOf(h[0], st.out), st.out) : f_.scene.environment;
        }
        const float tr = st.s.material->transmission;
        st.result = (1.0f - tr) * local(st.s, st.v) + tr * ((1.0f - st.fresnel) * st.s.albedo * st.through + st.fresnel * st.reflected);
        st.traced = st.through;
        st.done = true;
        return;
      }
    }
  }

  const Frame& f_;
  const Tracer& tracer_;
  EffectConfig config_;
  RayObserver* observer_;
  Query query_ = Query::Closest;
  std::vector<std::pair<glm::vec3, glm::vec3>> lights_;  ///< camera-space position, intensity
  float maxDist_ = 1.0f, aoRadius_ = 1.0f, eps_ = 1e-4f;
  Camera warp_;                   ///< Effect::Warp: the second camera
  glm::vec3 warpOrigin_{0.0f};    ///< its eye in the first camera's space
  float warpMax_ = 1.0f;          ///< its rays' length
  tbb::enumerable_thread_specific<Accum> accums_;
};

#if LAYERTRACE_HAS_GPU
}  // namespace

GpuEffectParams gpuEffectParams(const Frame& f, const EffectConfig& c) {
  GpuEffectParams p;
  switch (c.effect) {
    case Effect::Shade: p.kind = GpuEffectKind::Shade; break;
    case Effect::Reflection: p.kind = GpuEffectKind::Reflection; break;
    case Effect::AO: p.kind = GpuEffectKind::AO; break;
    case Effect::Shadow: p.kind = GpuEffectKind::Shadow; break;
    case Effect::Refraction: p.kind = GpuEffectKind::Refraction; break;
    case Effect::Warp: {
      p.kind = GpuEffectKind::Warp;
      const WarpRays w = warpRays(f, c);
      p.warp = {w.camera, w.origin, w.maxDistance};
      break;
    }
  }
  const RayLengths lengths = rayLengths(f, c);
  p.bounces = c.bounces;
  p.aoSamples = c.aoSamples;
  p.maxDistance = lengths.maxDistance, p.aoRadius = lengths.aoRadius, p.eps = lengths.eps;
  p.seed = c.seed;
  p.countRays = c.countRays;
  p.mirrorBelowSurface = c.mirrorBelowSurface;
  return p;
}

namespace {

/// The effect on the GPU (EffectConfig::shadeOnDevice), with the Renderer's parameters.
std::optional<EffectResult> renderOnGpu(const Frame& f, const Tracer& tracer, const EffectConfig& c) {
  const auto* gpuTracer = dynamic_cast<const GpuEffectTracer*>(&tracer);
  if (!gpuTracer || !gpuTracer->effectsOnDevice() || !GpuEffects::supports(int(f.lights.size()))) return std::nullopt;
  const GpuEffectParams p = gpuEffectParams(f, c);
  const GpuEffects& effects = gpuTracer->effects(f.scene, f.layers, f.lights);
  const GpuEffectOutput out = effects.run(*gpuTracer, p);

  EffectResult res;
  const int W = out.width, H = out.height;
  res.image = Image(W, H);
  res.traced = Image(W, H);
  res.iterations = Image(W, H, 1);
  res.intervals = Image(W, H, 1);
  if (c.effect == Effect::Warp) res.holes.assign(size_t(W) * size_t(H), 0);
  // Row by row in parallel, each row's counters summed apart, then the rows in order.
  std::vector<Accum> rows(size_t(std::max(H, 0)));
  parallelFor(0, H, [&](int y) {
    Accum& a = rows[size_t(y)];
    for (int x = 0; x < W; ++x) {
      const size_t q = size_t(y) * size_t(W) + size_t(x);
      const GpuPixelTally& t = out.tally[q];
      res.image.set(x, y, out.image[q]);
      res.traced.set(x, y, out.traced[q]);
      res.iterations.at(x, y)[0] = float(t.iterations);
      res.intervals.at(x, y)[0] = float(t.intervals);
      if (!res.holes.empty()) res.holes[q] = uint8_t(t.hole);
      a.rays += t.rays, a.hits += t.hits, a.bent += t.bent;
      a.it += t.iterations, a.iv += t.intervals, a.px += t.pixels, a.giveUps += t.giveUps;
      for (int l = 0; l < RayCounters::kLevels; ++l) a.level[l] += t.levelIterations[l];
    }
  });
  for (const Accum& a : rows) {
    res.rays += a.rays, res.hits += a.hits, res.bentRays += a.bent;
    res.iterationSum += a.it, res.intervalSum += a.iv, res.pixelSum += a.px, res.giveUps += a.giveUps;
    for (int l = 0; l < RayCounters::kLevels; ++l) res.levelIterations[l] += a.level[l];
  }
  if (c.countRays) res.iterationsP99 = percentile99(out.histogram, res.rays);
  const GpuTracerSums sums = gpuTracer->effectSums();
  res.planeNodeSum = sums.planeNodes, res.boxNodeSum = sums.boxNodes, res.occlusionSum = sums.occlusions;
  res.onDevice = true;
  res.deviceBytes = effects.memoryBytes();
  res.traceMs = out.traceMs;
  res.shadeMs = out.shadeMs;
  return res;
}
#endif

}  // namespace

EffectResult renderEffect(const Frame& frame, const Tracer& tracer, const EffectConfig& config, RayObserver* observer) {
  validateEffectConfig(config);
#if LAYERTRACE_HAS_GPU
  if (config.shadeOnDevice && config.wholeWaves && !observer)
    if (std::optional<EffectResult> r = renderOnGpu(frame, tracer, config)) return std::move(*r);
#endif
  Renderer renderer(frame, tracer, config, observer);
  return renderer.run();
}

TraceTiming measureTrace(const Frame& frame, const Tracer& tracer, const EffectConfig& config, int repeat) {
  if (repeat < 1) inputError("--repeat ", repeat, ": must be at least 1");
  EffectConfig timing = config;
  timing.countRays = false;
  timing.progress = false;
  std::vector<double> trace, shade;
  for (int i = 0; i < repeat; ++i) {
    const EffectResult r = renderEffect(frame, tracer, timing);
    trace.push_back(r.traceMs), shade.push_back(r.shadeMs);
  }
  return {median(std::move(trace)), median(std::move(shade))};
}

}  // namespace lt
