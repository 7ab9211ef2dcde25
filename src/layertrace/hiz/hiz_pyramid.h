// The Hi-Z march of production engines (AMD FidelityFX SSSR, Unity HDRP, Godot; Uludag, GPU
// Pro 5), over this project's k-layer intervals.
//
// A Hi-Z pyramid keeps one depth range per cell: production engines keep the minimum depth of
// one depth buffer (a cell is empty in front of it), we keep [min front, max back] over all k
// intervals of the cell's pixels — the min/max depth mip of the k-layer arrays, so the march has
// the same multi-layer thickness semantics as ssr-layers and HSSR (choice: a min-only pyramid of
// the front layer would be the single-layer ssr's Hi-Z; the comparison is between structures
// over the same stored data). That range is exactly the interval pyramid of
// Hofmann et al. 2017, §4.3, with τ = ∞ (every child merged into one interval), which is
// conservative by construction, and the stackless Hi-Z march — go up a level after crossing a
// cell without overlap, down on an overlap, hits at level 0 — is HSSR's traversal with n_up = 1.
// Sharing that traversal keeps hiz exact against the oracles; what differs from HSSR is only
// what the pyramid stores.
#pragma once

#include <limits>

#include "layertrace/hssr/hssr_tracer.h"
#include "layertrace/hssr/interval_pyramid.h"

namespace lt {

/// A min/max pyramid: `levels` levels (level 0 = the k intervals of each pixel), each coarser
/// cell one interval [min front, max back] over its children.
inline IntervalPyramid buildHizPyramid(const LayerArrays& layers, const Camera& camera, int levels) {
  return buildIntervalPyramid(layers, camera, PyramidConfig{levels, std::numeric_limits<float>::infinity()});
}

/// The Hi-Z march's configuration: ascend after every cell without overlap.
inline HssrConfig hizConfig(int levels) {
  HssrConfig c;
  c.nUp = 1;
  c.maxLevels = levels;
  c.name = "hiz";
  return c;
}

}  // namespace lt
