#include "layertrace/quadtree/quadtree_method.h"

namespace lt {

std::span<const Param<QuadtreeConfig>> quadtreeParams() {
  static const Param<QuadtreeConfig> params[] = {
      {"--quadtree-lambda-h", "--lambda-h", "zero one-sided depth derivatives above this (Algorithm 1)", &QuadtreeConfig::lambdaH},
      {"--quadtree-lambda-d", "--lambda-d", "Laplacian discontinuity threshold (Algorithm 1)", &QuadtreeConfig::lambdaD},
      {"--quadtree-gamma-norm", "--gamma-norm", "merge planes whose normals differ by less (1 - dot)", &QuadtreeConfig::gammaNorm},
      {"--quadtree-gamma-dist", "--gamma-dist", "merge planes within this relative depth", &QuadtreeConfig::gammaDist},
      {"--quadtree-root-start", "", "start each layer's walk at the root (Algorithm 3 as published) instead of the ray's first pixel",
       &QuadtreeConfig::rootStart, "true"},
      {"--quadtree-printed-line8", "", "Algorithm 1 line 8 as printed: of the two one-sided derivatives, the larger (off: the smaller)",
       &QuadtreeConfig::printedLine8, "true"},
      {"--quadtree-printed-line10", "", "Algorithm 1 line 10 as printed: keep derivatives above lambda-h, zero the small ones",
       &QuadtreeConfig::printedLine10, "true"},
      {"--quadtree-backface-hits", "", "a plane crossed from behind is a hit (off: an occlusion only, as in the pseudo-code)",
       &QuadtreeConfig::backfaceHits, "false"},
  };
  return params;
}

}  // namespace lt
