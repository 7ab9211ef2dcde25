// Per-pixel linked lists of all rasterized fragments (Hofmann et al. 2017, §4.1; Yang et al. 2010).
#pragma once

#include <cstdint>
#include <vector>

#include "layertrace/raster/fragment.h"
#include "layertrace/util/default_init.h"

namespace lt {

struct FragmentLists {
  int width = 0;
  int height = 0;
  std::vector<uint32_t> head;        ///< per pixel: first node, kNullIndex when empty
  std::vector<uint32_t> complexity;  ///< per pixel: fragments generated, stored or lost (exact)
  PoolVector<FragmentNode> nodes;   ///< the preallocated pool; capacity = nodes.size()
  /// Per node: the scene triangle it came from. Not part of the 16-byte node: an evaluation
  /// side channel (verification against Embree, material lookup for effects).
  PoolVector<uint32_t> triangle;
  uint64_t generated = 0;  ///< fragments the rasterizer produced
  uint64_t stored = 0;     ///< fragments written to the pool
  uint64_t lost() const { return generated - stored; }
  uint64_t capacity() const { return nodes.size(); }

  size_t pixelIndex(int x, int y) const { return size_t(y) * size_t(width) + size_t(x); }

  /// Bytes of heads, counters and the pool (the "lists" stage of Hofmann et al. 2017, Figure 9).
  size_t memoryBytes() const {
    return head.size() * sizeof(uint32_t) + complexity.size() * sizeof(uint32_t) +
           nodes.size() * sizeof(FragmentNode) + triangle.size() * sizeof(uint32_t);
  }
};

}  // namespace lt
