// Layered depth cube (Bürger et al. 2007: Bürger, Hertel, Krüger, Westermann, "GPU Rendering of
// Secondary Effects", VMV 2007): three
// orthographic layered depth images (LDIs) along the axes of the scene's box, each holding every
// fragment of the triangles that face its axis, with a coarse min/max block grid for skipping
// empty space (§1.3) and a two-level DDA that traces any ray through them (§1.4).
//
// Unlike the camera's k layers it is view independent: it answers rays that leave the frustum or
// pass behind the k-th layer. It is built from the scene with this project's rasterizer (an
// orthographic camera per axis and a triangle mask), so it lives with the screen structures —
// it stores samples, not triangles, and its hits are as exact as its texels.
//
// Choices where the paper is open:
//  - Box and texel: the scene box padded by one texel on every side; the texel is square and the
//    same on all three axes, resolution = texels along the longest (padded) box axis, the other
//    axes get ceil(extent / texel) (non-square extents cost no stretched texels).
//  - Axis of a triangle (Fig. 5): the largest |component| of its geometric normal; ties go to the
//    lower axis (x before y before z). Zero-area triangles are skipped (no ray can hit them;
//    Embree skips them too) and counted.
//  - Thin triangles: a triangle that covers no texel centre of its LDI gets one sample at the
//    texel of its centroid (depth, normals and material of the centroid) — the "centroid texel"
//    policy; they are counted as lost_triangles so a user sees how many were rescued this way.
//  - Hit test (§1.4 uses a point distance < 0.001 world units, which does not scale): a sample is
//    the patch of its triangle's plane over its texel, widened by epsilon texels on each side. A
//    ray hits it when the ray meets that plane inside the widened texel. The plane is the
//    triangle's *geometric* normal, kept in the node's 4th word (octahedral; the list pointer /
//    thickness of the camera layers has no meaning here), so flat surfaces are hit exactly; the
//    2nd word keeps the shading normal as in the camera layers. epsilon closes the cracks between
//    texels and between the LDIs that share a surface's triangles.
//  - Secondary rays (Ray::startsOnSurface) ignore hits closer than one texel: the surface they
//    start on is sampled at texel resolution and would otherwise be hit again. (Measured on the
//    default scene against ignoring only the samples within 1.5 texels of the origin: 99.75 %
//    vs 99.69 % correct, 32.4 vs 31.2 dB.)

#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec2.hpp>

#include "layertrace/raster/fragment.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"
#include "layertrace/trace/tracer.h"

namespace lt {

struct LdcConfig {
  int resolution = 1024;  ///< texels along the longest box axis (--ldc-resolution; paper: 512, 1024)
  int block = 8;          ///< coarse block edge in texels (--ldc-block, §1.3)
  float epsilon = 0.25f;  ///< hit tolerance in texels (--ldc-epsilon; see the header comment)
  /// Depth intervals per block (--ldc-block-intervals). 1 is §1.3's min/max over all layers; in
  /// a room every block then spans floor to ceiling and skips nothing, so by default a block
  /// keeps up to 4 disjoint intervals covering its samples (the 3 widest gaps between sorted
  /// sample depths are left out) — the merged z-intervals of Hofmann et al. 2017 applied to the
  /// LDI.
  int blockIntervals = 4;
  /// Bürger et al. 2007, §1.4's hit test: a hit where the ray passes a stored sample (its
  /// texel's centre at its depth) closer than this, in world units (the paper: 0.001). 0, the
  /// default, intersects the sample's tangent-plane patch instead (above): an absolute distance
  /// does not scale with the scene or the texel size. Tested against the samples of the texels
  /// the ray crosses.
  float hitDistance = 0.0f;
};

/// InputError naming the option for values out of range (resolution 16..16384, block 1..256,
/// epsilon 0..4, block intervals 1..16).
void validateLdcConfig(const LdcConfig& config);

/// One orthographic layered depth image, looking along +axis from the box's low side.
struct LdcView {
  int axis = 0;
  Camera camera;  ///< orthographic; its camera space is the view's space (depth = -z)
  int width = 0, height = 0;
  /// Texel (x, y) holds samples[offset[y * width + x] .. offset[y * width + x + 1]), sorted by
  /// depth (ties by triangle). Node: depth (view depth), shading normal (view space, octahedral),
  /// albedoSpec, and the triangle's geometric normal (view space, octahedral) in `next`.
  std::vector<uint32_t> offset;
  std::vector<FragmentNode> samples;
  std::vector<uint32_t> triangle;  ///< side channel: scene triangle of each sample
  int blocksX = 0, blocksY = 0;
  /// Per block, config.blockIntervals slots of [front, back] sample depths, sorted; unused slots
  /// are empty (front > back). One slot holds the block's min and max (§1.3).
  std::vector<glm::vec2> blockIntervals;
  uint64_t triangles = 0;      ///< triangles given to this axis
  uint64_t lostTriangles = 0;  ///< of those, covering no texel centre (one centroid sample each)
  double rasterMs = 0.0;

  size_t texelIndex(int x, int y) const { return size_t(y) * size_t(width) + size_t(x); }
  uint32_t countAt(int x, int y) const { return offset[texelIndex(x, y) + 1] - offset[texelIndex(x, y)]; }
  size_t memoryBytes() const;
};

struct LayeredDepthCube {
  LdcConfig config;
  Bounds box;          ///< padded scene box
  float texel = 0.0f;  ///< texel edge in scene units (all axes)
  std::array<LdcView, 3> views;
  uint64_t degenerateTriangles = 0;  ///< zero-area (or non-finite) triangles, in no view
  double buildMs = 0.0;

  uint64_t samples() const { return views[0].samples.size() + views[1].samples.size() + views[2].samples.size(); }
  uint64_t lostTriangles() const { return views[0].lostTriangles + views[1].lostTriangles + views[2].lostTriangles; }
  size_t memoryBytes() const { return views[0].memoryBytes() + views[1].memoryBytes() + views[2].memoryBytes(); }
};

/// Builds the three LDIs and their block grids (Bürger et al. 2007, §1.2–1.3). Throws InputError
/// for an empty scene, invalid options or a structure over the memory limit (util/memory.h).
LayeredDepthCube buildLdc(const Scene& scene, const LdcConfig& config = {});

/// Traces camera-space rays through a layered depth cube (§1.4). Hits carry the sample's
/// triangle, its shading normal and material, the point where the ray meets the sample's plane,
/// layer -1 (not a camera layer) and the camera pixel the point projects to (or -1).
/// Counters: iterations = visited blocks (level 1) + visited texels (level 0); intervals =
/// samples tested; pixels = visited texels.
class LdcTracer : public TracerImpl<LdcTracer> {
 public:
  LdcTracer(const Camera& camera, const LayeredDepthCube& ldc);
  const char* name() const override { return "ldc"; }
  template <class C>
  TraceHit traceImpl(const Ray& ray, C& counters) const {
    return traceAny<false>(ray, counters);
  }
  template <class C>
  TraceHit occludedImpl(const Ray& ray, C& counters) const {
    return traceAny<true>(ray, counters);
  }

 private:
  struct ViewHit;
  template <bool AnyHit, class C>
  TraceHit traceAny(const Ray& ray, C& counters) const;
  template <bool AnyHit, class C>
  /// One LDI; `found` says whether an earlier LDI hit (then tMax is that hit). Returns whether
  /// any LDI so far hit.
  bool traceView(const LdcView& view, glm::vec3 worldOrigin, glm::vec3 worldDir, float tMin, float& tMax, bool found,
                 ViewHit& hit, C& counters) const;

  const Camera& camera_;
  const LayeredDepthCube& ldc_;
};

}  // namespace lt
