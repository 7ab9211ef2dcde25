#include "layertrace/hybrid/hybrid_method.h"

#include "layertrace/util/error.h"

namespace lt {

std::span<const Param<HybridConfig>> hybridParams() {
  static const Param<HybridConfig> params[] = {
      {"--hybrid-screen", "", "the image-space half: hssr, hiz, quadtree or ldc", &HybridConfig::screen},
      {"--hybrid-geo", "", "the geometric half for what the layers do not know: embree, embree-robust or grid", &HybridConfig::geo},
  };
  return params;
}

void validateHybridConfig(const HybridConfig& c) {
  if (c.screen != "hssr" && c.screen != "hiz" && c.screen != "quadtree" && c.screen != "ldc")
    inputError("--hybrid-screen ", c.screen, ": unknown (use hssr, hiz, quadtree or ldc)");
  if (c.geo != "embree" && c.geo != "embree-robust" && c.geo != "grid")
    inputError("--hybrid-geo ", c.geo, ": unknown (use embree, embree-robust or grid)");
}

}  // namespace lt
