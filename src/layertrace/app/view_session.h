// The CPU side of `layertrace view`: the scene loaded once, and one picture per request — capture
// for the request's camera, the tracer's structure, the effect, and the overlay the user picked.
// It has no window, so tests run it headless; apps/viewer/ puts it on screen. With
// `--device gpu` the capture and the tracers that have a GPU version run on the GPU, through a
// headless context of its own (gpu/): the caller makes its window's context current again after
// render(). The plain picture of hssr, hiz and exhaustive is one resident frame
// (gpu/gpu_frame.h), made once per tracer and parameters: the next frames link, allocate and
// upload nothing, wait once and read back only the picture.
#pragma once

#include <array>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "layertrace/app/commands.h"

namespace lt {

/// What the viewer shows over (instead of) the traced image.
enum class ViewOverlay { None, Classes, Iterations, Layer, DepthComplexity };
inline constexpr const char* kViewOverlayNames[] = {"image", "classes vs Embree", "iterations", "layer albedo", "depth complexity"};
/// The --overlay names, in ViewOverlay order.
inline constexpr const char* kViewOverlayOptions[] = {"image", "classes", "iterations", "layer", "complexity"};
/// --overlay NAME → ViewOverlay (InputError naming the value).
ViewOverlay parseViewOverlay(const std::string& name);

/// One picture: the camera, the size (divided by `scale` while the camera moves) and every
/// option the panel edits.
struct ViewRequest {
  CameraDesc camera;
  int width = 1280, height = 720;  ///< full size
  int scale = 1;                   ///< 1 = full resolution; 2 = half width and height (¼ of the pixels)
  std::string tracer = "hssr";
  EffectConfig effect;
  TracerOptions tracers;
  int layers = 4;                  ///< k
  float thicknessPx = kDefaultThicknessPx;
  ViewOverlay overlay = ViewOverlay::None;
  int layer = 0;  ///< ViewOverlay::Layer: which stored layer
  /// With a shared context (ViewSession::presentOnGpu) and a resident frame: leave the picture on
  /// the GPU (ViewResult::gpuPicture) instead of reading it back.
  bool pictureOnGpu = false;
};

struct ViewResult {
  Image image;   ///< what to show: the traced image or the overlay, width/scale × height/scale
  Image traced;  ///< the effect's image (what `render` writes)
  int scale = 1;
  double captureMs = 0.0, structureMs = 0.0, traceMs = 0.0, shadeMs = 0.0, totalMs = 0.0;
  uint64_t rays = 0;
  double iterationsMean = 0.0;
  bool classified = false;  ///< classFractions hold the strict classes of this frame's rays
  std::array<double, kRayClasses> classFractions{};
  std::string error;  ///< a refused option (the picture is then empty)
  std::string device = "cpu";  ///< where the tracer ran ("gpu": --device gpu and a tracer with a GPU version)
  std::string shading = "cpu";  ///< where rays were generated and shaded (EffectResult::onDevice)
  /// --device gpu: what the frame asked of the GPU (the keys of gpu.frame: upload_bytes,
  /// download_bytes, host_waits, program_links, buffer_allocations, dispatches, draws).
  nlohmann::json gpuFrame;
  /// ViewRequest::pictureOnGpu honoured: the GL buffer, shared with the window's context, that
  /// holds the picture as RGBA8 sRGB codes (R in the low byte), `pictureWidth` × `pictureHeight`
  /// rows from the top (image and traced are then empty); 0 otherwise. It is rewritten by the
  /// next render: draw or copy it first.
  uint32_t gpuPicture = 0;
  int pictureWidth = 0, pictureHeight = 0;
};

/// Checks --frames and the screenshot paths (InputError naming the option).
void validateViewOptions(const ViewOptions& options);

struct ViewCache;
class GpuContext;

class ViewSession {
 public:
  /// Loads the scene and sets the first camera from `options` (as `render` does).
  explicit ViewSession(const RenderOptions& options);
  ~ViewSession();
  /// The request that reproduces `layertrace render` with the same options.
  ViewRequest initialRequest() const { return initial_; }
  const Frame& frame() const { return frame_; }
  /// Renders `request` (not thread-safe: one caller at a time). Invalid options come back as
  /// ViewResult::error, not as exceptions.
  ViewResult render(const ViewRequest& request);
  /// View-independent structures built so far: one per tracer and set of its own parameters.
  size_t cachedStructures() const;
  /// --device gpu: render from now on through a context that shares its objects with the
  /// caller's EGL context (a window's), so that resident pictures can stay on the GPU
  /// (ViewRequest::pictureOnGpu). Returns the reason it could not (the session then keeps its
  /// headless context), else empty. Call it before the first render.
  std::string presentOnGpu(void* eglDisplay, void* eglContext);
  bool presentsOnGpu() const { return sharedGpu_; }
  /// Frees what the session holds on the GPU and its context: before the window whose display a
  /// shared context uses closes (no render after it).
  void closeGpu();

 private:
  RenderOptions options_;
  Frame frame_;
  ViewRequest initial_;
  std::unique_ptr<ViewCache> cache_;  ///< view-independent structures built so far (refer to frame_)
  std::shared_ptr<GpuContext> gpu_;   ///< --device gpu
  bool sharedGpu_ = false;            ///< gpu_ shares its objects with the window's context
};

}  // namespace lt
