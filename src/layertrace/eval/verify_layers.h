// `layers --verify`: the rasterizer's fragment lists against Embree's all-hit primary rays.
#pragma once

#include <cstdint>

#include "layertrace/geometry/embree_scene.h"
#include "layertrace/raster/fragment_lists.h"
#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"

namespace lt {

struct VerifyResult {
  uint64_t pixels = 0;
  uint64_t matching = 0;       ///< same number of surfaces, every depth within tolerance
  uint64_t fewerFragments = 0;  ///< Embree found more surfaces than the list holds
  uint64_t moreFragments = 0;   ///< the list holds more fragments than Embree found
  uint64_t depthMismatch = 0;   ///< same count, some depth outside tolerance
  double matchFraction() const { return pixels ? double(matching) / double(pixels) : 1.0; }
};

/// Relative depth tolerance of the comparison. Both sides evaluate the same pixel-centre ray
/// against the same plane in float, so they agree to a few ulps except at grazing angles.
inline constexpr float kVerifyRelativeTolerance = 1e-4f;
/// ...where the plane's distance along the ray, n·(p − e) / (n·d), is ill-conditioned: rounding
/// the coordinates (magnitude M) moves the numerator by about ε·M on either side, and dividing by
/// cos θ = |n·d| amplifies that. A depth may also differ by this many float epsilons of M over
/// cos θ. Found by a sweep of random views: a random eye 4.5·10⁻⁶ units under a textured plane it
/// sees, 5.75 units from the origin (assimp's TexturedPlane_ImageUv*_248.blend), made the two
/// sides' depths differ by up to 3 % on 911 and 1 352 pixels; 0.5 epsilons already match them all,
/// 4 leave a margin, and 16 would no longer see a depth doubled there
/// (Verify.GrazingPlaneMatchesWithinItsConditioning). At 60° incidence the term is 10⁻⁶ of a depth
/// of 1 at coordinates of 1; the real views' residues (shared edges, silhouettes) are unchanged by
/// it.
inline constexpr float kVerifyConditioningEpsilons = 4.0f;

/// The depth tolerance at one hit: `depth` along `dir` (world space, unit depth component) from
/// `eye`, on a surface with (unnormalised) normal `normal`.
float verifyDepthTolerance(float depth, glm::vec3 eye, glm::vec3 dir, glm::vec3 normal);

/// For each pixel, casts the pixel-centre ray through Embree between the near and far planes,
/// collects all hits (deduplicated by triangle) and compares them with the pixel's list.
/// With `frontFacesOf` (the scene of a --front-faces-only capture), Embree's hits on triangles
/// facing away from the eye (the rasterizer's rule: clockwise seen from the eye) are left out.
VerifyResult verifyLayers(const FragmentLists& lists, const Camera& camera, const EmbreeScene& embree, const Scene* frontFacesOf = nullptr);

/// The same for a capture that kept only the k layer arrays (depth peeling): each pixel's k
/// layers against the first k surfaces Embree finds along its ray.
VerifyResult verifyLayerArrays(const LayerArrays& layers, const Camera& camera, const EmbreeScene& embree,
                               const Scene* frontFacesOf = nullptr);

/// Two captures of one view compared slot by slot (the GPU's against the CPU's): a pixel-layer
/// matches when both hold a fragment of the same triangle at depths within `relativeTolerance`,
/// or neither holds one.
struct LayerAgreement {
  uint64_t pixelLayers = 0;   ///< width × height × k
  uint64_t matching = 0;
  uint64_t countsDiffer = 0;  ///< pixels whose number of layers differs
  uint64_t filled = 0;        ///< pixel-layers holding a fragment in both
  uint64_t sameBits = 0;      ///< matching pixel-layers whose depth, normal and material are the same bits
  double matchFraction() const { return pixelLayers ? double(matching) / double(pixelLayers) : 1.0; }
};
LayerAgreement compareLayerArrays(const LayerArrays& a, const LayerArrays& b, float relativeTolerance);

/// Embree's answer to capture: every hit of every pixel-centre ray between the near and far
/// planes, collected (and deduplicated) as verifyLayers does, without the comparison — the
/// geometric ray tracer's cost of the fragments the rasterizer produces. Returns the hit count.
uint64_t embreeCapture(const Camera& camera, const EmbreeScene& embree);

}  // namespace lt
