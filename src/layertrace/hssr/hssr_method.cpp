#include "layertrace/hssr/hssr_method.h"

#include <cmath>

#include "layertrace/util/error.h"

namespace lt {

// The paper's level count: Fig. 13 shows level 5, and Fig. 9's 147 MB at 720p is the worst case
// of five coarse levels (each, with nothing merged, holds the 29.5 MB of four full base layers
// of 8-byte intervals: 5 × 29.5 MB). "5 levels of our hierarchy" therefore counts the levels
// above the base, and --preset paper builds levels 0 to 5: 6 including level 0.
std::span<const Param<PyramidConfig>> pyramidParams() {
  static const Param<PyramidConfig> params[] = {
      {"--hssr-tau", "--tau", "merge threshold in pixel footprints (paper: 25)", &PyramidConfig::tau, "25"},
      {"--hssr-levels", "--levels", "pyramid levels including level 0, 1..16 (also Hi-Z's; paper: 6, levels 0-5)", &PyramidConfig::levels, "6"},
  };
  return params;
}

std::span<const Param<HssrConfig>> hssrParams() {
  static const Param<HssrConfig> params[] = {
      {"--hssr-n-up", "--n-up", "cells without overlap before ascending a level", &HssrConfig::nUp},
      {"--hssr-parent-ascent", "", "also ascend on entering another parent cell (off: the paper's pure n_up rule)", &HssrConfig::parentAscent, "false"},
      {"--hssr-ray-reloading", "", "GPU: persistent threads pull rays from a queue, a subgroup's lanes reloading one by one where the driver has subgroup operations (paper §5.3; no effect on the CPU)", &HssrConfig::rayReloading, "true"},
  };
  return params;
}

void validatePyramidConfig(const PyramidConfig& c) {
  if (c.levels < 1 || c.levels > 16) inputError("--hssr-levels ", c.levels, ": must be between 1 and 16");
  if (!(c.tau > 0.0f && std::isfinite(c.tau))) inputError("--hssr-tau ", c.tau, ": must be positive and finite");
}

void validateHssrConfig(const HssrConfig& c) {
  if (c.nUp < 1) inputError("--hssr-n-up ", c.nUp, ": must be >= 1");
}

}  // namespace lt
