#version 450
// One step of every pixel's path (src/layertrace/render/effects.cpp Renderer, the same floats
// in the same order): step 0 begins each path at its front fragment and emits its first rays;
// step w > 0 takes the answers to wave w − 1 (after the origin rule, effect_resolve.comp),
// counts them, shades, and emits the rays of wave w. One invocation per pixel slot.
layout(local_size_x = 64) in;

#include "ray_io.glsl"
#include "glm_float.glsl"
#include "effect_common.glsl"

layout(std430, binding = 0) writeonly buffer Rays { GpuRay rays[]; };
// [0, 16): unused; [16, 16 + 65537): histogram of iterations per ray (capped at 65536); then 16
// words per pixel slot: rays, hits, iterations, intervals, pixels, give-ups, bent rays, 1 for a
// hole (view synthesis), and the iterations at levels 0…7.
layout(std430, binding = 1) buffer Tally { uint tally[]; };
layout(std430, binding = 4) buffer EffectRays { EffectRay effectRays[]; };
layout(std430, binding = 5) readonly buffer Answers { GpuHit answers[]; };
layout(std430, binding = 6) buffer States { PathState states[]; };
layout(std430, binding = 7) writeonly buffer Out { PixelOut pixels[]; };

const int kShade = 0, kReflection = 1, kAO = 2, kShadow = 3, kRefraction = 4, kWarp = 5;
const int kMaxLights = 16;
const uint kHistogram = 16u, kHistogramMax = 65536u, kPixelTally = kHistogram + kHistogramMax + 1u;
const float kMinElevation = 0.01;  // effects.cpp Renderer::kMinElevation

uniform int uEffect, uWave, uAoSamples;
// The frame's pixel slots run in chunks (GpuEffects::run): the rays, answers and path states
// are the chunk's, indexed from its first slot uSlotBase; the picture and the tally are the
// frame's.
uniform uint uSlotBase;
uniform int uWaves;  // waves of rays: the bounces (reflection), 2 (refraction), 1 (AO, shadow, view synthesis), 0 (shade)
uniform float uMaxDistance, uAoRadius, uEps;
uniform uint uSeedLo, uSeedHi;
uniform bool uCount, uMirrorBelowSurface, uExcludeOriginTriangle;
uniform uint uTriangleCount;  // triangles[uTriangleCount] describes an unknown triangle
uniform vec3 uEnvironment;
uniform int uLights;
uniform vec3 uLightPosition[kMaxLights];  // camera space
uniform vec3 uLightIntensity[kMaxLights];
uniform float uSrgb[256];  // raster/fragment.cpp's sRGB decode table
// View synthesis (effects.h Effect::Warp): the second camera, and the first camera's view.
uniform mat4 uView, uWarpViewInverse;
uniform float uWarpPixelScale, uWarpMax;
uniform bool uWarpOrtho;
uniform vec3 uWarpOrigin;  // the second camera's eye in the first camera's space

// effects.cpp Surface.
struct Surface {
  vec3 p, n, ng, albedo;
  float specular, mirror, shininess, transmission, ior;
  uint triangle;
};



// std::clamp(v, 0, 1).
float clampUnit(float v) {
  return v < 0.0 ? 0.0 : (1.0 < v ? 1.0 : v);
}

// std::pow for the specular lobe (GLSL's pow is undefined at 0^0).
float powStd(float x, float e) {
  if (e == 0.0) return 1.0;
  if (x == 0.0) return 0.0;
  return pow(x, e);
}

// effects.cpp Renderer::surfaceOf.
Surface surfaceOf(SurfaceRecord r, vec3 incoming) {
  Surface s;
  s.p = r.point.xyz;
  s.triangle = r.triangle;
  const vec3 normal = r.normal.xyz;
  s.n = dotStd(normal, incoming) > 0.0 ? -normal : normal;
  s.ng = s.n;
  const TriangleInfo t = triangles[min(r.triangle, uTriangleCount)];
  if (r.triangle < uTriangleCount) {
    if (t.normalMirror.xyz != vec3(0.0)) s.ng = t.normalMirror.xyz;
    if (dotStd(s.ng, incoming) > 0.0) s.ng = -s.ng;
  }
  const uint a = r.albedoSpec;
  s.albedo = vec3(uSrgb[a & 0xFFu], uSrgb[(a >> 8) & 0xFFu], uSrgb[(a >> 16) & 0xFFu]);
  s.specular = float(a >> 24) / 255.0;
  s.mirror = t.normalMirror.w;
  s.shininess = t.material.x;
  s.transmission = t.material.y;
  s.ior = t.material.z;
  return s;
}

// effects.cpp Renderer::light.
vec3 light(Surface s, vec3 incoming, int i) {
  precise vec3 toL = uLightPosition[i] - s.p;
  precise float d2 = max(dotStd(toL, toL), 1e-12);
  precise vec3 l = toL / sqrt(d2);
  const float ndl = dotStd(s.n, l);
  if (ndl <= 0.0) return vec3(0.0);
  const vec3 hv = normalizeStd(l - incoming);
  const float e = s.shininess;
  precise float spec = s.specular * (e + 8.0) / 8.0 * powStd(max(0.0, dotStd(s.n, hv)), e);
  precise vec3 c = uLightIntensity[i] / d2 * (s.albedo * ndl + vec3(spec));
  return c;
}

// effects.cpp Renderer::local.
vec3 local(Surface s, vec3 incoming) {
  precise vec3 c = 0.05 * s.albedo;
  for (int i = 0; i < uLights; ++i) c += light(s, incoming, i);
  return c;
}

uint gBent = 0u;  // this step's rays bent out of their surface
uint gSlot;       // the pixel slot of the frame (uSlotBase + this invocation's slot of the chunk)

// effects.cpp Renderer::keepOutside.
vec3 keepOutside(vec3 dir, Surface s) {
  precise vec3 d = normalizeStd(dir);
  precise float e = dotStd(d, s.ng);
  if (e >= kMinElevation) return dir;
  ++gBent;
  if (uMirrorBelowSurface && e < 0.0) {
    d -= 2.0 * e * s.ng;
    e = -e;
    if (e >= kMinElevation) return d;
  }
  precise vec3 bentUp = d + s.ng * (kMinElevation - e);
  return bentUp;
}

// effects.cpp Renderer::ray: a ray leaving surface s, which never answers with s's triangle
// (unless the slots name no triangles: uExcludeOriginTriangle off).
void emitRay(uint slot, Surface s, vec3 d, float maxDistance) {
  const vec3 dir = normalizeStd(d);
  rays[slot].originMax = vec4(s.p, maxDistance);
  rays[slot].dirSurface = vec4(dir, 1.0);
  effectRays[slot].originMax = vec4(s.p, maxDistance);
  effectRays[slot].dirSurface = vec4(dir, 1.0);
  effectRays[slot].originTriangle = uExcludeOriginTriangle ? s.triangle : kNoTriangle;
  effectRays[slot].pending = 1u;
}

void noRay(uint slot) {
  rays[slot].originMax = vec4(0.0, 0.0, 0.0, -1.0);
  effectRays[slot].originMax = vec4(0.0, 0.0, 0.0, -1.0);
  effectRays[slot].pending = 0u;
}

// glm::reflect.
vec3 reflectStd(vec3 i, vec3 n) {
  precise vec3 r = i - n * dotStd(n, i) * 2.0;
  return r;
}

// splitmix64 (effects.cpp, Effect::AO) in 32-bit halves: x = low word, y = high word.
uvec2 add64(uvec2 a, uvec2 b) {
  uint carry;
  const uint lo = uaddCarry(a.x, b.x, carry);
  return uvec2(lo, a.y + b.y + carry);
}
uvec2 mul64(uvec2 a, uvec2 b) {
  uint hi, lo;
  umulExtended(a.x, b.x, hi, lo);
  return uvec2(lo, hi + a.x * b.y + a.y * b.x);
}
uvec2 shr64(uvec2 a, uint n) {  // 0 < n < 32
  return uvec2((a.x >> n) | (a.y << (32u - n)), a.y >> n);
}
const uvec2 kGolden = uvec2(0x7F4A7C15u, 0x9E3779B9u);
uvec2 gRandom;
float nextUniform() {
  gRandom = add64(gRandom, kGolden);
  uvec2 z = gRandom;
  z = mul64(z ^ shr64(z, 30u), uvec2(0x1CE4E5B9u, 0xBF58476Du));
  z = mul64(z ^ shr64(z, 27u), uvec2(0x133111EBu, 0x94D049BBu));
  z = z ^ shr64(z, 31u);
  return float(z.y >> 8) * (1.0 / 16777216.0);  // the top 24 bits
}

void finish(inout PathState st, vec3 result, vec3 traced) {
  pixels[gSlot].result = vec4(result, 0.0);
  pixels[gSlot].traced = vec4(traced, 0.0);
  st.flags.x = 0u;
}

// effects.cpp Renderer::reflectFrom: blend in the surface's own light, continue the mirror path.
void reflectFrom(uint slot, inout PathState st, Surface s) {
  const float m = s.mirror;
  precise vec3 colour = st.colour.xyz + st.weight.xyz * (1.0 - m) * local(s, st.incoming.xyz);
  st.colour.xyz = colour;
  st.weight.xyz *= m;
  st.dir.xyz = keepOutside(reflectStd(st.incoming.xyz, s.n), s);
  emitRay(slot, s, st.dir.xyz, uMaxDistance);
}

// glm::refract.
vec3 refractStd(vec3 i, vec3 n, float eta) {
  const float d = dotStd(n, i);
  precise float k = 1.0 - eta * eta * (1.0 - d * d);
  precise vec3 r = eta * i - (eta * d + sqrt(k)) * n;
  return k >= 0.0 ? r : vec3(0.0);
}

// glm::mat4 * glm::vec4(d, 0) in glm's order, as Camera::dirToCamera and dirToWorld compute it.
vec3 mulDirection(mat4 m, vec3 d) {
  precise vec4 r = (m[0] * d.x + m[1] * d.y) + (m[2] * d.z + m[3] * 0.0);
  return r.xyz;
}

// Emits the path's rays of wave uWave into its slots; returns how many.
uint emit(uint i, inout PathState st, ivec2 px) {
  const uint first = i * uint(uRaysPerPixel);
  uint n = 0u;
  if (uEffect == kWarp) {
    // The second camera's primary ray through this pixel, in the first camera's space; it
    // leaves an eye, not a surface.
    vec3 through = vec3(0.0, 0.0, -1.0);
    if (!uWarpOrtho)
      through = vec3((float(px.x) + 0.5 - float(uWidth) * 0.5) * uWarpPixelScale, -((float(px.y) + 0.5 - float(uHeight) * 0.5) * uWarpPixelScale), -1.0);
    st.dir.xyz = normalizeStd(mulDirection(uView, mulDirection(uWarpViewInverse, through)));
    rays[first].originMax = vec4(uWarpOrigin, uWarpMax);
    rays[first].dirSurface = vec4(st.dir.xyz, 0.0);
    effectRays[first].originMax = vec4(uWarpOrigin, uWarpMax);
    effectRays[first].dirSurface = vec4(st.dir.xyz, 0.0);
    effectRays[first].originTriangle = kNoTriangle;
    effectRays[first].pending = 1u;
    st.incoming.w = 1.0;
    return 1u;
  }
  const Surface s = surfaceOf(st.surface, st.incoming.xyz);
  if (uEffect == kReflection) {
    reflectFrom(first, st, s);
    n = 1u;
  } else if (uEffect == kRefraction && uWave == 0) {
    // Enter (air → ior), travel to the back surface (a deeper layer), leave (ior → air).
    const float cosi = -dotStd(st.view.xyz, s.n);
    precise float r0 = (1.0 - s.ior) / (1.0 + s.ior);
    precise float f0 = r0 * r0;
    precise float fresnel = f0 + (1.0 - f0) * powStd(1.0 - clampUnit(cosi), 5.0);
    reflectFrom(first, st, s);
    const vec3 entering = refractStd(st.view.xyz, s.n, 1.0 / s.ior);
    st.refracted = vec4(entering, fresnel);
    n = 1u;
    if (dotStd(entering, entering) == 0.0) {
      noRay(first + 1u);
    } else {
      emitRay(first + 1u, s, entering, uMaxDistance);
      n = 2u;
    }
  } else if (uEffect == kRefraction) {
    // Wave 1: leaving the transmissive back surface.
    emitRay(first, surfaceOf(st.back, st.refracted.xyz), st.refracted.xyz, uMaxDistance);
    noRay(first + 1u);
    n = 1u;
  } else if (uEffect == kShadow) {
    for (int l = 0; l < uLights; ++l) {
      precise vec3 toL = uLightPosition[l] - s.p;
      const float d = sqrt(dotStd(toL, toL));
      if (dotStd(toL, s.n) <= 0.0) {
        noRay(first + uint(l));
        continue;
      }
      emitRay(first + uint(l), s, toL, max(d - uEps, 0.0));
      ++n;
    }
    if (n == 0u) finish(st, 0.05 * s.albedo, 0.05 * s.albedo);  // every light behind the surface: dark without a ray
  } else if (uEffect == kAO) {
    gRandom = add64(mul64(uvec2(uSeedLo, uSeedHi), kGolden), add64(mul64(uvec2(uint(px.y), 0u), uvec2(65537u, 0u)), uvec2(uint(px.x), 0u)));
    const vec3 nn = s.n;
    const vec3 t = normalizeStd(abs(nn.x) > 0.5 ? crossStd(nn, vec3(0.0, 1.0, 0.0)) : crossStd(nn, vec3(1.0, 0.0, 0.0)));
    const vec3 bt = crossStd(nn, t);
    for (int k = 0; k < uAoSamples; ++k) {
      const float r1 = nextUniform(), r2 = nextUniform();
      precise float r = sqrt(r1), phi = 6.2831855 * r2;
      precise vec3 d = t * (r * cos(phi)) + bt * (r * sin(phi)) + nn * sqrt(max(0.0, 1.0 - r1));
      emitRay(first + uint(k), s, keepOutside(d, s), uAoRadius);
    }
    n = uint(uAoSamples);
  }
  st.incoming.w = float(n);
  return n;
}

// Refraction's end (effects.cpp, Effect::Refraction): the front surface's own light, and through
// it the Fresnel blend of what the reflection and the refraction brought back.
void finishRefraction(inout PathState st, vec3 through) {
  const Surface s = surfaceOf(st.surface, st.view.xyz);
  const float tr = s.transmission, fresnel = st.refracted.w;
  precise vec3 c = (1.0 - tr) * local(s, st.view.xyz) + tr * ((1.0 - fresnel) * s.albedo * through + fresnel * st.reflected.xyz);
  finish(st, c, through);
}

bool hit(GpuHit h) {
  return h.layer >= 0;
}

// Takes the answers to the path's rays of wave uWave − 1 (those with a non-negative length).
void consume(uint i, inout PathState st) {
  const uint first = i * uint(uRaysPerPixel);
  const int wave = uWave - 1;
  const uint t = kPixelTally + gSlot * 16u;
  uint open = 0u;
  for (uint j = 0u; j < uint(uRaysPerPixel); ++j) {
    if (effectRays[first + j].originMax.w < 0.0) continue;
    const GpuHit h = answers[first + j];
    ++tally[t];
    if (hit(h)) ++tally[t + 1u];
    else ++open;
    if (uCount) {
      tally[t + 2u] += h.iterations;
      tally[t + 3u] += h.intervals;
      tally[t + 4u] += h.pixels;
      tally[t + 5u] += h.giveUps;
      for (int l = 0; l < 8; ++l) tally[t + 8u + uint(l)] += h.levelIterations[l];
      atomicAdd(tally[kHistogram + min(h.iterations, kHistogramMax)], 1u);
    }
  }
  const GpuHit h0 = answers[first];
  if (uEffect == kWarp) {
    if (!hit(h0)) tally[t + 7u] = 1u;  // a hole
    const vec3 c = hit(h0) ? local(surfaceOf(effectRays[first].hit, st.dir.xyz), st.dir.xyz) : uEnvironment;
    finish(st, c, c);
  } else if (uEffect == kReflection) {
    if (!hit(h0)) {
      precise vec3 c = st.colour.xyz + st.weight.xyz * uEnvironment;
      finish(st, c, uEnvironment);
      return;
    }
    st.surface = effectRays[first].hit;
    st.incoming.xyz = st.dir.xyz;
    if (wave + 1 == uWaves) {
      const vec3 traced = local(surfaceOf(st.surface, st.incoming.xyz), st.incoming.xyz);
      precise vec3 c = st.colour.xyz + st.weight.xyz * traced;
      finish(st, c, traced);
    }
  } else if (uEffect == kRefraction && wave == 0) {
    precise vec3 reflected = st.colour.xyz + st.weight.xyz * (hit(h0) ? local(surfaceOf(effectRays[first].hit, st.dir.xyz), st.dir.xyz) : uEnvironment);
    st.reflected.xyz = reflected;
    vec3 through = uEnvironment;
    const GpuHit h1 = answers[first + 1u];
    if (effectRays[first + 1u].originMax.w >= 0.0 && hit(h1)) {
      const vec3 dir = st.refracted.xyz;
      const Surface back = surfaceOf(effectRays[first + 1u].hit, dir);
      vec3 leaving = refractStd(normalizeStd(dir), back.n, back.transmission > 0.0 ? back.ior : 1.0);
      if (dotStd(leaving, leaving) == 0.0) leaving = reflectStd(normalizeStd(dir), back.n);  // total internal reflection
      if (back.transmission <= 0.0) {
        through = local(back, dir);  // the refracted ray met an opaque surface
      } else {
        st.refracted.xyz = leaving;
        st.back = effectRays[first + 1u].hit;
        return;  // wave 1 leaves the back surface
      }
    }
    finishRefraction(st, through);
  } else if (uEffect == kRefraction) {
    finishRefraction(st, hit(h0) ? local(surfaceOf(effectRays[first].hit, st.refracted.xyz), st.refracted.xyz) : uEnvironment);
  } else if (uEffect == kShadow) {
    const Surface s = surfaceOf(st.surface, st.incoming.xyz);
    precise vec3 c = 0.05 * s.albedo;
    for (int l = 0; l < uLights; ++l)
      if (effectRays[first + uint(l)].originMax.w >= 0.0 && !hit(answers[first + uint(l)])) c += light(s, st.view.xyz, l);
    finish(st, c, c);
  } else if (uEffect == kAO) {
    const vec3 ao = vec3(float(open) / float(max(1, uAoSamples)));
    finish(st, ao, ao);
  }
}

void main() {
  const uint i = gl_GlobalInvocationID.x + uint(uFirst);
  if (i >= uint(uItems)) return;
  gSlot = uSlotBase + i;
  ivec2 px;
  const bool inside = slotPixel(gSlot, px);
  PathState st;
  if (uWave == 0) {
    // effects.cpp Renderer::begin: the front surface; pixels without fragments show the
    // environment and trace nothing (view synthesis: every pixel of the second camera traces).
    st.surface = SurfaceRecord(vec4(0.0), vec4(0.0), kNoTriangle, 0u, 0u, 0u);
    st.back = st.surface;
    st.flags = uvec4(0u);
    st.incoming = vec4(0.0);
    st.dir = vec4(0.0);
    st.colour = vec4(0.0);
    st.weight = vec4(1.0);
    st.view = vec4(0.0);
    st.refracted = vec4(0.0);
    st.reflected = vec4(0.0);
    if (inside && uEffect == kWarp) {
      st.flags.x = 1u;
    } else if (inside) {
      const uvec4 f = fragmentAt(px.x, px.y, 0);
      if (f.x == kEmptySlot) {
        pixels[gSlot].result = vec4(uEnvironment, 0.0);
        pixels[gSlot].traced = vec4(uEnvironment, 0.0);
      } else {
        st.view.xyz = normalizeStd(fragmentPoint(px.x, px.y, f));
        st.incoming.xyz = st.view.xyz;
        st.flags.x = 1u;
        st.surface = fragmentRecord(px.x, px.y, f);
        const Surface s = surfaceOf(st.surface, st.view.xyz);
        if (uEffect == kShade || (uEffect == kRefraction && s.transmission <= 0.0)) {
          const vec3 c = local(s, st.view.xyz);
          finish(st, c, c);
        }
      }
    }
  } else {
    st = states[i];
    if (st.flags.x != 0u && st.incoming.w > 0.0) consume(i, st);
  }
  if (st.flags.x != 0u && uWave < uWaves) {
    emit(i, st, px);
  } else {
    st.incoming.w = 0.0;
    for (uint j = 0u; j < uint(uRaysPerPixel); ++j) noRay(i * uint(uRaysPerPixel) + j);
  }
  if (gBent > 0u) tally[kPixelTally + gSlot * 16u + 6u] += gBent;
  states[i] = st;
}
