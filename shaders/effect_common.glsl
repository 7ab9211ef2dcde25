// Shared by the effect passes (effect_step.comp, effect_resolve.comp): the GLSL twins of the ray
// generation and shading of src/layertrace/render/effects.cpp, written once for every GPU
// tracer. The tracer's march (hssr_march.comp, ssr_march.comp) runs between these passes on the
// same ray and answer buffers, so no ray leaves the device.
//
// Rays live in fixed slots: pixel slot i (8×8-pixel tiles over the frame rounded up to whole
// tiles, tiles row by row, pixels row by row inside a tile: the CPU renderer's ray order) owns
// rays i·R … i·R + R − 1, R the effect's most rays per pixel. A slot without a ray has a negative
// length, and the march answers it with a miss at once. Include after ray_io.glsl.

// The effect's ray: as emitted, with the triangle it leaves (Ray::originTriangle) and whether it
// still waits for an answer under the origin rule (Tracer::query); once answered with a hit, the
// surface it met (effect_resolve.comp).
struct EffectRay {
  vec4 originMax;
  vec4 dirSurface;
  uint originTriangle, pending, pad0, pad1;
  SurfaceRecord hit;
};
// One pixel's path between waves (effects.cpp PathState).
struct PathState {
  SurfaceRecord surface;  // the surface the path is on
  SurfaceRecord back;     // refraction: the transmissive back surface
  vec4 incoming;  // xyz: the direction arriving at the surface; w: the rays of the last wave (as float)
  vec4 dir;       // the direction of the ray in flight, as computed (unnormalised)
  vec4 colour;    // reflection: the accumulated colour
  vec4 weight;    // reflection: the path weight
  vec4 view;      // the view direction at the front surface
  vec4 refracted; // refraction: xyz the refracted direction in flight, w the Fresnel weight
  vec4 reflected; // refraction: the colour the reflection ray brought back
  uvec4 flags;    // x: 1 while the path is active
};
struct PixelOut {
  vec4 result;
  vec4 traced;
};

const uint kNoTriangle = 0xFFFFFFFFu;
const uint kEmptySlot = 0xFFFFFFFFu;  // the depth bits of a slot without a fragment

// The layer arrays as the shading reads them: per slot (pixel-major, k per pixel) the depth's
// bits, the octahedral normal, the packed albedo and specular, and the scene triangle.
layout(std430, binding = 2) readonly buffer Fragments { uvec4 fragments[]; };
// Per scene triangle: the camera-space geometric normal (0 for a degenerate triangle) and the
// mirror weight, then shininess, transmission and ior of its material.
struct TriangleInfo {
  vec4 normalMirror;
  vec4 material;
};
layout(std430, binding = 3) readonly buffer Triangles { TriangleInfo triangles[]; };

uniform int uWidth, uHeight, uK;
uniform int uRaysPerPixel;  // R
uniform int uFirst;         // the first item of this dispatch (GpuContext::dispatch)
uniform int uItems;         // pixel slots (step) or ray slots (resolve)
uniform float uPixelScale;  // 1 / focal
uniform bool uOrtho;

// The pixel of slot i in tile order; false for a slot beyond the frame's edge.
bool slotPixel(uint i, out ivec2 p) {
  const uint tilesX = (uint(uWidth) + 7u) / 8u;
  const uint tile = i / 64u, inside = i % 64u;
  p = ivec2(int((tile % tilesX) * 8u + inside % 8u), int((tile / tilesX) * 8u + inside / 8u));
  return p.x < uWidth && p.y < uHeight;
}

uvec4 fragmentAt(int x, int y, int layer) {
  return fragments[(uint(y) * uint(uWidth) + uint(x)) * uint(uK) + uint(layer)];
}

// scene/camera.h Camera::rayThrough.
vec3 rayThrough(vec2 pixel) {
  if (uOrtho) return vec3(0.0, 0.0, -1.0);
  precise vec3 d = vec3((pixel.x - float(uWidth) * 0.5) * uPixelScale, -((pixel.y - float(uHeight) * 0.5) * uPixelScale), -1.0);
  return d;
}

// screen/fragment_hit.h fragmentHit: the point where the pixel-centre ray meets the stored depth.
vec3 fragmentPoint(int x, int y, uvec4 f) {
  precise vec3 p = rayThrough(vec2(float(x) + 0.5, float(y) + 0.5)) * uintBitsToFloat(f.x);
  return p;
}

// A fragment as a surface (screen/fragment_hit.h fragmentHit).
SurfaceRecord fragmentRecord(int x, int y, uvec4 f) {
  SurfaceRecord r;
  r.point = vec4(fragmentPoint(x, y, f), 0.0);
  r.normal = vec4(decodeOctahedral(f.y), 0.0);
  r.triangle = f.w;
  r.albedoSpec = f.z;
  r.pad0 = r.pad1 = 0u;
  return r;
}
