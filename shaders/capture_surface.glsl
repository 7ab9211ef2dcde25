// Textured surfaces in the capture: src/layertrace/scene/surface.cpp and texture.cpp, operation
// for operation. The alpha test (surfacePresent) gives the CPU's answer bit for bit (the same
// barycentrics, texture coordinates and integer texel lookup); the sampled colour may differ in
// the last bit of a channel where the GPU's log2 and square root round differently.
//
// Everything lives in two buffers of 32-bit words, sections at the offsets of the uniforms below
// (gpu_capture.cpp SurfaceTables): per vertex the texture and lightmap coordinates, per
// triangle the texture coordinates' scale, per material its colour, textures and alpha cut-off,
// per texture its mip levels, and the sRGB tables; the texels in their own buffer.
// Needs capture_common.glsl (fragmentBarycentrics) before it.

layout(std430, binding = 8) readonly buffer SurfaceWords { uint surface[]; };
layout(std430, binding = 9) readonly buffer SurfaceTexels { uint texels[]; };
uniform uint uTexcoords, uLightmapCoords, uUvScale, uMaterials, uTextures, uLevels, uDecode, uThresholds;
uniform bool uHaveTexcoords, uHaveLightmapCoords;

const uint kMaterialWords = 10u;  // albedo rgb, specular, base, specular and light map, wrap u | v << 8, cut-off, flags
const uint kSampled = 1u, kCutOut = 2u;

float word(uint i) { return uintBitsToFloat(surface[i]); }
int textureOf(uint material, uint which) { return int(surface[uMaterials + material * kMaterialWords + 4u + which]); }
uint materialFlags(uint material) { return surface[uMaterials + material * kMaterialWords + 9u]; }

vec2 coordAt(uint section, uint v) { return vec2(word(section + 2u * v), word(section + 2u * v + 1u)); }

vec2 interpolate(uint section, uvec3 t, vec2 b) {
  precise float w0 = (1.0 - b.x) - b.y;
  precise vec2 c = (coordAt(section, t.x) * w0 + coordAt(section, t.y) * b.x) + coordAt(section, t.z) * b.y;
  return c;
}

// texture.cpp tame: |t| < 1024 as it is; beyond, moved by a multiple of 2 (trunc(t / 2) · 2 is
// exact for such floats, so t - that is std::fmod(t, 2)).
float tame(float t) {
  if (abs(t) < 1024.0) return t;
  if (isinf(t) || isnan(t)) return 0.0;
  precise float r = t - 2.0 * trunc(t * 0.5);
  precise float moved = (t < 0.0 ? -1024.0 : 1024.0) + r;
  return moved;
}

// i mod n in [0, n) for any i (n > 0). GLSL leaves % undefined for a negative operand, and
// llvmpipe computes it as if both were unsigned (−1 % 20 gives 15, not −1): only non-negative
// operands reach % here.
int floorMod(int i, int n) { return i >= 0 ? i % n : n - 1 - (-(i + 1)) % n; }

int wrapIndex(int i, int n, uint mode) {
  if (mode == 1u) return clamp(i, 0, n - 1);  // Clamp
  if (mode == 2u) {                           // Mirror
    const int period = 2 * n, m = floorMod(i, period);
    return m < n ? m : period - 1 - m;
  }
  return floorMod(i, n);  // Repeat
}

uvec4 levelOf(int texture, int level) {
  const uint first = surface[uTextures + 3u * uint(texture)];
  const uint i = uLevels + 3u * (first + uint(level));
  return uvec4(surface[i], surface[i + 1u], surface[i + 2u], 0u);  // width, height, first texel
}
int levelCount(int texture) { return int(surface[uTextures + 3u * uint(texture) + 1u]); }

vec4 texelLinear(uint t) {
  return vec4(word(uDecode + (t & 0xFFu)), word(uDecode + ((t >> 8) & 0xFFu)), word(uDecode + ((t >> 16) & 0xFFu)), float(t >> 24) / 255.0);
}

// texture.cpp alphaNearest.
float alphaNearest(int texture, vec2 uv, uint wrapU, uint wrapV) {
  const uvec4 L = levelOf(texture, 0);
  precise float fx = floor(tame(uv.x) * float(L.x));
  precise float fy = floor((1.0 - tame(uv.y)) * float(L.y));
  const int x = wrapIndex(int(fx), int(L.x), wrapU), y = wrapIndex(int(fy), int(L.y), wrapV);
  return float(texels[L.z + uint(y) * L.x + uint(x)] >> 24) / 255.0;
}

// surface.cpp surfacePresent (for a triangle whose material has kCutOut).
bool surfacePresent(uint material, uvec3 t, vec2 b) {
  const uint m = uMaterials + material * kMaterialWords;
  const vec2 uv = interpolate(uTexcoords, t, b);
  return alphaNearest(int(surface[m + 4u]), uv, surface[m + 7u] & 0xFFu, surface[m + 7u] >> 8) >= word(m + 8u);
}

vec4 sampleBilinear(int texture, int level, vec2 uv, uint wrapU, uint wrapV) {
  const uvec4 L = levelOf(texture, level);
  precise float x = tame(uv.x) * float(L.x) - 0.5, y = (1.0 - tame(uv.y)) * float(L.y) - 0.5;
  precise float fx = floor(x), fy = floor(y);
  precise float ax = x - fx, ay = y - fy;
  const int x0 = int(fx), y0 = int(fy);
  const int xa = wrapIndex(x0, int(L.x), wrapU), xb = wrapIndex(x0 + 1, int(L.x), wrapU);
  const int ya = wrapIndex(y0, int(L.y), wrapV), yb = wrapIndex(y0 + 1, int(L.y), wrapV);
  const uint row0 = L.z + uint(ya) * L.x, row1 = L.z + uint(yb) * L.x;
  precise vec4 top = texelLinear(texels[row0 + uint(xa)]) * (1.0 - ax) + texelLinear(texels[row0 + uint(xb)]) * ax;
  precise vec4 bottom = texelLinear(texels[row1 + uint(xa)]) * (1.0 - ax) + texelLinear(texels[row1 + uint(xb)]) * ax;
  precise vec4 s = top * (1.0 - ay) + bottom * ay;
  return s;
}

// texture.cpp sampleTrilinear.
vec4 sampleTrilinear(int texture, vec2 uv, float lod, uint wrapU, uint wrapV) {
  const int last = levelCount(texture) - 1;
  if (!(lod > 0.0)) return sampleBilinear(texture, 0, uv, wrapU, wrapV);
  if (lod >= float(last)) return sampleBilinear(texture, last, uv, wrapU, wrapV);
  const int l0 = int(lod);
  precise float f = lod - float(l0);
  const vec4 a = sampleBilinear(texture, l0, uv, wrapU, wrapV);
  if (f == 0.0) return a;
  precise vec4 s = a * (1.0 - f) + sampleBilinear(texture, l0 + 1, uv, wrapU, wrapV) * f;
  return s;
}

// Texture::texelsLog2, computed once on the CPU.
float texelsLog2(int texture) { return word(uTextures + 3u * uint(texture) + 2u); }

// texture.cpp linearToSrgb8: the number of thresholds at or below v (upper_bound).
uint linearToSrgb8(float v) {
  if (!(v > 0.0)) return 0u;
  uint lo = 0u, hi = 255u;
  while (lo < hi) {
    const uint mid = (lo + hi) / 2u;
    if (word(uThresholds + mid) <= v) lo = mid + 1u;
    else hi = mid;
  }
  return lo;
}

// surface.cpp surfaceColor, packed (packSurfaceColor): the albedo and specular of `material` on
// `triangle` (vertices t) at barycentrics b (the weights of t.y and t.z) for a texel footprint.
uint surfaceAlbedoSpec(uint material, uint triangle, uvec3 t, vec2 b, float footprint) {
  const uint m = uMaterials + material * kMaterialWords;
  vec3 albedo = vec3(word(m), word(m + 1u), word(m + 2u));
  float specular = word(m + 3u);
  const uint wrapU = surface[m + 7u] & 0xFFu, wrapV = surface[m + 7u] >> 8;
  const int base = int(surface[m + 4u]), spec = int(surface[m + 5u]), light = int(surface[m + 6u]);
  if (uHaveTexcoords && (base >= 0 || spec >= 0)) {
    const vec2 uv = interpolate(uTexcoords, t, b);
    const float lodBase = word(uUvScale + triangle) + log2(max(footprint, 1e-30));
    if (base >= 0) albedo *= sampleTrilinear(base, uv, lodBase + texelsLog2(base), wrapU, wrapV).xyz;
    if (spec >= 0) {
      const vec4 s = sampleTrilinear(spec, uv, lodBase + texelsLog2(spec), wrapU, wrapV);
      specular *= 0.2126 * s.x + 0.7152 * s.y + 0.0722 * s.z;
    }
  }
  if (uHaveLightmapCoords && light >= 0) albedo *= sampleTrilinear(light, interpolate(uLightmapCoords, t, b), 0.0, 1u, 1u).xyz;
  albedo = clamp(albedo, 0.0, 1.0);
  specular = clamp(specular, 0.0, 1.0);
  const uint s8 = uint(roundHalfAway(specular * 255.0));
  return linearToSrgb8(albedo.x) | (linearToSrgb8(albedo.y) << 8) | (linearToSrgb8(albedo.z) << 16) | (s8 << 24);
}

// raster_setup.h fragmentAlbedoSpec: surfaceColor with the pixel's footprint at that depth.
uint fragmentAlbedoSpec(TriangleSetup ts, uint material, uint triangle, vec3 origin, vec3 dir, float depth) {
  const vec2 b = fragmentBarycentrics(ts, origin, dir, depth);
  const float nl = length(ts.plane.xyz), dl = length(dir);
  const float cosine = nl > 0.0 && dl > 0.0 ? dot3(ts.plane.xyz, dir) / (nl * dl) : 1.0;
  const float footprint = (uOrtho ? uPixelScale : depth * uPixelScale) / max(abs(cosine), 1.0 / 64.0);
  return surfaceAlbedoSpec(material, triangle, ts.info.xyz, b, footprint);
}

// The fragment's surface: false when its material's alpha test cuts it away; otherwise its
// albedo and specular in `albedoSpec` (the material's constant unless the material is textured).
// The triangle's material index travels in its setup (e1.w).
bool fragmentSurface(TriangleSetup ts, uint triangle, vec3 origin, vec3 dir, float depth, bool colour, out uint albedoSpec) {
  albedoSpec = ts.info.w;
  const uint material = floatBitsToUint(ts.e1.w);
  const uint flags = materialFlags(material);
  if (flags == 0u) return true;
  if ((flags & kCutOut) != 0u && !surfacePresent(material, ts.info.xyz, fragmentBarycentrics(ts, origin, dir, depth))) return false;
  if (colour && (flags & kSampled) != 0u) albedoSpec = fragmentAlbedoSpec(ts, material, triangle, origin, dir, depth);
  return true;
}
