#include "layertrace/grid/grid_method.h"

#include "layertrace/util/error.h"

namespace lt {

std::span<const Param<GridConfig>> gridParams() {
  static const Param<GridConfig> params[] = {
      {"--grid-lambda1", "--lambda1", "top-level density (paper: 0.12)", &GridConfig::lambda1, "0.12"},
      {"--grid-lambda2", "--lambda2", "second-level density (paper: 2.4)", &GridConfig::lambda2},
      {"--grid-partial-expansion", "--partial-expansion",
       "also expand into neighbours whose swept part holds only shared primitives", &GridConfig::partialExpansion, "false"},
  };
  return params;
}

void validateGridConfig(const GridConfig& c) {
  if (!(c.lambda1 > 0.0f)) inputError("--grid-lambda1 ", c.lambda1, ": must be positive");
  if (!(c.lambda2 > 0.0f)) inputError("--grid-lambda2 ", c.lambda2, ": must be positive");
}

}  // namespace lt
