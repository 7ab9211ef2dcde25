// The adaptive quad-tree as the registry sees it (trace/method.h).
#pragma once

#include "layertrace/quadtree/quadtree.h"
#include "layertrace/trace/method.h"

namespace lt {

inline constexpr MethodInfo kQuadtreeMethod{
    "quadtree", TracerKind::Screen, "per-layer quad-tree of depth planes and boxes",
    "Widmer, Pajak, Schulz, Pulli, Kautz, Goesele, Luebke 2015, An Adaptive Acceleration Structure for Screen-space Ray Tracing (HPG)"};

/// --quadtree-lambda-h, --quadtree-lambda-d, --quadtree-gamma-norm, --quadtree-gamma-dist.
std::span<const Param<QuadtreeConfig>> quadtreeParams();

}  // namespace lt
