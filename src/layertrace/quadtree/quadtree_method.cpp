#include "layertrace/quadtree/quadtree_method.h"

namespace lt {

std::span<const Param<QuadtreeConfig>> quadtreeParams() {
  static const Param<QuadtreeConfig> params[] = {
      {"--quadtree-lambda-h", "--lambda-h", "zero one-sided depth derivatives above this (Algorithm 1)", &QuadtreeConfig::lambdaH},
      {"--quadtree-lambda-d", "--lambda-d", "Laplacian discontinuity threshold (Algorithm 1)", &QuadtreeConfig::lambdaD},
      {"--quadtree-gamma-norm", "--gamma-norm", "merge planes whose normals differ by less (1 - dot)", &QuadtreeConfig::gammaNorm},
      {"--quadtree-gamma-dist", "--gamma-dist", "merge planes within this relative depth", &QuadtreeConfig::gammaDist},
  };
  return params;
}

}  // namespace lt
