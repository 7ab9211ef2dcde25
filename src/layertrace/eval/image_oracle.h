// The independent image-space oracle (docs/evaluation.md; `--check-oracle`).
//
// Written apart from the screen tracers and sharing none of their traversal code: no screen
// segment, no homogeneous interpolation, no DDA. It works on the 3D ray in double precision:
//   1. clip the segment [0, maxDistance] to the near plane;
//   2. find every parameter t where the ray crosses a pixel column plane (x_px = X) or a pixel
//      row plane (y_px = Y) — each is a plane through the eye, so this is Liang–Barsky on every
//      pixel's frustum column the segment touches — and sort them;
//   3. between consecutive crossings the ray is inside one pixel, over a depth range that is
//      linear in t; test every stored interval of that pixel against it, and take the interval
//      the ray meets first: the smallest entry depth max(front, z_enter) when depth grows, the
//      largest entry depth min(back, z_enter) when it shrinks (ties: the front-most layer when
//      growing, the back-most when shrinking);
//   4. stop at the viewport edge or the segment's end.
// Conventions shared with the tracers (they define what an image-space answer is, not how it is
// computed): the origin's own pixel is not tested (Hofmann et al. 2017, §5.1) — unless the ray
// starts outside the view (behind the near plane or off-screen, e.g. at another camera's eye),
// where it enters the view with no surface of its own; intervals are closed, [front, back] of the
// k-layer arrays.
//
// Where a decision lies within float precision of a boundary, the answer is marked `ambiguous`:
// an overlap test within 1e-5 relative of the interval's ends (plus what a pixel boundary
// sliding along the line by the float line's error does to the ray's depth range), a near tie
// between two intervals, or a pixel corner passed closer than a float line's error (5e-4 px
// plus 4e-6 × the pixels travelled) where the corner pixel holds an overlapping interval, or the
// segment's end that close to a pixel boundary where a pixel on either side holds an interval
// at the end's depth — the float line may or may not reach into that pixel, and the answer
// depends on it (a miss, or a hit in the last pixel). A
// float tracer may legitimately decide such rays either way, so they are counted apart
// (`rays.oracle_ambiguous`) instead of as mismatches.
#pragma once

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/render/ray_observer.h"
#include "layertrace/scene/camera.h"
#include "layertrace/trace/tracer.h"

#include <tbb/enumerable_thread_specific.h>

#include <vector>

namespace lt {

struct OracleAnswer {
  TraceHit hit;
  bool ambiguous = false;
};

class ImageSpaceOracle {
 public:
  ImageSpaceOracle(const Camera& camera, const LayerArrays& layers) : camera_(camera), layers_(layers) {}
  OracleAnswer answer(const Ray& ray) const;

 private:
  const Camera& camera_;
  const LayerArrays& layers_;
};

/// Counts the observed rays whose answer differs from the oracle's (`rays.oracle_mismatch`),
/// apart from those the oracle calls ambiguous (`rays.oracle_ambiguous`). Any-hit rays compare
/// only hit against miss.
class OracleObserver : public RayObserver {
 public:
  explicit OracleObserver(const ImageSpaceOracle& oracle) : oracle_(oracle) {}
  void observe(std::span<const RayEvent> events) override;
  uint64_t mismatches() const;
  uint64_t ambiguous() const;

 private:
  const ImageSpaceOracle& oracle_;
  struct Local {
    uint64_t mismatches = 0, ambiguous = 0;
  };
  tbb::enumerable_thread_specific<Local> local_;
};

}  // namespace lt
