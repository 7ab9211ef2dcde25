// One frame of the pipeline, shared by every subcommand: load the scene, choose the camera and
// lights, rasterize all fragments, sort and truncate to k layers (Hofmann et al. 2017, §4.1–4.2).
//
// Layer: pipeline/ assembles a frame — load → capture → structures — and builds any tracer by
// name with the structure it needs (tracer_factory.h). It includes screen/, geometry/ and the
// layers below them; never render/, eval/ or app/.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <glm/ext/vector_double3.hpp>
#include <glm/ext/vector_double4.hpp>
#include <nlohmann/json.hpp>

#include "layertrace/raster/capture.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/raster/rasterizer.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"
#include "layertrace/screen/interval_layers.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/util/memory.h"

namespace lt {

/// The default z-thickness: this many pixel footprints at each fragment's own depth (chosen from
/// the strict-class sweep in docs/results.md, "Choosing the z-thickness"). It follows the view, not
/// the scene's bounding box: 0.5 % of the diagonal was 0.12 m in a house but 59 units in an
/// OpenArena map whose skybox makes the bounds 8,000 units wide.
inline constexpr float kDefaultThicknessPx = 6.0f;

/// The common options of CLI (docs/cli.md).
struct FrameOptions {
  std::string scenePath;
  std::string cameraName;              ///< --camera; empty = the scene's first camera, else auto-framed
  /// --eye/--target override the camera; world coordinates (those of the scene file), in double so
  /// that a view of a scene far from the origin keeps its precision (Scene::origin).
  std::optional<glm::dvec3> eye, target;
  std::optional<glm::vec3> up;         ///< --up
  std::optional<float> fov;            ///< --fov, vertical degrees
  int width = 1280, height = 720;      ///< --width --height
  int layers = 4;                      ///< --layers (k)
  std::optional<float> thickness;      ///< --thickness: fixed, in scene units
  std::optional<float> thicknessPx;    ///< --thickness-px: pixel footprints at the fragment's depth (default kDefaultThicknessPx)
  float minSeparation = 0.0f;          ///< --min-separation
  bool adaptiveThickness = false;      ///< --adaptive-thickness (Hofmann et al. 2017, §4.2)
  bool frontFacesOnly = false;         ///< --front-faces-only: cull back faces at capture
  uint64_t pool = 0;                   ///< --pool fragments; 0 = automatic (grows on overflow)
  /// Keep every fragment in per-pixel lists as well. Not an option of its own: `layers --verify`
  /// and the list-reading options (--adaptive-thickness, --min-separation) set it.
  bool captureLists = false;
  /// Capture with the reference pipeline (Hofmann et al. 2017, §4.1–4.2 as written: every fragment linked
  /// into lists in a pool through an atomic counter, then sorted): what `--pool` selects, and
  /// what tests and `bench --experiment capture` compare the tile-local capture with.
  bool referenceCapture = false;
  /// Capture by depth peeling (`--capture peel`, LayerCapture::capturePeeled): k geometry passes,
  /// no fragment stored; the baseline of Hofmann et al. 2017, Fig. 8.
  bool depthPeeling = false;
  /// Build this interval pyramid with the capture, into memory the frame keeps from frame to
  /// frame; an hssr tracer with the same configuration uses it instead of building its own. Set
  /// by the commands whose tracers read it; unset, nothing is built.
  std::optional<PyramidConfig> pyramid;
  /// Merge its levels 1… inside the tile pass, tile by tile while each tile is in cache
  /// (PyramidTileBuilder), instead of over the whole level 0 after it. Off by
  /// default: measured, it costs the same wall time at two threads and 30–60 % more at one
  /// (docs/architecture.md, capture). Tile-local capture only.
  bool pyramidPerTile = false;
  std::vector<glm::dvec4> lights;      ///< --light x,y,z[,intensity] (repeatable), world coordinates
  /// --textures on|off: map the materials' textures per fragment and hit, with their alpha
  /// cut-outs (on), or give each material its textures' mean colour (off, flattenTextures).
  bool textures = true;
  bool lightmaps = false;              ///< --lightmaps: Quake 3 lightmaps multiply the albedo
};

struct Frame {
  Scene scene;
  Camera camera;
  std::vector<PointLight> lights;  ///< the lights in effect (scene's, --light, or the default)
  /// The fragment lists. When nothing asked for them (capturePipeline "tiles") only the
  /// per-pixel complexity and the counts are set, no nodes.
  FragmentLists lists;
  LayerArrays layers;
  LayerCapture capture;  ///< owns the tile-local capture's scratch, reused frame to frame
  /// The interval pyramid's level 0 (Hofmann et al. 2017, Figure 3 right: [depth, depth + thickness] per
  /// kept fragment), written by the capture tile by tile while each tile is in cache; every
  /// pyramid built for this frame shares it (tracer_factory.cpp). level0() checks it still
  /// matches `layers`.
  std::shared_ptr<IntervalLayers> intervals;
  /// The interval pyramid over `intervals` built by the capture (FrameOptions::pyramid), or null.
  std::shared_ptr<IntervalPyramid> pyramid;
  PyramidTileBuilder pyramidTiles;  ///< its per-tile storage, reused frame to frame
  float thickness = 0.0f;          ///< fixed part of the z-thickness (scene units)
  float thicknessPerDepth = 0.0f;  ///< plus this per unit depth (--thickness-px / focal)
  bool frontFacesOnly = false;     ///< captured with --front-faces-only
  double loadMs = 0.0, rasterMs = 0.0, sortMs = 0.0;
  RasterStats raster;
  std::string capturePipeline;  ///< "tiles", "tiles+lists", "reference", "peel", "gpu-lists" or "gpu-peel" (stats key capture_pipeline)
  size_t gpuMemoryBytes = 0;    ///< a GPU capture's memory (its pool, lists, arrays and the scene)
  int geometryPasses = 1;       ///< times the capture rasterized the scene (depth peeling: k on the CPU, 2k on the GPU)
  uint64_t fragmentsRasterized = 0;  ///< fragments of all geometry passes (depth peeling)
  /// A capture that stayed on the GPU (render's resident frame): its lists and layers were
  /// never read back (`lists` holds only the counts, `layers` only the size and k), and the
  /// statistics read what the device reduced instead.
  struct DeviceCapture {
    uint32_t maxComplexity = 0;  ///< the largest number of fragments in one pixel
  };
  std::optional<DeviceCapture> deviceCapture;
  /// The capture's pyramid when it was built with `config` over the current level 0, else null.
  std::shared_ptr<IntervalPyramid> pyramidFor(const PyramidConfig& config) const {
    const std::shared_ptr<IntervalLayers> l0 = level0();
    return pyramid && l0 && pyramid->base == l0 && pyramidConfig == config ? pyramid : nullptr;
  }
  PyramidConfig pyramidConfig;  ///< what `pyramid` was built with
  std::shared_ptr<IntervalLayers> level0() const {
    return intervals && intervals->width == layers.width && intervals->height == layers.height && intervals->k == layers.k ? intervals
                                                                                                                        : nullptr;
  }
};

/// Whether `options` need whole per-pixel lists (see FrameOptions::captureLists).
bool needsFragmentLists(const FrameOptions& options);

/// Checks values that need no scene (sizes, k, memory); throws InputError naming the option.
void validateFrameOptions(const FrameOptions& options);

/// Loads the scene and sets up camera and lights (no rasterization).
void loadFrameScene(const FrameOptions& options, Frame& frame);

/// Points the loaded frame's camera at `desc` with the options' size and sets the z-thickness
/// for it (lights stay; the viewer moves the camera with it). Call rasterizeFrame next.
void setFrameView(const FrameOptions& options, const CameraDesc& desc, Frame& frame);
/// The layer rules of a capture of `frame` with `options`: k, the frame's z-thickness, the minimum
/// separation and adaptive thickness (the CPU and GPU captures read the same).
LayerConfig layerConfig(const FrameOptions& options, const Frame& frame);
/// Rasterizes and sorts for the frame's camera. Throws InputError on fragment-pool overflow
/// when --pool fixed the capacity, with the exact counts.
void rasterizeFrame(const FrameOptions& options, Frame& frame);

/// loadFrameScene + rasterizeFrame.
Frame buildFrame(const FrameOptions& options);

/// The default light of a scene without lights: one point light 10 % of the eye-to-target
/// distance above the eye, bright enough to light the target (intensity = distance²).
PointLight defaultLight(const Camera& camera);

/// The stats keys every subcommand shares: scene, width, height, layers, timings (raster, sort),
/// memory (lists, arrays), fragments.
/// Positions in them (bounds, view) are world coordinates: Scene::origin added back.
nlohmann::json frameStats(const Frame& frame);
/// A point of the scene as the stats write it: [x, y, z] in world coordinates.
nlohmann::json worldStats(const Scene& scene, glm::vec3 p);

}  // namespace lt
