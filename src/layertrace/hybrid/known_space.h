// What the k layers know, and where a ray leaves that knowledge: the certainty rules of the
// hybrid tracer (docs/methods/hybrid.md).
//
// A screen-space answer is backed by stored data while the ray
//   1. starts inside the view (in front of the near plane, inside the viewport),
//   2. stays inside it: it has not crossed the near plane or the viewport's border, nor gone
//      beyond the far plane where that plane cuts the scene's bounds, and
//   3. at every pixel it crosses stays in front of the pixel's *unknown depth* u(p): the back of
//      the pixel's last stored interval when the capture kept fewer fragments than the pixel's
//      list held (more than k, or merged by adaptive thickness — conservative), +∞ when every
//      fragment of the pixel is stored. With --front-faces-only no back face was captured, so
//      u(p) is the back of the first interval (0 on an uncovered pixel: anything may be there).
//      A triangle thinner than a pixel that crosses the pixel without being stored in it (seen
//      edge-on, raster/unsampled.h) ends the pixel's knowledge at its nearest depth.
// Over [0, knownUntil) a miss is certain, up to the pixel sampling every screen tracer shares;
// from knownUntil on nobody saw what the ray meets.
//
// knownUntil comes from HSSR's march (Hofmann et al. 2017; hssr_march.h) over a pyramid of the
// intervals [u, ∞): exact at level 0 by the same argument as HSSR, with one interval per coarse
// cell (min u) and n_up = 1 — the Hi-Z rule, which fits a single interval per cell. A screen
// tracer that marches solidIntervals() below meets rule 3 itself (the last interval of a
// truncated pixel reaches to ∞); KnownSpace then checks rules 1–2 only, without a march.
#pragma once

#include <cstdint>
#include <span>

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/hssr/hssr_march.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/screen/screen_segment.h"
#include "layertrace/trace/tracer.h"

namespace lt {

/// What a capture stored per pixel, for the rules above.
struct CaptureCoverage {
  const LayerArrays& layers;
  std::span<const uint32_t> complexity;  ///< fragments per pixel (FragmentLists::complexity); empty = unknown
  bool frontFacesOnly = false;
  /// Per pixel, the nearest depth of a surface that crosses the pixel unstored (a triangle thinner
  /// than a pixel: raster/unsampled.h); empty = none. Knowledge ends there too.
  std::span<const float> unsampled = {};
  /// Per pixel, the nearest depth of any surface over the pixel's square where that lies in front
  /// of its first stored surface (raster/unsampled.h); empty = none. The solid intervals start
  /// there.
  std::span<const float> nearest = {};
  /// u(p) of rule 3 for pixel index p (+∞ when the pixel is complete and crossed by no unstored
  /// surface).
  float unknownDepth(size_t p) const;
};

/// The intervals a hybrid's screen march uses (the thickness of Hofmann et al. 2017, §4.2, chosen
/// for an exact check): every stored surface is solid up to the next stored one, so a ray cannot
/// pass behind it between two pixel samples without meeting its interval (no tunnelling — the exact
/// triangle check rejects what is not a crossing); the last stored surface is solid to +∞ where
/// the pixel is truncated (rule 3) and `lastThicknessPx` pixel footprints deep where the pixel
/// is complete (behind it the pixel is known to be empty).
IntervalLayers solidIntervals(const Camera& camera, const CaptureCoverage& coverage, float lastThicknessPx);

class KnownSpace {
 public:
  /// Rules 1–2, and rule 3 unless `frustumOnly` (the screen tracer marches solidIntervals()).
  /// `sceneBounds` decides whether the far plane cuts the scene (rule 2).
  KnownSpace(const Camera& camera, const CaptureCoverage& coverage, const Bounds& sceneBounds, bool frustumOnly = false,
             int levels = 8);

  struct Boundary {
    /// Ray parameter where the ray enters the first pixel it crosses behind u(p) or leaves the
    /// view; ≥ ray.maxDistance when the whole ray stays in known space. 0 when it starts outside.
    float knownUntil = 0.0f;
    /// One pixel of screen motion earlier (≥ 0): where a geometric tracer should take over, so
    /// that a surface the pixel sampling left between two pixels is not skipped.
    float geoFrom = 0.0f;
    bool certain(const Ray& ray) const { return knownUntil >= ray.maxDistance; }
  };
  /// Counted like a tracer (one iteration per visited cell).
  template <class C>
  Boundary boundary(const Ray& ray, C& counters) const;
  /// boundary() of every ray of a batch, uncounted: the rule-3 marches run together through
  /// hssrMarchBatch (vector lanes on the CPU's best target; the same answers bit for bit).
  /// `segments`, when not empty (one per ray), receives makeScreenSegment of each ray, made here
  /// anyway: the caller need not make them again.
  void boundaries(std::span<const Ray> rays, std::span<Boundary> out, std::span<ScreenSegment> segments = {}) const;

  size_t memoryBytes() const { return pyramid_.memoryBytes(); }
  /// Whether boundaries march rule 3 (false: rules 1–2 only, the screen tracer marches the
  /// solid intervals).
  bool marchesUnknownDepths() const { return pyramid_.levelCount() > 0; }
  /// Rule 2's depth beyond which nothing was captured (+∞ when the far plane covers the scene).
  float farLimit() const { return farLimit_; }
  /// Rule 3's pyramid over [u, ∞) (empty when marchesUnknownDepths() is false).
  const IntervalPyramid& pyramid() const { return pyramid_; }
  double buildMs() const { return buildMs_; }

 private:
  /// The boundary from the ray's segment and its rule-3 march (no hit when there was none).
  Boundary finish(const Ray& ray, const ScreenSegment& seg, const MarchHit& m) const;

  const Camera& camera_;
  IntervalPyramid pyramid_;  ///< over [u, ∞); empty when frustumOnly
  float farLimit_;  ///< depth beyond which nothing was captured (+∞ when the far plane covers the scene)
  double buildMs_ = 0.0;
};

}  // namespace lt
