// The irregular grid as the registry sees it (trace/method.h).
#pragma once

#include "layertrace/grid/irregular_grid.h"
#include "layertrace/trace/method.h"

namespace lt {

inline constexpr MethodInfo kGridMethod{"grid", TracerKind::Geometric, "two-level grid with expanded, merged irregular cells",
                                        "Perard-Gayot, Kalojanov, Slusallek 2017, GPU Ray Tracing using Irregular Grids (Eurographics)"};

/// --grid-lambda1, --grid-lambda2, --grid-partial-expansion.
std::span<const Param<GridConfig>> gridParams();
/// InputError naming the flag for a value out of range.
void validateGridConfig(const GridConfig& config);

}  // namespace lt
