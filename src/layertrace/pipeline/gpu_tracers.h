// The GPU back end as the commands see it: which tracers have a GPU version, opening the
// device, and building a GPU tracer for a frame beside the CPU structures it mirrors. A build
// without the back end (LAYERTRACE_GPU off, or its packages missing) still has these functions:
// openGpu() then says so.
#pragma once

#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "layertrace/pipeline/tracer_registry.h"

namespace lt {

class GpuContext;

/// True when this build has the GPU back end (src/layertrace/gpu/).
bool gpuBuilt();
/// Opens the GPU; InputError naming `--device gpu` when this build has no back end or the
/// machine no OpenGL 4.5 device.
std::shared_ptr<GpuContext> openGpu();
/// A GPU context on the caller's EGL display sharing its objects with the caller's EGL context
/// (GpuContext::ShareWith: a window draws the GPU's picture where it lies), not current on
/// return. InputError where the display gives none, or in a build without the back end.
std::shared_ptr<GpuContext> openGpuSharing(void* eglDisplay, void* eglContext);
/// The device as the statistics report it: renderer, OpenGL version, and whether it is a
/// CPU rasterizer (whose times are CPU times, never GPU speed).
nlohmann::json gpuStats(const GpuContext& gpu);
/// Makes the GPU's context current on this thread again (after a window system's context was:
/// the viewer).
void makeGpuCurrent(const GpuContext& gpu);
/// Releases the GPU's context from this thread, for another thread to make it current.
void releaseGpu(const GpuContext& gpu);

/// The frame's capture on the GPU (--device gpu; `capture` "lists" or "peel"), for a frame whose
/// scene is loaded (loadFrameScene): its layers, level 0, fragment counts and timings, as
/// rasterizeFrame sets them on the CPU. The lists' nodes are kept when the options ask for lists
/// (layers --verify). GPU times come from timer queries: raster = setup + geometry passes.
void rasterizeFrameOnGpu(GpuContext& gpu, const FrameOptions& options, const std::string& capture, Frame& frame);

/// A reading of the process's GPU activity so far (gpu/gpu_context.h GpuActivity) under the keys
/// of gpu.frame: upload_bytes, download_bytes, host_waits, program_links, buffer_allocations,
/// dispatches, draws (all 0 in a build without the back end).
nlohmann::json gpuActivityReading();
/// gpu.frame for one frame between two readings: frames 1, wall_ms, gpu_ms and the differences.
nlohmann::json gpuFrameStats(const nlohmann::json& before, const nlohmann::json& after, double wallMs, double gpuMs);

/// Why the frame's scene cannot be captured on `gpu` (its textures exceed the GPU's largest
/// storage buffer), or empty when it can.
std::string gpuCaptureLimit(GpuContext& gpu, const Frame& frame);

/// The tracers with a GPU version: every one but embree and embree-robust.
bool hasGpuTracer(const std::string& name);
/// "ssr, ssr-layers, hiz, hssr, …", for messages.
const std::string& gpuTracerNames();

/// The registry's tracer `name` on the GPU, over the same structures the CPU tracer reads (the
/// pyramid and the quad-tree built on the GPU from the uploaded layers; the layered depth cube
/// and the grid built on the CPU and uploaded). `memoryBytes` is the GPU's share. InputError for
/// a tracer without a GPU version.
BuiltTracer buildGpuTracer(const std::string& name, const Frame& frame, const TracerOptions& options, GpuContext& gpu);
/// Persistent threads for a GPU hssr, hiz or exhaustive tracer (Hofmann et al. 2017, §5.3: ray
/// reloading from a queue); false for any other tracer, which is left as it is.
bool setGpuPersistentThreads(Tracer& tracer, bool on);
/// GPU time of the dispatches of all batches a GPU tracer traced so far (GL timer queries),
/// milliseconds; 0 for a CPU tracer.
double gpuTraceMs(const Tracer& tracer);
/// What the GPU's build of the irregular grid made and cost (gpu/gpu_grid_build.h).
struct GpuGridBuildStats {
  size_t cells = 0, cellsInitial = 0, refs = 0, memoryBytes = 0;
  int mergeRounds = 0;
  uint64_t expandedFaces = 0;
  double gpuMs = 0.0, wallMs = 0.0;            ///< timer queries summed; host wall time, read-backs included
  double topMs = 0.0, leavesMs = 0.0, mergeMs = 0.0, expandMs = 0.0, packMs = 0.0;  ///< by step (timer queries)
};
/// The irregular grid of `frame`'s scene built on the GPU for `config` (all four steps: the
/// CPU's cells), as a tracer the GPU walks (buildGpuTracer "grid"'s), with
/// `cutOuts` (a CPU grid of the scene, or null where it has no alpha-tested triangles)
/// answering the rays an alpha-tested candidate stops. `stats` receives the build's figures.
BuiltTracer buildGpuGridOnGpu(const Frame& frame, const GridConfig& config, const IrregularGrid* cutOuts, GpuContext& gpu,
                              GpuGridBuildStats& stats);

/// World-space queries through the GPU grid `tracer` (buildGpuTracer "grid"), answered as
/// IrregularGrid::intersect / occluded answer them; returns the dispatch's GPU milliseconds.
/// InternalError where `tracer` is no GPU grid.
double traceGpuGrid(const Tracer& tracer, std::span<const IrregularGrid::Query> queries, bool anyHit, std::span<GeoHit> hits);

}  // namespace lt
