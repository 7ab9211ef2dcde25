// Capture on the GPU (Hofmann et al. 2017, §4.1–4.2): the scene rasterized by the OpenGL
// pipeline, every fragment kept, sorted to the k-layer arrays — the same 16-byte nodes, layout
// and precision as the CPU capture (raster/), which the result is compared with. Two captures:
//   lists  every fragment linked into per-pixel lists in one geometry pass (an atomic counter
//          over a pool, an atomic exchange on the pixel's head; a thin 12-byte node: depth,
//          next and triangle), then a compute pass sorts each pixel to its k front-most
//          fragments with the minimum separation or the adaptive thickness of §4.2 and
//          evaluates the normal and material of those it keeps;
//   peel   depth peeling, the baseline of Fig. 8: the nearest remaining layer per geometry
//          pass pair, k times (no pool, no lists).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "layertrace/gpu/gpu_context.h"
#include "layertrace/gpu/gpu_scene_tables.h"
#include "layertrace/raster/fragment_lists.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"

namespace lt {

enum class GpuCaptureMethod { Lists, Peel };

struct GpuCaptureConfig {
  GpuCaptureMethod method = GpuCaptureMethod::Lists;
  LayerConfig layers;
  /// The pool in fragments (lists); 0 = 8 per pixel, at least 2^20.
  uint64_t poolCapacity = 0;
  /// On overflow capture again with a pool that holds every fragment (the count is exact).
  bool growOnOverflow = true;
  bool frontFacesOnly = false;
  /// Lists: also download every fragment's list (GpuCaptureResult::lists), for verification.
  bool keepLists = false;
};

struct GpuCaptureResult {
  LayerArrays layers;
  /// Every fragment in its pixel's list (GpuCaptureConfig::keepLists, lists capture), as the CPU
  /// capture's lists: heads, pool, triangles. Otherwise only the sizes and counts.
  FragmentLists lists;
  uint64_t generated = 0;            ///< fragments the rasterizer produced (of the last pass)
  uint64_t stored = 0;               ///< of them in the pool (lists); = generated when nothing was lost
  uint64_t overflowLost = 0;         ///< fragments lost by a first pass that overflowed (before growing)
  uint64_t poolCapacity = 0;         ///< the pool of the last pass (lists)
  int passes = 0;                    ///< capture passes (2 when the pool grew)
  int geometryPasses = 0;            ///< times the scene was rasterized (peel: 2k)
  /// GPU milliseconds (timer queries): the vertex and triangle setup, the geometry passes, and
  /// the sort (or the peel's resolve).
  double setupMs = 0.0, rasterMs = 0.0, sortMs = 0.0;
  size_t memoryBytes = 0;  ///< GPU memory the capture held: scene, pool, lists and arrays
};

/// The capture of one scene, kept on the device from frame to frame: the scene (geometry,
/// materials, textures) uploaded once, the programs the context's, and every buffer allocated
/// on the first frame, then again only for a new size or k, or a pool that overflowed.
class GpuCapture {
 public:
  /// Uploads `scene`; InputError when its textures exceed the GPU's largest storage buffer.
  GpuCapture(GpuContext& gpu, const Scene& scene);
  /// Why `scene` cannot be captured on `gpu` (its textures exceed the largest storage buffer),
  /// or empty when it can.
  static std::string limit(GpuContext& gpu, const Scene& scene);
  ~GpuCapture();
  GpuCapture(const GpuCapture&) = delete;
  GpuCapture& operator=(const GpuCapture&) = delete;

  /// Issues the capture of the scene seen by `camera` (setup, geometry passes, sort), with no
  /// read-back: a pool that overflows keeps counting (counter() holds the exact number of
  /// fragments), stores what fits, and the caller grows it (growPool) and captures again.
  void submit(const Camera& camera, const GpuCaptureConfig& config);
  /// Takes the k-layer arrays of the view `camera` from a caller instead of capturing them
  /// (layertrace/gpu.h GpuLayers): `slots` holds k 16-byte nodes a pixel (depth, octahedral
  /// normal, albedo and specular, z-thickness; pixel-major, ascending depth), `counts` a uint a
  /// pixel (held to k), `materials` (or none: material 0) a uint a slot (held below
  /// `materialCount`), which stands in for the slot's triangle.
  void submitLayers(const Camera& camera, int k, const GpuBuffer& slots, const GpuBuffer& counts, const GpuBuffer* materials,
                    uint32_t materialCount);
  /// A pool of `fragments`, for the next submit.
  void growPool(uint64_t fragments);

  /// The k-layer arrays of the last submit: per slot (pixel-major, k a pixel) the 16-byte node
  /// with its z-thickness in place of the list pointer, per pixel the count, per slot the scene
  /// triangle; the depth complexity per pixel; the fragments generated (one uint, lists).
  const GpuBuffer& slots() const { return slots_; }
  const GpuBuffer& counts() const { return counts_; }
  const GpuBuffer& slotTriangle() const { return slotTriangle_; }
  const GpuBuffer& complexity() const { return complexity_; }
  const GpuBuffer& counter() const { return counter_; }
  /// Binds the scene's world-space positions (3 floats a vertex), its triangles' vertex indices
  /// (3 uints a triangle) and their materials (a uint a triangle) to these storage bindings.
  void bindScene(uint32_t positions, uint32_t indices, uint32_t triMaterial) const;
  /// The scene's world-space vertex positions and normals (3 floats a vertex) and its
  /// triangles' materials (a uint a triangle), as uploaded: a frame whose geometry comes from a
  /// caller's draw calls writes them on the device (GpuFrame::setGeometryPass).
  const GpuBuffer& positions() const;
  const GpuBuffer& normals() const;
  const GpuBuffer& triMaterial() const;
  /// The scene's tables as uploaded (positions, normals, triangles, materials, textures).
  const GpuSceneTables& sceneTables() const { return *sceneBuffers_; }
  /// The pool's fragments (lists).
  uint64_t poolCapacity() const { return capacity_; }
  int geometryPasses() const { return geometryPasses_; }
  /// Bytes held: scene, pool, lists and arrays.
  size_t memoryBytes() const;
  /// GPU milliseconds of the last submit (timer queries; waits unless the frame was read).
  double setupMs() const, rasterMs() const, sortMs() const;
  /// Downloads the last submit's results (generated: the fragments the counter holds).
  void download(const GpuCaptureConfig& config, uint64_t generated, GpuCaptureResult& out) const;

 private:
  /// The per-view buffers for a width × height view with k layers (allocated when these change).
  void prepareView(int width, int height, int k);
  GpuContext& gpu_;
  const Scene& scene_;
  std::unique_ptr<GpuSceneTables> sceneBuffers_;
  GpuBuffer camPos_, camNormals_, setups_;
  GpuBuffer complexity_, slots_, counts_, slotTriangle_;
  GpuBuffer nodes_, nodeTriangle_, heads_, counter_;  ///< the pool's thin nodes (depth, next), their triangles
  GpuBuffer fullNodes_;                               ///< the pool as 16-byte nodes (keepLists only)
  GpuBuffer peelDepth_, peelTriangle_;
  uint64_t capacity_ = 0;
  size_t pixels_ = 0;
  int width_ = 0, height_ = 0;
  int k_ = 0;
  bool peel_ = false;
  int geometryPasses_ = 0;
  uint32_t vao_ = 0, fbo_ = 0;
  int fboWidth_ = 0, fboHeight_ = 0;
  GpuTimer setupTimer_, rasterTimer_, sortTimer_;
};

/// Captures `scene` seen by `camera` on the GPU into `out` (its layers downloaded to the CPU).
/// InputError for an invalid layer configuration, for adaptive thickness with depth peeling
/// (it needs every fragment), and for a pool that overflows with growOnOverflow off (with the
/// exact counts).
void captureOnGpu(GpuContext& gpu, const Scene& scene, const Camera& camera, const GpuCaptureConfig& config, GpuCaptureResult& out);

}  // namespace lt
