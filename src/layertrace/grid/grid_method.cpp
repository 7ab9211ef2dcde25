#include "layertrace/grid/grid_method.h"

#include "layertrace/util/error.h"

namespace lt {

std::span<const Param<GridConfig>> gridParams() {
  static const Param<GridConfig> params[] = {
      {"--grid-lambda1", "--lambda1", "top-level density (paper: 0.12)", &GridConfig::lambda1, "0.12"},
      {"--grid-lambda2", "--lambda2", "second-level density (paper: 2.4)", &GridConfig::lambda2},
      {"--grid-max-depth", "", "cap on each top cell's octree depth (levels; paper: up to 15, i.e. 2^15 per axis)", &GridConfig::maxDepth, "15"},
      {"--grid-one-depth-per-cell", "", "one octree depth per top cell, from its longest side (off: each axis its own)",
       &GridConfig::oneDepthPerCell, "true"},
      {"--grid-partial-expansion", "--partial-expansion",
       "also expand into neighbours whose swept part holds only shared primitives", &GridConfig::partialExpansion, "false"},
      {"--grid-gpu-build", "", "--device gpu: build the grid on the GPU (all four steps as compute passes: the CPU build's cells)",
       &GridConfig::gpuBuild},
  };
  return params;
}

void validateGridConfig(const GridConfig& c) {
  if (!(c.lambda1 > 0.0f)) inputError("--grid-lambda1 ", c.lambda1, ": must be positive");
  if (!(c.lambda2 > 0.0f)) inputError("--grid-lambda2 ", c.lambda2, ": must be positive");
  if (c.maxDepth < 0 || c.maxDepth > 15) inputError("--grid-max-depth ", c.maxDepth, ": must be between 0 and 15");
}

}  // namespace lt
