// Surfaces the capture touched but could not store. The rasterizer samples pixel centres; a
// triangle thinner than a pixel along its whole length — seen edge-on (its plane through the
// eye: zero area on screen) or nearly — can fall between the centres of every pixel it crosses,
// and then no pixel stores it although it is there. The hybrid tracer's knowledge rule (3) must
// not count the space behind such a surface as known: a ray could pass through it unseen and be
// certified against whatever lies behind (found on assimp's cameras.dae, whose camera sits at
// the apex of a pyramid: 14 % of its reflection rays wrong).
#pragma once

#include <vector>

#include "layertrace/raster/layer_arrays.h"
#include "layertrace/scene/camera.h"
#include "layertrace/scene/scene.h"

namespace lt {

/// What the pass below finds per pixel (row-major, the layers' size); each vector is empty when
/// nothing was marked.
struct UnsampledDepths {
  /// The nearest depth of a surface that crosses the pixel without the pixel holding it (+∞
  /// elsewhere): knowledge ends there (known_space.h, rule 3).
  std::vector<float> unsampled;
  /// The nearest depth of any triangle over the pixel's square where that lies in front of the
  /// pixel's first stored surface (+∞ elsewhere, and on pixels that store nothing — `unsampled`
  /// covers those): a ray can meet a surface that far in front of the centre sample inside the
  /// pixel.
  std::vector<float> nearest;
};

/// `unsampled`: a triangle is thin when, clipped to the near plane and projected, every vertex
/// lies within one pixel of the line through its two farthest vertices, and it is longer than two
/// pixels (smaller triangles are mesh detail between neighbours that are stored; the hybrid's
/// windows cover those). Its pixels are those of the samples every half pixel along that line and
/// their eight neighbours; its depth there is its nearest vertex's (conservative: knowledge ends
/// no later than it must).
///
/// Also every pixel where a triangle has depths the pixel's solid intervals do
/// not hold — in front of its first stored surface, or behind its last one's end, by more than
/// `lastThicknessPx` footprints (the hybrid's solid intervals: the last stored surface of a
/// complete pixel is that deep) — marked with the triangle's nearest depth in the pixel: a
/// triangle covering part of a pixel but not its centre in front of what the pixel stores, and a
/// surface seen at a grazing angle that spans more depth inside one pixel than its interval.
///
/// `nearest`: every triangle over every pixel square it overlaps — a conservative
/// rasterization: the plane's nearest corner where the square lies inside the triangle, the
/// clipped polygon's nearest point on its border — when that is in front of the pixel's first
/// stored surface.
UnsampledDepths unsampledDepths(const Scene& scene, const Camera& camera, const LayerArrays& layers, float lastThicknessPx);

}  // namespace lt
