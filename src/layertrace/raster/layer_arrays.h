// Sorted, truncated per-pixel arrays of the k front-most fragments (Hofmann et al. 2017, §4.2,
// Figure 3 centre): each pixel owns k slots whether or not it fills them (coherent indexing, no
// synchronisation), and each kept fragment carries its z-thickness in place of the list pointer,
// giving the interval [depth, depth + thickness].
#pragma once

#include <cstdint>
#include <vector>

#include "layertrace/raster/fragment_lists.h"

namespace lt {

struct LayerConfig {
  int k = 4;                 ///< layers kept per pixel, 1..16 (Hofmann et al. 2017, §4.2: "4 to 8")
  /// z-thickness of every fragment in scene units (Hofmann et al. 2017, §4.2: "fixed,
  /// scene-dependent [McGuire and Mara 2014] or adaptive"). thickness + thicknessPerDepth must
  /// be > 0.
  float thickness = 0.1f;
  /// Minimum separation between successive kept fragments (McGuire & Mara's deep G-buffer
  /// rule, optional in Hofmann et al. 2017, §4.2); 0 disables it.
  float minSeparation = 0.0f;
  /// The adaptive thickness of Hofmann et al. 2017, §4.2: a fragment that starts inside the
  /// previous kept interval is merged into it (the interval grows to cover it) instead of taking a
  /// layer, so the k slots reach deeper. The merged interval keeps the front fragment's attributes.
  bool adaptiveThickness = false;
  /// Plus this much per unit of depth: N pixel footprints at the fragment's own depth is
  /// thicknessPerDepth = N / focal (pipeline: --thickness-px, the default). A fixed thickness is
  /// too thin far away and too thick near the camera; one that grows with the footprint keeps
  /// the same screen-space meaning at every depth.
  float thicknessPerDepth = 0.0f;
  float thicknessAt(float depth) const { return thickness + thicknessPerDepth * depth; }
};

struct LayerArrays {
  int width = 0, height = 0, k = 0;
  /// Pool vectors (util/default_init.h): sized without zeroing — every writer fills every slot
  /// — and backed by transparent huge pages, so a cold first frame faults 512× less often
  /// (the CLI captures exactly one frame).
  PoolVector<FragmentNode> slots;  ///< pixel-major: slots[(y * width + x) * k + layer]
  std::vector<uint8_t> count;      ///< valid slots per pixel (≤ k)
  PoolVector<uint32_t> triangle;   ///< side channel: scene triangle of each slot

  size_t pixelIndex(int x, int y) const { return size_t(y) * size_t(width) + size_t(x); }
  const FragmentNode* pixel(int x, int y) const { return &slots[pixelIndex(x, y) * size_t(k)]; }
  int countAt(int x, int y) const { return count[pixelIndex(x, y)]; }
  size_t memoryBytes() const {
    return slots.size() * sizeof(FragmentNode) + count.size() + triangle.size() * sizeof(uint32_t);
  }
};

/// Throws InputError naming the option for k outside 1..16, a negative, non-finite or zero
/// thickness, or a negative minimum separation.
void validateLayerConfig(const LayerConfig& config);

/// Insertion sort of each pixel's list, keeping the k front-most fragments (ties keep list
/// order, so the result is deterministic). Throws InputError for k outside 1..16 or a
/// non-positive thickness.
LayerArrays sortAndTruncate(const FragmentLists& lists, const LayerConfig& config);

}  // namespace lt
