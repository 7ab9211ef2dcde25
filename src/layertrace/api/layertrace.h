// layertrace's public API: trace rays through depth layers you already have, and measure the hits
// against the triangles that made them.
//
//   #include <layertrace/layertrace.h>          CMake: find_package(layertrace) → layertrace::layertrace
//                                               pkg-config: layertrace
//
// Layer: api/ is the installed interface of the library (docs/library.md).
// It may include every layer except app/ (the CLI); this header itself includes only
// trace/tracer.h (Ray, TraceHit) and the generated export header, so that it installs alone.
//
// Conventions, the same everywhere in layertrace (scene/camera.h):
//   camera space  right-handed, looking down -z, +y up; depth = -z, the positive linear distance
//                 along the viewing direction, in scene units.
//   screen        pixels, x to the right, y DOWN; pixel (x, y) covers [x, x+1) × [y, y+1) and is
//                 sampled at its centre (x + 0.5, y + 0.5); buffers are row-major, index
//                 y · width + x, and k-layer buffers are layer-major: layer l of pixel (x, y) at
//                 (l · height + y) · width + x.
//   normals       camera-space unit vectors (only shading uses them; tracing reads depths).
//   errors        every function validates its arguments and throws std::invalid_argument with a
//                 one-line message naming the argument and the bad value; std::runtime_error for a
//                 failure inside layertrace.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/ext/vector_double3.hpp>

#include "layertrace/api/export.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// A pinhole view: its pose (world space), vertical field of view and image.
struct View {
  glm::vec3 eye{0.0f, 0.0f, 0.0f};
  glm::vec3 target{0.0f, 0.0f, -1.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float fovY = 60.0f;  ///< vertical field of view in degrees, in (0, 180)
  int width = 0, height = 0;  ///< pixels, 1..32768 each
  float near = 0.01f;   ///< depths in front of the near plane are not visible (scene units, > 0)
  float far = 1000.0f;  ///< nor beyond the far plane (> near)
};

/// World-space point → camera space of `view` (and back), and the unit camera-space direction of
/// the ray through screen point (px, py) in pixels. Throw std::invalid_argument for an invalid view.
LAYERTRACE_API glm::vec3 worldToCamera(const View& view, glm::vec3 point);
LAYERTRACE_API glm::vec3 cameraToWorld(const View& view, glm::vec3 point);
LAYERTRACE_API glm::vec3 pixelDirection(const View& view, float px, float py);

/// The k-layer depth intervals of one view, ready to trace: per pixel up to k intervals
/// [front, back] sorted front to back, built from one of three kinds of buffers you own (copied).
class LAYERTRACE_API ScreenLayers {
 public:
  /// (a) One depth buffer: depth[y·width + x] = the front surface's depth, +inf where the pixel
  /// is empty. Each surface gets a z-thickness of `thicknessPx` pixel footprints at its own depth
  /// (layertrace's default: 6). `normals` (optional, one per pixel) are returned with the hits.
  static ScreenLayers fromDepthBuffer(const View& view, std::span<const float> depth, std::span<const glm::vec3> normals = {},
                                      float thicknessPx = 6.0f);
  /// (b) k layers: front and back depth of each layer (layer-major, k · width · height each); an
  /// empty slot has front = +inf and only empty slots may follow it. Per pixel the layers must be
  /// sorted (front non-decreasing) and back ≥ front. `normals` and `ids` (returned as
  /// TraceHit::triangle) are optional, laid out the same way.
  static ScreenLayers fromLayers(const View& view, int k, std::span<const float> front, std::span<const float> back,
                                 std::span<const glm::vec3> normals = {}, std::span<const uint32_t> ids = {});
  /// (c) Full fragment lists: pixel p's fragments are [offsets[p], offsets[p+1]) of `depth`
  /// (width · height + 1 offsets, non-decreasing; fragments in any order); they are sorted and the
  /// k front-most kept, each `thicknessPx` pixel footprints thick (Hofmann et al. 2017, §4.2).
  static ScreenLayers fromFragments(const View& view, std::span<const uint32_t> offsets, std::span<const float> depth,
                                    std::span<const glm::vec3> normals = {}, std::span<const uint32_t> ids = {}, int k = 4,
                                    float thicknessPx = 6.0f);

  ScreenLayers(ScreenLayers&&) noexcept;
  ScreenLayers& operator=(ScreenLayers&&) noexcept;
  ~ScreenLayers();

  const View& view() const;
  int layers() const;                ///< k
  int countAt(int x, int y) const;   ///< intervals stored at pixel (x, y), 0..k

  /// layertrace's own use (the state is opaque to users).
  struct Impl;
  explicit ScreenLayers(std::unique_ptr<Impl> impl);
  const Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

/// Which space rays (and the hits returned for them) are in.
enum class RaySpace : uint8_t { Camera, World };

/// Method parameters by their registry names, the CLI's flags without the dashes ("hssr-tau",
/// "ssr-stride", "quadtree-plane-error"; `layertrace tracers` lists every one with its default),
/// over a preset: "tuned" (the defaults) or "paper" (every method as published). A value set
/// here wins over the preset's, as a flag beside --preset does. set() checks the name and the
/// value at once (std::invalid_argument with the CLI's message).
class LAYERTRACE_API TracerParams {
 public:
  explicit TracerParams(const std::string& preset = "tuned");
  TracerParams& set(const std::string& name, const std::string& value);
  /// The value in effect, as the CLI prints it ("4", "true").
  std::string get(const std::string& name) const;
  const std::string& preset() const { return preset_; }
  /// The values set, by canonical name, in the order first set.
  const std::vector<std::pair<std::string, std::string>>& values() const { return values_; }
  /// Every parameter's name, in `layertrace tracers`' order.
  static std::vector<std::string> names();

 private:
  std::string preset_;
  std::vector<std::pair<std::string, std::string>> values_;
};

/// A screen-space tracer over ScreenLayers (which must outlive it): "hssr" (Hofmann et al. 2017's
/// hierarchical tracer, exact against its oracle), "hiz", "ssr", "ssr-layers" or "quadtree".
/// It builds the structure it needs (e.g. the interval pyramid) once; std::invalid_argument for
/// another name. Its trace calls may run concurrently from several threads.
class LAYERTRACE_API ScreenTracer {
 public:
  explicit ScreenTracer(const ScreenLayers& layers, const std::string& name = "hssr", const TracerParams& params = TracerParams());
  /// Refused at compile time: the tracer reads the layers it was given, so they must be named.
  explicit ScreenTracer(ScreenLayers&& temporary, const std::string& name = "hssr", const TracerParams& params = TracerParams()) = delete;
  ScreenTracer(ScreenTracer&&) noexcept;
  ~ScreenTracer();

  /// Closest hit of every ray: hits[i] answers rays[i] (same sizes). A hit carries its pixel,
  /// layer, the point where the ray meets the stored interval, and the stored normal and id, in
  /// the rays' space. Secondary rays (Ray::startsOnSurface) skip their own pixel
  /// (Hofmann et al. 2017, §5.1). std::invalid_argument for different sizes, a non-finite origin, a
  /// direction that is not of unit length or a maxDistance that is not positive (naming rays[i]).
  void trace(std::span<const Ray> rays, std::span<TraceHit> hits, RaySpace space = RaySpace::Camera) const;
  /// Whether anything blocks each ray before its maxDistance (hits[i].hit).
  void occluded(std::span<const Ray> rays, std::span<TraceHit> hits, RaySpace space = RaySpace::Camera) const;
  const char* name() const;

  struct Impl;  ///< layertrace's own use

 private:
  std::unique_ptr<Impl> impl_;
};

/// A material of TriangleScene (linear RGB; mirror weight in [0, 1]).
struct MeshMaterial {
  glm::vec3 albedo{0.7f};
  float mirror = 0.0f;
};

/// Triangles in world space (copied): positions, index triples, and optionally a material per
/// triangle. Throws std::invalid_argument for an index out of range or a non-finite position.
class LAYERTRACE_API TriangleScene {
 public:
  TriangleScene(std::span<const glm::vec3> positions, std::span<const glm::uvec3> triangles,
                std::span<const uint32_t> materialOfTriangle = {}, std::span<const MeshMaterial> materials = {});
  TriangleScene(TriangleScene&&) noexcept;
  ~TriangleScene();
  size_t triangleCount() const;
  /// The scene's vertices (moved as origin() says), their shading normals, its triangles' vertex
  /// indices and material indices: what a renderer draws (layertrace/gpu.h GpuGeometry).
  std::span<const glm::vec3> positions() const;
  std::span<const glm::vec3> normals() const;
  std::span<const glm::uvec3> triangles() const;
  std::span<const uint32_t> materialOfTriangle() const;
  size_t materialCount() const;

  /// A scene file as the CLI reads it: any model assimp reads (OBJ, glTF, PLY, Collada, IFC,
  /// FBX, …), a Quake 3 .pk3 or a JSON scene with its materials, textures, lights and cameras.
  /// std::invalid_argument naming the file for one that cannot be read.
  static TriangleScene load(const std::string& path);
  /// The scene's named cameras (a JSON scene's, then the model's), in file order.
  std::vector<std::string> cameraNames() const;
  /// A camera's view at width × height, with the near and far planes the CLI derives from the
  /// scene; `camera` empty: the CLI's default view (the first camera, else one framing the
  /// whole scene).
  View view(const std::string& camera, int width, int height) const;
  /// Where the scene's coordinates start in the file's: a scene far from the origin is moved
  /// next to it on loading (its vertices keep their float precision), and every View and Ray of
  /// this API is in the moved coordinates; zero for most scenes.
  glm::dvec3 origin() const;

  struct Impl;  ///< layertrace's own use
  const Impl& impl() const { return *impl_; }

 private:
  explicit TriangleScene(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

/// A geometric tracer over a TriangleScene (which must outlive it), for rays in `view`'s camera
/// space (or world space): "embree" (Embree 3 with its default flags, the speed baseline, as the
/// CLI's --tracer embree), "embree-robust" (Embree 3 in robust mode: layertrace's ground truth,
/// what `compare` grades against) or "grid" (the irregular grid of Pérard-Gayot et al. 2017);
/// std::invalid_argument for another name or an
/// invalid view. Hits carry the triangle index, the exact point and normal, and layer -1; trace and
/// occluded validate their arguments as ScreenTracer's do.
class LAYERTRACE_API MeshTracer {
 public:
  MeshTracer(const TriangleScene& scene, const View& view, const std::string& name = "embree", const TracerParams& params = TracerParams());
  MeshTracer(MeshTracer&&) noexcept;
  ~MeshTracer();
  void trace(std::span<const Ray> rays, std::span<TraceHit> hits, RaySpace space = RaySpace::Camera) const;
  void occluded(std::span<const Ray> rays, std::span<TraceHit> hits, RaySpace space = RaySpace::Camera) const;

  struct Impl;  ///< layertrace's own use

 private:
  std::unique_ptr<Impl> impl_;
};

/// The strict classes of layertrace's evaluation (docs/evaluation.md): CorrectHit,
/// WrongHitThickness, WrongHitUnstored, WrongHitOther, FalseMiss, OriginPixelMiss, InfoMiss,
/// CorrectMiss (trace/tracer.h).
using HitClass = RayClass;
/// "correct_hit", "wrong_hit_thickness", ... (the stats keys of `layertrace compare`).
LAYERTRACE_API const char* hitClassName(HitClass c);

/// Grades closest-hit answers `hits` to camera-space `rays` against the true hits `truth` (a
/// MeshTracer's answers to the same rays) over `layers`: one HitClass (as uint8_t) per ray.
LAYERTRACE_API std::vector<uint8_t> classifyHits(const ScreenLayers& layers, std::span<const Ray> rays,
                                                 std::span<const TraceHit> hits, std::span<const TraceHit> truth);

/// Captures a TriangleScene with layertrace's rasterizer: all fragments, sorted, the k front-most
/// kept, `thicknessPx` pixel footprints thick (what `layertrace render` traces).
LAYERTRACE_API ScreenLayers captureLayers(const TriangleScene& scene, const View& view, int k = 4, float thicknessPx = 6.0f);

/// A linear-RGB image (width · height · 3 floats, row-major, y down).
struct LAYERTRACE_API RgbImage {
  int width = 0, height = 0;
  std::vector<float> rgb;
  /// Writes an 8-bit sRGB PNG (to a temporary name, then renamed). Throws std::invalid_argument
  /// naming the path when it cannot be written.
  void savePng(const std::string& path) const;
};

/// One effect of a TriangleScene, as `layertrace render` makes it: capture k layers, trace with
/// `tracer` (any CLI tracer name: hssr, hiz, ssr, ssr-layers, quadtree, ldc, hybrid, embree, embree-robust, grid),
/// shade with one point light above the eye.
struct RenderRequest {
  View view;
  std::string tracer = "hssr";
  std::string effect = "reflection";  ///< shade, reflection, refraction, ao, shadow, warp
  int bounces = 1;
  int layers = 4;
  TracerParams params;  ///< the tracer's parameters and preset
  int aoSamples = 8;         ///< AO rays per pixel
  float maxDistance = 0.0f;  ///< ray length (0: the scene's diagonal)
  /// warp (view synthesis): the second view's eye (required) and target (default: the first
  /// view's), in the scene's coordinates; the image is the second view's, traced through the
  /// first view's layers.
  std::optional<glm::vec3> warpEye, warpTarget;
  uint64_t seed = 1;  ///< the random sequence of AO and refraction, as the CLI's --seed
};
LAYERTRACE_API RgbImage render(const TriangleScene& scene, const RenderRequest& request);

}  // namespace lt
