// The Hi-Z march as the registry sees it (trace/method.h). It has no parameters of its own: its
// pyramid takes --hssr-levels.
#pragma once

#include "layertrace/hiz/hiz_pyramid.h"
#include "layertrace/trace/method.h"

namespace lt {

inline constexpr MethodInfo kHizMethod{"hiz", TracerKind::Screen,
                                       "hierarchical march over a min/max depth pyramid, one interval per cell",
                                       "the Hi-Z march of production engines (Uludag 2014, GPU Pro 5)"};

}  // namespace lt
