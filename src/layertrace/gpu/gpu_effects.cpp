#include "layertrace/gpu/gpu_effects.h"

#include <algorithm>
#include <bit>
#include <array>
#include <initializer_list>

#include <glm/geometric.hpp>

#include "layertrace/gpu/gpu_screen_tracer.h"
#include "layertrace/gpu/shader_sources.h"
#include "layertrace/raster/fragment.h"
#include "layertrace/trace/tracer.h"
#include "layertrace/util/default_init.h"
#include "layertrace/util/error.h"
#include "layertrace/util/parallel.h"

namespace lt {

namespace {

/// shaders/effect_common.glsl sizes (std430).
constexpr size_t kRayBytes = 32, kHitBytes = 64, kEffectRayBytes = 96, kStateBytes = 224, kOutBytes = 32, kRecordBytes = 48;
/// shaders/effect_step.comp's tally: 16 words, the histogram, then 16 words per pixel slot.
constexpr size_t kHistogramFirst = 16, kHistogramBins = 65537, kPixelTallyFirst = kHistogramFirst + kHistogramBins;
static_assert(kOriginSkips == 4, "effect_resolve.comp continues a ray past its own triangle 4 times");
constexpr int kTile = 8;  ///< pixel slots run in 8×8 tiles (effect_common.glsl slotPixel)

struct TriangleRecord {
  float normal[3], mirror;
  float shininess, transmission, ior, unused;
};
static_assert(sizeof(TriangleRecord) == 32);

int waves(const GpuEffectParams& p) {
  switch (p.kind) {
    case GpuEffectKind::Shade: return 0;
    case GpuEffectKind::Reflection: return p.bounces;
    case GpuEffectKind::AO:
    case GpuEffectKind::Shadow:
    case GpuEffectKind::Warp: return 1;
    case GpuEffectKind::Refraction: return 2;
  }
  return 0;
}

}  // namespace

GpuEffects::GpuEffects(GpuContext& gpu, const Scene& scene, std::span<const PointLight> lights)
    : gpu_(gpu), lights_(int(lights.size())), triangleCount_(uint32_t(scene.triangles.size())), environment_(scene.environment) {
  LT_CHECK(lights.size() <= size_t(kMaxLights), lights.size());
  gpu_.makeCurrent();
  step_ = &gpu_.computeProgram("effect_step.comp", shader_source::effect_step_comp);
  resolve_ = &gpu_.computeProgram("effect_resolve.comp", shader_source::effect_resolve_comp);
  rounds_ = &gpu_.computeProgram("effect_rounds.comp", shader_source::effect_rounds_comp);
  sum_ = &gpu_.computeProgram("effect_sums.comp", shader_source::effect_sums_comp);
  percentile_ = &gpu_.computeProgram("effect_percentile.comp", shader_source::effect_percentile_comp);
  for (const PointLight& l : lights) lightPosition_.push_back(l.position), lightIntensity_.push_back(l.intensity);
}

GpuEffects::GpuEffects(GpuContext& gpu, const Scene& scene, const Camera& camera, const LayerArrays& layers,
                       std::span<const PointLight> lights)
    : GpuEffects(gpu, scene, lights) {
  LT_CHECK(layers.width == camera.width() && layers.height == camera.height(), layers.width, camera.width());
  camera_ = camera;
  k_ = layers.k;

  // The layer arrays as the passes read them: depth bits, normal, albedo/specular, triangle;
  // a slot without a fragment has depth bits kEmptySlot.
  const size_t pixels = size_t(layers.width) * size_t(layers.height), slots = pixels * size_t(layers.k);
  PoolVector<glm::uvec4> fragments(std::max<size_t>(slots, 1));
  parallelFor(size_t(0), pixels, [&](size_t p) {
    for (int l = 0; l < layers.k; ++l) {
      const size_t s = p * size_t(layers.k) + size_t(l);
      if (l < int(layers.count[p])) {
        const FragmentNode& f = layers.slots[s];
        fragments[s] = {std::bit_cast<uint32_t>(f.depth), f.normal, f.albedoSpec, layers.triangle[s]};
      } else {
        fragments[s] = {0xFFFFFFFFu, 0u, 0u, kNoTriangle};
      }
    }
  });
  ownFragments_ = GpuBuffer(fragments.size() * sizeof(glm::uvec4), fragments.data());

  // Per triangle (render/effects.cpp surfaceOf): the camera-space geometric normal, 0 for a
  // degenerate triangle, and its material; one more record for a triangle the scene lacks.
  PoolVector<TriangleRecord> triangles(scene.triangles.size() + 1);
  auto material = [&](size_t t) -> const Material& {
    return scene.materials[t < scene.triMaterial.size() ? scene.triMaterial[t] : 0];
  };
  parallelFor(size_t(0), triangles.size(), [&](size_t t) {
    glm::vec3 n(0.0f);
    if (t < scene.triangles.size()) {
      const glm::uvec3 v = scene.triangles[t];
      const glm::vec3 a = scene.positions[v.x];
      const glm::vec3 g = glm::cross(scene.positions[v.y] - a, scene.positions[v.z] - a);
      if (glm::dot(g, g) > 0.0f) n = glm::normalize(camera.dirToCamera(g));
    }
    const Material& m = material(t < scene.triangles.size() ? t : 0);
    triangles[t] = {{n.x, n.y, n.z}, m.mirror, m.shininess, m.transmission, m.ior, 0.0f};
  });
  ownTriangles_ = GpuBuffer(triangles.size() * sizeof(TriangleRecord), triangles.data());
}

GpuEffects::~GpuEffects() {
  gpu_.makeCurrent();  // the buffers go with the context current
}

void GpuEffects::setFrame(const Camera& camera, const GpuBuffer& fragments, const GpuBuffer& triangles, int k) {
  camera_ = camera;
  fragments_ = &fragments;
  triangles_ = &triangles;
  k_ = k;
}

void GpuEffects::setUniforms() const {
  // The sRGB decode table of raster/fragment.cpp, read through unpackAlbedo.
  static const std::array<float, 256> srgb = [] {
    std::array<float, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) t[i] = unpackAlbedo(i).x;
    return t;
  }();
  for (const GpuProgram* p : {step_, resolve_}) {
    p->set("uWidth", camera_.width());
    p->set("uHeight", camera_.height());
    p->set("uK", k_);
    p->set("uPixelScale", 1.0f / camera_.focal());
    p->set("uOrtho", int(camera_.orthographic()));
  }
  step_->set("uSrgb", srgb.data(), 256);
  step_->set("uTriangleCount", triangleCount_);
  step_->setVec3("uEnvironment", &environment_.x);
  // The lights in camera space, as the CPU renderer moves them.
  std::vector<glm::vec3> position;
  for (const glm::vec3& l : lightPosition_) position.push_back(camera_.toCamera(l));
  step_->set("uLights", lights_);
  if (lights_ > 0) {
    step_->setVec3("uLightPosition", &position[0].x, lights_);
    step_->setVec3("uLightIntensity", &lightIntensity_[0].x, lights_);
  }
}

size_t GpuEffects::memoryBytes() const {
  size_t b = 0;
  for (const GpuBuffer* buf : std::initializer_list<const GpuBuffer*>{fragments_, triangles_, &rays_, &hits_, &effectRays_, &answers_, &states_, &out_,
                                                                      &tally_, &pending_, &groups_, &sums_, &records_})
    b += buf->bytes();
  return b;
}

namespace {
/// `b` with room for `bytes`: grown when too small, shrunk only when more than four times too
/// large (a frame's buffers stay from frame to frame).
void fit(GpuBuffer& b, size_t bytes) {
  if (b.bytes() < bytes || b.bytes() > 4 * std::max<size_t>(bytes, 16)) b = GpuBuffer(bytes);
}
}  // namespace

void GpuEffects::resize(size_t pixelSlots, size_t chunkSlots, size_t raySlots) const {
  fit(rays_, raySlots * kRayBytes);
  fit(hits_, raySlots * kHitBytes);
  fit(effectRays_, raySlots * kEffectRayBytes);
  fit(answers_, raySlots * kHitBytes);
  fit(states_, chunkSlots * kStateBytes);
  fit(out_, pixelSlots * kOutBytes);
  fit(tally_, (kPixelTallyFirst + 16 * pixelSlots) * sizeof(uint32_t));
  fit(pending_, sizeof(uint32_t));
  fit(groups_, 8 * sizeof(uint32_t));
  fit(sums_, kSumsWords * sizeof(uint32_t));
}

void GpuEffects::collectTimes(double& traceMs, double& shadeMs) const {
  const std::vector<double> ms = timeline_.collect(2);
  traceMs = ms[0], shadeMs = ms[1];
}

const GpuEffects& GpuEffectTracer::effects(const Scene& scene, const LayerArrays& layers, std::span<const PointLight> lights) const {
  auto same = [](const PointLight& a, const PointLight& b) { return a.position == b.position && a.intensity == b.intensity; };
  if (!effects_ || effectsScene_ != &scene || effectsLayers_ != &layers ||
      !std::equal(lights.begin(), lights.end(), effectsLights_.begin(), effectsLights_.end(), same)) {
    effects_.reset();  // (its buffers go before the new ones are made)
    effects_ = std::make_unique<GpuEffects>(context(), scene, effectCamera(), layers, lights);
    effectsScene_ = &scene, effectsLayers_ = &layers;
    effectsLights_.assign(lights.begin(), lights.end());
  }
  return *effects_;
}

void GpuEffectTracer::setEffectCamera(const Camera&) { throw InternalError("setEffectCamera: the tracer's structure belongs to its frame"); }

GpuEffectOutput GpuEffects::run(const GpuEffectTracer& tracer, const GpuEffectParams& p, const GpuEffectReadback& readback) const {
  LT_CHECK(p.bounces >= 1 && p.bounces <= 16 && p.aoSamples >= 1 && p.aoSamples <= 4096, p.bounces, p.aoSamples);
  const Camera& traced = tracer.effectCamera();
  LT_CHECK(camera_.width() == traced.width() && camera_.height() == traced.height(), camera_.width(), traced.width());
  gpu_.makeCurrent();
  GpuDebugGroup group("effect");
  const int W = camera_.width(), H = camera_.height();
  const size_t tilesX = size_t((W + kTile - 1) / kTile), tilesY = size_t((H + kTile - 1) / kTile);
  const size_t pixelSlots = tilesX * tilesY * size_t(kTile * kTile);
  const int R = p.kind == GpuEffectKind::AO           ? p.aoSamples
                : p.kind == GpuEffectKind::Shadow     ? std::max(1, lights_)
                : p.kind == GpuEffectKind::Refraction ? 2
                                                      : 1;
  // Chunks of whole tiles, each run wave by wave to its end.
  const size_t perRaySlot = kRayBytes + 2 * kHitBytes + kEffectRayBytes;  // rays, hits, answers, effect rays
  const size_t tilesPerChunk = std::max<size_t>(1, p.chunkBytes / (perRaySlot * size_t(R) * size_t(kTile * kTile)));
  const size_t chunkSlots = std::min(pixelSlots, tilesPerChunk * size_t(kTile * kTile));
  const size_t raySlots = chunkSlots * size_t(R);
  // One dispatch of 64-invocation groups covers a chunk's rays (indirect dispatches are one).
  LT_CHECK(raySlots <= size_t(65535) * 64, raySlots, p.chunkBytes);
  resize(pixelSlots, chunkSlots, raySlots);
  const GpuEffectTracer::Surfaces surfaces = tracer.surfaces();
  if (surfaces != GpuEffectTracer::Surfaces::Fragments) fit(records_, raySlots * kRecordBytes);
  tally_.fill(0u);
  tracer.beginEffect();
  setUniforms();

  const int nWaves = waves(p);
  const GpuProgram& step = *step_;
  const GpuProgram& resolve = *resolve_;
  step.set("uEffect", int(p.kind));
  step.set("uWaves", nWaves);
  step.set("uAoSamples", p.aoSamples);
  step.set("uMaxDistance", p.maxDistance);
  step.set("uAoRadius", p.aoRadius);
  step.set("uEps", p.eps);
  step.set("uSeedLo", uint32_t(p.seed));
  step.set("uSeedHi", uint32_t(p.seed >> 32));
  step.set("uCount", int(p.countRays));
  step.set("uMirrorBelowSurface", int(p.mirrorBelowSurface));
  step.set("uExcludeOriginTriangle", int(p.excludeOriginTriangle));
  step.set("uRaysPerPixel", R);
  resolve.set("uRaysPerPixel", R);
  resolve.set("uSurfaces", int(surfaces));
  if (p.kind == GpuEffectKind::Warp) {
    LT_CHECK(p.warp.camera.width() == W && p.warp.camera.height() == H, p.warp.camera.width(), W);
    step.setMatrix("uView", &camera_.view()[0][0]);  // (read by view synthesis only)
    step.setMatrix("uWarpViewInverse", &p.warp.camera.viewInverse()[0][0]);
    step.set("uWarpPixelScale", 1.0f / p.warp.camera.focal());
    step.set("uWarpOrtho", int(p.warp.camera.orthographic()));
    step.setVec3("uWarpOrigin", &p.warp.origin.x);
    step.set("uWarpMax", p.warp.maxDistance);
  }

  enum Stage { kTrace = 0, kShade = 1 };
  // One chunk of `items` pixel slots from `base`, wave by wave: a step pass, then per wave the
  // march and the origin rule's rounds, then the next step pass, which takes the answers and
  // emits the next wave. A round after the first runs only where the last left rays pending:
  // the rounds pass turns the pending count into the next round's work groups (0 for none), so
  // the host never waits for it.
  auto runChunk = [&](size_t base, size_t items) {
    const size_t rayItems = items * size_t(R);
    const uint32_t rayGroups = uint32_t((rayItems + 63) / 64);
    // (the march binds its own buffers: each pass binds all of its own)
    auto bindRays = [&] {
      rays_.bindStorage(0);
      fragments_->bindStorage(2);
      effectRays_.bindStorage(4);
      answers_.bindStorage(5);
    };
    auto stepPass = [&](int wave) {
      GpuDebugGroup g("effect step");
      timeline_.begin(kShade);
      bindRays();
      tally_.bindStorage(1);
      triangles_->bindStorage(3);
      states_.bindStorage(6);
      out_.bindStorage(7);
      step.set("uSlotBase", uint32_t(base));
      step.set("uItems", int(items));
      step.set("uWave", wave);
      gpu_.dispatch(step, items);
      timeline_.end(kShade);
    };
    stepPass(0);
    for (int wave = 0; wave < nWaves; ++wave) {
      GpuDebugGroup g("origin rule");
      for (int round = 0; round <= kOriginSkips; ++round) {
        timeline_.begin(kTrace);
        tracer.answerWave(GpuEffectWave{rays_, hits_, records_, rayItems, round == 0 ? nullptr : &groups_, p.countRays,
                                        p.kind == GpuEffectKind::Shadow || p.kind == GpuEffectKind::AO});
        pending_.fill(0u);
        bindRays();
        hits_.bindStorage(1);
        if (surfaces != GpuEffectTracer::Surfaces::Fragments) records_.bindStorage(3);
        pending_.bindStorage(6);
        resolve.set("uItems", int(rayItems));
        resolve.set("uRound", round);
        if (round == 0) gpu_.dispatch(resolve, rayItems);
        else gpu_.dispatchIndirect(resolve, groups_);
        if (round < kOriginSkips) {
          groups_.bindStorage(7);  // (pending_ is bound at 6 from the resolve pass)
          rounds_->set("uGroups", rayGroups);
          rounds_->set("uPersistentGroups", GpuScreenTracer::persistentGroups(size_t(rayItems)));
          gpu_.dispatchGroups(*rounds_, 1);
        }
        timeline_.end(kTrace);
      }
      stepPass(wave + 1);
    }
  };
  for (size_t base = 0; base < pixelSlots; base += chunkSlots) runChunk(base, std::min(chunkSlots, pixelSlots - base));
  {
    // The frame's sums, reduced on the device.
    GpuDebugGroup g("effect sums");
    sums_.fill(0u);
    tally_.bindStorage(1);
    sums_.bindStorage(6);
    sum_->set("uItems", int(pixelSlots));
    gpu_.dispatch(*sum_, pixelSlots);
    if (p.countRays) gpu_.dispatchGroups(*percentile_, 1);  // after the sums (dispatch ends with a barrier)
  }

  GpuEffectOutput out;
  out.width = W, out.height = H;
  if (!readback.image && !readback.tally && !readback.histogram && !readback.sums) return out;
  // Read back, from tile order to rows.
  PoolVector<glm::vec4> pixels(readback.image ? pixelSlots * 2 : 0);
  if (readback.image) out_.read(pixels.data(), pixelSlots * kOutBytes);
  PoolVector<GpuPixelTally> tally(readback.tally ? pixelSlots : 0);
  if (readback.tally) tally_.read(tally.data(), pixelSlots * sizeof(GpuPixelTally), kPixelTallyFirst * sizeof(uint32_t));
  if (readback.histogram && p.countRays) {
    out.histogram.resize(kHistogramBins);
    tally_.read(out.histogram.data(), kHistogramBins * sizeof(uint32_t), kHistogramFirst * sizeof(uint32_t));
  }
  if (readback.sums) {
    uint32_t words[kSumsWords];
    sums_.read(words, sizeof words);
    for (size_t i = 0; i < 16; ++i) out.sums[i] = uint64_t(words[2 * i]) | uint64_t(words[2 * i + 1]) << 32;
    out.iterationsP99 = p.countRays ? words[kPercentileWord] : 0;
  }
  collectTimes(out.traceMs, out.shadeMs);
  if (readback.image) out.image.resize(size_t(W) * size_t(H)), out.traced.resize(size_t(W) * size_t(H));
  if (readback.tally) out.tally.resize(size_t(W) * size_t(H));
  parallelFor(size_t(0), pixelSlots, [&](size_t i) {
    const size_t tile = i / 64, inside = i % 64;
    const size_t x = (tile % tilesX) * kTile + inside % kTile, y = (tile / tilesX) * kTile + inside / kTile;
    if (x >= size_t(W) || y >= size_t(H)) return;
    const size_t q = y * size_t(W) + x;
    if (readback.image) out.image[q] = glm::vec3(pixels[2 * i]), out.traced[q] = glm::vec3(pixels[2 * i + 1]);
    if (readback.tally) out.tally[q] = tally[i];
  });
  return out;
}

}  // namespace lt
