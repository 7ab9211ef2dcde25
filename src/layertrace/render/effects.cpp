#include "layertrace/render/effects.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/gtc/constants.hpp>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include "layertrace/util/error.h"
#include "layertrace/util/progress.h"

namespace lt {

Effect parseEffect(const std::string& name) {
  if (name == "shade") return Effect::Shade;
  if (name == "reflection") return Effect::Reflection;
  if (name == "refraction") return Effect::Refraction;
  if (name == "ao") return Effect::AO;
  if (name == "shadow") return Effect::Shadow;
  inputError("--effect ", name, ": unknown (use shade, reflection, refraction, ao, shadow)");
}

const char* effectName(Effect e) {
  switch (e) {
    case Effect::Shade: return "shade";
    case Effect::Reflection: return "reflection";
    case Effect::Refraction: return "refraction";
    case Effect::AO: return "ao";
    case Effect::Shadow: return "shadow";
  }
  return "?";
}

namespace {

constexpr int kHistogramMax = 1 << 16;

struct Accum {
  uint64_t rays = 0, hits = 0, it = 0, iv = 0, px = 0, mismatch = 0;
  uint64_t level[RayCounters::kLevels] = {};
  uint64_t classes[kRayClasses] = {};
  int firstClass = -1;  ///< class of the current pixel's first ray (reset per pixel)
  std::vector<uint64_t> histogram = std::vector<uint64_t>(kHistogramMax + 1, 0);
};

struct Surface {
  glm::vec3 p, n;  ///< camera space; n faces the viewer of this surface
  glm::vec3 albedo;
  float specular;
  const Material* material;
};

class Renderer {
 public:
  Renderer(const Frame& f, const Tracer& t, const EffectConfig& c, const Tracer* o, const Tracer* ref)
      : f_(f), tracer_(t), config_(c), oracle_(o), reference_(ref) {
    for (const PointLight& l : f.lights) lights_.push_back({f.camera.toCamera(l.position), l.intensity});
    const float diag = f.scene.bounds().diagonal();
    maxDist_ = c.maxDistance > 0.0f ? c.maxDistance : diag;
    aoRadius_ = c.aoRadius > 0.0f ? c.aoRadius : 0.05f * diag;
    eps_ = 1e-4f * diag;
  }

  /// Traces one ray, counting it for the pixel, comparing with the oracle and classifying it
  /// against the reference. `firstClass` receives the class of the pixel's first ray.
  TraceHit trace(const ScreenRay& r, Accum& a, float& pixIt, float& pixIv) const {
    RayCounters c;
    const TraceHit h = tracer_.trace(r, c);
    ++a.rays;
    a.hits += h.hit;
    a.it += c.iterations, a.iv += c.intervals, a.px += c.pixels;
    for (int l = 0; l < RayCounters::kLevels; ++l) a.level[l] += c.levelIterations[l];
    ++a.histogram[std::min<uint32_t>(c.iterations, kHistogramMax)];
    pixIt += float(c.iterations), pixIv += float(c.intervals);
    if (oracle_) {
      RayCounters oc;
      const TraceHit o = oracle_->trace(r, oc);
      const bool same = o.hit == h.hit && (!h.hit || (o.x == h.x && o.y == h.y && o.layer == h.layer));
      a.mismatch += !same;
    }
    if (reference_) {
      RayCounters rc;
      const TraceHit truth = reference_->trace(r, rc);
      const RayClass cls = classifyRay(h, truth, f_.camera, f_.layers, f_.thickness);
      ++a.classes[int(cls)];
      if (a.firstClass < 0) a.firstClass = int(cls);
    }
    return h;
  }

  Surface surfaceOf(const TraceHit& h, glm::vec3 incoming) const {
    Surface s;
    s.p = h.point;
    s.n = glm::dot(h.normal, incoming) > 0.0f ? -h.normal : h.normal;
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

  ScreenRay ray(glm::vec3 o, glm::vec3 d, float maxDist) const { return ScreenRay{o, glm::normalize(d), maxDist}; }

  /// Mirror reflection path of `bounces` rays from s (every bounce traced, weights only blend).
  glm::vec3 reflection(const Surface& s0, glm::vec3 incoming0, int bounces, Accum& a, float& it, float& iv) const {
    glm::vec3 colour(0.0f), weight(1.0f);
    Surface s = s0;
    glm::vec3 incoming = incoming0;
    for (int b = 0; b < bounces; ++b) {
      const float m = s.material->mirror;
      colour += weight * (1.0f - m) * local(s, incoming);
      weight *= m;
      const glm::vec3 dir = glm::reflect(incoming, s.n);
      const TraceHit h = trace(ray(s.p, dir, maxDist_), a, it, iv);
      if (!h.hit) return colour + weight * f_.scene.environment;
      s = surfaceOf(h, dir);
      incoming = dir;
    }
    return colour + weight * local(s, incoming);
  }

  glm::vec3 pixel(int x, int y, Accum& a, float& it, float& iv) const {
    const LayerArrays& L = f_.layers;
    if (L.countAt(x, y) == 0) return f_.scene.environment;
    TraceHit front;
    {
      const FragmentNode& fr = L.pixel(x, y)[0];
      front.hit = true;
      front.point = f_.camera.rayThrough({x + 0.5f, y + 0.5f}) * fr.depth;
      front.normal = decodeOctahedral(fr.normal);
      front.albedoSpec = fr.albedoSpec;
      front.triangle = L.triangle[L.pixelIndex(x, y) * size_t(L.k)];
    }
    const glm::vec3 v = glm::normalize(front.point);
    const Surface s = surfaceOf(front, v);
    switch (config_.effect) {
      case Effect::Shade: return local(s, v);
      case Effect::Reflection: return reflection(s, v, config_.bounces, a, it, iv);
      case Effect::Shadow: {
        glm::vec3 c = 0.05f * s.albedo;
        for (int i = 0; i < int(lights_.size()); ++i) {
          const glm::vec3 toL = lights_[size_t(i)].first - s.p;
          const float d = glm::length(toL);
          if (glm::dot(toL, s.n) <= 0.0f) continue;  // facing away: dark without a ray
          const TraceHit h = trace(ray(s.p, toL, std::max(d - eps_, 0.0f)), a, it, iv);
          if (!h.hit) c += light(s, v, i);
        }
        return c;
      }
      case Effect::AO: {
        // One splitmix64 stream per pixel: deterministic for any thread count, and cheap to
        // seed (a Mersenne Twister per pixel would cost more than its rays).
        uint64_t state = config_.seed * 0x9E3779B97F4A7C15ull + uint64_t(y) * 65537ull + uint64_t(x);
        auto u = [&state] {
          uint64_t z = (state += 0x9E3779B97F4A7C15ull);
          z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
          z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
          return float((z ^ (z >> 31)) >> 40) * (1.0f / 16777216.0f);  // 24 bits → [0, 1)
        };
        const glm::vec3 t = glm::normalize(std::abs(s.n.x) > 0.5f ? glm::cross(s.n, {0, 1, 0}) : glm::cross(s.n, {1, 0, 0}));
        const glm::vec3 bt = glm::cross(s.n, t);
        int open = 0;
        for (int k = 0; k < config_.aoSamples; ++k) {
          const float r1 = u(), r2 = u(), r = std::sqrt(r1), phi = 2.0f * glm::pi<float>() * r2;
          const glm::vec3 d = t * (r * std::cos(phi)) + bt * (r * std::sin(phi)) + s.n * std::sqrt(std::max(0.0f, 1.0f - r1));
          open += !trace(ray(s.p, d, aoRadius_), a, it, iv).hit;
        }
        return glm::vec3(float(open) / float(std::max(1, config_.aoSamples)));
      }
      case Effect::Refraction: {
        const float tr = s.material->transmission;
        if (tr <= 0.0f) return local(s, v);
        // Enter (air → ior), travel to the back surface (a deeper layer), leave (ior → air).
        const float eta = 1.0f / s.material->ior;
        const float cosi = -glm::dot(v, s.n);
        const float f0 = std::pow((1.0f - s.material->ior) / (1.0f + s.material->ior), 2.0f);
        const float fresnel = f0 + (1.0f - f0) * std::pow(1.0f - std::clamp(cosi, 0.0f, 1.0f), 5.0f);
        const glm::vec3 reflected = reflection(s, v, 1, a, it, iv);
        glm::vec3 dir = glm::refract(v, s.n, eta);
        glm::vec3 through = f_.scene.environment;
        if (glm::dot(dir, dir) > 0.0f) {
          const TraceHit inside = trace(ray(s.p, dir, maxDist_), a, it, iv);
          if (inside.hit) {
            const Surface back = surfaceOf(inside, dir);
            glm::vec3 out = glm::refract(glm::normalize(dir), back.n, back.material->transmission > 0.0f ? back.material->ior : 1.0f);
            if (glm::dot(out, out) == 0.0f) out = glm::reflect(glm::normalize(dir), back.n);  // total internal reflection
            if (back.material->transmission <= 0.0f) {
              through = local(back, dir);  // the refracted ray met an opaque surface
            } else {
              const TraceHit beyond = trace(ray(back.p, out, maxDist_), a, it, iv);
              through = beyond.hit ? local(surfaceOf(beyond, out), out) : f_.scene.environment;
            }
          }
        }
        return (1.0f - tr) * local(s, v) + tr * ((1.0f - fresnel) * s.albedo * through + fresnel * reflected);
      }
    }
    return glm::vec3(0.0f);
  }

 private:
  const Frame& f_;
  const Tracer& tracer_;
  EffectConfig config_;
  const Tracer* oracle_;
  const Tracer* reference_;
  std::vector<std::pair<glm::vec3, glm::vec3>> lights_;  ///< camera-space position, intensity
  float maxDist_ = 1.0f, aoRadius_ = 1.0f, eps_ = 1e-4f;
};

}  // namespace

void validateEffectConfig(const EffectConfig& config) {
  if (config.bounces < 1 || config.bounces > 16) inputError("--bounces ", config.bounces, ": must be between 1 and 16");
  if (config.aoSamples < 1 || config.aoSamples > 4096) inputError("--ao-samples ", config.aoSamples, ": must be between 1 and 4096");
  if (!(config.aoRadius >= 0.0f)) inputError("--ao-radius ", config.aoRadius, ": must be >= 0");
  if (!(config.maxDistance >= 0.0f)) inputError("--max-distance ", config.maxDistance, ": must be >= 0");
}

EffectResult renderEffect(const Frame& frame, const Tracer& tracer, const EffectConfig& config, const Tracer* oracle,
                          const Tracer* reference) {
  validateEffectConfig(config);
  const int W = frame.camera.width(), H = frame.camera.height();
  EffectResult res;
  res.image = Image(W, H);
  res.iterations = Image(W, H, 1);
  res.intervals = Image(W, H, 1);
  if (reference) res.classImage = Image(W, H);
  const Renderer renderer(frame, tracer, config, oracle, reference);
  tbb::enumerable_thread_specific<Accum> accums;
  Progress progress(cat(tracer.name(), " ", effectName(config.effect)), uint64_t(H), config.progress);
  const auto start = std::chrono::steady_clock::now();
  tbb::parallel_for(tbb::blocked_range<int>(0, H, 2), [&](const tbb::blocked_range<int>& r) {
    Accum& a = accums.local();
    for (int y = r.begin(); y != r.end(); ++y)
      for (int x = 0; x < W; ++x) {
        float it = 0.0f, iv = 0.0f;
        a.firstClass = -1;
        res.image.set(x, y, renderer.pixel(x, y, a, it, iv));
        if (reference && a.firstClass >= 0) res.classImage.set(x, y, rayClassColor(RayClass(a.firstClass)));
        res.iterations.at(x, y)[0] = it;
        res.intervals.at(x, y)[0] = iv;
      }
    progress.add(uint64_t(r.end() - r.begin()));
  });
  res.traceMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  std::vector<uint64_t> histogram(kHistogramMax + 1, 0);
  for (const Accum& a : accums) {
    res.rays += a.rays, res.hits += a.hits, res.iterationSum += a.it, res.intervalSum += a.iv, res.pixelSum += a.px;
    res.exhaustiveMismatch += a.mismatch;
    for (int l = 0; l < RayCounters::kLevels; ++l) res.levelIterations[l] += a.level[l];
    for (int c = 0; c < kRayClasses; ++c) res.classCounts[c] += a.classes[c];
    for (size_t i = 0; i < histogram.size(); ++i) histogram[i] += a.histogram[i];
  }
  uint64_t seen = 0;
  for (size_t i = 0; i < histogram.size(); ++i) {
    seen += histogram[i];
    if (res.rays && double(seen) >= 0.99 * double(res.rays)) {
      res.iterationsP99 = i;
      break;
    }
  }
  return res;
}

}  // namespace lt
