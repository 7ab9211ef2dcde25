// Embree as the registry sees it (trace/method.h): the geometric baseline and ground truth.
#pragma once

#include "layertrace/trace/method.h"

namespace lt {

inline constexpr MethodInfo kEmbreeMethod{"embree", TracerKind::Geometric, "Embree 3 BVH, default scene flags (the speed baseline)",
                                          "Wald, Woop, Benthin, Johnson, Ernst 2014, Embree: A Kernel Framework for Efficient CPU Ray Tracing (SIGGRAPH)"};
/// The same BVH built with RTC_SCENE_FLAG_ROBUST (watertight edges): the ground truth every
/// ray is graded against (`compare`'s reference, eval/classify.h).
inline constexpr MethodInfo kEmbreeRobustMethod{"embree-robust", TracerKind::Geometric,
                                                "Embree 3 BVH with RTC_SCENE_FLAG_ROBUST (the ground truth rays are graded against)",
                                                "Wald, Woop, Benthin, Johnson, Ernst 2014, Embree: A Kernel Framework for Efficient CPU Ray Tracing (SIGGRAPH)"};

}  // namespace lt
