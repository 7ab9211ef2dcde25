// The hybrid as the registry sees it (trace/method.h).
#pragma once

#include <string>

#include "layertrace/trace/method.h"

namespace lt {

struct HybridConfig {
  std::string screen = "hssr";  ///< the image-space half: hssr, hiz, quadtree or ldc
  std::string geo = "embree";   ///< the geometric half: embree, embree-robust or grid
};

inline constexpr MethodInfo kHybridMethod{"hybrid", TracerKind::Hybrid,
                                          "an image-space tracer first, a geometric one for what the layers cannot know", ""};

/// --hybrid-screen, --hybrid-geo.
std::span<const Param<HybridConfig>> hybridParams();
/// InputError naming the flag for an unknown half.
void validateHybridConfig(const HybridConfig& config);

}  // namespace lt
