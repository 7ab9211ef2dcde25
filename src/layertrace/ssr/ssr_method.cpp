#include "layertrace/ssr/ssr_method.h"

#include "layertrace/util/error.h"

namespace lt {

std::span<const Param<SsrConfig>> ssrParams() {
  static const Param<SsrConfig> params[] = {
      {"--ssr-stride", "--stride", "pixels per step, >= 1", &SsrConfig::stride},
      {"--ssr-jitter", "--jitter", "start offset in strides, [0, 1]", &SsrConfig::jitter},
      {"--ssr-max-steps", "--max-steps", "step limit (0 = march to the viewport edge; paper: 25)", &SsrConfig::maxSteps, "25"},
      {"--ssr-refine", "", "refine a strided hit by binary search between the last two samples (the listing reports the sample)",
       &SsrConfig::refine, "false"},
  };
  return params;
}

void validateSsrConfig(const SsrConfig& c) {
  if (!(c.stride >= 1.0f && c.stride <= 4096.0f)) inputError("--ssr-stride ", c.stride, ": must be between 1 and 4096 pixels");
  if (!(c.jitter >= 0.0f && c.jitter <= 1.0f)) inputError("--ssr-jitter ", c.jitter, ": must be in [0, 1]");
  if (c.maxSteps < 0) inputError("--ssr-max-steps ", c.maxSteps, ": must be >= 0");
}

}  // namespace lt
