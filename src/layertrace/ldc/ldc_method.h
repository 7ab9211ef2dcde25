// The layered depth cube as the registry sees it (trace/method.h).
#pragma once

#include "layertrace/ldc/ldc.h"
#include "layertrace/trace/method.h"

namespace lt {

inline constexpr MethodInfo kLdcMethod{"ldc", TracerKind::ViewIndependent,
                                       "three orthographic layered depth images of the scene box, blocked min/max intervals",
                                       "Bürger, Hertel, Krüger, Westermann 2007, GPU Rendering of Secondary Effects (VMV)"};

/// --ldc-resolution, --ldc-block, --ldc-block-intervals, --ldc-epsilon.
std::span<const Param<LdcConfig>> ldcParams();

}  // namespace lt
