// layertrace on the GPU inside your renderer: the GPU back end's resident frame (capture, sort
// to k layers, interval pyramid, march, effect; Hofmann et al. 2017, §4–5) run in YOUR OpenGL
// 4.5 context, its picture written into your texture and its tracer answering rays from your
// buffers. layertrace creates no context and needs no EGL here. The layers come from a
// TriangleScene layertrace draws, from YOUR draw calls (GpuGeometry), from YOUR k-layer buffers
// (GpuLayers) or from YOUR G-buffer's depth and normals (GpuGBuffer). docs/library.md, "On the
// GPU", has a 20-line program and every layout in one table.
//
//   #include <layertrace/gpu.h>        CMake: find_package(layertrace) → layertrace::layertrace
//                                      pkg-config: layertrace (its private libs hold -lepoxy)
//
// Threading and state: every call runs on the thread where your context is current, and that
// context stays current (and alive) while these objects live. Every call saves the OpenGL state
// it changes and restores it before it returns, also when it throws (docs/library.md, "On the
// GPU", lists it): your program, vertex array, framebuffers, viewport, polygon mode, depth,
// cull, stencil, scissor and rasterizer-discard switches, shader storage bindings 0–15, the
// dispatch-indirect and pixel-unpack buffers, the unpack pixel-store settings, the transform
// feedback object, the active texture unit and the 2D textures and samplers of units 0–2. It
// creates its own buffers, programs, vertex arrays, framebuffers, a transform feedback object
// and queries, which it deletes with the objects.
//
// Errors: std::invalid_argument with one line naming the argument and the value (a texture too
// small or of a format it cannot write, a buffer too small, an unknown tracer or parameter);
// std::runtime_error when no context is current, the context is older than 4.5, or layertrace
// was built without its GPU back end.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>

#include "layertrace/api/export.h"
#include "layertrace/api/layertrace.h"

namespace lt {

/// The OpenGL context current on the calling thread, adopted (OpenGL 4.5 or newer).
class LAYERTRACE_API GpuDevice {
 public:
  GpuDevice();
  ~GpuDevice();
  GpuDevice(const GpuDevice&) = delete;
  GpuDevice& operator=(const GpuDevice&) = delete;
  /// GL_RENDERER: "NVIDIA GeForce …", "llvmpipe (LLVM 15.0.6, 256 bits)".
  std::string renderer() const;
  /// True for a CPU rasterizer (llvmpipe): its times are CPU times.
  bool software() const;

  struct Impl;  ///< layertrace's own use
  Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

/// One effect per frame, as `layertrace render --device gpu` makes it.
struct GpuEffectRequest {
  std::string effect = "reflection";  ///< shade, reflection, refraction, ao, shadow
  int bounces = 1;                    ///< reflection and refraction bounces, 1–16
  int aoSamples = 8;                  ///< AO rays per pixel
  float maxDistance = 0.0f;           ///< ray length (0: the scene's diagonal)
  uint64_t seed = 1;                  ///< AO's and refraction's random sequence (the CLI's --seed)
};

/// What one frame did: counted on the device, read with the frame's one wait.
struct GpuFrameInfo {
  uint64_t fragments = 0;  ///< fragments the capture generated (every one, exactly)
  uint64_t rays = 0, hits = 0;
  double iterationsMean = 0.0;  ///< cells visited per ray
  double gpuMs = 0.0;           ///< GPU time of the frame's passes (timer queries)
  int attempts = 1;             ///< 2 or more: a buffer overflowed, grew, and the frame ran again
  uint64_t triangles = 0;       ///< triangles your draw calls gave (GpuGeometry), exactly
};

/// The geometry YOUR draw calls give the capture, each frame (GpuRenderer's second constructor).
/// layertrace links your vertex shader alone (GLSL, with its #version line, 4.50 core or older)
/// and captures three of its outputs by transform feedback, per vertex, in draw order:
///
///   out vec3 ltPosition;       // the vertex in the scene's coordinates (those of your View)
///   out vec3 ltNormal;         // its shading normal there (not necessarily unit length)
///   flat out uint ltMaterial;  // its triangle's material: an index into the TriangleScene's
///                              // materials (a triangle takes its first vertex's; beyond the
///                              // last: the last)
///
/// gl_Position and every other output are ignored; no fragment is drawn (the rasterizer is
/// off). Inside the GpuDrawCalls callback, issue your draw calls (GL_TRIANGLES, strips or fans,
/// indexed, instanced or indirect) with your vertex arrays and buffers, and set the uniforms of
/// the program it is given, which is bound. Textures are not mapped on this geometry: its
/// materials' albedo and specular are their constant values.
struct GpuGeometry {
  std::string vertexShader;
  size_t maxTriangles = 1 << 16;  ///< the first capacity; a frame that draws more grows it and draws again
};
/// One slot of YOUR k-layer arrays (GpuLayers), std430, 16 bytes: the fragment node of Hofmann
/// et al. 2017, §4.1, as layertrace's capture writes it.
struct GpuLayerSlot {
  float depth;          ///< positive camera-space depth (-z of the point, the View's camera space)
  uint32_t normal;      ///< camera-space unit normal, octahedral: two snorm16, x in the low half
  uint32_t albedoSpec;  ///< albedo as 8-bit sRGB codes (R in the low byte) and specular weight · 255 (high byte)
  float thickness;      ///< z-thickness: the surface spans depths [depth, depth + thickness]
};
static_assert(sizeof(GpuLayerSlot) == 16);

/// YOUR layers, in buffers of the current context (render with GpuLayers): k slots a pixel,
/// pixel-major with pixel = row · width + column and row 0 the TOP row, each pixel's slots in
/// ascending depth.
struct GpuLayers {
  uint32_t slots = 0;      ///< GpuLayerSlot[width · height · k]
  uint32_t counts = 0;     ///< uint[width · height]: the slots in use (a count above k reads as k)
  uint32_t materials = 0;  ///< optional uint[width · height · k]: each slot's material, an index into
                           ///< the TriangleScene's materials (its mirror, transmission, …); 0: material 0
};

/// YOUR G-buffer (render with GpuGBuffer, a renderer of k = 1): 2D textures of the view's size,
/// drawn with the View's perspective (glm::perspective of its fovY, near and far) and the default
/// depth range, row 0 the BOTTOM row as OpenGL draws them.
struct GpuGBuffer {
  uint32_t depth = 0;    ///< depth texture (window depth; 1: nothing drawn)
  uint32_t normals = 0;  ///< camera-space normals in RGB: signed (float, snorm) as they are, unsigned normalized as n · 0.5 + 0.5
  uint32_t albedo = 0;   ///< optional: linear albedo in RGB, specular weight in A (sRGB textures decode as they are read); 0: grey
};

/// The k of your layers, and for a G-buffer the z-thickness of its one layer in pixel footprints.
struct GpuLayerFormat {
  int k = 4;
  float thicknessPx = 6.0f;
};

/// Your draw calls, issued into the capture with `program` (your vertex shader) bound. Called at
/// least once per frame, again when a buffer of the frame overflowed and it runs again.
using GpuDrawCalls = std::function<void(uint32_t program)>;

/// The rays `trace` reads and the answers it writes, std430 in your buffers (32 and 64 bytes).
/// Rays are in the camera space of the last rendered view (layertrace.h's conventions).
struct GpuRayRecord {
  float origin[3];
  float maxDistance;
  float dir[3];          ///< unit length
  float startsOnSurface; ///< 1 when the origin lies on a stored surface (a reflection's), else 0
};
struct GpuHitRecord {
  int32_t x, y;    ///< the hit fragment's pixel
  int32_t layer;   ///< its layer, 0 = front; -1: no hit
  uint32_t iterations, intervals, pixels, giveUps;  ///< the march's counters
  uint32_t fragments;  ///< stored fragments tested at the visited level-0 pixels
  uint32_t levelIterations[8];                               ///< cells visited per pyramid level
};
static_assert(sizeof(GpuRayRecord) == 32 && sizeof(GpuHitRecord) == 64);

/// A scene's frames on the GPU: the scene (copied) is uploaded on the first render, programs are
/// linked once, buffers allocated once per size and kept. `tracer` is hssr, hiz, exhaustive
/// (the one-level march), ssr (McGuire and Mara's march over the front layer) or ssr-layers
/// (over all k), `params` any registry parameter and preset (TracerParams), `layers`
/// the k of the capture (1–16) and `thicknessPx` the fragments' z-thickness in pixel footprints.
/// The lights are the scene's, else one above the first rendered view's eye, as the CLI's.
class LAYERTRACE_API GpuRenderer {
 public:
  GpuRenderer(GpuDevice& device, const TriangleScene& scene, const std::string& tracer = "hssr", const TracerParams& params = TracerParams(),
              int layers = 4, float thicknessPx = 6.0f);
  /// Frames of the geometry your draw calls give (render with GpuDrawCalls). `materials` gives
  /// the materials that ltMaterial indexes, the lights (as above) and the extent that sets the
  /// rays' default length; its triangles are not drawn (a TriangleScene of your scene's, or one
  /// made of its bounding box's corners and its materials). std::invalid_argument when the
  /// vertex shader does not compile or link, or lacks an output, with the driver's log.
  GpuRenderer(GpuDevice& device, const TriangleScene& materials, const GpuGeometry& geometry, const std::string& tracer = "hssr",
              const TracerParams& params = TracerParams(), int layers = 4, float thicknessPx = 6.0f);
  /// Frames of the layers you give (render with GpuLayers or GpuGBuffer), k as `format` says;
  /// `materials` as above.
  GpuRenderer(GpuDevice& device, const TriangleScene& materials, const GpuLayerFormat& format, const std::string& tracer = "hssr",
              const TracerParams& params = TracerParams());
  ~GpuRenderer();
  GpuRenderer(const GpuRenderer&) = delete;
  GpuRenderer& operator=(const GpuRenderer&) = delete;

  /// Renders `effect` seen from `view` and writes the picture into level 0 of your 2D texture
  /// `texture` (at least view.width × view.height texels), row 0 = the picture's TOP row: for
  /// GL_RGBA8 or GL_SRGB8_ALPHA8 the 8-bit sRGB codes a PNG of `layertrace render` holds (to
  /// the bit), for GL_RGBA16F or GL_RGBA32F the linear values. Nothing is read back but the
  /// frame's counters (one wait).
  GpuFrameInfo render(const View& view, const GpuEffectRequest& effect, uint32_t texture);
  /// The same for a renderer of your geometry: `draw` issues your draw calls into the capture.
  GpuFrameInfo render(const View& view, const GpuEffectRequest& effect, uint32_t texture, const GpuDrawCalls& draw);
  /// The same for a renderer of your layers (GpuLayerFormat): the frame starts at your k-layer
  /// arrays, read on the device (no capture). std::invalid_argument for a buffer too small.
  GpuFrameInfo render(const View& view, const GpuEffectRequest& effect, uint32_t texture, const GpuLayers& layers);
  /// The same from your G-buffer, one layer (a renderer of GpuLayerFormat{1, …}): Hi-Z, HSSR or
  /// the one-level march over a single depth layer. std::invalid_argument for a texture not of
  /// the view's size.
  GpuFrameInfo render(const View& view, const GpuEffectRequest& effect, uint32_t texture, const GpuGBuffer& gbuffer);

  /// Traces `count` rays from your buffer `rays` (GpuRayRecord each) through the last rendered
  /// frame's layers with this renderer's tracer, writing a GpuHitRecord per ray into your buffer
  /// `hits`, on the device (nothing read back). The answers are the CPU tracer's, ray for ray.
  void trace(uint32_t rays, uint32_t hits, size_t count) const;

  struct Impl;  ///< layertrace's own use

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace lt
