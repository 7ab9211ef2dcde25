// HSSR as the registry sees it (trace/method.h): Hofmann et al. 2017's interval pyramid and
// multi-level DDA. Its pyramid parameters also set the Hi-Z pyramid's levels (hiz/).
#pragma once

#include "layertrace/hssr/hssr_tracer.h"
#include "layertrace/hssr/interval_pyramid.h"
#include "layertrace/trace/method.h"

namespace lt {

inline constexpr MethodInfo kHssrMethod{
    "hssr", TracerKind::Screen, "multi-level DDA over the tau-merged interval pyramid of the k layers",
    "Hofmann, Bogendörfer, Stamminger, Selgrad 2017, Hierarchical Multi-Layer Screen-Space Ray Tracing (HPG)"};

/// --hssr-tau, --hssr-levels.
std::span<const Param<PyramidConfig>> pyramidParams();
/// --hssr-n-up.
std::span<const Param<HssrConfig>> hssrParams();
/// InputError naming the flag for a value out of range.
void validatePyramidConfig(const PyramidConfig& config);
void validateHssrConfig(const HssrConfig& config);

}  // namespace lt
