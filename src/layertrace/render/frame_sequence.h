// Frames along a camera path, as a renderer draws them: `bench --experiment frame`. On the CPU
// each frame captures, builds the tracer's structure and renders the effect; on the GPU the
// whole frame stays on the device (gpu/gpu_frame.h) and each frame is counted: its wall and GPU
// time, what crossed the bus, how often the host waited, what was linked, allocated and
// dispatched. A renderer's steady state is the frames after the first.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "layertrace/pipeline/frame.h"
#include "layertrace/pipeline/tracer_registry.h"
#include "layertrace/render/effects.h"
#include "layertrace/util/image.h"

namespace lt {

class GpuContext;

inline constexpr float kOrbitDegreesPerFrame = 3.0f;

/// One frame's record (stats key gpu.frame, frame.json's entries).
struct FrameSample {
  int frame = 0;
  double wallMs = 0.0;  ///< host wall time of the whole frame, its read-back included
  double gpuMs = 0.0;   ///< the GPU's timer queries summed (0 on the CPU)
  double captureMs = 0.0, pyramidMs = 0.0, traceMs = 0.0, shadeMs = 0.0;  ///< by stage (GPU: timer queries; CPU: wall)
  uint64_t uploadBytes = 0, downloadBytes = 0, hostWaits = 0, programLinks = 0, bufferAllocations = 0, dispatches = 0, draws = 0;
  uint64_t rays = 0, hits = 0, fragments = 0;
  int attempts = 1;  ///< runs of the frame (GPU: 2 or more when a buffer grew)
};

/// The camera of frame `i` on the orbit of `desc` about its target: turned about the up axis
/// through the target by `degrees` a frame, at the eye's height and distance (frame 0 is
/// `desc`). Choice: 3° a frame (a turn in 120 frames, 4 s at 30 Hz), so that a short run stays
/// near the chosen view, as a walk through a scene would, and still moves every frame.
CameraDesc orbitCamera(const CameraDesc& desc, int i, float degrees = kOrbitDegreesPerFrame);

struct FrameSequenceConfig {
  std::string tracer = "hssr";  ///< --tracer (GPU: hssr, hiz, exhaustive, ssr or ssr-layers)
  TracerOptions tracers;
  EffectConfig effect;
  int frames = 30;              ///< --frames
  /// Called with each frame's picture when set (--images); otherwise no picture is read back.
  std::function<void(int, const Image&)> onImage;
};

/// Whether a resident GPU frame (gpu/gpu_frame.h) marches with `name`: over the interval pyramid
/// (hssr, hiz, exhaustive) or SSR over the front layer or all k (ssr, ssr-layers). Used by
/// render, view, bench --experiment frame and layertrace/gpu.h.
bool isGpuFrameTracer(const std::string& name);

/// What one resident frame gives `render --device gpu`: the picture and the effect's counters
/// (reduced on the device), the capture's counts, the pyramid's intervals per level, the GPU
/// times. Nothing per pixel but the picture crosses the bus.
struct ResidentRender {
  EffectResult effect;  ///< image (unless srgb8), counters, iterationsP99, the counted frame's GPU times, onDevice
  std::vector<uint8_t> srgb8;  ///< with `srgb8` asked for: the picture as encode8's RGB bytes, row 0 first
  uint64_t fragments = 0, poolCapacity = 0, overflowLost = 0;
  uint32_t maxComplexity = 0;
  std::vector<uint64_t> levelIntervals;  ///< per pyramid level, level 0 included
  double rasterMs = 0.0, sortMs = 0.0, layersMs = 0.0, pyramidMs = 0.0;  ///< GPU timer queries
  size_t hierarchyBytes = 0;  ///< level 0, the counts and the pyramid on the GPU
  size_t captureBytes = 0;    ///< the scene, the pool, the lists and the arrays on the GPU
  int attempts = 1;           ///< runs of the frame (2 or more: a buffer grew)
  double timedTraceMs = 0.0, timedShadeMs = 0.0;  ///< medians of the --repeat runs without counters
  nlohmann::json frameAccount;  ///< the counted frame's gpu.frame (the scene's upload and the links included)
  /// A tracer of the scene (isResidentSceneTracer): its structure, built on the CPU and uploaded
  /// once beside the frame, with its statistics.
  std::optional<BuiltTracer> structure;
};

class GpuFrame;
/// The resident frame (gpu/gpu_frame.h) of the loaded `frame`'s scene and lights for `tracer`
/// (hasResidentFrame; InputError for another, for the grid in a scene with alpha-tested
/// triangles, or for more lights than the GPU passes hold) with `tracers`' parameters and
/// `options`' capture; a tracer of the scene is built here, beside the frame. `geometry`, when
/// given, is the scene the frame captures in place of `frame`'s (a caller's draw calls write its
/// geometry on the device: GpuFrame::setGeometryPass; screen tracers only). `frame` and
/// `geometry` must outlive it.
std::unique_ptr<GpuFrame> makeResidentFrame(GpuContext& gpu, const FrameOptions& options, const Frame& frame, const std::string& tracer,
                                            const TracerOptions& tracers, const Scene* geometry = nullptr);

/// Whether `render --device gpu` can run `tracer` with `effect` as one resident frame: a resident
/// tracer, lights the GPU passes hold, and an effect that needs nothing per pixel on the host
/// (view synthesis counts its holes per pixel).
bool rendersResident(const std::string& tracer, const Frame& frame, const EffectConfig& effect);
/// Whether `tracer` traces the resident frame with a structure of the scene built once beside it
/// (ldc, grid) rather than a march over the frame's own layers.
bool isResidentSceneTracer(const std::string& tracer);
/// Whether `tracer` has a resident GPU frame: a march over the frame's own layers
/// (isGpuFrameTracer), the quad-tree built from them, or a tracer of the scene.
bool hasResidentFrame(const std::string& tracer);
/// Renders the loaded `frame` (loadFrameScene) as one resident GPU frame, then runs the effect
/// `repeat` times more without counters for the timings. The picture comes back as 32-bit floats,
/// or with `srgb8` as the 8-bit sRGB codes a PNG holds (encoded on the device, to the bit).
ResidentRender renderResident(const FrameOptions& options, Frame& frame, const std::string& tracer, const TracerOptions& tracers,
                              const EffectConfig& effect, int repeat, bool srgb8, GpuContext& gpu);

/// One row of `bench --experiment stages --device gpu` for a resident tracer: medians of GPU
/// timer queries over `repeat` frames of the loaded `frame`'s view after a counted one, each
/// frame captured, sorted, built and traced on the device with the effect's counter-free march.
struct ResidentStages {
  double rasterMs = 0.0, sortMs = 0.0;  ///< the capture's setup and geometry passes, its sort
  double layersMs = 0.0;                ///< the layer arrays from the sorted slots
  double pyramidMs = 0.0, traceMs = 0.0, shadeMs = 0.0;
  double iterationsMean = 0.0;          ///< of the counted frame's rays
  size_t memoryBytes = 0;               ///< the capture's buffers and the hierarchy on the GPU
  size_t effectBytes = 0;               ///< the effect passes' buffers
};
ResidentStages measureResidentStages(const FrameOptions& options, Frame& frame, const std::string& tracer, const TracerOptions& tracers,
                                     const EffectConfig& effect, int repeat, GpuContext& gpu);

/// The GPU capture of the loaded `frame`'s view in a resident frame (lists, or peeling with
/// options.depthPeeling): medians over `repeat` frames after a warm-up of its GPU milliseconds
/// (timer queries), its buffers and the fragments it generated. Nothing is read back but the
/// frame's counters.
struct ResidentCapture {
  double rasterMs = 0.0;  ///< the setup and geometry passes (peeling: every layer's)
  double sortMs = 0.0;    ///< the sort of the lists (peeling: the resolve of the last pass)
  size_t bytes = 0;       ///< the scene, the pool, the lists and the arrays on the GPU
  uint64_t fragments = 0;
};
ResidentCapture measureResidentCapture(const FrameOptions& options, Frame& frame, int repeat, GpuContext& gpu);

/// Renders `config.frames` frames of the loaded `frame` (loadFrameScene) along the orbit of its
/// camera, on the CPU (`gpu` null) or resident on the GPU. InputError for a tracer the GPU frame
/// lacks or more lights than the GPU passes hold.
std::vector<FrameSample> runFrameSequence(const FrameOptions& options, Frame& frame, const FrameSequenceConfig& config, GpuContext* gpu);

/// The JSON object of one sample, and the summary: every key's median over the frames after the
/// first (all frames when there is one), with "frames" the count.
nlohmann::json frameSampleJson(const FrameSample& s);
nlohmann::json frameSummary(const std::vector<FrameSample>& samples);

}  // namespace lt
